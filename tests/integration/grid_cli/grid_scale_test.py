#!/usr/bin/env python3
"""CLI tests of the plate's scale and temperature (SPEC §11, issue 34): the stage magnification
tied to a certified plate scale, per-view temperatures, bad scale lines, the uncertainty budget
against the Monte Carlo on three plans (one stitched), free view scales, and the summary's view
numbers.

Usage: grid_scale_test.py CLI TMPDIR CASE
Assertions compare against the simulated truth or what the input says, never against stored
outputs of selfcal itself.
"""
import json
import math
import os
import random
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import clitest  # noqa: E402  (the shared preamble: tests/integration/clitest.py)
from clitest import fail, fresh_dir, map_error, rows, run, simulate  # noqa: E402

CLI, TMP, CASE = clitest.setup("grid_scale_", timeout=900)


def temps(n_views, seed, spread=0.5):
    r = random.Random(seed)
    return ",".join("%.3f" % (20 + r.uniform(-spread, spread)) for _ in range(n_views))


def strip_temperatures(src, dst):
    """The same data without what the temperatures say: no temp_C, no CTE line."""
    out = [re.sub(r" temp_C=[-0-9.e]+", "", l) for l in open(src)
           if not l.startswith("# plate_cte_ppm_per_K")]
    open(dst, "w").write("".join(out))


SCALE = ["--plate-scale-ppm", "2.5,0.02", "--plate-cte-ppm-per-k", "8,0.3"]


def case_noise_free():
    """Acceptance: per-view temperatures, a CTE, a stage magnification and a certified plate
    scale, noise-free: G including M to <= 1e-6 um (Petrò's plan and a stitched one); the same
    data without the temperatures give a visibly biased G; without the plate scale G carries no
    magnification and the summary says so."""
    d = fresh_dir("noise_free")
    for name, plan, views in (("petro", ["--plan", "double-shift", "--n", 25], 4),
                              ("stitch", ["--plan", "stitch", "--n", 11, "--stage", "21,15"], 0)):
        if views == 0:  # the stitch plan's views: count them from a first simulation
            probe = simulate(d, "probe", *plan)
            views = sum(1 for l in open(probe["inp"]) if l.startswith("# view"))
        s = simulate(d, name, *plan, "--sigma-r-um", 0, *SCALE, "--view-temp-c",
                     temps(views, 7, 0.6), "--magnification-ppm", -15)
        g, sj = os.path.join(d, name + "_g.csv"), os.path.join(d, name + "_s.json")
        run("grid", "--method", "lsq", s["inp"], "--map", g, "--summary", sj)
        e = map_error(g, s["g"])
        if e > 1e-6:
            fail("%s: G with M off by %g um from the truth" % (name, e))
        summ = json.load(open(sj))
        if not summ["scale_included"] or abs(summ["magnification_ppm"] + 15) > 1e-6:
            fail("%s: magnification_ppm %r, want -15" % (name, summ["magnification_ppm"]))
        if not summ["u_magnification_ppm"] >= 0.02:  # at least U of the plate's scale
            fail("%s: u_magnification_ppm %r below U(E)" % (name, summ["u_magnification_ppm"]))
        nt = os.path.join(d, name + "_notemp.csv")
        strip_temperatures(s["inp"], nt)
        g2 = os.path.join(d, name + "_g2.csv")
        run("grid", "--method", "lsq", nt, "--map", g2)
        e2 = map_error(g2, s["g"])
        if e2 < 0.01:
            fail("%s: without the temperatures G is off by only %g um" % (name, e2))
        print("%s: G with temperatures %.2g um off the truth, without %.3g um" % (name, e, e2))
    # the closed forms take the same model (no budget: they give no uncertainties)
    s = simulate(d, "ye9", "--plan", "ye", "--n", 9, "--sigma-r-um", 0, *SCALE, "--view-temp-c",
                 "20.3,19.8,20.5", "--magnification-ppm", 5)
    g, sj = os.path.join(d, "ye9_g.csv"), os.path.join(d, "ye9_s.json")
    run("grid", "--method", "ye", s["inp"], "--map", g, "--summary", sj)
    if map_error(g, s["g"]) > 1e-6 or abs(json.load(open(sj))["magnification_ppm"] - 5) > 1e-6:
        fail("Ye's closed form: G with M off by %g um" % map_error(g, s["g"]))
    # no plate scale: G in the SPEC gauge (no magnification), scale_included false
    s = simulate(d, "noE", "--plan", "double-shift", "--n", 15, "--sigma-r-um", 0,
                 "--plate-cte-ppm-per-k", "8,0.3", "--view-temp-c", temps(4, 3),
                 "--magnification-ppm", 30)
    g, sj = os.path.join(d, "noE_g.csv"), os.path.join(d, "noE_s.json")
    p = run("grid", "--method", "lsq", s["inp"], "--map", g, "--summary", sj)
    if map_error(g, s["g"]) > 1e-6:
        fail("without E: G off the SPEC-gauge truth by %g" % map_error(g, s["g"]))
    summ = json.load(open(sj))
    if summ["scale_included"] or summ["magnification_ppm"] is not None:
        fail("without E the summary claims a magnification: %r" % summ["magnification_ppm"])
    if "scale: not included" not in p.stdout:
        fail("stdout does not say that scale is not included:\n" + p.stdout)


def case_bad_input():
    """U < 0, a temperature without a CTE, temp_C on some views only, bad numbers: exit 2 with
    FILE:LINE and no output file."""
    d = fresh_dir("bad_input")
    head = "# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n"
    views = "# view 0: rot=0 shift=0,0%s\n# view 1: rot=90 shift=0,0%s\n# view 2: rot=0 shift=1,0%s\n"
    cases = [
        ("u_neg_scale", head + "# plate_scale_ppm = 1.5, -0.1\n" + views % ("", "", ""), 4,
         "uncertainty"),
        ("u_neg_cte", head + "# plate_cte_ppm_per_K = 8, -2\n" + views % ("", "", ""), 4,
         "uncertainty"),
        ("temp_no_cte", head + views % (" temp_C=20.1", " temp_C=20.2", " temp_C=20"), 4,
         "plate_cte_ppm_per_K"),
        ("temp_some", head + "# plate_cte_ppm_per_K = 8, 0.2\n" +
         views % (" temp_C=20.1", "", " temp_C=20"), 6, "every view or on none"),
        ("temp_word", head + "# plate_cte_ppm_per_K = 8, 0.2\n" +
         views % (" temp_C=warm", " temp_C=20", " temp_C=20"), 5, "temp_C"),
        ("temp_u_neg", head + "# plate_cte_ppm_per_K = 8, 0.2\n# temp_u_K = -0.1\n" +
         views % (" temp_C=20", " temp_C=20", " temp_C=20"), 5, "temp_u_K"),
        ("scale_one", head + "# plate_scale_ppm = 1.5\n" + views % ("", "", ""), 4,
         "plate_scale_ppm"),
    ]
    for name, text, line, word in cases:
        path = os.path.join(d, name + ".csv")
        open(path, "w").write(text + "view,i,j,x_mm,y_mm\n0,2,2,0,0\n")
        out, summ = os.path.join(d, name + "_g.csv"), os.path.join(d, name + "_s.json")
        p = run("grid", "--method", "lsq", path, "--map", out, "--summary", summ, expect=2)
        want = "%s:%d:" % (path, line)
        if want not in p.stderr or word not in p.stderr or len(p.stderr.strip().splitlines()) != 1:
            fail("%s: want one line with %r and %r, got %r" % (name, want, word, p.stderr))
        if os.path.exists(out) or os.path.exists(summ):
            fail("%s: an output file was written" % name)
    # the simulator's options are checked too
    p = run("simulate", "grid", "--plan", "ye", "--n", 5, "--out", os.path.join(d, "x.csv"),
            "--truth-map", os.path.join(d, "xg.csv"), "--view-temp-c", "20,20,20", expect=2)
    if os.path.exists(os.path.join(d, "x.csv")):
        fail("simulate wrote a file for --view-temp-c without a CTE")


def mc_check(d, name, plan_args, views, trials=1000):
    """Budget u against the Monte Carlo's on a noisy simulation: every node's ratio within the
    statistical scatter of a standard deviation from `trials` draws."""
    # every source of about the same weight, so that a wrong sensitivity shows in the ratio
    s = simulate(d, name, *plan_args, "--sigma-r-um", 0.004, "--plate-scale-ppm", "1.5,0.3",
                 "--plate-cte-ppm-per-k", "10,1", "--view-temp-c", temps(views, 11),
                 "--temp-u-k", 0.1, "--magnification-ppm", 8, "--seed", 5)
    g, sj, mc = (os.path.join(d, name + x) for x in ("_g.csv", "_s.json", "_mc.csv"))
    p = run("grid", "--method", "lsq", s["inp"], "--map", g, "--summary", sj, "--monte-carlo",
            trials, "--seed", 3, "--monte-carlo-out", mc)
    summ = json.load(open(sj))
    m = summ["monte_carlo"]
    # the relative standard deviation of a sample standard deviation: 1/sqrt(2(M-1))
    rel = 1 / math.sqrt(2 * (trials - 1))
    if abs(m["ratio_mean"] - 1) > 3 * rel or m["ratio_min"] < 1 - 6 * rel or \
            m["ratio_max"] > 1 + 6 * rel:
        fail("%s: MC u / budget u: mean %.4f, min %.4f, max %.4f (scatter %.3f)"
             % (name, m["ratio_mean"], m["ratio_min"], m["ratio_max"], rel))
    if abs(summ["u_magnification_ppm"] / m["magnification_sd_ppm"] - 1) > 6 * rel:
        fail("%s: u(M) %.4g ppm, the Monte Carlo's %.4g" % (name, summ["u_magnification_ppm"],
                                                            m["magnification_sd_ppm"]))
    b = summ["budget"]
    contrib = [r["contribution_um"] for r in b["rows"]]
    if abs(math.sqrt(sum(c * c for c in contrib)) - b["u_c_um"]) > 1e-9 + 1e-6 * b["u_c_um"] \
            or abs(b["U_um"] - b["k"] * b["u_c_um"]) > 1e-12:
        fail("%s: the budget's rows do not combine to u_c, U: %r" % (name, b))
    if [r["source"] for r in b["rows"]][:2] != ["measurement noise", "plate scale E"]:
        fail("%s: budget rows %r" % (name, [r["source"] for r in b["rows"]]))
    # the map's u is the combined one: at the budget's node it is u_c
    i, j = b["node"]
    row = next(r for r in rows(g) if int(r["i"]) == i and int(r["j"]) == j)
    if abs(float(row["ug" + b["component"][1] + "_um"]) - b["u_c_um"]) > 1e-9:
        fail("%s: the map's u at the budget's node differs from u_c" % name)
    # 95 % coverage intervals about contain the estimate
    gm = {(r["i"], r["j"]): r for r in rows(g)}
    inside = sum(1 for r in rows(mc) if float(r["gx_lo_um"]) <= float(gm[(r["i"], r["j"])]["gx_um"])
                 <= float(r["gx_hi_um"]))
    if inside < 0.9 * len(gm):
        fail("%s: the estimate lies in only %d of %d MC intervals" % (name, inside, len(gm)))
    print("%s: MC/budget mean %.4f [%.4f, %.4f], u(M) %.3g vs %.3g ppm, %d trials in %.2f s on "
          "%d threads" % (name, m["ratio_mean"], m["ratio_min"], m["ratio_max"],
                          summ["u_magnification_ppm"], m["magnification_sd_ppm"], m["trials"],
                          m["seconds"], m["threads"]))
    return p


def case_budget_mc():
    """Acceptance: the budget's u(G) agrees with the Monte Carlo's within its statistical
    scatter on three plans, one of them stitched."""
    d = fresh_dir("budget_mc")
    mc_check(d, "petro25", ["--plan", "double-shift", "--n", 25], 4)
    mc_check(d, "ye9", ["--plan", "ye", "--n", 9], 3)
    probe = simulate(d, "probe", "--plan", "stitch", "--n", 9, "--stage", "17,13")
    views = sum(1 for l in open(probe["inp"]) if l.startswith("# view"))
    mc_check(d, "stitch", ["--plan", "stitch", "--n", 9, "--stage", "17,13"], views)


def case_view_scale_free():
    """A plate whose temperature changed between views, no temperature log: --view-scale free
    finds the views' relative scales (within 4 u of the truth's), warns that they are
    significant, and on noise-free data gives the truth's G where the fit without them is
    visibly off."""
    d = fresh_dir("view_scale_free")
    t = [20.3, 19.6, 20.5, 20.0]
    s = simulate(d, "vs", "--plan", "double-shift", "--n", 25, "--sigma-r-um", 0.01,
                 "--plate-cte-ppm-per-k", "8,0.3", "--view-temp-c", ",".join(map(str, t)))
    nt = os.path.join(d, "vs_notemp.csv")
    strip_temperatures(s["inp"], nt)
    g, g0, sj = (os.path.join(d, x) for x in ("g.csv", "g0.csv", "s.json"))
    p = run("grid", "--method", "lsq", nt, "--map", g, "--summary", sj, "--view-scale", "free")
    run("grid", "--method", "lsq", nt, "--map", g0)
    if "scales differ significantly" not in p.stderr:
        fail("no warning about significant view scales: %r" % p.stderr)
    summ = json.load(open(sj))
    true_rel = [8 * (x - 20) for x in t]
    mean = sum(true_rel) / len(true_rel)
    for v in summ["views"]:
        want = true_rel[v["view"]] - mean
        if abs(v["scale_free_ppm"] - want) > 4 * v["u_scale_free_ppm"]:
            fail("view %d: free scale %.4g ppm (u %.2g), truth %.4g" % (
                v["view"], v["scale_free_ppm"], v["u_scale_free_ppm"], want))
    # noise-free: with free scales G is the truth's (SPEC gauge: no plate scale given), without
    # them visibly not
    s = simulate(d, "vs0", "--plan", "double-shift", "--n", 25, "--sigma-r-um", 0,
                 "--plate-cte-ppm-per-k", "8,0.3", "--view-temp-c", ",".join(map(str, t)))
    strip_temperatures(s["inp"], nt)
    run("grid", "--method", "lsq", nt, "--map", g, "--view-scale", "free")
    run("grid", "--method", "lsq", nt, "--map", g0)
    e, e0 = map_error(g, s["g"]), map_error(g0, s["g"])
    if not (e <= 1e-6 and e0 > 0.01):
        fail("noise-free: free view scales leave G off by %g um, without them %g" % (e, e0))
    # scales that agree raise no warning
    s = simulate(d, "same", "--plan", "double-shift", "--n", 15, "--sigma-r-um", 0.01)
    p = run("grid", "--method", "lsq", s["inp"], "--map", g, "--view-scale", "free")
    if "significantly" in p.stderr:
        fail("a warning on views of one temperature: %r" % p.stderr)
    run("grid", "--method", "ye", s["inp"], "--map", g, "--view-scale", "free", expect=2)


def case_views_declared():
    """The summary numbers views as the file declares them; a declared view with no rows leaves
    the other views' view_sigma_u_um finite under --view-noise estimate."""
    d = fresh_dir("views_declared")
    s = simulate(d, "ye", "--plan", "ye", "--n", 11, "--view-sigma-r-um", "0.01,0.02,0.015")
    ids = {0: 4, 1: 9, 2: 2}
    out = []
    for l in open(s["inp"]):
        m = re.match(r"# view (\d+):(.*)", l)
        if m:
            l = "# view %d:%s\n" % (ids[int(m.group(1))], m.group(2))
            if int(m.group(1)) == 2:
                l += "# view 7: rot=180 shift=0,0 sigma_um=0.01\n"
        elif re.match(r"\d+,", l):
            v, rest = l.split(",", 1)
            l = "%d,%s" % (ids[int(v)], rest)
        out.append(l)
    path = os.path.join(d, "renum.csv")
    open(path, "w").write("".join(out))
    g, sj = os.path.join(d, "g.csv"), os.path.join(d, "s.json")
    run("grid", "--method", "lsq", path, "--map", g, "--summary", sj, "--view-noise", "estimate")
    summ = json.load(open(sj))
    got = [v["view"] for v in summ["views"]]
    if got != [4, 9, 2, 7]:
        fail("summary views %r, the file declares [4, 9, 2, 7]" % got)
    for v in summ["views"][:3]:
        u = v.get("u_sigma_um_est")
        if u is None or not u > 0:
            fail("view %d: u_sigma_um_est %r (a view without rows made it NaN)" % (v["view"], u))
    if summ["views"][3].get("u_sigma_um_est") is not None:
        fail("the view without rows has a noise estimate: %r" % summ["views"][3])


def case_coverage_factor():
    """k = 2 when sigma_r has many degrees of freedom or is given; Student's t for the
    Welch-Satterthwaite degrees of freedom when it is estimated from few (Ye, N = 3: dof 10)."""
    d = fresh_dir("coverage_factor")
    s = simulate(d, "ye3", "--plan", "ye", "--n", 3, "--sigma-r-um", 0.05, "--plate-scale-ppm",
                 "1,0.01")
    g, sj = os.path.join(d, "g.csv"), os.path.join(d, "s.json")
    run("grid", "--method", "lsq", s["inp"], "--map", g, "--summary", sj)
    summ = json.load(open(sj))
    b = summ["budget"]
    if summ["dof"] != 10 or not abs(b["nu_eff"] - 10) < 0.01:
        fail("Ye N = 3: dof %r, nu_eff %r (want 10, about 10)" % (summ["dof"], b["nu_eff"]))
    if not b["k_from"].startswith("Welch") or abs(b["k"] - 2.228139) > 1e-4:
        fail("few degrees of freedom: k %r from %r, want t95(10) = 2.228" % (b["k"], b["k_from"]))
    run("grid", "--method", "lsq", s["inp"], "--map", g, "--summary", sj, "--sigma-r-um", 0.05)
    b = json.load(open(sj))["budget"]
    if b["k"] != 2 or b["k_from"] != "k = 2" or b["rows"][0]["dof"] is not None:
        fail("a given sigma_r: k %r from %r, noise dof %r" % (b["k"], b["k_from"],
                                                             b["rows"][0]["dof"]))


CASES = {"noise_free": case_noise_free, "coverage_factor": case_coverage_factor, "bad_input": case_bad_input,
         "budget_mc": case_budget_mc, "view_scale_free": case_view_scale_free,
         "views_declared": case_views_declared}

if __name__ == "__main__":
    if CASE not in CASES:
        fail("unknown case " + CASE)
    CASES[CASE]()
    print("PASS " + CASE)
