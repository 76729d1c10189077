#!/usr/bin/env python3
"""SPEC §1/§3 conformance (black box): selfcal simulate grid, selfcal grid, selfcal plan.

usage: spec_grid.py SELFCAL TMPDIR {simulate|recover|plan}
The oracle is the interface contract (docs/formats.md): an independent parser, an independent forward model and an
independent gauge projection; nothing is compared with stored outputs of selfcal.
"""
import math
import os
import random
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from spec_common import *  # noqa

SELFCAL, BASE, MODE = sys.argv[1], sys.argv[2], sys.argv[3]
TOL_UM = 1e-8

MAP_COLS = ["i", "j", "x_mm", "y_mm", "gx_um", "gy_um", "ugx_um", "ugy_um"]
ART_COLS = ["i", "j", "ax_um", "ay_um"]
VIEW_RE = re.compile(r"^# view (\d+): rot=(0|90|180|270) shift=(-?\d+),(-?\d+)((?: (?:rows|cols)=\d+(?:,\d+)*)*)\s*$")


def parse_grid_file(path):
    """Independent strict parser of selfcal-grid v1; returns (n, pitch, origin, views, data)."""
    with open(path) as fh:
        lines = [l.rstrip("\n") for l in fh]
    assert lines[0] == "# selfcal-grid v1", "first line %r" % lines[0]
    n = pitch = None
    origin = (0.0, 0.0)
    views = {}
    k = 1
    while k < len(lines) and lines[k].startswith("#"):
        l = lines[k]
        m = VIEW_RE.match(l)
        if m:
            v = View(int(m.group(2)), int(m.group(3)), int(m.group(4)))
            for attr in m.group(5).split():
                key, val = attr.split("=")
                setattr(v, key, [int(t) for t in val.split(",")])
            views[int(m.group(1))] = v
        elif re.match(r"^# N = \d+$", l):
            n = int(l.split("=")[1])
        elif re.match(r"^# pitch_mm = ", l):
            pitch = float(l.split("=")[1])
        elif re.match(r"^# origin_mm = ", l):
            a, b = l.split("=")[1].split(",")
            origin = (float(a), float(b))
        else:
            raise AssertionError("unexpected header line %r" % l)
        k += 1
    assert n is not None and n % 2 == 1 and pitch is not None and pitch > 0
    assert lines[k] == "view,i,j,x_mm,y_mm", "column header %r" % lines[k]
    data = {}
    for l in lines[k + 1:]:
        if not l:
            continue
        f = l.split(",")
        assert len(f) == 5, l
        key = (int(f[0]), int(f[1]), int(f[2]))
        assert key not in data, "duplicate %r" % (key,)
        x, y = float(f[3]), float(f[4])
        assert math.isfinite(x) and math.isfinite(y)
        data[key] = (x, y)
    return n, pitch, origin, views, data


def check_map(path, n, pitch, origin, label):
    comments, header, rows = read_csv(path)
    check(header == MAP_COLS, "%s: map header %r, SPEC says %r" % (label, header, MAP_COLS))
    check(len(rows) == n * n, "%s: map has %d rows, want one per node (%d)" % (label, len(rows), n * n))
    c = (n - 1) // 2
    gx, gy = {}, {}
    for r in rows:
        i, j = int(r["i"]), int(r["j"])
        check((i, j) not in gx, "%s: duplicate node %d,%d" % (label, i, j))
        x, y = float(r["x_mm"]), float(r["y_mm"])
        if not check(abs(x - (origin[0] + (j - c) * pitch)) < 1e-9 and abs(y - (origin[1] + (i - c) * pitch)) < 1e-9,
                     "%s: node %d,%d at %r,%r; SPEC: origin + ((j-c)P, (i-c)P)" % (label, i, j, x, y)):
            break
        gx[(i, j)], gy[(i, j)] = float(r["gx_um"]), float(r["gy_um"])
        for u in ("ugx_um", "ugy_um"):
            if r[u] != "":
                check(float(r[u]) >= 0, "%s: negative uncertainty" % label)
    return gx, gy


def check_gauge(n, pitch, gx, gy, ax, ay, label):
    c = (n - 1) // 2
    X = {k: (k[1] - c) * pitch for k in gx}
    Y = {k: (k[0] - c) * pitch for k in gx}
    scale = max(1.0, max(abs(v) for v in list(gx.values()) + list(gy.values())))
    tol = 1e-9 * scale * n * n * n
    sums = {
        "sum Gx": sum(gx.values()), "sum Gy": sum(gy.values()),
        "G rotation": sum(X[k] * gy[k] - Y[k] * gx[k] for k in gx),
        "G magnification": sum(X[k] * gx[k] + Y[k] * gy[k] for k in gx),
    }
    if ax is not None:
        sums.update({"sum Ax": sum(ax.values()), "sum Ay": sum(ay.values()),
                     "A rotation": sum(X[k] * ay[k] - Y[k] * ax[k] for k in ax)})
    for name, v in sums.items():
        check(abs(v) < tol, "%s: gauge %s = %g (SPEC: 0)" % (label, name, v))


def read_artifact(path, n, label):
    comments, header, rows = read_csv(path)
    check(header == ART_COLS, "%s: artifact header %r, SPEC says %r" % (label, header, ART_COLS))
    check(len(rows) == n * n, "%s: artifact has %d rows, want %d" % (label, len(rows), n * n))
    ax = {(int(r["i"]), int(r["j"])): float(r["ax_um"]) for r in rows}
    ay = {(int(r["i"]), int(r["j"])): float(r["ay_um"]) for r in rows}
    return ax, ay


# ------------------------------------------------------------------ simulate
def test_simulate():
    d = tmpdir(BASE, "simgrid")
    for plan, n in (("ye", 7), ("double-shift", 9)):
        inp, gt = os.path.join(d, "in_%s.csv" % plan), os.path.join(d, "gt_%s.csv" % plan)
        rc, out, err = run([SELFCAL, "simulate", "grid", "--plan", plan, "--n", str(n), "--pitch-mm", "1.5",
                            "--origin-mm", "3,-2", "--out", inp, "--truth-map", gt, "--seed", "4"])
        if not check(rc == 0, "simulate grid %s: exit %d %s" % (plan, rc, err)):
            continue
        try:
            N, pitch, origin, views, data = parse_grid_file(inp)
        except (AssertionError, ValueError) as e:
            check(False, "simulate grid %s: not a valid selfcal-grid v1 file: %s" % (plan, e))
            continue
        check(N == n and pitch == 1.5 and origin == (3.0, -2.0), "simulate %s: header N/pitch/origin" % plan)
        want = YE(n) if plan == "ye" else PETRO(n)
        check(len(views) == len(want), "simulate %s: %d views" % (plan, len(views)))
        for k, v in enumerate(want):
            got = views.get(k)
            if not check(got is not None and (got.rot, got.sx, got.sy) == (v.rot, v.sx, v.sy),
                         "simulate %s: view %d differs from SPEC plan" % (plan, k)):
                continue
            marks = {(i, j): (ni, nj) for (i, j, ni, nj) in got.measured_marks(n)}
            if plan == "double-shift" and k == 3:
                check(got.rows == [(n - 1) // 2] and sorted(got.cols) == [(n - 1) // 2, (n - 1) // 2 + 1],
                      "simulate: Petro view 3 header rows/cols")
            present = {(i, j) for (vk, i, j) in data if vk == k}
            check(present == set(marks), "simulate %s view %d: marks present differ from SPEC geometry (%d vs %d)"
                  % (plan, k, len(present), len(marks)))
            # measured ≈ nominal stage position (errors are µm, positions mm)
            c = (n - 1) // 2
            for (i, j), (ni, nj) in marks.items():
                if (k, i, j) in data:
                    x, y = data[(k, i, j)]
                    xn, yn = origin[0] + (nj - c) * pitch, origin[1] + (ni - c) * pitch
                    if not check(abs(x - xn) < 0.05 and abs(y - yn) < 0.05,
                                 "simulate %s: mark %d,%d view %d at %r,%r far from nominal %r,%r" % (plan, i, j, k, x, y, xn, yn)):
                        break
        gx, gy = check_map(gt, n, pitch, origin, "simulate truth-map " + plan)
        check_gauge(n, pitch, gx, gy, None, None, "simulate truth-map " + plan)
        # and the simulated file is accepted by the calibration of its plan
        rc, out, err = run([SELFCAL, "grid", "--method", plan, inp, "--map", os.path.join(d, "G.csv")])
        check(rc == 0, "grid on simulated %s: exit %d %s" % (plan, rc, err))


# ------------------------------------------------------------------ noise-free recovery
def recover_case(label, method, n, pitch, origin, views, seed, drop_view=None, shuffle=True,
                 origin_line=True, extra_views=()):
    d = tmpdir(BASE, "rec")
    allviews = list(views) + list(extra_views)
    t = synthesize_grid(n, pitch, origin, views, seed, drop_view=drop_view)
    inp = os.path.join(d, "in.csv")
    write_grid_file(inp, n, pitch, origin, allviews, t["lines"], origin_line=origin_line,
                    shuffle_seed=seed if shuffle else None)
    mp, ap, sp = (os.path.join(d, f) for f in ("G.csv", "A.csv", "S.out"))
    rc, out, err = run([SELFCAL, "grid", "--method", method, inp, "--map", mp, "--artifact", ap, "--summary", sp])
    if not check(rc == 0, "%s: selfcal grid --method %s exit %d: %s" % (label, method, rc, err.strip())):
        return
    check(os.path.getsize(sp) > 0, "%s: empty summary" % label)
    Gx, Gy, Ax, Ay = gauge_truth(n, pitch, t["gx"], t["gy"], t["ax"], t["ay"])
    gx, gy = check_map(mp, n, pitch, origin, label)
    ax, ay = read_artifact(ap, n, label)
    check_gauge(n, pitch, gx, gy, ax, ay, label)
    eg = max(max(abs(gx.get(k, 1e9) - Gx[k]), abs(gy.get(k, 1e9) - Gy[k])) for k in Gx)
    ea = max(max(abs(ax.get(k, 1e9) - Ax[k]), abs(ay.get(k, 1e9) - Ay[k])) for k in Ax)
    check(eg <= TOL_UM, "%s: max |G - truth| = %g um" % (label, eg))
    check(ea <= TOL_UM, "%s: max |A - truth| = %g um" % (label, ea))
    print("%-48s G err %.2e um, A err %.2e um" % (label, eg, ea))


def test_recover():
    custom = [View(0), View(90), View(180), View(0, 1, 0), View(270, 0, -1, rows=[0, 1])]
    recover_case("ye N=5", "ye", 5, 1.0, (0.0, 0.0), YE(5), 11)
    recover_case("ye N=9 pitch 0.5 origin (10.5,-3.25)", "ye", 9, 0.5, (10.5, -3.25), YE(9), 12)
    recover_case("ye N=7 no origin line", "ye", 7, 2.0, (0.0, 0.0), YE(7), 13, origin_line=False)
    recover_case("double-shift N=7", "double-shift", 7, 1.0, (0.0, 0.0), PETRO(7), 21)
    recover_case("double-shift N=9", "double-shift", 9, 1.0, (0.0, 0.0), PETRO(9), 14)
    recover_case("double-shift N=11 origin (1,2)", "double-shift", 11, 1.25, (1.0, 2.0), PETRO(11), 15)
    recover_case("lsq Ye N=7", "lsq", 7, 1.0, (0.0, 0.0), YE(7), 16)
    recover_case("lsq Petro N=9", "lsq", 9, 1.0, (-4.0, 4.0), PETRO(9), 17)
    recover_case("lsq custom (180, y shift, partial) N=5", "lsq", 5, 1.0, (0.0, 0.0), custom, 18)
    # a view declared in the header but absent from the data, not needed by the method
    recover_case("ye N=5 + declared unused rot=180 view", "ye", 5, 1.0, (0.0, 0.0), YE(5), 19,
                 extra_views=[View(180)])
    recover_case("double-shift N=9 + declared unused view", "double-shift", 9, 1.0, (0.0, 0.0), PETRO(9), 20,
                 extra_views=[View(180)])


# ------------------------------------------------------------------ independent least squares (small N)
def design(n, views, data=None):
    """Rows of the SPEC model's Jacobian (unknowns Gx,Gy per node, Ax,Ay per mark, tx,ty,theta per
    view; pitch-1 units for theta) and, with data {(k,i,j): (dx_um, dy_um)}, the right-hand side."""
    c = (n - 1) // 2
    nn = n * n
    rows, rhs = [], []
    for k, v in enumerate(views):
        cx, sx = {0: (1, 0), 90: (0, 1), 180: (-1, 0), 270: (0, -1)}[v.rot]
        for (i, j, ni, nj) in v.measured_marks(n):
            if data is not None and (k, i, j) not in data:
                continue
            node, mark = ni * n + nj, i * n + j
            xc, yc = nj - c, ni - c
            ex = {node: 1.0, 4 * nn + 3 * k: 1.0, 4 * nn + 3 * k + 2: -yc}
            ey = {nn + node: 1.0, 4 * nn + 3 * k + 1: 1.0, 4 * nn + 3 * k + 2: xc}
            for dct, a, b in ((ex, cx, -sx), (ey, sx, cx)):
                if a:
                    dct[2 * nn + mark] = dct.get(2 * nn + mark, 0) + a
                if b:
                    dct[3 * nn + mark] = dct.get(3 * nn + mark, 0) + b
            rows += [ex, ey]
            if data is not None:
                rhs += list(data[(k, i, j)])
    return rows, rhs


def gauge_rows(n, m):
    c = (n - 1) // 2
    nn = n * n
    X = [(q % n) - c for q in range(nn)]
    Y = [(q // n) - c for q in range(nn)]
    C = [{q: 1.0 for q in range(nn)}, {nn + q: 1.0 for q in range(nn)}]
    d = {q: -Y[q] for q in range(nn)}
    d.update({nn + q: X[q] for q in range(nn)})
    C.append(d)
    d = {q: X[q] for q in range(nn)}
    d.update({nn + q: Y[q] for q in range(nn)})
    C.append(d)
    C += [{2 * nn + q: 1.0 for q in range(nn)}, {3 * nn + q: 1.0 for q in range(nn)}]
    d = {2 * nn + q: -Y[q] for q in range(nn)}
    d.update({3 * nn + q: X[q] for q in range(nn)})
    C.append(d)
    return [[r.get(a, 0.0) for a in range(m)] for r in C]


def constrained_ls(n, views, data=None):
    """KKT inverse of [J'J C'; C 0] (SPEC gauge as hard constraints); solution if data given."""
    nn = n * n
    m = 4 * nn + 3 * len(views)
    rows, rhs = design(n, views, data)
    JTJ = [[0.0] * m for _ in range(m)]
    JTb = [0.0] * m
    for r, idx in zip(rows, range(len(rows))):
        for a, va in r.items():
            if data is not None:
                JTb[a] += va * rhs[idx]
            for b, vb in r.items():
                JTJ[a][b] += va * vb
    C = gauge_rows(n, m)
    K = [JTJ[a] + [C[r][a] for r in range(7)] for a in range(m)] + [C[r] + [0.0] * 7 for r in range(7)]
    inv = invert_dense(K)
    sol = None
    rss = None
    if data is not None:
        sol = [sum(inv[a][b] * JTb[b] for b in range(m)) for a in range(m)]
        rss = 0.0
        for r, b in zip(rows, rhs):
            rss += (sum(v * sol[a] for a, v in r.items()) - b) ** 2
    return inv, sol, rss, len(rows) - m + 7


def plan_sigma_ref(n, views):
    inv, _, _, _ = constrained_ls(n, views)
    nn = n * n
    comp = [math.sqrt(inv[q][q]) for q in range(2 * nn)]
    rms = math.sqrt(sum(v * v for v in comp) / len(comp))
    per_node = [math.sqrt((inv[q][q] + inv[nn + q][nn + q]) / 2) for q in range(nn)]
    return rms, max(comp), max(per_node)


def test_lsq_noise():
    """lsq on noisy data against an independent constrained least-squares solution: G, A, the
    per-node uncertainty with --sigma-r-um, and with the noise estimated from the residuals."""
    custom = [View(0), View(90), View(180), View(0, 1, 0), View(270, 0, -1, rows=[0, 1])]
    for label, n, views in (("Ye N=5", 5, YE(5)), ("custom N=5", 5, custom)):
        d = tmpdir(BASE, "lsqn")
        t = synthesize_grid(n, 1.0, (0.0, 0.0), views, 31)
        rng = random.Random(32)
        lines = [(k, i, j, x + rng.gauss(0, 2e-5), y + rng.gauss(0, 2e-5)) for (k, i, j, x, y) in t["lines"]]
        inp = os.path.join(d, "in.csv")
        write_grid_file(inp, n, 1.0, (0.0, 0.0), views, lines, shuffle_seed=3)
        # the data as written (15 decimals), relative to nominal, in um
        _, _, _, _, parsed = parse_grid_file(inp)
        c = (n - 1) // 2
        data = {}
        for (k, i, j), (x, y) in parsed.items():
            v = views[k]
            xr, yr = rot_vec(v.rot, j - c, i - c)
            data[(k, i, j)] = ((x - (xr + v.sx)) * 1000.0, (y - (yr + v.sy)) * 1000.0)
        inv, sol, rss, dof = constrained_ls(n, views, data)
        sig_est = math.sqrt(rss / dof)
        nn = n * n
        for sigma_arg in (None, 0.05):
            mp, ap = os.path.join(d, "G.csv"), os.path.join(d, "A.csv")
            argv = [SELFCAL, "grid", "--method", "lsq", inp, "--map", mp, "--artifact", ap]
            if sigma_arg is not None:
                argv += ["--sigma-r-um", repr(sigma_arg)]
            rc, out, err = run(argv)
            if not check(rc == 0, "lsq noise %s: exit %d %s" % (label, rc, err.strip())):
                continue
            _, header, rows = read_csv(mp)
            ax, ay = read_artifact(ap, n, label)
            sig = sigma_arg if sigma_arg is not None else sig_est
            eg = eu = ea = 0.0
            for r in rows:
                q = int(r["i"]) * n + int(r["j"])
                eg = max(eg, abs(float(r["gx_um"]) - sol[q]), abs(float(r["gy_um"]) - sol[nn + q]))
                if r["ugx_um"] == "" or r["ugy_um"] == "":
                    check(False, "lsq noise %s: empty uncertainty" % label)
                    break
                eu = max(eu, abs(float(r["ugx_um"]) / (sig * math.sqrt(inv[q][q])) - 1),
                         abs(float(r["ugy_um"]) / (sig * math.sqrt(inv[nn + q][nn + q])) - 1))
            for (i, j) in ax:
                q = i * n + j
                ea = max(ea, abs(ax[(i, j)] - sol[2 * nn + q]), abs(ay[(i, j)] - sol[3 * nn + q]))
            what = "sigma %s" % ("estimated %.4g um" % sig_est if sigma_arg is None else "given")
            check(eg < 1e-8 and ea < 1e-8, "lsq noise %s: G/A differ from independent LS by %g/%g um" % (label, eg, ea))
            check(eu < 1e-6, "lsq noise %s (%s): ug differs from sigma*sqrt(diag cov) by rel %g" % (label, what, eu))
            print("lsq noise %-12s %-26s G %.1e A %.1e um, u rel %.1e" % (label, what, eg, ea, eu))


# ------------------------------------------------------------------ plan
def plan_free_independent(n, views):
    """K = nullity(design matrix) - 7 gauge directions, by exact rank (mod p) of the SPEC model's
    Jacobian with unknowns Gx,Gy per node, Ax,Ay per mark, tx,ty,theta per view (pitch 1)."""
    c = (n - 1) // 2
    nn = n * n
    ncols = 4 * nn + 3 * len(views)
    rows = []
    for k, v in enumerate(views):
        for (i, j, ni, nj) in v.measured_marks(n):
            node, mark = ni * n + nj, i * n + j
            xc, yc = nj - c, ni - c
            # x equation: Gx(node) + (R A)_x + tx - theta*y
            ex = {node: 1, 3 * k + 4 * nn: 1, 3 * k + 2 + 4 * nn: -yc}
            ey = {nn + node: 1, 3 * k + 1 + 4 * nn: 1, 3 * k + 2 + 4 * nn: xc}
            cx, sx = {0: (1, 0), 90: (0, 1), 180: (-1, 0), 270: (0, -1)}[v.rot]
            # R A = (cx*Ax - sx*Ay, sx*Ax + cx*Ay)
            for dct, a, b in ((ex, cx, -sx), (ey, sx, cx)):
                if a:
                    dct[2 * nn + mark] = dct.get(2 * nn + mark, 0) + a
                if b:
                    dct[3 * nn + mark] = dct.get(3 * nn + mark, 0) + b
            rows.append({kk: vv for kk, vv in ex.items() if vv})
            rows.append({kk: vv for kk, vv in ey.items() if vv})
    r = rank_mod_p(rows, ncols)
    return ncols - r - 7


def plan_output(views, n, label):
    d = tmpdir(BASE, "plan")
    p = os.path.join(d, "plan.csv")
    write_grid_file(p, n, 1.0, (0.0, 0.0), views, None)
    rc, out, err = run([SELFCAL, "plan", p])
    if not check(rc == 0, "plan %s: exit %d %s" % (label, rc, err.strip())):
        return None
    got = {}
    for line in out.splitlines():
        m = re.match(r"^(identifiable|free|sigma_c_ratio_rms|sigma_c_ratio_max): (.*)$", line)
        if m:
            got[m.group(1)] = m.group(2).strip()
    for key in ("identifiable", "free", "sigma_c_ratio_rms", "sigma_c_ratio_max"):
        check(key in got, "plan %s: no line '%s: ...' in output" % (label, key))
    return got


def test_plan():
    c9 = 4
    cases = [
        ("Ye N=7", 7, YE(7)),
        ("Petro N=9", 9, PETRO(9)),
        ("Ye N=5", 5, YE(5)),
        ("{0,90,+2} N=7", 7, [View(0), View(90), View(0, 2, 0)]),
        ("{0,90} N=7", 7, [View(0), View(90)]),
        ("{0,180,+1} N=7", 7, [View(0), View(180), View(0, 1, 0)]),
        ("{0,90,+2} N=9", 9, [View(0), View(90), View(0, 2, 0)]),
        ("{0,90,+2,-3 partial} N=9 rows/cols", 9, [View(0), View(90), View(0, 2, 0), View(0, -3, 0, rows=[c9], cols=[c9, c9 + 1])]),
        ("{0,+1} N=5", 5, [View(0), View(0, 1, 0)]),
        ("{0,90,0+y1} N=5", 5, [View(0), View(90), View(0, 0, 1)]),
    ]
    for label, n, views in cases:
        got = plan_output(views, n, label)
        if got is None or "free" not in got:
            continue
        k_ref = plan_free_independent(n, views)
        ident = "yes" if k_ref == 0 else "no"
        check(got.get("identifiable") == ident, "plan %s: identifiable %r, independent rank analysis says %s"
              % (label, got.get("identifiable"), ident))
        check(got.get("free") == str(k_ref), "plan %s: free %r, independent rank analysis says %d"
              % (label, got.get("free"), k_ref))
        if ident == "yes":
            try:
                rms, mx = float(got["sigma_c_ratio_rms"]), float(got["sigma_c_ratio_max"])
                check(0 < rms <= mx < 10, "plan %s: sigma ratios %r %r" % (label, rms, mx))
                if n <= 7:
                    r_rms, r_max_comp, r_max_node = plan_sigma_ref(n, views)
                    check(abs(rms / r_rms - 1) < 2e-5, "plan %s: sigma_c_ratio_rms %r, independent covariance %.6f"
                          % (label, rms, r_rms))
                    check(abs(mx / r_max_comp - 1) < 2e-5 or abs(mx / r_max_node - 1) < 2e-5,
                          "plan %s: sigma_c_ratio_max %r, independent %.6f (per component) / %.6f (per node)"
                          % (label, mx, r_max_comp, r_max_node))
            except ValueError:
                check(False, "plan %s: sigma_c_ratio not numbers: %r" % (label, got))
        print("plan %-36s identifiable %s free %s (ref %d) rms %s max %s" % (
            label, got.get("identifiable"), got.get("free"), k_ref, got.get("sigma_c_ratio_rms"), got.get("sigma_c_ratio_max")))


{"simulate": test_simulate, "recover": test_recover, "plan": test_plan, "lsqnoise": test_lsq_noise}[MODE]()
finish("spec_grid " + MODE)
