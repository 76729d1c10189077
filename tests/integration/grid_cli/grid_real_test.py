#!/usr/bin/env python3
"""CLI tests of grid least squares on real measurements (SPEC §5, issue 10): damaged marks,
stages larger than the plate, weights, residuals and outliers, covariance, drift, the plan
designer, and the bad inputs of the new columns and headers.

Usage: grid_real_test.py CLI TMPDIR CASE
Assertions compare against the simulated truth or what the input says, never against stored
outputs of selfcal itself.
"""
import json
import math
import os
import re
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import clitest  # noqa: E402  (the shared preamble: tests/integration/clitest.py)
from clitest import fail, fresh_dir, map_error, rows, run, simulate  # noqa: E402

CLI, TMP, CASE = clitest.setup("grid_real_", timeout=600)


def data_lines(path):
    lines = open(path).read().splitlines(True)
    h = next(k for k, l in enumerate(lines) if l.startswith("view,"))
    return lines, h


def case_damaged():
    """The issue's reproduction: Ye N = 9, the rows of mark (0,0) deleted; and a stitched,
    rectangular, weighted plan with the centre mark deleted. Noise-free: truth to 1e-9 um."""
    d = fresh_dir("damaged")
    s = simulate(d, "ye9", "--plan", "ye", "--n", 9, "--sigma-r-um", 0)
    lines, h = data_lines(s["inp"])
    cut = [l for k, l in enumerate(lines) if k <= h or l.split(",")[1:3] != ["0", "0"]]
    path = os.path.join(d, "ye9_dmg.csv")
    open(path, "w").write("".join(cut))
    g, a = os.path.join(d, "g.csv"), os.path.join(d, "a.csv")
    run("grid", "--method", "lsq", path, "--map", g, "--artifact", a)
    e = map_error(g, s["g"])
    if e > 1e-9:
        fail("damaged Ye: G error %g" % e)
    art = {(r["i"], r["j"]): r for r in rows(a)}
    if art[("0", "0")]["ax_um"] != "" or art[("0", "0")]["ay_um"] != "":
        fail("the unmeasured mark's plate error is not empty: %r" % art[("0", "0")])
    if art[("0", "1")]["ax_um"] == "":
        fail("a measured mark's plate error is empty")
    # the exact methods refuse it (they need every mark)
    run("grid", "--method", "ye", path, "--map", g, expect=2)
    # stitched rectangular stage, centre mark damaged, each row its own stated uncertainty
    s = simulate(d, "st", "--plan", "stitch", "--n", 7, "--stage", "15,9", "--sigma-r-um", 0)
    lines, h = data_lines(s["inp"])
    if "# stage = 15,9" not in "".join(lines[:h]):
        fail("simulate did not write the stage")
    out = lines[:h] + [lines[h].rstrip("\n") + ",ux_um,uy_um\n"]
    for k, l in enumerate(lines[h + 1:]):
        if l.split(",")[1:3] != ["3", "3"]:
            out.append(l.rstrip("\n") + ",%g,%g\n" % (0.01 + 0.001 * (k % 7), 0.02 - 0.001 * (k % 5)))
    path = os.path.join(d, "st_dmg.csv")
    open(path, "w").write("".join(out))
    sm = os.path.join(d, "st_S.json")
    run("grid", "--method", "lsq", path, "--map", g, "--artifact", a, "--summary", sm)
    e = map_error(g, s["g"])
    if e > 1e-9 or len(rows(g)) != 15 * 9:
        fail("stitched: G error %g, %d rows" % (e, len(rows(g))))
    S = json.load(open(sm))
    if S["stage"] != [15, 9] or not S["weighted"]:
        fail("summary: %r" % S)
    art = {(r["i"], r["j"]): r for r in rows(a)}
    if art[("3", "3")]["ax_um"] != "":
        fail("damaged centre mark not empty")
    # per-view noise in the simulator: written as sigma_um= on the view lines
    s = simulate(d, "vs", "--plan", "ye", "--n", 7, "--view-sigma-r-um", "0.01,0.02,0.03")
    if "sigma_um=0.02" not in open(s["inp"]).read():
        fail("simulate did not write sigma_um")
    print("damaged: ok")


def case_weights():
    """Weighted data with the stated noise: the variance factor passes; a wrong --sigma-r-um on
    unweighted data gives a warning and exit 0."""
    d = fresh_dir("weights")
    s = simulate(d, "w", "--plan", "ye", "--n", 15, "--view-sigma-r-um", "0.01,0.03,0.02", "--seed", 3)
    g, sm = os.path.join(d, "g.csv"), os.path.join(d, "s.json")
    p = run("grid", "--method", "lsq", s["inp"], "--map", g, "--summary", sm)
    S = json.load(open(sm))
    vf = S["variance_factor"]
    lo, hi = S["chi2_95_interval"]
    if not (lo < 1 < hi) or not (lo <= vf <= hi) or S["chi2_test"] != "pass":
        fail("variance factor %r interval %r" % (vf, (lo, hi)))
    if p.stderr:
        fail("warnings on clean weighted data: %s" % p.stderr)
    # uncertainties follow the stated weights: a map's u is that of sigma 1 times the weights
    m = rows(g)
    if not all(r["ugx_um"] != "" for r in m):
        fail("uncertainties missing")
    # the closed form on the same weighted file: its noise estimate is the equal-weight least
    # squares' sigma_r in um (the data are the unweighted file's), with that fit's dof
    lines, h = data_lines(s["inp"])
    bare = os.path.join(d, "bare.csv")
    open(bare, "w").write("".join(re.sub(r" sigma_um=\S+", "", l) if l.startswith("# view") else l
                                  for l in lines))
    sy, sb = os.path.join(d, "sy.json"), os.path.join(d, "sb.json")
    run("grid", "--method", "ye", s["inp"], "--map", g, "--summary", sy)
    run("grid", "--method", "lsq", bare, "--map", g, "--summary", sb)
    Y, B = json.load(open(sy)), json.load(open(sb))
    if abs(Y["sigma_r_est_um"] - B["sigma_r_est_um"]) > 1e-12 * B["sigma_r_est_um"] or \
            Y["dof"] != B["dof"] or not 0.005 < Y["sigma_r_est_um"] < 0.05:
        fail("ye on weighted data: sigma_r_est_um %r dof %r, lsq unweighted %r dof %r"
             % (Y["sigma_r_est_um"], Y["dof"], B["sigma_r_est_um"], B["dof"]))
    # the same data with the columns ux_um,uy_um (values from sigma_um) read the same
    sig = {}
    for l in lines[:h]:
        if l.startswith("# view"):
            sig[l.split()[2].rstrip(":")] = l.split("sigma_um=")[1].split()[0]
    out = [l.replace(" sigma_um=" + sig[l.split()[2].rstrip(":")], "") if l.startswith("# view") else l
           for l in lines[:h]]
    out.append(lines[h].rstrip("\n") + ",ux_um,uy_um\n")
    for l in lines[h + 1:]:
        v = l.split(",")[0]
        out.append(l.rstrip("\n") + ",%s,%s\n" % (sig[v], sig[v]))
    p2 = os.path.join(d, "cols.csv")
    open(p2, "w").write("".join(out))
    g2, sm2 = os.path.join(d, "g2.csv"), os.path.join(d, "s2.json")
    run("grid", "--method", "lsq", p2, "--map", g2, "--summary", sm2)
    if abs(json.load(open(sm2))["variance_factor"] - vf) > 1e-9 * vf:
        fail("columns and sigma_um= disagree")
    # --sigma-r-um 10x too small on unweighted data: a warning, exit 0
    s = simulate(d, "u", "--plan", "ye", "--n", 15, "--sigma-r-um", 0.01)
    p = run("grid", "--method", "lsq", s["inp"], "--map", g, "--summary", sm, "--sigma-r-um", 0.001)
    if "disagree" not in p.stderr or len(p.stderr.strip().splitlines()) > 3:
        fail("no sigma warning: %r" % p.stderr)
    S = json.load(open(sm))
    if S["chi2_test"] != "fail" or not S["variance_factor"] > 50:
        fail("summary chi2: %r" % S)
    # --sigma-r-um on a file that states its noise: ignored with a warning, same result
    p = run("grid", "--method", "lsq", p2, "--map", g, "--summary", sm2, "--sigma-r-um", 0.5)
    if "is ignored" not in p.stderr or abs(json.load(open(sm2))["variance_factor"] - vf) > 1e-9 * vf:
        fail("--sigma-r-um on weighted data: %r" % p.stderr)
    # ... and the summaries say the stated uncertainties were used, not the ignored sigma
    S2 = json.load(open(sm2))
    if S2["stated_uncertainties"] is not True or S2["sigma_r_used_um"] != 1:
        fail("--sigma-r-um on weighted data, summary: %r" % S2)
    if "the data state their uncertainties" not in p.stdout or "from the least-squares" in p.stdout:
        fail("--sigma-r-um on weighted data, stdout summary: %r" % p.stdout)
    if json.load(open(sm))["stated_uncertainties"] is not False:
        fail("unweighted data said to state their uncertainties")
    print("weights: ok")


def case_outliers():
    """One mark 5 um off (sigma_r 10 nm): flagged with a warning (exit 0); --reject-outliers
    removes it, names it on stderr, and the map is close to the truth again."""
    d = fresh_dir("outliers")
    s = simulate(d, "o", "--plan", "ye", "--n", 15, "--sigma-r-um", 0.01, "--seed", 5)
    lines, h = data_lines(s["inp"])
    k = next(k for k, l in enumerate(lines) if k > h and l.startswith("1,6,8,"))
    f = lines[k].rstrip("\n").split(",")
    f[3] = "%.15f" % (float(f[3]) + 0.005)
    lines[k] = ",".join(f) + "\n"
    path = os.path.join(d, "bad.csv")
    open(path, "w").write("".join(lines))
    g, r, sm = os.path.join(d, "g.csv"), os.path.join(d, "r.csv"), os.path.join(d, "s.json")
    p = run("grid", "--method", "lsq", path, "--map", g, "--residuals", r, "--summary", sm)
    warn = [l for l in p.stderr.splitlines() if "outlier" in l]
    if not any("view 1 mark (6,8)" in l for l in warn):
        fail("no warning for the outlier: %r" % p.stderr)
    R = rows(r)
    if list(R[0].keys()) != ["view", "i", "j", "rx_um", "ry_um", "tx", "ty", "outlier"]:
        fail("residual columns %r" % list(R[0].keys()))
    flagged = [(x["view"], x["i"], x["j"]) for x in R if x["outlier"] == "1"]
    if ("1", "6", "8") not in flagged:
        fail("outlier not flagged: %r" % flagged)
    err_before = map_error(g, s["g"])
    p = run("grid", "--method", "lsq", path, "--map", g, "--residuals", r, "--reject-outliers")
    if "removed outlier view 1 mark (6,8)" not in p.stderr:
        fail("reject did not name the row: %r" % p.stderr)
    R = {(x["view"], x["i"], x["j"]): x for x in rows(r)}
    x = R[("1", "6", "8")]
    if x["outlier"] != "1" or abs(float(x["rx_um"]) - 5.0) > 0.1:
        fail("removed row in R.csv: %r" % x)
    m = rows(g)
    err_after = map_error(g, s["g"])
    umax = max(float(q["ugx_um"]) for q in m)
    if not (err_after < 6 * umax < err_before):
        fail("map error %g before, %g after rejection (u max %g)" % (err_before, err_after, umax))
    nflag = sum(1 for q in R.values() if q["outlier"] == "1")
    if nflag > 3:
        fail("%d rows flagged after rejection" % nflag)
    print("outliers: ok (error %.3g -> %.3g um)" % (err_before, err_after))


def case_outlier_test():
    """The outlier test's significance: by default 0.05 for the whole data set, so that clean
    simulated plates (Petro N = 25, ~3800 coordinates) stay quiet, where Baarda's 0.001 for each
    coordinate (--outlier-alpha-each) flags several marks on nearly every one; the summary, the
    printed summary and the residual file agree with the warnings; bad values exit 2."""
    d = fresh_dir("outlier_test")
    quiet = noisy = 0
    tsq = []
    for seed in range(1, 7):
        s = simulate(d, "p%d" % seed, "--plan", "double-shift", "--seed", seed)
        g, r, sm = (os.path.join(d, "p%d_%s" % (seed, x)) for x in ("g.csv", "r.csv", "s.json"))
        for each in (False, True):
            extra = ["--outlier-alpha-each", "0.001"] if each else []
            p = run("grid", "--method", "lsq", s["inp"], "--map", g, "--residuals", r,
                    "--summary", sm, *extra)
            warn = [l for l in p.stderr.splitlines() if "is an outlier" in l]
            test = json.load(open(sm))["outlier_test"]
            want_alpha, want_for = (0.001, "each coordinate") if each else (0.05, "data set")
            if test["alpha"] != want_alpha or test["for"] != want_for:
                fail("summary outlier_test %r" % test)
            m = test["coordinates_tested"]
            if not 3000 < m <= 2 * sum(1 for _ in rows(r)):
                fail("coordinates tested %d" % m)
            a = want_alpha if each else 1 - (1 - want_alpha) ** (1.0 / m)
            # the critical value: P(|Z| > crit) = a (erfc: independent of selfcal's own solver)
            if abs(math.erfc(test["critical_t"] / math.sqrt(2)) / a - 1) > 1e-9:
                fail("critical value %r for alpha %g" % (test["critical_t"], a))
            R = rows(r)
            flagged = [x for x in R if x["outlier"] == "1"]
            beyond = [x for x in R if x["tx"] != "" and
                      max(abs(float(x["tx"])), abs(float(x["ty"]))) > test["critical_t"]]
            if len(flagged) != len(warn) or len(beyond) != len(flagged):
                fail("seed %d: %d warnings, %d flagged rows, %d beyond the critical value"
                     % (seed, len(warn), len(flagged), len(beyond)))
            line = [l for l in p.stdout.splitlines() if l.startswith("outliers:")]
            if line != ["outliers: %d flagged, 0 removed (|t| > %.4g: alpha %g %s)"
                        % (len(flagged), test["critical_t"], want_alpha,
                           "for each coordinate" if each else "for the whole data set")]:
                fail("printed summary %r" % line)
            if each:
                noisy += len(flagged) > 0
            else:
                quiet += not flagged
                tsq += [float(x[k]) ** 2 for x in R for k in ("tx", "ty") if x[k] != ""]
    if quiet < 5 or noisy < 5:
        fail("clean plates: %d of 6 quiet by default, %d of 6 flagged at 0.001 each" % (quiet, noisy))
    # The leverage, end to end: on clean data each t = r / (sigma sqrt(1 - h)) has variance 1, so
    # the mean of t^2 over ~22 000 coordinates is 1 within a few per cent; without the leverage
    # (t = r / sigma) it would be the residuals' share of freedom, dof / equations (about 1/3
    # here), and with sqrt(1 + h) less still.
    mean_tsq = sum(tsq) / len(tsq)
    if len(tsq) < 18000 or abs(mean_tsq - 1) > 0.1:
        fail("clean plates: mean t^2 %.4f over %d coordinates (expected 1)" % (mean_tsq, len(tsq)))
    s = simulate(d, "p1", "--plan", "double-shift", "--seed", 1)
    g = os.path.join(d, "bad_g.csv")
    for args, needle in ((["--outlier-alpha", "0"], "between 0 and 1"),
                         (["--outlier-alpha", "1"], "between 0 and 1"),
                         (["--outlier-alpha-each", "x"], "between 0 and 1"),
                         (["--outlier-alpha", "0.1", "--outlier-alpha-each", "0.1"], "exclude")):
        p = run("grid", "--method", "lsq", s["inp"], "--map", g, *args, expect=2)
        if needle not in p.stderr or os.path.exists(g):
            fail("%r: %r" % (args, p.stderr))
    p = run("grid", "--method", "double-shift", s["inp"], "--map", g, "--outlier-alpha", "0.01",
            expect=2)
    if "need least squares" not in p.stderr or os.path.exists(g):
        fail("a closed form with --outlier-alpha: %r" % p.stderr)
    print("outlier_test: ok (%d of 6 clean plates quiet by default, %d flagged at 0.001 each; "
          "mean t^2 %.4f over %d coordinates)" % (quiet, noisy, mean_tsq, len(tsq)))


def case_view_noise():
    """--view-noise estimate: each view's noise from its residuals. A stitched plan simulated
    with unequal views (the file then stating none): the summary's per-view estimates match the
    simulation, the printed line lists them, the chi-square test is n/a; noise-free data warn and
    keep the weights; bad combinations exit 2."""
    d = fresh_dir("view_noise")
    sig = [0.02 if v == 1 else 0.03 if v == 3 else 0.05 if v == 20 else 0.01 for v in range(22)]
    s = simulate(d, "st", "--plan", "stitch", "--n", 15, "--stage", "41,31", "--seed", 3,
                 "--view-sigma-r-um", ",".join(str(x) for x in sig))
    lines = open(s["inp"]).read().splitlines(True)
    if lines[6].count("sigma_um=") != 1:
        fail("simulate did not state the views' noise: %r" % lines[6])
    path = os.path.join(d, "unstated.csv")
    open(path, "w").write("".join(re.sub(r" sigma_um=[0-9.e-]+", "", l) for l in lines))
    g, sm = os.path.join(d, "g.csv"), os.path.join(d, "s.json")
    p = run("grid", "--method", "lsq", path, "--map", g, "--summary", sm, "--view-noise", "estimate")
    S = json.load(open(sm))
    if S["view_noise"] != "estimated" or S["chi2_test"] != "n/a":
        fail("summary view_noise %r chi2 %r" % (S["view_noise"], S["chi2_test"]))
    est = [v["sigma_um_est"] for v in S["views"]]
    bad = [(v, e, t) for v, (e, t) in enumerate(zip(est, sig)) if abs(e / t - 1) > 0.25]
    if len(est) != 22 or bad:
        fail("estimates off the simulated noise: %r" % bad)
    line = [l for l in p.stdout.splitlines() if l.startswith("view_sigma_um:")]
    if len(line) != 1 or len(line[0].split("(")[0].split()) != 23:
        fail("printed line %r" % line)
    line = [l for l in p.stdout.splitlines() if l.startswith("view_sigma_u_um:")]
    if len(line) != 1 or len(line[0].split("(")[0].split()) != 23:
        fail("printed line %r" % line)
    # each estimate's own uncertainty: a few % where every placement has redundancy of its own
    rel = [v["u_sigma_um_est"] / v["sigma_um_est"] for v in S["views"]]
    if not all(0.02 < x < 0.15 for x in rel):
        fail("the estimates' uncertainties %r" % rel)
    # the map with estimated weights is close to the truth (within 6 u of each node)
    m = {(r["i"], r["j"]): r for r in rows(g)}
    t = {(r["i"], r["j"]): r for r in rows(s["g"])}
    worst = max(abs(float(m[k]["gx_um"]) - float(t[k]["gx_um"])) / float(m[k]["ugx_um"]) for k in t)
    if worst > 6:
        fail("estimated-weight map off its uncertainty: %g u" % worst)
    # noise-free data: a warning, the weights as stated
    s0 = simulate(d, "nf", "--plan", "ye", "--n", 9, "--sigma-r-um", 0)
    p = run("grid", "--method", "lsq", s0["inp"], "--map", g, "--summary", sm, "--view-noise",
            "estimate")
    if "rounding level" not in p.stderr or json.load(open(sm))["view_noise"] != "stated":
        fail("noise-free data: %r" % p.stderr)
    os.remove(g)
    for args in (["--view-noise", "estimate", "--sigma-r-um", "0.01"], ["--view-noise", "maybe"],
                 ["--view-noise", "estimate", "--method", "ye"]):
        meth = [] if "--method" in args else ["--method", "lsq"]
        p = run("grid", *meth, s0["inp"], "--map", g, *args, expect=2)
        if os.path.exists(g) or len(p.stderr.strip().splitlines()) != 1:
            fail("%r: %r" % (args, p.stderr))
        if "--sigma-r-um" in args and not p.stderr.startswith("selfcal grid: --sigma-r-um and"):
            fail("conflicting options said as a file's problem: %r" % p.stderr)
    print("view_noise: ok (estimates within %.0f %% of the simulated noise)"
          % (100 * max(abs(e / t - 1) for e, t in zip(est, sig))))


def case_covariance():
    d = fresh_dir("cov")
    s = simulate(d, "c", "--plan", "stitch", "--n", 5, "--stage", "9,7", "--sigma-r-um", 0.01)
    g, c = os.path.join(d, "g.csv"), os.path.join(d, "c.npy")
    run("grid", "--method", "lsq", s["inp"], "--map", g, "--covariance", c)
    b = open(c, "rb").read()
    if b[:8] != b"\x93NUMPY\x01\x00":
        fail("npy magic")
    hl = struct.unpack("<H", b[8:10])[0]
    head = b[10:10 + hl].decode()
    if (10 + hl) % 64 or "'descr': '<f8'" not in head or "'fortran_order': False" not in head \
            or "(126, 126)" not in head:
        fail("npy header %r" % head)
    vals = struct.unpack("<%dd" % (126 * 126), b[10 + hl:])
    m = rows(g)
    for k, r in enumerate(m):  # map rows are node order i*NX + j
        for comp, col in ((0, "ugx_um"), (1, "ugy_um")):
            v = vals[(2 * k + comp) * 126 + 2 * k + comp]
            if abs(math.sqrt(v) - float(r[col])) > 1e-9 * float(r[col]):
                fail("covariance diagonal %g vs u %s" % (math.sqrt(v), r[col]))
    print("covariance: ok")


def case_drift():
    """A drift during the views biases G; --drift linear removes it (noise-free: to 1e-9 um)."""
    d = fresh_dir("drift")
    s = simulate(d, "dr", "--plan", "ye", "--n", 11, "--sigma-r-um", 0, "--dt-s", 3,
                 "--drift-um-s", "1e-4,-2e-4")
    g, sm = os.path.join(d, "g.csv"), os.path.join(d, "s.json")
    run("grid", "--method", "lsq", s["inp"], "--map", g)
    e0 = map_error(g, s["g"])
    run("grid", "--method", "lsq", s["inp"], "--map", g, "--summary", sm, "--drift", "linear")
    e1 = map_error(g, s["g"])
    if not (e0 > 1e-3 and e1 < 1e-9):
        fail("drift: error %g without, %g with the model" % (e0, e1))
    if json.load(open(sm))["drift"] != "linear":
        fail("summary drift")
    p = run("plan", s["inp"], "--drift", "linear")
    if not p.stdout.startswith("identifiable: yes"):
        fail("plan --drift: %s" % p.stdout)
    print("drift: ok (%.3g -> %.3g um)" % (e0, e1))


def case_plan_stitched():
    d = fresh_dir("plan")
    pl = os.path.join(d, "design.csv")
    p = run("plan", "--design", "--stage", "19,13", "--n", 7, "-o", pl)
    if not p.stdout.startswith("identifiable: yes\nfree: 0\nsigma_c_ratio_rms: "):
        fail("design: %s" % p.stdout)
    p2 = run("plan", pl)
    if p2.stdout.splitlines()[:4] != p.stdout.splitlines()[:4]:
        fail("plan of the designed plan differs:\n%s\n%s" % (p.stdout, p2.stdout))
    # Baarda's internal reliability: counts add up, the redundancy numbers sum to the residual
    # dof, and the minimal detectable blunder is (crit + z_0.8)/sqrt(r) (Python's NormalDist)
    kv = dict(l.split(": ", 1) for l in p2.stdout.splitlines() if ": " in l)
    nt, nu = int(kv["testable_equations"]), int(kv["untestable_equations"])
    if nt + nu != int(kv["equations"]) or nu == 0:  # the corner placements' marks are seen once
        fail("testable %d + untestable %d vs %s equations" % (nt, nu, kv["equations"]))
    rmin, rmean = float(kv["redundancy_min"]), float(kv["redundancy_mean"])
    if abs(rmean * nt - int(kv["residual_dof"])) > 1e-3 * nt or not 0 < rmin <= rmean < 1:
        fail("redundancy min %g mean %g, %d testable, dof %s" % (rmin, rmean, nt, kv["residual_dof"]))
    from statistics import NormalDist
    a = -math.expm1(math.log1p(-0.05) / nt)
    crit = -NormalDist().inv_cdf(a / 2)
    for key, r in (("mdb_ratio_max", rmin), ("mdb_ratio_mean_r", rmean)):
        want = (crit + NormalDist().inv_cdf(0.8)) / math.sqrt(r)
        if abs(float(kv[key]) / want - 1) > 1e-5:
            fail("%s %s, want %g" % (key, kv[key], want))
    s = simulate(d, "des", "--plan", pl, "--sigma-r-um", 0)
    g = os.path.join(d, "g.csv")
    run("grid", "--method", "lsq", s["inp"], "--map", g)
    if map_error(g, s["g"]) > 1e-9:
        fail("designed plan: truth not recovered")
    # the designed plan without its first (corner) placement leaves stage nodes unmeasured
    lines = open(pl).read().splitlines(True)
    cut = [l for l in lines if not l.startswith("# view 0:")]
    pc = os.path.join(d, "cut.csv")
    open(pc, "w").write("".join(cut))
    p = run("plan", pc)
    out = p.stdout.splitlines()
    if out[0] != "identifiable: no" or int(out[1].split()[1]) < 2 or "unmeasured_stage_nodes" not in p.stdout:
        fail("plan without a corner placement: %s" % p.stdout)
    print("plan: ok")


def case_bad_input():
    """exit 2, one line 'selfcal: FILE:LINE: reason', no output file."""
    d = fresh_dir("bad")
    s = simulate(d, "b", "--plan", "ye", "--n", 7, "--sigma-r-um", 0.001, "--dt-s", 1)
    lines, h = data_lines(s["inp"])
    hdr = lines[h].rstrip("\n")
    if hdr != "view,i,j,x_mm,y_mm,t_s":
        fail("simulate header %r" % hdr)
    cases = []

    def with_u(ux, uy, at):
        out = lines[:h] + ["view,i,j,x_mm,y_mm,ux_um,uy_um\n"]
        for k, l in enumerate(lines[h + 1:]):
            f = l.rstrip("\n").split(",")[:5]
            out.append(",".join(f + ([ux, uy] if k == at else ["0.01", "0.01"])) + "\n")
        return out
    cases.append(("u_zero", with_u("0", "0.01", 4), h + 6, "ux_um must be a standard uncertainty of 1e-06 to 1e+06 um"))
    cases.append(("u_negative", with_u("0.01", "-1", 4), h + 6, "uy_um must be a standard uncertainty"))
    cases.append(("u_nan", with_u("nan", "0.01", 7), h + 9, "ux_um must be a standard uncertainty"))
    cases.append(("u_text", with_u("abc", "0.01", 2), h + 4, "ux_um must be a standard uncertainty"))
    cases.append(("u_tiny", with_u("1e-80", "0.01", 2), h + 4, "ux_um must be a standard uncertainty"))
    cases.append(("u_empty", with_u("", "0.01", 2), h + 4, "states no sigma_um"))
    ins = lambda extra: lines[:4] + [extra] + lines[4:]
    cases.append(("stage_even", ins("# stage = 8,7\n"), 5, "odd"))
    cases.append(("stage_small", ins("# stage = 1,7\n"), 5, "3.."))
    cases.append(("stage_text", ins("# stage = 9\n"), 5, "stage"))
    # a view that lands no mark on the stage
    far = [l.replace("# view 2: rot=0 shift=1,0", "# view 2: rot=0 shift=40,0") for l in lines]
    vline = next(k for k, l in enumerate(far) if "shift=40,0" in l) + 1
    cases.append(("view_off_stage", far, vline, "off the"))
    # t_s on some rows only
    out = list(lines)
    k = h + 5
    f = out[k].rstrip("\n").split(",")
    f[5] = ""
    out[k] = ",".join(f) + "\n"
    cases.append(("t_some_rows", out, k + 1, "t_s"))
    # sigma_um not positive on a view line
    out = [l.replace("# view 1: rot=90 shift=0,0", "# view 1: rot=90 shift=0,0 sigma_um=0") for l in lines]
    cases.append(("sigma_zero", out, 6, "sigma_um"))
    # views 0 and 2 state sigma_um, view 1 (line 6) does not: its weights would be a guess
    out = [l.replace("# view 0: rot=0 shift=0,0", "# view 0: rot=0 shift=0,0 sigma_um=0.01")
            .replace("# view 2: rot=0 shift=1,0", "# view 2: rot=0 shift=1,0 sigma_um=0.02") for l in lines]
    cases.append(("sigma_mixed", out, 6, "view 1 states no sigma_um but view 0 does (sigma_um=0.01)"))
    for name, body, line, needle in cases:
        path = os.path.join(d, name + ".csv")
        open(path, "w").write("".join(body))
        outs = [os.path.join(d, name + x) for x in ("_G.csv", "_A.csv", "_S.json", "_R.csv", "_C.npy")]
        p = run("grid", "--method", "lsq", path, "--map", outs[0], "--artifact", outs[1],
                "--summary", outs[2], "--residuals", outs[3], "--covariance", outs[4], expect=2)
        err = p.stderr.strip().splitlines()
        want = "selfcal: %s:%d: " % (path, line)
        if len(err) != 1 or not err[0].startswith(want) or needle not in err[0]:
            fail("%s: stderr %r, want one line starting %r containing %r" % (name, p.stderr, want, needle))
        if [o for o in outs if os.path.exists(o)]:
            fail("%s: output files left" % name)
        run("plan", path, expect=2)
        print("ok %-16s %s" % (name, err[0]))
    # --drift without times
    s2 = simulate(d, "nt", "--plan", "ye", "--n", 7)
    run("grid", "--method", "lsq", s2["inp"], "--map", os.path.join(d, "x.csv"), "--drift", "linear", expect=2)
    if os.path.exists(os.path.join(d, "x.csv")):
        fail("--drift without t_s left a map")


def case_one_mark_view():
    """A view that measures a single mark (its rotation undetermined): its translation absorbs
    both coordinates, so its residuals are 0 and the solution, the noise estimate, the dof and the
    variance factor are those of the data without that view, and so are the other views'
    misalignments with their uncertainties; `plan` counts the same dof. And --reject-outliers
    that leaves a view with one mark keeps the removed row in R.csv, its residual empty."""
    d = fresh_dir("one_mark")
    head = "# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n"
    views = ["rot=0 shift=0,0", "rot=90 shift=0,0", "rot=0 shift=1,0", "rot=0 shift=4,4"]
    plan = os.path.join(d, "plan.csv")
    open(plan, "w").write(head + "".join("# view %d: %s\n" % (k, v) for k, v in enumerate(views)))
    s = simulate(d, "one", "--plan", plan, "--sigma-r-um", 0.01, "--seed", 4)
    lines, h = data_lines(s["inp"])
    if sum(1 for l in lines[h + 1:] if l.startswith("3,")) != 1:
        fail("view 3 should measure one mark")
    without = os.path.join(d, "without.csv")
    open(without, "w").write("".join(l for l in lines if not l.startswith(("3,", "# view 3:"))))
    weighted = os.path.join(d, "weighted.csv")
    open(weighted, "w").write("".join(re.sub(r"^(# view \d+: .*)$", r"\1 sigma_um=0.01", l.rstrip("\n")) + "\n"
                                      for l in lines))
    weighted_wo = os.path.join(d, "weighted_without.csv")
    open(weighted_wo, "w").write("".join(l for l in open(weighted) if not l.startswith(("3,", "# view 3:"))))
    out = {}
    for name, path in (("all", s["inp"]), ("without", without), ("w_all", weighted), ("w_without", weighted_wo)):
        g, r, sm = (os.path.join(d, name + x) for x in ("_g.csv", "_r.csv", "_s.json"))
        run("grid", "--method", "lsq", path, "--map", g, "--residuals", r, "--summary", sm)
        pl = run("plan", path).stdout
        dof_plan = int(re.search(r"^residual_dof: (\d+)$", pl, re.M).group(1))
        out[name] = (rows(g), rows(r), json.load(open(sm)), dof_plan)
    for a, b in (("all", "without"), ("w_all", "w_without")):
        ga, ra, sa, pa = out[a]
        gb, rb, sb, pb = out[b]
        worst = max(abs(float(x[c]) - float(y[c])) for x, y in zip(ga, gb) for c in ("gx_um", "gy_um", "ugx_um", "ugy_um"))
        if worst > 1e-9:
            fail("%s: the map differs from the data without the one-mark view by %g um" % (a, worst))
        for key in ("dof", "sigma_r_est_um", "residual_rms_um") + (("variance_factor",) if a == "w_all" else ()):
            va, vb = float(sa[key]), float(sb[key])
            if key == "residual_rms_um":  # an RMS over 2 more equations, both 0
                vb *= math.sqrt(float(len(rb)) / len(ra))
            if abs(va - vb) > 1e-9 * abs(vb):
                fail("%s: %s %r, without the one-mark view %r" % (a, key, va, vb))
        # the other views' misalignments and their uncertainties, O and R: as without the view
        for va, vb in zip(sa["views"][:3], sb["views"]):
            for key in ("tx_um", "ty_um", "theta_urad", "utx_um", "uty_um", "utheta_urad"):
                if va[key] is None or abs(va[key] - vb[key]) > 1e-9 * (abs(vb[key]) + 1e-3):
                    fail("%s: view %d %s %r, without the one-mark view %r" % (a, va["view"], key, va[key], vb[key]))
        for key in ("O", "uO", "R", "uR"):
            if abs(sa[key] - sb[key]) > 1e-9 * abs(sb[key]) + 1e-15:
                fail("%s: %s %r, without the one-mark view %r" % (a, key, sa[key], sb[key]))
        if any(sa["views"][3][k] is not None for k in ("tx_um", "theta_urad", "utx_um")):
            fail("%s: the one-mark view's misalignment is reported: %r" % (a, sa["views"][3]))
        if pa != int(sa["dof"]) or pb != int(sb["dof"]):
            fail("%s: plan residual_dof %d / %d, grid dof %s / %s" % (a, pa, pb, sa["dof"], sb["dof"]))
        one = [x for x in ra if x["view"] == "3"]
        if len(one) != 1 or abs(float(one[0]["rx_um"])) > 1e-9 or abs(float(one[0]["ry_um"])) > 1e-9 \
                or one[0]["tx"] != "" or one[0]["ty"] != "":
            fail("%s: the one-mark view's residual row %r" % (a, one))
    if out["w_all"][2].get("chi2_test") != "pass":
        fail("weighted: the chi^2 test: %r (variance factor %r)" % (out["w_all"][2].get("chi2_test"),
                                                                    out["w_all"][2].get("variance_factor")))
    # a two-mark view and two outliers: rejection takes one of the view's marks first
    views[3] = "rot=0 shift=3,4"
    open(plan, "w").write(head + "".join("# view %d: %s\n" % (k, v) for k, v in enumerate(views)))
    s = simulate(d, "two", "--plan", plan, "--sigma-r-um", 0.01, "--seed", 4)
    lines, h = data_lines(s["inp"])
    for key, du in (("3,0,0,", 0.0005), ("0,2,2,", 0.0003)):  # mm: 0.5 and 0.3 um
        k = next(k for k, l in enumerate(lines) if k > h and l.startswith(key))
        f = lines[k].rstrip("\n").split(",")
        f[3] = "%.15f" % (float(f[3]) + du)
        lines[k] = ",".join(f) + "\n"
    bad = os.path.join(d, "two_bad.csv")
    open(bad, "w").write("".join(lines))
    g, r = os.path.join(d, "two_g.csv"), os.path.join(d, "two_r.csv")
    p = run("grid", "--method", "lsq", bad, "--map", g, "--residuals", r, "--reject-outliers")
    R = rows(r)
    n_in = len(lines) - h - 1
    if len(R) != n_in:
        fail("R.csv has %d rows for %d measurements: %s" % (len(R), n_in, p.stderr))
    v3 = {(x["i"], x["j"]): x for x in R if x["view"] == "3"}
    removed = [k for k, x in v3.items() if x["outlier"] == "1"]
    kept = [x for x in v3.values() if x["outlier"] == "0"]
    # the removed mark's residual is not estimable (its view's rotation is free without it):
    # the row stays, flagged, its residual empty
    if len(removed) != 1 or len(kept) != 1 or abs(float(kept[0]["rx_um"])) > 1e-9 or \
            abs(float(kept[0]["ry_um"])) > 1e-9 or any(v3[removed[0]][c] for c in ("rx_um", "ry_um")):
        fail("rejection in the two-mark view: %r\n%s" % (v3, p.stderr))
    # with drift: a declared view without measurements changes nothing (it was refused: "all its
    # measurements have the same time")
    s = simulate(d, "drift", "--plan", "ye", "--n", 7, "--sigma-r-um", 0.001, "--dt-s", 1)
    lines = open(s["inp"]).read().splitlines(True)
    k = next(k for k, l in enumerate(lines) if l.startswith("# view 2:"))
    empty = os.path.join(d, "drift_empty_view.csv")
    open(empty, "w").write("".join(lines[:k + 1] + ["# view 3: rot=180 shift=0,0\n"] + lines[k + 1:]))
    maps = []
    for name, path in (("plain", s["inp"]), ("empty", empty)):
        g, sm = os.path.join(d, name + "_dg.csv"), os.path.join(d, name + "_ds.json")
        run("grid", "--method", "lsq", path, "--map", g, "--drift", "linear", "--summary", sm)
        maps.append(rows(g))
    worst = max(abs(float(x[c]) - float(y[c])) for x, y in zip(*maps) for c in ("gx_um", "ugx_um", "gy_um", "ugy_um"))
    v3 = json.load(open(sm))["views"][3]
    if worst > 1e-9 or v3["vx_um_s"] is not None or v3["tx_um"] is not None:
        fail("drift with an empty declared view: map differs by %g um; view 3 %r" % (worst, v3))
    print("one_mark_view: ok")


CASES = {"damaged": case_damaged, "one_mark_view": case_one_mark_view, "weights": case_weights, "outliers": case_outliers,
         "outlier_test": case_outlier_test, "view_noise": case_view_noise,
         "covariance": case_covariance, "drift": case_drift, "plan": case_plan_stitched,
         "bad_input": case_bad_input}
CASES[CASE]()
print("PASS " + CASE)
