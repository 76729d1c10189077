#!/usr/bin/env python3
"""CLI tests of selfcal's grid commands (simulate grid, grid, plan, plot map).

Usage: grid_cli_test.py CLI TMPDIR CASE [args]
Every assertion compares against the simulated truth or against what the input file says, never
against stored outputs of selfcal itself.
"""
import csv
import zlib
import json
import math
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import clitest  # noqa: E402  (the shared preamble: tests/integration/clitest.py)
from clitest import fail, fresh_dir, run  # noqa: E402

CLI, TMP, CASE = clitest.setup("grid_cli_")
ARGS = sys.argv[4:]


def read_map(path):
    with open(path, newline="") as f:
        r = csv.reader(f)
        head = next(r)
        if head[:8] != ["i", "j", "x_mm", "y_mm", "gx_um", "gy_um", "ugx_um", "ugy_um"]:
            fail("%s: map header %s" % (path, head))
        rows = {}
        for row in r:
            rows[(int(row[0]), int(row[1]))] = row
        return rows


def read_art(path):
    with open(path, newline="") as f:
        r = csv.reader(f)
        if next(r) != ["i", "j", "ax_um", "ay_um"]:
            fail("%s: artifact header" % path)
        return {(int(a[0]), int(a[1])): (float(a[2]), float(a[3])) for a in r}


def simulate(d, name, plan, n, *extra):
    files = dict(inp=os.path.join(d, name + ".csv"), g=os.path.join(d, name + "_G.csv"),
                 a=os.path.join(d, name + "_A.csv"), t=os.path.join(d, name + "_T.json"))
    run("simulate", "grid", "--plan", plan, "--n", n, "--out", files["inp"], "--truth-map", files["g"],
        "--truth-artifact", files["a"], "--truth-summary", files["t"], *extra)
    return files


def write(path, text):
    with open(path, "w") as f:
        f.write(text)


def plan_text(n, views, pitch=1.0, origin=None):
    s = "# selfcal-grid v1\n# N = %d\n# pitch_mm = %g\n" % (n, pitch)
    if origin:
        s += "# origin_mm = %s\n" % origin
    for k, v in enumerate(views):
        s += "# view %d: %s\n" % (k, v)
    return s


# --------------------------------------------------------------------------------------------
def case_end_to_end():
    """Noise-free simulate -> grid: G and A equal the truth to 1e-9 um, O, R and misalignments too."""
    method, plan, ns = ARGS[0], ARGS[1], [int(a) for a in ARGS[2].split(",")]
    # one directory per (method, plan): tests run in parallel, so custom plans need distinct names
    tag = ("custom_%08x" % zlib.crc32(plan.encode())) if plan.startswith("views:") else plan
    d = fresh_dir("e2e_%s_%s" % (method, tag))
    for n in ns:
        planarg = plan
        if plan.startswith("views:"):  # a custom plan file written here
            planarg = os.path.join(d, "plan%d.csv" % n)
            write(planarg, plan_text(n, plan[6:].split("|"), origin="50.5,-20.25"))
        sim = simulate(d, "n%d" % n, planarg, n, "--sigma-r-um", 0, "--seed", 100 + n,
                       "--origin-mm", "50.5,-20.25", "--sigma-g-um", 2)
        out = {k: os.path.join(d, "est%d_%s" % (n, k)) for k in ("G.csv", "A.csv", "S.json")}
        run("grid", "--method", method, sim["inp"], "--map", out["G.csv"], "--artifact", out["A.csv"],
            "--summary", out["S.json"])
        g, gt = read_map(out["G.csv"]), read_map(sim["g"])
        if len(g) != n * n or set(g) != set(gt):
            fail("N=%d: map has %d nodes" % (n, len(g)))
        worst = 0.0
        for key, row in g.items():
            t = gt[key]
            if abs(float(row[2]) - float(t[2])) > 1e-9 or abs(float(row[3]) - float(t[3])) > 1e-9:
                fail("N=%d node %s: position %s,%s vs truth %s,%s" % (n, key, row[2], row[3], t[2], t[3]))
            worst = max(worst, abs(float(row[4]) - float(t[4])), abs(float(row[5]) - float(t[5])))
        a, at = read_art(out["A.csv"]), read_art(sim["a"])
        worst_a = max(max(abs(a[k][0] - at[k][0]), abs(a[k][1] - at[k][1])) for k in at)
        s, tr = json.load(open(out["S.json"])), json.load(open(sim["t"]))
        print("%s N=%d: max |G-G_true| = %.3g um, max |A-A_true| = %.3g um, O %.6g (true %.6g), R %.6g (true %.6g)"
              % (method, n, worst, worst_a, s["O"], tr["O"], s["R"], tr["R"]))
        if not worst <= 1e-9:
            fail("N=%d: max |G - G_true| = %g um > 1e-9" % (n, worst))
        if not worst_a <= 1e-9:
            fail("N=%d: max |A - A_true| = %g um > 1e-9" % (n, worst_a))
        if s["method"] != method or s["N"] != n:
            fail("summary method/N: %s %s" % (s["method"], s["N"]))
        if abs(s["O"] - tr["O"]) > 1e-12 or abs(s["R"] - tr["R"]) > 1e-12:
            fail("N=%d: O, R = %g, %g; truth %g, %g" % (n, s["O"], s["R"], tr["O"], tr["R"]))
        for sv, tv in zip(s["views"], tr["views"]):
            if sv["tx_um"] is None:
                continue
            if (abs(sv["tx_um"] - tv["tx_um"]) > 1e-8 or abs(sv["ty_um"] - tv["ty_um"]) > 1e-8
                    or abs(sv["theta_urad"] - tv["theta_urad"]) > 1e-6):
                fail("N=%d view %d misalignment %s vs truth %s" % (n, sv["view"], sv, tv))
        if s["residual_rms_um"] is not None and s["residual_rms_um"] > 1e-9:
            fail("N=%d: residual RMS %g on noise-free data" % (n, s["residual_rms_um"]))


def case_lsq_noise():
    """lsq on noisy data: sigma_r estimated near the truth, uncertainties consistent with errors."""
    d = fresh_dir("lsq_noise")
    n, sr = 15, 0.05
    zs, ests = [], []
    for seed in range(1, 5):
        sim = simulate(d, "s%d" % seed, "double-shift", n, "--sigma-r-um", sr, "--seed", seed)
        gp, sp = os.path.join(d, "G%d.csv" % seed), os.path.join(d, "S%d.json" % seed)
        run("grid", "--method", "lsq", sim["inp"], "--map", gp, "--summary", sp)
        g, gt = read_map(gp), read_map(sim["g"])
        for k, row in g.items():
            for c, uc in ((4, 6), (5, 7)):
                u = float(row[uc])
                if not u > 0:
                    fail("uncertainty %s at %s" % (row[uc], k))
                zs.append((float(row[c]) - float(gt[k][c])) / u)
        ests.append(json.load(open(sp))["sigma_r_est_um"])
        # With --sigma-r-um the uncertainties scale with the given value.
        if seed == 1:
            g2p = os.path.join(d, "G_given.csv")
            run("grid", "--method", "lsq", sim["inp"], "--map", g2p, "--sigma-r-um", 2 * sr)
            s1 = json.load(open(sp))
            g2 = read_map(g2p)
            k = (n // 2, n // 2)
            ratio = float(g2[k][6]) / float(g[k][6])
            want = 2 * sr / s1["sigma_r_used_um"]
            if abs(ratio / want - 1) > 1e-6:
                fail("--sigma-r-um: uncertainty ratio %g, want %g" % (ratio, want))
    # Without --summary the command leaves out the uncertainties of O, R and the misalignments
    # (they go nowhere else); the map and the residuals are the same bytes either way (at N = 101
    # solving the gauge columns together with the others changes 5 % of the printed σ).
    sim = simulate(d, "summary101", "double-shift", 101, "--sigma-r-um", sr, "--seed", 41)
    outs = {}
    for tag, extra in (("plain", []), ("summary", ["--summary", os.path.join(d, "S101.json")])):
        gp, rp = os.path.join(d, "G101_%s.csv" % tag), os.path.join(d, "R101_%s.csv" % tag)
        run("grid", "--method", "lsq", sim["inp"], "--map", gp, "--residuals", rp, "--quiet", *extra)
        outs[tag] = (open(gp, "rb").read(), open(rp, "rb").read())
    if outs["plain"] != outs["summary"]:
        fail("the map or the residuals differ with and without --summary")
    s101 = json.load(open(os.path.join(d, "S101.json")))
    if not (s101["uO"] and s101["uO"] > 0 and s101["uR"] > 0
            and all(v["utx_um"] > 0 and v["utheta_urad"] > 0 for v in s101["views"])):
        fail("summary without the uncertainties of O, R, misalignments: %s" % s101)
    zrms = math.sqrt(sum(z * z for z in zs) / len(zs))
    print("lsq N=%d sigma_r=%g: sigma_r estimates %s, RMS of (G-G_true)/u = %.3f over %d values"
          % (n, sr, ["%.4f" % e for e in ests], zrms, len(zs)))
    for e in ests:
        if abs(e / sr - 1) > 0.15:
            fail("sigma_r estimate %g vs %g" % (e, sr))
    if not 0.8 < zrms < 1.2:
        fail("RMS of normalised errors %g not near 1" % zrms)
    # The closed forms report the noise too (SPEC §1 summary), estimated from the same data.
    for method, plan in (("ye", "ye"), ("double-shift", "double-shift")):
        sim = simulate(d, "x_" + method, plan, n, "--sigma-r-um", sr, "--seed", 11)
        sp = os.path.join(d, "S_%s.json" % method)
        run("grid", "--method", method, sim["inp"], "--map", os.path.join(d, "G_x.csv"),
            "--summary", sp)
        e = json.load(open(sp))["sigma_r_est_um"]
        print("%s: sigma_r estimate %s (true %g)" % (method, e, sr))
        if e is None or abs(e / sr - 1) > 0.15:
            fail("%s: sigma_r estimate %s vs %g" % (method, e, sr))


def first_lines(out, k=4):
    return out.splitlines()[:k]


def case_plan():
    d = fresh_dir("plan")
    n = 25
    c = (n - 1) // 2
    cases = [
        ("ye", ["rot=0 shift=0,0", "rot=90 shift=0,0", "rot=0 shift=1,0"], True),
        ("petro", ["rot=0 shift=0,0", "rot=90 shift=0,0", "rot=0 shift=2,0",
                   "rot=0 shift=-3,0 rows=%d cols=%d,%d" % (c, c, c + 1)], True),
        ("rot_only", ["rot=0 shift=0,0", "rot=90 shift=0,0"], False),
        ("rot180_shift", ["rot=0 shift=0,0", "rot=180 shift=0,0", "rot=0 shift=1,0"], False),
        ("shift2_no_view3", ["rot=0 shift=0,0", "rot=90 shift=0,0", "rot=0 shift=2,0"], None),
    ]
    for name, views, ident in cases:
        path = os.path.join(d, name + ".csv")
        write(path, plan_text(n, views))
        p = run("plan", path)
        lines = first_lines(p.stdout)
        print("%s: %s" % (name, " | ".join(lines)))
        keys = [ln.split(":")[0] for ln in lines]
        if keys != ["identifiable", "free", "sigma_c_ratio_rms", "sigma_c_ratio_max"]:
            fail("%s: first lines %s" % (name, lines))
        val = {ln.split(":")[0]: ln.split(":", 1)[1].strip() for ln in lines}
        is_yes = val["identifiable"] == "yes"
        if ident is not None and is_yes != ident:
            fail("%s: identifiable %s, want %s" % (name, val["identifiable"], ident))
        free = int(val["free"])
        if is_yes:
            rms, mx = float(val["sigma_c_ratio_rms"]), float(val["sigma_c_ratio_max"])
            if free != 0 or not (0 < rms <= mx < 100):
                fail("%s: free %d rms %g max %g" % (name, free, rms, mx))
        else:
            if free < 1 or val["sigma_c_ratio_rms"] != "inf" or val["sigma_c_ratio_max"] != "inf":
                fail("%s: not identifiable but free %d, ratios %s %s"
                     % (name, free, val["sigma_c_ratio_rms"], val["sigma_c_ratio_max"]))
        if name == "ye":
            ye_rms = float(val["sigma_c_ratio_rms"])
            # A data file with the same plan gives the same analysis.
            sim = simulate(d, "yedata", "ye", n, "--sigma-r-um", 0.01)
            p2 = run("plan", sim["inp"])
            if first_lines(p2.stdout) != lines:
                fail("plan on a data file: %s vs %s" % (first_lines(p2.stdout), lines))
            # residual_dof of the plan = dof of the least-squares solution, also with a declared
            # view that has no data (its misalignment is unknown, not an equation).
            text = open(sim["inp"]).read().replace("# view 2: rot=0 shift=1,0\n",
                                                   "# view 2: rot=0 shift=1,0\n# view 9: rot=180 shift=0,0\n")
            extra = os.path.join(d, "ye_extra_view.csv")
            write(extra, text)
            for f in (sim["inp"], extra):
                pl = run("plan", f).stdout
                rd = int([ln for ln in pl.splitlines() if ln.startswith("residual_dof:")][0].split(":")[1])
                sp = os.path.join(d, "dof.json")
                run("grid", "--method", "lsq", f, "--map", os.path.join(d, "dofG.csv"), "--summary", sp)
                dof = json.load(open(sp))["dof"]
                if rd != dof or (f == extra and "view 9: rot=180 shift=0,0 marks=0" not in pl):
                    fail("%s: plan residual_dof %d vs lsq dof %d\n%s" % (f, rd, dof, pl))
        if name == "petro":
            if not float(val["sigma_c_ratio_rms"]) < ye_rms:
                fail("Petro's plan should predict less noise than Ye's")
    # Bad plan files exit 2.
    bad = os.path.join(d, "bad.csv")
    write(bad, plan_text(24, ["rot=0 shift=0,0"]))
    p = run("plan", bad, expect=2)
    if "bad.csv:2:" not in p.stderr:
        fail("plan on N even: %s" % p.stderr)


def case_plot():
    d = fresh_dir("plot")
    n = 9
    sim = simulate(d, "p", "ye", n, "--sigma-r-um", 0.02)
    g = os.path.join(d, "G.csv")
    svg1 = os.path.join(d, "grid.svg")
    run("grid", "--method", "lsq", sim["inp"], "--map", g, "--plot", svg1)
    svg2 = os.path.join(d, "map.svg")
    run("plot", "map", g, "-o", svg2, "--truth", sim["g"], "--scale-um-per-pitch", 5)
    svg3 = os.path.join(d, "truth.svg")
    run("plot", "map", sim["g"], "-o", svg3)
    for path, panels in ((svg1, 1), (svg2, 2), (svg3, 1)):
        root = ET.parse(path).getroot()
        ns = "{http://www.w3.org/2000/svg}"
        arrows = len(root.findall(ns + "polygon"))
        ellipses = len(root.findall(ns + "ellipse"))
        texts = " ".join(t.text or "" for t in root.iter(ns + "text"))
        if arrows < panels * n * n * 0.9:
            fail("%s: %d arrow heads for %d panels of %d nodes" % (path, arrows, panels, n * n))
        if "RMS" not in texts or "max" not in texts or "µm" not in texts:
            fail("%s: title lacks RMS/max: %s" % (path, texts[:200]))
        # u(G) is its own colour map (one cell per node), not ellipses lost at the arrow scale
        cells = len([r for r in root.findall(ns + "rect") if r.get("fill", "").startswith("#")])
        if ellipses:
            fail("%s: %d ellipses (u belongs in its own map)" % (path, ellipses))
        if path != svg3 and cells < n * n:
            fail("%s: %d u(G) colour cells" % (path, cells))
        if path == svg3 and cells >= n * n:
            fail("truth map has no uncertainties but %d colour cells" % cells)
    if "is 5 µm" not in open(svg2, encoding="utf-8").read():
        fail("scale bar does not show the requested 5 um per pitch")
    # Bad map input: exit 2, no SVG.
    bad = os.path.join(d, "bad.csv")
    write(bad, "i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n0,0,0,0,1,zz,,\n")
    out = os.path.join(d, "bad.svg")
    p = run("plot", "map", bad, "-o", out, expect=2)
    if os.path.exists(out) or "bad.csv:2:" not in p.stderr:
        fail("bad map: %s" % p.stderr)


def case_simulate():
    """Same seed: identical files; different seed: different; bad options exit 2 and write nothing."""
    d = fresh_dir("simulate")
    a = simulate(d, "a", "double-shift", 9, "--seed", 5)
    b = simulate(d, "b", "double-shift", 9, "--seed", 5)
    c = simulate(d, "c", "double-shift", 9, "--seed", 6)
    for k in ("inp", "g", "a"):
        if open(a[k]).read() != open(b[k]).read():
            fail("same seed, different %s" % k)
        if open(a[k]).read() == open(c[k]).read():
            fail("different seed, same %s" % k)
    # sigma_G of the truth map as requested (sample std over all gx, gy values).
    g = read_map(a["g"])
    vals = [float(r[4]) for r in g.values()] + [float(r[5]) for r in g.values()]
    m = sum(vals) / len(vals)
    sd = math.sqrt(sum((v - m) ** 2 for v in vals) / (len(vals) - 1))
    if abs(sd - 1.0) > 1e-9:
        fail("sigma_G of the truth %g" % sd)
    # The input file follows SPEC §1: view 3 restricted to row c, columns c, c+1 for N = 9.
    text = open(a["inp"]).read()
    if "# view 3: rot=0 shift=-3,0 rows=4 cols=4,5" not in text:
        fail("double-shift view 3 line:\n" + text[:400])
    for args in (["--n", 8], ["--n", 5], ["--sigma-g-um", "abc"], ["--rho", 1],
                 ["--pitch-mm", 10]):
        out = os.path.join(d, "bad.csv")
        tm = os.path.join(d, "bad_G.csv")
        p = run("simulate", "grid", "--plan", "double-shift", "--out", out, "--truth-map", tm,
                *(args if args[0] != "--n" else args), expect=2)
        if os.path.exists(out) or os.path.exists(tm):
            fail("simulate %s left a file" % args)
        if len(p.stderr.strip().splitlines()) < 1:
            fail("no message for %s" % args)


# --------------------------------------------------------------------------------------------
def with_field(lines, k, col, value):
    """A copy of the file's lines with field col of line k replaced by value."""
    out = list(lines)
    f = out[k].split(",")
    f[col] = value
    out[k] = ",".join(f)
    return out


def case_bad_input():
    """Each bad input: exit 2, 'selfcal: FILE:LINE: ...' on stderr, no output file."""
    d = fresh_dir("bad")
    ye = simulate(d, "ye9", "ye", 9, "--sigma-r-um", 0.001)
    ds = simulate(d, "ds9", "double-shift", 9, "--sigma-r-um", 0.001)
    ye_lines = open(ye["inp"]).read().splitlines(True)
    ds_lines = open(ds["inp"]).read().splitlines(True)
    # Layout of a file written by simulate: 1 tag, 2 N, 3 pitch, 4 origin, views, column header.
    def header_len(lines):
        return next(k for k, l in enumerate(lines) if l.startswith("view,")) + 1
    hy = header_len(ye_lines)  # 8 for Ye (3 views)

    def rows_of(lines, view):
        return [k for k, l in enumerate(lines) if l.split(",")[0] == str(view) and k >= hy]

    cases = []
    # A view the method needs is missing from the header (and its rows gone).
    lines = [l for k, l in enumerate(ye_lines) if not l.startswith("# view 2") and k not in rows_of(ye_lines, 2)]
    cases.append(("missing_view", "ye", lines, hy - 1, "needs a view"))
    # Declared but without data.
    lines = [l for k, l in enumerate(ye_lines) if k not in rows_of(ye_lines, 2)]
    cases.append(("view_without_rows", "ye", lines, 7, "no data rows"))
    # A mark of a needed view missing.
    r1 = rows_of(ye_lines, 1)
    lines = [l for k, l in enumerate(ye_lines) if k != r1[10]]
    cases.append(("incomplete_view", "ye", lines, 6, "lacks mark"))
    # N even.
    lines = list(ye_lines)
    lines[1] = "# N = 10\n"
    cases.append(("n_even", "ye", lines, 2, "even"))
    # Duplicate mark.
    lines = list(ye_lines)
    k = rows_of(ye_lines, 0)[3]
    lines.insert(k + 5, lines[k])
    cases.append(("duplicate", "lsq", lines, k + 6, "duplicate"))
    # A mark off the grid: view 2 (shift +1) mark in the last column.
    k = rows_of(ye_lines, 2)[0]
    lines = with_field(ye_lines, k, 2, "8")
    cases.append(("off_grid", "ye", lines, k + 1, "does not land on the stage grid"))
    # Off the plate altogether.
    lines = with_field(ye_lines, k, 1, "9")
    cases.append(("off_plate", "lsq", lines, k + 1, "off the plate"))
    # Non-numeric field.
    k = rows_of(ye_lines, 1)[5]
    lines = with_field(ye_lines, k, 4, "1.2.3\n")
    cases.append(("non_numeric", "ye", lines, k + 1, "not a finite number"))
    # Wrong field count.
    lines = list(ye_lines)
    lines[k] = lines[k].rstrip("\n") + ",7\n"
    cases.append(("field_count", "lsq", lines, k + 1, "expected 5 fields"))
    # Header contradicting the data: pitch 1.5 instead of 1 (first row is a corner mark).
    lines = list(ye_lines)
    lines[2] = "# pitch_mm = 1.5\n"
    cases.append(("pitch_contradicts", "ye", lines, hy + 1, "contradicts the data"))
    # ... or an origin that is off by a pitch.
    lines = list(ye_lines)
    lines[3] = "# origin_mm = 1,0\n"
    cases.append(("origin_contradicts", "lsq", lines, hy + 1, "contradicts the data"))
    # ... or a view rotation that is wrong (view 1 declared rot=270).
    lines = list(ye_lines)
    lines[5] = lines[5].replace("rot=90", "rot=270")
    r1 = rows_of(ye_lines, 1)
    cases.append(("rot_contradicts", "lsq", lines, r1[0] + 1, "contradicts the data"))
    # A view not declared.
    lines = list(ye_lines)
    k = rows_of(ye_lines, 0)[0]
    lines[k] = "7" + lines[k][1:]
    cases.append(("undeclared_view", "ye", lines, k + 1, "not declared"))
    # Unknown header.
    lines = list(ye_lines)
    lines.insert(2, "# temperature = 20\n")
    cases.append(("unknown_header", "ye", lines, 3, "unknown header"))
    # Double shift: N < 7 (a 5x5 plate simulated with Petrò's views from a plan file: its -3
    # shift leaves the method's chains too short); N = 7 is solved exactly (the paper says
    # N >= 9; the chains of docs/grid-exact.md §6 hold from 7)
    p5 = os.path.join(d, "ds5plan.csv")
    write(p5, plan_text(5, ["rot=0 shift=0,0", "rot=90 shift=0,0", "rot=0 shift=2,0",
                            "rot=0 shift=-3,0 rows=2 cols=2,3"]))
    ds5 = simulate(d, "ds5", p5, 5)
    cases.append(("ds_n_lt_7", "double-shift", open(ds5["inp"]).read().splitlines(True), 2, "N >= 7"))
    p7 = os.path.join(d, "ds7plan.csv")
    write(p7, plan_text(7, ["rot=0 shift=0,0", "rot=90 shift=0,0", "rot=0 shift=2,0",
                            "rot=0 shift=-3,0 rows=3 cols=3,4"]))
    ds7 = simulate(d, "ds7", p7, 7, "--sigma-r-um", 0)
    run("grid", "--method", "double-shift", ds7["inp"], "--map", os.path.join(d, "ds7_map.csv"))
    truth = {(r["i"], r["j"]): r for r in csv.DictReader(open(ds7["g"]))}
    worst = max(max(abs(float(r["gx_um"]) - float(truth[(r["i"], r["j"])]["gx_um"])),
                    abs(float(r["gy_um"]) - float(truth[(r["i"], r["j"])]["gy_um"])))
                for r in csv.DictReader(open(os.path.join(d, "ds7_map.csv"))))
    if not worst < 1e-9:
        fail("double shift at N = 7, noise-free: G error %g um" % worst)
    if "method double-shift: yes" not in run("plan", ds7["inp"]).stdout:
        fail("plan does not offer double shift at N = 7")
    # Double shift: view 3 missing its column c+1.
    hd = header_len(ds_lines)
    lines = [l for l in ds_lines if not (l.startswith("3,") and l.split(",")[2] == "5" and l.split(",")[1] != "4")]
    cases.append(("ds_view3_incomplete", "double-shift", lines, 8, "lacks mark"))
    # Double shift data given to Ye: shift +1 view missing.
    cases.append(("ye_on_ds_data", "ye", ds_lines, hd, "needs a view"))
    # lsq on a plan that does not identify G: views 0 and 1 only.
    lines = [l for k, l in enumerate(ye_lines) if not l.startswith("# view 2") and k not in rows_of(ye_lines, 2)]
    cases.append(("lsq_not_identifiable", "lsq", lines, hy - 1, "do not identify G"))
    # A plan file (no data) given to grid.
    lines = ye_lines[:hy]
    cases.append(("no_data", "lsq", lines, hy, "no data rows"))

    for name, method, lines, line, needle in cases:
        path = os.path.join(d, name + ".csv")
        write(path, "".join(lines))
        outs = [os.path.join(d, name + s) for s in ("_G.csv", "_A.csv", "_S.json", "_plot.svg")]
        p = run("grid", "--method", method, path, "--map", outs[0], "--artifact", outs[1],
                "--summary", outs[2], "--plot", outs[3], expect=2)
        err = p.stderr.strip().splitlines()
        want = "selfcal: %s:%d: " % (path, line)
        if len(err) != 1 or not err[0].startswith(want) or needle not in err[0]:
            fail("%s: stderr %r, want one line starting %r containing %r" % (name, p.stderr, want, needle))
        left = [o for o in outs if os.path.exists(o)]
        if left:
            fail("%s: output files left: %s" % (name, left))
        if [f for f in os.listdir(d) if ".tmp" in f or f.startswith(".")]:
            fail("%s: temporary files left: %s" % (name, os.listdir(d)))
        print("ok %-22s %s" % (name, err[0]))
    # Usage errors exit 2 too.
    run("grid", "--method", "magic", ye["inp"], "--map", os.path.join(d, "x.csv"), expect=2)
    run("grid", "--method", "ye", ye["inp"], expect=2)
    run("grid", "--method", "ye", os.path.join(d, "does_not_exist.csv"), "--map", os.path.join(d, "x.csv"), expect=2)
    if os.path.exists(os.path.join(d, "x.csv")):
        fail("usage error left a map")


def case_fuzz():
    """Randomly damaged input files (seeded): selfcal grid/plan exit 0 or 2, never crash, and on
    exit 2 leave no output file."""
    import random
    rnd = random.Random(12345)
    d = fresh_dir("fuzz")
    src = simulate(d, "src", "double-shift", 9, "--sigma-r-um", 0.001)
    base = open(src["inp"]).read().splitlines(True)
    junk = ["", "x", "-", "1e999", "nan", "0x10", " ", ",", "# view 0: rot=0 shift=0,0", "9999999999999999999",
            "-1", "3.5", "# N = 9", "view,i,j,x_mm,y_mm", "\x00", "1,2", "rot=90", "ü"]
    counts = {0: 0, 2: 0}
    for t in range(int(ARGS[0]) if ARGS else 150):
        lines = list(base)
        for _ in range(rnd.randint(1, 3)):
            k = rnd.randrange(len(lines))
            op = rnd.randrange(5)
            if op == 0:
                del lines[k]
            elif op == 1:
                lines.insert(k, lines[rnd.randrange(len(lines))])
            elif op == 2:
                f = lines[k].rstrip("\n").split(",")
                f[rnd.randrange(len(f))] = rnd.choice(junk)
                lines[k] = ",".join(f) + "\n"
            elif op == 3:
                lines[k] = lines[k][: rnd.randrange(len(lines[k]) + 1)]
            else:
                lines.insert(k, rnd.choice(junk) + "\n")
        path = os.path.join(d, "f%d.csv" % t)
        with open(path, "w", encoding="utf-8", errors="surrogateescape") as f:
            f.write("".join(lines).replace("\\x00", "\0"))
        method = rnd.choice(["ye", "double-shift", "lsq"])
        outs = [os.path.join(d, "f%d_%s" % (t, s)) for s in ("G.csv", "A.csv", "S.json")]
        for args in (["grid", "--method", method, path, "--map", outs[0], "--artifact", outs[1],
                      "--summary", outs[2]], ["plan", path]):
            p = subprocess.run([CLI] + args, capture_output=True, text=True, timeout=120)
            if p.returncode not in (0, 2):
                fail("%s: exit %d\n%s" % (" ".join(args), p.returncode, p.stderr[-2000:]))
            if p.returncode == 2:
                if args[0] == "grid" and any(os.path.exists(o) for o in outs):
                    fail("exit 2 but outputs left: %s" % path)
                if not p.stderr.startswith("selfcal: ") or len(p.stderr.strip().splitlines()) != 1:
                    fail("stderr for %s: %r" % (path, p.stderr))
            counts[p.returncode] += 1
    print("fuzz: exit codes %s" % counts)


def case_many_views():
    """Hundreds of views (no fixed cap): a 363-placement stitched plan (N = 3 plate on a 21 x 21
    stage, step 1) through simulate, the file, grid (lsq), plan, plan --design, report, simulate
    exports and import; noise-free G, A and every misalignment equal the truth."""
    d = fresh_dir("many_views")
    n, stage = 3, "21,21"
    sim = simulate(d, "s", "stitch", n, "--stage", stage, "--sigma-r-um", 0, "--seed", 5,
                   "--origin-mm", "12.5,-3")
    views = [l for l in open(sim["inp"]) if l.startswith("# view ")]
    if len(views) != 363 or not views[-1].startswith("# view 362: rot=0 shift=1,0"):
        fail("stitched plan: %d view lines, last %r" % (len(views), views[-1:]))
    out = {k: os.path.join(d, "est_" + k) for k in ("G.csv", "A.csv", "S.json", "R.csv")}
    run("grid", "--method", "lsq", sim["inp"], "--map", out["G.csv"], "--artifact", out["A.csv"],
        "--summary", out["S.json"], "--residuals", out["R.csv"], "--quiet")
    g, gt = read_map(out["G.csv"]), read_map(sim["g"])
    if len(g) != 21 * 21 or set(g) != set(gt):
        fail("map has %d nodes" % len(g))
    worst = max(max(abs(float(r[4]) - float(gt[k][4])), abs(float(r[5]) - float(gt[k][5])))
                for k, r in g.items())
    a, at = read_art(out["A.csv"]), read_art(sim["a"])
    worst_a = max(max(abs(a[k][0] - at[k][0]), abs(a[k][1] - at[k][1])) for k in at)
    s, tr = json.load(open(out["S.json"])), json.load(open(sim["t"]))
    if len(s["views"]) != 363 or len(tr["views"]) != 363:
        fail("summary views %d, truth views %d" % (len(s["views"]), len(tr["views"])))
    worst_m = max(max(abs(sv["tx_um"] - tv["tx_um"]), abs(sv["ty_um"] - tv["ty_um"]),
                      1e-3 * abs(sv["theta_urad"] - tv["theta_urad"]))
                  for sv, tv in zip(s["views"], tr["views"]))
    print("363 views: max |G-G_true| %.3g um, |A-A_true| %.3g um, misalignment %.3g um"
          % (worst, worst_a, worst_m))
    if not (worst <= 1e-9 and worst_a <= 1e-9 and worst_m <= 1e-8):
        fail("363 views: G %g, A %g, misalignment %g beyond 1e-9 / 1e-8" % (worst, worst_a, worst_m))
    rows = sum(1 for l in open(out["R.csv"]) if l[:1].isdigit())
    if rows != sum(1 for l in open(sim["inp"]) if l[:1].isdigit()):
        fail("residuals: %d rows" % rows)
    # plan: the file's 363 views analysed; plan --design proposes the same raster at this size
    p = run("plan", sim["inp"])
    if "identifiable: yes" not in p.stdout or "views: 363" not in p.stdout:
        fail("plan: %s" % p.stdout[:300])
    p = run("plan", "--design", "--n", n, "--stage", stage, "-o", os.path.join(d, "design.csv"))
    if "identifiable: yes" not in p.stdout:
        fail("plan --design: %s" % p.stdout[:300])
    run("report", "grid", sim["inp"], "-o", os.path.join(d, "r.html"))
    if open(os.path.join(d, "r.html")).read().count("<tr><td>362</td>") < 1:
        fail("report: view 362 not in its tables")
    # each view its own noise: 363 values on the command line, written back per view
    sig = ",".join("%g" % (0.01 + 0.001 * (v % 7)) for v in range(363))
    sim2 = simulate(d, "w", "stitch", n, "--stage", stage, "--view-sigma-r-um", sig)
    lines = [l for l in open(sim2["inp"]) if l.startswith("# view ")]
    if len(lines) != 363 or "sigma_um=0.016" not in lines[6] or "sigma_um=0.01" not in lines[362]:
        fail("--view-sigma-r-um: %r ... %r" % (lines[6:7], lines[362:]))
    # the measuring machine's files of every view and the import back
    ex = os.path.join(d, "exports")
    p = run("simulate", "exports", sim["inp"], "--dir", ex, "--units", "mm")
    cmd = p.stdout.replace("\\\n", " ")
    import shlex
    args = shlex.split(cmd)[1:]
    imported = os.path.join(d, "imported.csv")
    args[args.index("IN.csv")] = imported
    run(*args)
    run("grid", "--method", "lsq", imported, "--map", os.path.join(d, "imp_G.csv"), "--quiet")
    gi = read_map(os.path.join(d, "imp_G.csv"))
    wi = max(max(abs(float(r[4]) - float(gt[k][4])), abs(float(r[5]) - float(gt[k][5])))
             for k, r in gi.items())
    # the exported points carry 1e-6 mm of rounding: G within a few nm
    if not wi <= 5e-3:
        fail("imported 363 views: max |G-G_true| %g um" % wi)
    print("import of 363 view files: max |G-G_true| %.3g um" % wi)


def case_memory_progress():
    """Memory stated up front and refused beyond --max-memory (exit 1, before the assembly);
    --progress names every phase of a least-squares solve on stderr."""
    d = fresh_dir("memory_progress")
    sim = simulate(d, "s", "stitch", 9, "--stage", "29,29", "--sigma-r-um", 0.01)
    m = os.path.join(d, "G.csv")
    p = run("grid", "--method", "lsq", sim["inp"], "--map", m, "--quiet", "--max-memory", "64K",
            expect=1)
    if "needs about" not in p.stderr or "GB allowed" not in p.stderr or os.path.exists(m):
        fail("--max-memory 64K: %r" % p.stderr)
    p = run("plan", sim["inp"], "--max-memory", "64K", expect=1)
    if "needs about" not in p.stderr:
        fail("plan --max-memory 64K: %r" % p.stderr)
    p = run("plan", "--design", "--n", 9, "--stage", "29,29", "--max-memory", "64K", expect=1)
    if "needs about" not in p.stderr or "too large for the exact analysis" not in p.stderr:
        fail("plan --design --max-memory 64K: %r" % p.stderr)
    for bad in ("12X", "-1G", "0", "G", ""):
        run("grid", "--method", "lsq", sim["inp"], "--map", m, "--max-memory", bad, expect=2)
    p = run("grid", "--method", "lsq", sim["inp"], "--map", m, "--quiet", "--progress",
            "--max-memory", "4G")
    phases = [l.split(": ", 1)[1].split(" (")[0] for l in p.stderr.splitlines()
              if l.startswith("selfcal grid: ") and " (" in l]
    want = ["read", "assemble", "analyse", "factor", "selected inverse", "solve", "residuals",
            "write"]
    if [ph for ph in phases if ph in want] != want:
        fail("--progress phases %s (stderr %r)" % (phases, p.stderr))
    mem = [l for l in p.stderr.splitlines() if "peak memory about" in l]
    if len(mem) != 1 or "of 4.00 GiB allowed" not in mem[0]:
        fail("--progress memory line: %r" % mem)
    if not any("left)" in l for l in p.stderr.splitlines()):
        fail("--progress: no time left after the factor: %r" % p.stderr)
    # without --progress and not on a terminal: nothing on stderr
    p = run("grid", "--method", "lsq", sim["inp"], "--map", m, "--quiet")
    if p.stderr:
        fail("stderr without --progress: %r" % p.stderr)


def case_solver():
    """grid --solver: the full system (A kept) and the reduced one give the same map, artifact,
    summary and residuals (1e-9 of each column's scale) on a stitched plan of 27 placements
    (auto: full); --node-sigma none leaves the uncertainties and t empty, sample:K gives K nodes'
    σ equal to those of all; bad values and the options it excludes: exit 2."""
    d = fresh_dir("solver")
    sim = simulate(d, "s", "stitch", 5, "--stage", "13,13", "--sigma-r-um", 0.01, "--seed", 4)
    out = {}
    for solver in ("reduced", "full", "auto"):
        o = {k: os.path.join(d, solver + "_" + k) for k in ("G.csv", "A.csv", "S.json", "R.csv")}
        run("grid", "--method", "lsq", sim["inp"], "--map", o["G.csv"], "--artifact", o["A.csv"],
            "--summary", o["S.json"], "--residuals", o["R.csv"], "--quiet", "--solver", solver)
        out[solver] = o

    def close(a, b, what):  # numbers, or fields where '' (not tested, h = 1) must match
        if [x == "" for x in a] != [y == "" for y in b]:
            fail("%s: empty fields differ" % what)
        a = [float(x) for x in a if x != ""]
        b = [float(y) for y in b if y != ""]
        scale = max([abs(x) for x in a] + [1e-300])
        worst = max([abs(x - y) for x, y in zip(a, b)] + [0.0])
        if len(a) != len(b) or worst > 1e-9 * scale:
            fail("%s: reduced and full differ by %g (scale %g)" % (what, worst, scale))

    for other in ("full", "auto"):
        g, h = read_map(out["reduced"]["G.csv"]), read_map(out[other]["G.csv"])
        for c in (4, 5, 6, 7):
            close([float(g[k][c]) for k in sorted(g)], [float(h[k][c]) for k in sorted(g)],
                  "map column %d (%s)" % (c, other))
        a, b = read_art(out["reduced"]["A.csv"]), read_art(out[other]["A.csv"])
        close([a[k][0] for k in sorted(a)], [b[k][0] for k in sorted(a)], "artifact")
        ra = list(csv.reader(open(out["reduced"]["R.csv"])))[1:]
        rb = list(csv.reader(open(out[other]["R.csv"])))[1:]
        for c in (3, 4, 5, 6):
            close([r[c] for r in ra], [r[c] for r in rb], "residuals column %d" % c)
        sa, sb = json.load(open(out["reduced"]["S.json"])), json.load(open(out[other]["S.json"]))
        close([v["utx_um"] for v in sa["views"]], [v["utx_um"] for v in sb["views"]], "u(tx)")
    # --node-sigma none: no uncertainties, no t; sample:5: five nodes, as all gives them
    m, r = os.path.join(d, "none_G.csv"), os.path.join(d, "none_R.csv")
    run("grid", "--method", "lsq", sim["inp"], "--map", m, "--residuals", r, "--quiet",
        "--node-sigma", "none")
    if any(row[6] or row[7] for row in read_map(m).values()):
        fail("--node-sigma none: uncertainties written")
    if any(row[5] or row[6] for row in list(csv.reader(open(r)))[1:]):
        fail("--node-sigma none: standardized residuals written")
    m = os.path.join(d, "sample_G.csv")
    run("grid", "--method", "lsq", sim["inp"], "--map", m, "--quiet", "--node-sigma", "sample:5")
    g, full = read_map(m), read_map(out["reduced"]["G.csv"])
    got = [k for k, row in g.items() if row[6]]
    if len(got) != 5:
        fail("--node-sigma sample:5: %d nodes with sigma" % len(got))
    close([float(full[k][6]) for k in got], [float(g[k][6]) for k in got], "sampled sigma")
    for bad in (("--solver", "dense"), ("--node-sigma", "sample:0"), ("--node-sigma", "some"),
                ("--node-sigma", "none", "--reject-outliers")):
        run("grid", "--method", "lsq", sim["inp"], "--map", m, *bad, expect=2)


CASES = {"solver": case_solver, "fuzz": case_fuzz, "end_to_end": case_end_to_end, "lsq_noise": case_lsq_noise, "plan": case_plan,
         "plot": case_plot, "simulate": case_simulate, "bad_input": case_bad_input,
         "many_views": case_many_views, "memory_progress": case_memory_progress}
CASES[CASE]()
print("PASS " + CASE + " " + " ".join(ARGS))
