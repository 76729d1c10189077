#!/usr/bin/env python3
"""CLI tests of the straightness-profile commands (SPEC §2, §3): end to end against the simulated
truth, DABAM mirror profiles, bad input (exit 2, file:line, no output file), predicted against
Monte Carlo uncertainty, profile-plan and plot. Standard library only.

usage: profile_cli_test.py SELFCAL TMPDIR DATA_DIR CASE [args...]
"""
import math
import os
import re
import subprocess
import sys

CLI, TMP, DATA = sys.argv[1], sys.argv[2], sys.argv[3]
CASE, ARGS = sys.argv[4], sys.argv[5:]
os.makedirs(TMP, exist_ok=True)


def run(*args, expect=0):
    p = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True, timeout=120)
    if p.returncode != expect:
        sys.exit(f"FAIL: selfcal {' '.join(map(str, args))} exited {p.returncode}, expected {expect}\n"
                 f"stdout: {p.stdout}\nstderr: {p.stderr}")
    return p


# Tests run in parallel: every invocation (case + arguments) gets file names of its own.
TAG = re.sub(r"[^A-Za-z0-9.-]+", "_", "_".join([CASE, *ARGS]))


def path(name):
    return os.path.join(TMP, f"profile_cli_{TAG}_{name}")


def read_csv(p):
    with open(p) as fh:
        lines = [ln.rstrip("\n") for ln in fh if ln.strip() and not ln.startswith("#")]
    head = lines[0].split(",")
    rows = []
    for ln in lines[1:]:
        f = ln.split(",")
        assert len(f) == len(head), f"{p}: {ln}"
        rows.append({h: (float(v) if v != "" else None) for h, v in zip(head, f)})
    return head, rows


def check_against_truth(out, truth, tol_um, d1):
    head, rows = read_csv(out)
    assert head == ["n", "x_mm", "f_um", "uf_um", "ey_um"], head
    _, trows = read_csv(truth)
    assert len(rows) == len(trows)
    n = len(rows)
    ef = max(abs(r["f_um"] - t["f_um"]) for r, t in zip(rows, trows))
    ey = max(abs(r["ey_um"] - t["ey_um"]) for r, t in zip(rows[: n - d1], trows[: n - d1]))
    assert all(r["ey_um"] is None for r in rows[n - d1:]), "ey must be empty for n >= N - d1"
    assert all(int(r["n"]) == i for i, r in enumerate(rows))
    if not (ef <= tol_um and ey <= tol_um):
        sys.exit(f"FAIL: {out}: max |f err| {ef:.3g} um, max |e_y err| {ey:.3g} um > {tol_um}")
    return ef, ey


def case_end_to_end():
    """Noise-free simulation with stage and zero-point errors: f and e_y to 1e-9 µm."""
    method, configs = ARGS[0], ARGS[1]
    profile = ARGS[2] if len(ARGS) > 2 else "random"
    for cfg in configs.split("|"):
        n, d1, d2 = map(int, cfg.split(","))
        src = "random" if profile == "random" else os.path.join(DATA, "dabam", profile)
        inp, truth, out = path(f"{cfg}_in.csv"), path(f"{cfg}_truth.csv"), path(f"{cfg}_out.csv")
        run("simulate", "profile", "--n", n, "--s-mm", 1.0, "--d1", d1, "--d2", d2, "--profile", src,
            "--sigma-disp-um", 0, "--sigma-angle-urad", 0, "--seed", n + d1, "--out", inp, "--truth", truth)
        run("profile", "--method", method, inp, "--out", out)
        ef, ey = check_against_truth(out, truth, 1e-9, d1)
        print(f"{method} {profile} N={n} d={d1}/{d2}: max |f err| {ef:.2e} um, |e_y err| {ey:.2e} um")


def write_lines(p, lines):
    with open(p, "w") as fh:
        fh.write("\n".join(lines) + "\n")


def good_lines(n=30, d1=3, d2=5):
    out = ["# selfcal-profile v1", f"# N = {n}", "# s_mm = 1.0", f"# scan 1: d={d1}", f"# scan 2: d={d2}",
           "scan,n,m1_um,m2_um,m3_urad"]
    for k, d in ((1, d1), (2, d2)):
        out += [f"{k},{i},{0.01 * i:.6f},{0.02 * i + k:.6f},0.5" for i in range(n - d)]
    return out


def case_bad_input():
    """Each bad file: exit 2, one line naming file:line and the problem, no output written."""
    n, d1, d2 = 30, 3, 5
    s1, s2 = 7, 7 + n - d1  # first data lines of the scans
    cases = []
    g = good_lines()
    cases.append(("scan_missing_header", [ln for i, ln in enumerate(g) if i != 4], "dft", 5, "scan 2 missing"))
    cases.append(("scan_missing_rows", g[: s2 - 1], "lsq", 5, "scan 2 missing"))
    g = good_lines(30, 6, 10)
    cases.append(("not_coprime_dft", g, "dft", 5, "not coprime"))
    cases.append(("not_coprime_lsq", g, "lsq", 5, "common divisor"))
    cases.append(("not_multiple_dft", good_lines(31, 3, 5), "dft", 2, "not a multiple"))
    cases.append(("n_too_small_lsq", good_lines(7, 3, 5), "lsq", 2, "too small"))
    g = good_lines(8, 3, 5)
    g[1] = "# N = 5"
    cases.append(("n_too_small", g, "lsq", 2, "N too small"))
    g = good_lines()
    # a gap (SPEC §2a): least squares solves around it (profile_cli_rig), the DFT refuses it at
    # the scan's header line, naming --method lsq
    cases.append(("gap", g[: s1 + 3] + g[s1 + 4:], "dft", 4, "--method lsq"))
    g = good_lines()
    g[s1 + 5] = "1,5,0,0,0"
    cases.append(("duplicate", g, "dft", s1 + 6, "duplicate"))
    g = good_lines()
    g[s2 + 1] = "2,25,0,0,0"
    cases.append(("n_out_of_range", g, "lsq", s2 + 2, "out of range"))
    g = good_lines()
    g[s1 + 2] = "1,3,0.1,abc,0"
    cases.append(("non_numeric", g, "lsq", s1 + 3, "m2_um"))
    g = good_lines()
    g[s1 + 2] = "1,3,0.1,0.2,"
    cases.append(("empty_field", g, "dft", 4, "scan 1 has no complete sample for n = 3..3"))
    g = good_lines()
    g[s1 + 2] = "1,3,0.1,0.2,7,5"  # a decimal comma: read as 7 it would shift the data silently
    cases.append(("decimal_comma", g, "lsq", s1 + 3, "expected 5 fields (scan,n,m1_um,m2_um,m3_urad), got 6"))
    g = good_lines()
    g[s1 - 2] += ",note"
    cases.append(("extra_column", g, "dft", s1 - 1, "5 columns, got 6"))
    cases.append(("dft_equal_spacings", good_lines(40, 1, 1), "dft", 5, "d1 = d2 = 1: the DFT method combines two different spacings"))
    g = good_lines()
    g[2] = "# s_mm = x"
    cases.append(("bad_header_value", g, "dft", 3, "s_mm"))
    for name, lines, method, line, what in cases:
        inp, out = path(f"{name}.csv"), path(f"{name}_out.csv")
        write_lines(inp, lines)
        if os.path.exists(out):
            os.remove(out)
        p = run("profile", "--method", method, inp, "--out", out, expect=2)
        err = p.stderr.strip()
        if f"{inp}:{line}:" not in err or what not in err or len(err.splitlines()) != 1:
            sys.exit(f"FAIL: {name}: expected one line with '{inp}:{line}:' and '{what}', got:\n{err}")
        if os.path.exists(out):
            sys.exit(f"FAIL: {name}: output file written despite bad input")
        leftovers = [f for f in os.listdir(TMP) if f.startswith(os.path.basename(out))]
        if leftovers:
            sys.exit(f"FAIL: {name}: temporary files left: {leftovers}")
        print(f"{name}: {err}")
    # A header that promises N = 2e7 and two rows, through a pipe (no file size to check N
    # against): refused for its gap before any work the size of N (the plan made while the rows
    # are read starts only once 1/32 of them came good; it took 4 GB before)
    # the same with its first 1/32 of rows good (N = 4e6: 250 000 rows, then a gap): a pipe's
    # plan waits for every row (a file's size bounds its N; a pipe's does not)
    hdr = "# selfcal-profile v1\n# N = %d\n# s_mm = 0.001\n# scan 1: d=10\n# scan 2: d=11\nscan,n,m1_um,m2_um,m3_urad\n"
    with open(path("huge2.csv"), "w") as fh:
        fh.write(hdr % 4000000)
        fh.write("".join("1,%d,1,2,3\n" % k for k in range(250002)))
    with open(path("huge1.csv"), "w") as fh:
        fh.write(hdr % 20000000 + "1,0,1,2,3\n2,0,1,2,3\n")
    for name, line, limit_mb in (("huge1.csv", 8, 100), ("huge2.csv", 250008, 250)):
        for method in ("lsq", "dft"):
            # this child's own peak (wait4: the shell and its pipeline, no earlier process)
            proc = subprocess.Popen(["sh", "-c", 'cat "$1" | "$2" profile --method "$3" /dev/stdin '
                                     '--out "$4" 2>"$5"', "sh", path(name), CLI, method,
                                     path("h.csv"), path("h.err")])
            _, status, ru = os.wait4(proc.pid, 0)
            proc.returncode = os.waitstatus_to_exitcode(status)
            err = open(path("h.err")).read()
            rss_mb = ru.ru_maxrss / 1024
            if proc.returncode != 2 or f"/dev/stdin:{line}: gap in scan 1" not in err:
                sys.exit(f"FAIL: {name} through a pipe ({method}): exit {proc.returncode}: {err}")
            if rss_mb > limit_mb:
                sys.exit(f"FAIL: {name} through a pipe ({method}): {rss_mb:.0f} MB before the refusal")
            print(f"{name} through a pipe ({method}): refused, peak {rss_mb:.0f} MB")
    # a DABAM profile that is an endless run of comments (a FIFO fed by `yes '#'`) is refused
    import shutil
    shutil.copy(os.path.join(DATA, "dabam", "dabam-001.txt"), path("endless.txt"))
    if os.path.exists(path("endless.dat")):
        os.remove(path("endless.dat"))
    os.mkfifo(path("endless.dat"))
    feeder = subprocess.Popen(["sh", "-c", 'yes "#" > "$1"', "sh", path("endless.dat")],
                              stderr=subprocess.DEVNULL)
    p = subprocess.run([CLI, "simulate", "profile", "--profile", path("endless.dat"), "--out",
                        path("e_in.csv"), "--truth", path("e_t.csv")], capture_output=True, text=True,
                       timeout=100)
    feeder.kill()
    feeder.wait()
    if p.returncode != 2 or "comment or blank lines in a row" not in p.stderr:
        sys.exit(f"FAIL: endless DABAM comments: exit {p.returncode}: {p.stderr}")
    # a noise option out of range: the same words in every command that takes it
    good = path("good_noise.csv")
    write_lines(good, good_lines())
    for args in (["profile", "--method", "lsq", good, "--out", path("x.csv"), "--sigma-disp-um", "1e7"],
                 ["report", "profile", good, "-o", path("x.html"), "--sigma-disp-um", "1e300"],
                 ["profile", "--method", "dft", good, "--out", path("x.csv"), "--sigma-angle-urad", "-1"],
                 ["import", "profile", "--spacing-mm", "1", good, "--spacing-mm", "1.1", good,
                  "-o", path("x.csv"), "--sigma-disp-um", "0"]):
        p = run(*args, expect=2)
        err = p.stderr.strip()
        if "is not a noise: a number" not in err or args[-2] not in err or len(err.splitlines()) != 1:
            sys.exit(f"FAIL: noise option message for {args[:2]}: {err}")
    # usage errors exit 2 too
    run("profile", "--method", "fourier", path("gap.csv"), "--out", path("x.csv"), expect=2)
    run("profile", path("gap.csv"), expect=2)
    run("profile", "--method", "lsq", path("does_not_exist.csv"), "--out", path("x.csv"), expect=2)


def case_noise():
    """Noisy data: predicted uncertainty (analytic) against Monte Carlo through the CLI, the header
    sigma lines against the command line, and the residual noise estimate; errors within ~3·u."""
    n, d1, d2 = 330, 10, 11
    inp, truth = path("in.csv"), path("truth.csv")
    run("simulate", "profile", "--n", n, "--d1", d1, "--d2", d2, "--sigma-disp-um", 0.01,
        "--sigma-angle-urad", 1.0, "--seed", 11, "--out", inp, "--truth", truth)
    _, trows = read_csv(truth)
    for method in ("dft", "lsq"):
        out, mc = path(f"{method}.csv"), path(f"{method}_mc.csv")
        run("profile", "--method", method, inp, "--out", out)
        run("profile", "--method", method, inp, "--out", mc, "--mc", 2000, "--seed", 5)
        _, a = read_csv(out)
        _, b = read_csv(mc)
        ua = [r["uf_um"] for r in a]
        ub = [r["uf_um"] for r in b]
        ratio = math.sqrt(sum(x * x for x in ub) / sum(x * x for x in ua))
        mid = ua[n // 2] * 1e3
        z = [(r["f_um"] - t["f_um"]) / r["uf_um"] for r, t in zip(a, trows)]
        zrms = math.sqrt(sum(v * v for v in z) / n)
        print(f"{method}: u(mid) {mid:.2f} nm, MC/predicted RMS {ratio:.4f}, RMS of error/u {zrms:.3f}")
        assert abs(ratio - 1) < 0.03, ratio
        assert 10 < mid < 14, mid
        assert 0.6 < zrms < 1.4, zrms
        # the command line wins over the header lines: 10× the noise, 10× the uncertainty
        big = path(f"{method}_big.csv")
        run("profile", "--method", method, inp, "--out", big, "--sigma-disp-um", 0.1, "--sigma-angle-urad", 10)
        _, c = read_csv(big)
        assert abs(c[n // 2]["uf_um"] / a[n // 2]["uf_um"] - 10) < 1e-6
    # without sigma lines: the noise is estimated from the residuals
    inp2 = path("in_nosigma.csv")
    run("simulate", "profile", "--n", n, "--d1", d1, "--d2", d2, "--sigma-disp-um", 0.01,
        "--sigma-angle-urad", 0, "--seed", 12, "--no-sigma-lines", "--out", inp2, "--truth", path("t2.csv"))
    with open(inp2) as fh:
        assert "sigma" not in fh.read()
    out = path("est.csv")
    p = run("profile", "--method", "lsq", inp2, "--out", out)
    m = re.search(r"sigma_y1_um: ([0-9.eE+-]+)", p.stdout)
    est = float(m.group(1))
    print(f"estimated sigma_y {est:.5f} um (simulated {math.sqrt(2) * 0.01:.5f})")
    assert abs(est / (math.sqrt(2) * 0.01) - 1) < 0.15
    # the noise stated as 0 on noisy data: uf 0 as stated, and a warning giving the residuals'
    # scale (about sigma_y, 14 nm); none on noise-free data stating 0
    for cmd in (["profile", "--method", "lsq", inp2, "--out", path("zero.csv")],
                ["profile", "--method", "dft", inp2, "--out", path("zero_dft.csv")],
                ["report", "profile", inp2, "-o", path("zero.html")],
                ["report", "profile", inp2, "--method", "dft", "-o", path("zero_dft.html")]):
        p = run(*cmd, "--sigma-disp-um", 0, "--sigma-angle-urad", 0)
        m = re.search(r"warning: the noise is stated as 0 but the residuals' scale is ([0-9.]+) nm", p.stderr)
        assert m and abs(float(m.group(1)) / (math.sqrt(2) * 10) - 1) < 0.15, p.stderr
    nf = path("noise_free.csv")
    run("simulate", "profile", "--n", n, "--d1", d1, "--d2", d2, "--noise-free", "--seed", 12,
        "--out", nf, "--truth", path("t3.csv"))
    p = run("profile", "--method", "lsq", nf, "--out", path("nf_out.csv"))
    assert "warning" not in p.stderr, p.stderr


def case_plan():
    p = run("profile-plan", "--n", 330, "--s-mm", 1, "--sigma-disp-um", 0.01, "--sigma-angle-urad", 1,
            "--d-max", 12, "--top", 100)
    lines = [ln for ln in p.stdout.splitlines() if not ln.startswith("#")]
    assert lines[0] == "rank,d1,d2,D1_mm,D2_mm,lsq_rms_nm,lsq_max_nm,dft_rms_nm,dft_max_nm"
    rows = [ln.split(",") for ln in lines[1:]]
    pairs = {(int(r[1]), int(r[2])) for r in rows}
    assert (10, 11) in pairs and (3, 11) in pairs
    assert all(math.gcd(a, b) == 1 for a, b in pairs), "non-coprime pair listed"
    rms = [float(r[5]) for r in rows]
    assert rms == sorted(rms), "not ranked by RMS"
    for r in rows:
        a, b = int(r[1]), int(r[2])
        assert (r[7] != "") == (330 % (a * b) == 0), f"DFT column wrong for {a}/{b}"
    # the ranking's figures are those `selfcal profile` predicts
    r1011 = next(r for r in rows if (int(r[1]), int(r[2])) == (10, 11))
    inp = path("in.csv")
    run("simulate", "profile", "--n", 330, "--d1", 10, "--d2", 11, "--out", inp, "--truth", path("t.csv"))
    run("profile", "--method", "lsq", inp, "--out", path("p.csv"))
    _, a = read_csv(path("p.csv"))
    rms_nm = 1e3 * math.sqrt(sum(r["uf_um"] ** 2 for r in a) / len(a))
    assert abs(rms_nm - float(r1011[5])) < 1e-3, (rms_nm, r1011)
    run("profile-plan", "--n", 330, "--s-mm", 1, expect=2)
    print(p.stdout)


def case_plot():
    inp, truth = path("in.csv"), path("truth.csv")
    run("simulate", "profile", "--out", inp, "--truth", truth)
    run("profile", "--method", "dft", inp, "--out", path("p.csv"), "--plot", path("p.svg"))
    run("profile", "--method", "lsq", inp, "--out", path("q.csv"))
    run("plot", "profile", path("p.csv"), "-o", path("pq.svg"), "--truth", truth, "--compare", path("q.csv"))
    for f in ("p.svg", "pq.svg"):
        with open(path(f)) as fh:
            s = fh.read()
        assert s.startswith("<?xml") and s.rstrip().endswith("</svg>") and s.count("<polyline") >= 3, f
    run("plot", "profile", path("missing.csv"), "-o", path("x.svg"), expect=2)
    # --uncertainty-only of a result whose uf_um is empty: exit 2 naming the file
    rows = open(path("q.csv")).read().splitlines()
    with open(path("q_nou.csv"), "w") as fh:
        fh.write(rows[0] + "\n" + "".join(",".join(c if k != 3 else "" for k, c in enumerate(r.split(",")))
                                       + "\n" for r in rows[1:]))
    p = run("plot", "profile", path("q_nou.csv"), "-o", path("u.svg"), "--uncertainty-only", expect=2)
    if not p.stderr.startswith("selfcal: " + path("q_nou.csv") + ":1: nothing to plot"):
        sys.exit(f"FAIL: --uncertainty-only without uf: {p.stderr}")
    case_plot_long()


def svg_shapes(p, tag):
    """The points of every <tag> (polyline, polygon) of an SVG file, as lists of (x, y)."""
    import xml.etree.ElementTree as ET
    root = ET.parse(p).getroot()
    return [[tuple(map(float, q.split(","))) for q in e.get("points").split()]
            for e in root.iter("{http://www.w3.org/2000/svg}" + tag)]


def case_plot_long():
    """A curve of 300 000 points is thinned to what the drawing shows (svg.c: per half-pixel
    column its first, lowest, highest and last point), and keeps what the eye sees: one sample
    high and one low on a flat line, and its ends."""
    n = 300000
    lines = ["n,x_mm,f_um,uf_um,ey_um"]
    for i in range(n):
        f = 1.0 if i == 123457 else -1.0 if i == 234567 else 0.0
        u = 0.5 if i == 54321 else 0.1
        lines.append(f"{i},{i * 0.001:.3f},{f},{u},{f}")
    write_lines(path("long.csv"), lines)
    run("plot", "profile", path("long.csv"), "-o", path("long.svg"))
    size = os.path.getsize(path("long.svg"))
    assert size < 2_000_000, f"long.svg: {size} bytes"
    curves = [c for c in svg_shapes(path("long.svg"), "polyline") if len(c) > 4]
    assert curves, "no curve"
    for c in curves:
        assert len(c) < 8 * 900, f"{len(c)} points kept of {n}"
    f_curve = curves[0]  # the profile panel's f
    ys = sorted({y for _, y in f_curve})
    assert len(ys) == 3, f"f drawn at {len(ys)} heights, expected the line and both samples: {ys[:5]}"
    xs = [x for x, _ in f_curve]
    assert xs[0] == min(xs) and xs[-1] == max(xs), "the curve's ends are kept"
    bands = [b for b in svg_shapes(path("long.svg"), "polygon") if len(b) > 8]
    assert bands, "no band"
    # f ± k·u: the upper edge at two heights (0.1k, 0.5k) and the spikes of f add theirs
    assert all(len({y for _, y in b}) >= 4 for b in bands), "a band lost its wide sample"
    # plot xy: a dot on each point of a short series, none on a long one (only its thinned line)
    import xml.etree.ElementTree as ET
    write_lines(path("short.csv"), lines[:151])
    for name, dots in (("short", 2 * 150), ("long", 0)):
        run("plot", "xy", path(f"{name}.csv"), "-o", path(f"{name}_xy.svg"), "--x", "x_mm",
            "--y", "f_um", "--y", "uf_um")
        root = ET.parse(path(f"{name}_xy.svg")).getroot()
        circles = len(root.findall("{http://www.w3.org/2000/svg}circle"))
        assert circles == dots, f"plot xy {name}: {circles} dots, expected {dots}"
    assert os.path.getsize(path("long_xy.svg")) < 1_000_000


def data_rows(p):
    """The header lines and the rows {(scan, n): [m1, m2, m3]} of a selfcal-profile v1 file."""
    head, rows = [], {}
    for ln in open(p).read().splitlines():
        f = ln.split(",")
        if len(f) == 5 and f[0] in ("1", "2"):
            rows[(int(f[0]), int(f[1]))] = [float(v) for v in f[2:]]
        else:
            head.append(ln)
    return head, rows


def write_rows(p, head, rows, extra_header=()):
    lines = head[:-1] + list(extra_header) + head[-1:]
    for (k, j), v in sorted(rows.items()):
        lines.append(f"{k},{j}," + ",".join("" if x is None else repr(x) for x in v))
    write_lines(p, lines)


def f_error(out, truth, skip=()):
    """max |f - truth| over the points given, the truth relative to its LS line over them."""
    _, rows = read_csv(out)
    _, trows = read_csv(truth)
    idx = [i for i, r in enumerate(rows) if r["f_um"] is not None and i not in skip]
    m = len(idx)
    xm = sum(idx) / m
    tm = sum(trows[i]["f_um"] for i in idx) / m
    b = sum((i - xm) * (trows[i]["f_um"] - tm) for i in idx) / sum((i - xm) ** 2 for i in idx)
    return max(abs(rows[i]["f_um"] - (trows[i]["f_um"] - tm - b * (i - xm))) for i in idx)


def case_rig():
    """SPEC §2a on simulated rigs through the command: gaps (least squares exact, DFT refused
    naming --method lsq, an undetermined point left empty and named), probe gain and angle scale
    stated (exact) with their U in the budget, a common drift, residuals and outliers, the χ²
    verdict."""
    inp, truth, out = path("in.csv"), path("t.csv"), path("p.csv")
    run("simulate", "profile", "--out", inp, "--truth", truth, "--seed", "21", "--sigma-disp-um",
        "0", "--sigma-angle-urad", "0")
    head, rows = data_rows(inp)
    # 20 missing rows and an empty field: exact; the DFT refuses at the scan's line
    g = dict(rows)
    for j in range(100, 120):
        del g[(1, j)]
    g[(2, 200)] = [g[(2, 200)][0], None, g[(2, 200)][2]]
    write_rows(path("gap.csv"), head, g)
    run("profile", "--method", "lsq", path("gap.csv"), "--out", out)
    assert f_error(out, truth) < 1e-10, f_error(out, truth)
    # e_y where scan 1 has no row comes from scan 2's m1: the result is complete, and plots
    _, res = read_csv(out)
    _, tr = read_csv(truth)
    assert max(abs(r["ey_um"] - t["ey_um"]) for r, t in zip(res[:320], tr[:320])) < 1e-10
    run("plot", "profile", out, "-o", path("gap.svg"))
    p = run("profile", "--method", "dft", path("gap.csv"), "--out", out, expect=2)
    assert "--method lsq" in p.stderr and f"{path('gap.csv')}:4:" in p.stderr, p.stderr
    # point 150 tied to nothing (its four rows missing): left empty, named on stderr
    for key in ((1, 150), (1, 140), (2, 150), (2, 139)):
        del g[key]
    write_rows(path("gap0.csv"), head, g)
    p = run("profile", "--method", "lsq", path("gap0.csv"), "--out", out)
    assert "1 point no row ties to the rest, left empty: n = 150" in p.stderr, p.stderr
    _, res = read_csv(out)
    assert res[150]["f_um"] is None and res[150]["uf_um"] is None and res[149]["f_um"] is not None
    assert f_error(out, truth) < 1e-10
    # the first (or last) point reached by no row: the header contradicts the data
    del g[(1, 0)], g[(2, 0)]
    write_rows(path("gap1.csv"), head, g)
    p = run("profile", "--method", "lsq", path("gap1.csv"), "--out", out, expect=2)
    assert "no row reaches the profile's first point" in p.stderr, p.stderr
    # probe 2 reading 0.1 % high, the angle sensor 1 % high: stated, exact; U in the budget
    g = {key: [v[0], v[1] * 1.001, v[2] * 1.01] for key, v in rows.items()}
    write_rows(path("gain.csv"), head, g)
    run("profile", "--method", "lsq", path("gain.csv"), "--out", out)
    assert f_error(out, truth) > 1e-4, "a gain not stated biases f"
    write_rows(path("gain.csv"), head, g, ["# probe_gain = 1.001, 0.0005",
                                           "# angle_scale = 1.01, 0.001", "# spacing_u_mm = 0.01",
                                           ])
    p = run("profile", "--method", "lsq", path("gain.csv"), "--out", out)
    assert f_error(out, truth) < 1e-10, f_error(out, truth)
    for src in ("noise", "probe_gain,0.0005", "angle_scale,0.001", "spacing,0.01"):
        assert f"budget: {src}" in p.stdout, p.stdout
    # the same budget in the report; a report of data with gaps
    run("report", "profile", path("gain.csv"), "-o", path("r.html"))
    html = open(path("r.html")).read()
    for i in range(4):
        assert f'id="budget-rms-{i}"' in html, f"budget row {i} missing from the report"
    run("report", "profile", path("gap.csv"), "-o", path("rg.html"))
    assert 'id="budget"' not in open(path("rg.html")).read()
    # a common differential drift (5 nm over the scan) with --drift linear: exact
    g = {(k, j): [v[0], v[1] + 0.005 * (2 * j - 329) / 329, v[2]] for (k, j), v in rows.items()}
    write_rows(path("drift.csv"), head, g)
    run("profile", "--method", "lsq", path("drift.csv"), "--out", out)
    assert f_error(out, truth) > 1e-4
    p = run("profile", "--method", "lsq", path("drift.csv"), "--out", out, "--drift", "linear")
    assert f_error(out, truth) < 1e-9 and "drift_um: a 0.005" in p.stdout, p.stdout
    run("profile", "--method", "dft", path("drift.csv"), "--out", out, "--drift", "linear", expect=2)
    # profile-plan shows the same cost for the spacings (noise stated the same way)
    write_rows(path("drift_n.csv"), [h for h in head if "sigma" not in h], g,
               ["# sigma_disp_um = 0.01", "# sigma_angle_urad = 1"])
    p = run("profile", "--method", "lsq", path("drift_n.csv"), "--out", out, "--drift", "linear")
    cost = float(re.search(r"drift_cost: ([0-9.]+)", p.stdout).group(1))
    p = run("profile-plan", "--n", 330, "--s-mm", 1, "--sigma-disp-um", 0.01, "--sigma-angle-urad",
            1, "--d-min", 10, "--d-max", 11, "--drift", "linear")
    head_p, row = p.stdout.splitlines()[1].split(","), p.stdout.splitlines()[2].split(",")
    assert head_p[-3:] == ["drift_rms_nm", "drift_max_nm", "drift_cost"], head_p
    assert abs(float(row[-1]) - cost) < 1e-3 and cost > 3, (row, cost)
    # the same rig from simulate profile's own options: gain, drift and a gap at once
    run("simulate", "profile", "--out", path("sim_rig.csv"), "--truth", truth, "--seed", "21",
        "--noise-free", "--probe-gain", "1.001", "--drift-um", "0.005", "--gap", "1:100..119")
    h2, r2 = data_rows(path("sim_rig.csv"))
    assert (1, 100) not in r2 and (1, 99) in r2 and len(r2) == len(rows) - 20
    write_rows(path("sim_rig_k.csv"), h2, r2, ["# probe_gain = 1.001, 0"])
    run("profile", "--method", "lsq", path("sim_rig_k.csv"), "--out", out, "--drift", "linear")
    assert f_error(out, truth) < 1e-9, f_error(out, truth)
    run("simulate", "profile", "--out", path("x.csv"), "--truth", path("xt.csv"), "--gap",
        "1:5..400", expect=2)
    # noise stated, one 10-sigma outlier: flagged in R.csv and on stderr, removed on request
    run("simulate", "profile", "--out", inp, "--truth", truth, "--seed", "22")
    head, rows = data_rows(inp)
    sy = math.sqrt(2 * 0.01 ** 2 + (10 * 1.0 * 1e-3) ** 2)
    rows[(1, 150)][1] += 10 * sy
    write_rows(path("out.csv"), head, rows)
    R = path("R.csv")
    p = run("profile", "--method", "lsq", path("out.csv"), "--out", out, "--residuals", R)
    assert "flagged outlier scan 1 n = 150" in p.stderr and "chi2_test: " in p.stdout, p.stderr
    lines = open(R).read().splitlines()
    assert lines[0] == "scan,n,r_um,t,outlier" and len(lines) == 1 + 320 + 319
    r150 = lines[1 + 150].split(",")
    assert r150[:2] == ["1", "150"] and r150[4] == "1" and abs(float(r150[3])) > 4, r150
    p = run("profile", "--method", "lsq", path("out.csv"), "--out", out, "--residuals", R,
            "--reject-outliers")
    assert "removed outlier scan 1 n = 150" in p.stderr, p.stderr
    assert "chi2_test: pass" in p.stdout, p.stdout
    assert open(R).read().splitlines()[1 + 150].split(",")[4] == "1"
    # the noise stated too small: the verdict fails, a warning, u scaled a posteriori
    p = run("profile", "--method", "lsq", inp, "--out", out, "--sigma-disp-um", "0.003",
            "--sigma-angle-urad", "0.3")
    assert "chi2_test: fail" in p.stdout and "uf_um scaled by sqrt(wrss/dof)" in p.stderr, p.stdout
    u_scaled = float(re.search(r"uf_rms_um: ([0-9.e-]+)", p.stdout).group(1))
    p = run("profile", "--method", "lsq", inp, "--out", out)
    assert "chi2_test: pass" in p.stdout and p.stderr == "", p.stderr
    u_true = float(re.search(r"uf_rms_um: ([0-9.e-]+)", p.stdout).group(1))
    assert abs(u_scaled / u_true - 1) < 0.2, (u_scaled, u_true)
    assert f_error(out, truth) < 0.06


{"end_to_end": case_end_to_end, "rig": case_rig, "bad_input": case_bad_input, "noise": case_noise, "plan": case_plan,
 "plot": case_plot}[CASE]()
print("OK")
