#!/usr/bin/env python3
"""The precision-stage controllers' 2-D tables, applied to the written files by rules written
again from the vendors' documentation (not from the exporter):

- Aerotech Automation1 (`--format aerotech-a1`), help page "Axis Calibration": a 2-D table gives
  the corrections of two output axes from the positions of two reference axes (one-based axis
  indices in the file), linear interpolation between the table's reference positions, "the nearest
  end point of the table" beyond them. File: `:START2D RowAxis ColumnAxis OutputAxis1 OutputAxis2
  SampleDistRow SampleDistCol NumCols`, `:START2D POSUNIT=.. CORUNIT=.. OFFSETROW=.. OFFSETCOL=..
  [NEGCOR]`, one line per row of NumCols pairs, `:END`; the table's index along an axis is
  (position + OFFSET) / SampleDist (the convention of the public calibration scripts).
- Power PMAC (`--format powerpmac`), Software Reference, CompTable[m]: Source[0], Source[1] (the
  motors of dimensions 0 and 1), Nx[i] zones, X0[i] first position, Dx[i] span, Target[0] the
  motor's CompPos, Sf[0] its scale, Data[] dimension 0 fastest; bilinear inside; beyond the table
  the end entries (Ctrl=3: no rollover, the assumption the exporter states).

Both are exported from the demo's map (scripts/demo.sh: `simulate grid --n 25 --pitch-mm 1
--seed 1`, sigmas 1, 1, 0.01 um; `grid --method lsq`) and from a stitched rectangular stage (41 x 31 nodes at 2 mm, 15 x 15 plate), and
compared with the map as selfcald applies it (`lut build` + `lut dump`: bilinear, clamped, SPEC §4)
on a dense sampling inside and 10 mm beyond the map. The machine is simulated: a stage with error
map G stands at p - G(p) when its encoder reads p; the controller commands t + c(t). With the
default sign the error left is the table's quantization plus G·grad G (the first-order inverse's
error); with --negate it is twice the uncorrected error (RMS ratio 2 within 1 %).

usage: test_precision.py SELFCAL_CLI WORKDIR"""
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from exportlib import Export, precision_maps  # noqa: E402

cli, work = sys.argv[1], sys.argv[2]
E = Export(cli, work)
check, run, path, selfcal = E.check, E.run, E.path, E.selfcal


def bilinear_clamped(xs, ys, val, x, y):
    """Bilinear interpolation over an ascending grid xs x ys of val[(row, col)], each coordinate
    held at the grid's ends beyond it."""
    def locate(gs, s):
        if s <= gs[0]:
            return 0, 0.0
        if s >= gs[-1]:
            return len(gs) - 2, 1.0
        k = min(int((s - gs[0]) / (gs[1] - gs[0])), len(gs) - 2)
        while k > 0 and gs[k] > s:
            k -= 1
        while k < len(gs) - 2 and gs[k + 1] < s:
            k += 1
        return k, (s - gs[k]) / (gs[k + 1] - gs[k])
    i, fu = locate(xs, x)
    j, fv = locate(ys, y)
    a = val[(j, i)] * (1 - fu) + val[(j, i + 1)] * fu
    b = val[(j + 1, i)] * (1 - fu) + val[(j + 1, i + 1)] * fu
    return a * (1 - fv) + b * fv


class SelfcaldMap:
    """The map as selfcald holds it: `lut dump` of the table `lut build` made."""

    def __init__(self, csv, name):
        selfcal("lut", "build", "--map", csv, "-o", path(name + ".lut"))
        rows = [ln.split(",") for ln in selfcal("lut", "dump", path(name + ".lut")).splitlines()]
        head = rows[0]
        ii, jj, xi, yi = head.index("i"), head.index("j"), head.index("x_mm"), head.index("y_mm")
        gxi, gyi = head.index("gx_um"), head.index("gy_um")
        self.gx, self.gy, xs, ys = {}, {}, {}, {}
        for r in rows[1:]:
            if len(r) < len(head) or not r[ii].strip().isdigit():
                continue
            i, j = int(r[ii]), int(r[jj])
            xs[j], ys[i] = float(r[xi]), float(r[yi])
            self.gx[(i, j)], self.gy[(i, j)] = float(r[gxi]), float(r[gyi])
        self.xs = [xs[k] for k in range(len(xs))]
        self.ys = [ys[k] for k in range(len(ys))]

    def g(self, x, y):
        return (bilinear_clamped(self.xs, self.ys, self.gx, x, y),
                bilinear_clamped(self.xs, self.ys, self.gy, x, y))

    def samples(self, margin=10.0, sub=3):
        """Nodes, sub x sub points per cell, and a ring margin mm beyond the map."""
        x0, x1, y0, y1 = self.xs[0], self.xs[-1], self.ys[0], self.ys[-1]
        nx, ny = (len(self.xs) - 1) * sub, (len(self.ys) - 1) * sub
        pts = [(x0 + (x1 - x0) * a / nx, y0 + (y1 - y0) * b / ny)
               for a in range(nx + 1) for b in range(ny + 1)]
        for a in range(nx + 1):
            for y in (y0 - margin, y1 + margin):
                pts.append((x0 + (x1 - x0) * a / nx, y))
        for b in range(ny + 1):
            for x in (x0 - margin, x1 + margin):
                pts.append((x, y0 + (y1 - y0) * b / ny))
        for x in (x0 - margin, x1 + margin):
            for y in (y0 - margin, y1 + margin):
                pts.append((x, y))
        return pts


# ---- Automation1: a reader and the documented rule ----

def read_a1(name):
    """(correction(x, y) -> (cx, cy) in um, header dict)."""
    lines = [ln.strip() for ln in open(path(name), encoding="utf-8")]
    lines = [ln for ln in lines if ln and not ln.startswith(";")]
    check(lines[0].startswith(":START2D ") and lines[1].startswith(":START2D ")
          and lines[-1] == ":END", f"{name}: :START2D, :START2D options, ..., :END")
    f = lines[0].split()[1:]
    row_ax, col_ax, out1, out2 = (int(v) for v in f[:4])
    d_row, d_col, ncols = float(f[4]), float(f[5]), int(f[6])
    opts = dict(kv.split("=") for kv in lines[1].split()[1:])
    units = {"PRIMARY": 1.0, "PRIMARY/1000": 1e-3}
    pos_mm, cor_um = units[opts["POSUNIT"]], units[opts["CORUNIT"]] * 1e3
    # table index = (reference position + OFFSET) / SampleDist: the first row stands at -OFFSETROW
    off_row, off_col = -float(opts["OFFSETROW"]) * pos_mm, -float(opts["OFFSETCOL"]) * pos_mm
    if "NEGCOR" in lines[1].split():
        cor_um = -cor_um
    data = [list(map(float, ln.split())) for ln in lines[2:-1]]
    check(all(len(r) == 2 * ncols for r in data), f"{name}: every row has NumCols pairs")
    nrows = len(data)
    c1 = {(r, k): data[r][2 * k] * cor_um for r in range(nrows) for k in range(ncols)}
    c2 = {(r, k): data[r][2 * k + 1] * cor_um for r in range(nrows) for k in range(ncols)}
    rows = [off_row + r * d_row * pos_mm for r in range(nrows)]
    cols = [off_col + k * d_col * pos_mm for k in range(ncols)]
    hdr = {"row_axis": row_ax, "col_axis": col_ax, "out": (out1, out2), "nrows": nrows,
           "ncols": ncols, "cor_unit_um": cor_um}

    def corr(pos):
        """pos: axis index (one-based) -> position, mm; returns {axis index: correction um}."""
        r, c = pos[row_ax], pos[col_ax]
        return {out1: bilinear_clamped(cols, rows, c1, c, r),
                out2: bilinear_clamped(cols, rows, c2, c, r)}
    return corr, hdr


# ---- Power PMAC: a reader and the documented rule ----

def read_pmac(name):
    """{target motor: correction(motor positions) -> um at upm motor units per mm}."""
    el = {}
    for ln in open(path(name)):
        ln = ln.split("//")[0].strip()
        if not ln:
            continue
        m = re.match(r"CompTable\[(\d+)\]\.(\w+)(?:\[(\d+)\])?=(.*)$", ln)
        check(m is not None, f"{name}: a CompTable element, not {ln!r}")
        if not m:
            continue
        t, key, idx, val = int(m.group(1)), m.group(2), m.group(3), m.group(4)
        tab = el.setdefault(t, {"Data": {}})
        if key == "Data":
            for k, v in enumerate(val.split(",")):
                tab["Data"][int(idx) + k] = float(v)
        else:
            tab[(key, int(idx) if idx is not None else None)] = val
    tables = {}
    for t, tab in el.items():
        src = [int(tab[("Source", d)]) for d in (0, 1)]
        nx = [int(tab[("Nx", d)]) for d in (0, 1)]
        check(int(tab[("Nx", 2)]) == 0, f"CompTable[{t}] is 2-D")
        x0 = [float(tab[("X0", d)]) for d in (0, 1)]
        span = [float(tab[("Dx", d)]) for d in (0, 1)]
        tgt = re.match(r"Motor\[(\d+)\]\.CompPos\.a$", tab[("Target", 0)])
        check(tgt is not None, f"CompTable[{t}].Target[0] is a motor's CompPos")
        sf = float(tab[("Sf", 0)])
        check(tab[("Ctrl", None)] == "3", f"CompTable[{t}].Ctrl=3 (no rollover, as stated)")
        n0, n1 = nx[0] + 1, nx[1] + 1
        check(len(tab["Data"]) == n0 * n1, f"CompTable[{t}]: (Nx[0]+1) x (Nx[1]+1) entries")
        val = {(j, i): tab["Data"][j * n0 + i] * sf for j in range(n1) for i in range(n0)}
        g0 = [x0[0] + span[0] * i / nx[0] for i in range(n0)]
        g1 = [x0[1] + span[1] * j / nx[1] for j in range(n1)]
        tables[t] = (src, int(tgt.group(1)), g0, g1, val)
    return tables


def pmac_corrections(tables, motor_pos):
    """Each target motor's compensation (motor units) at motor positions, tables summed."""
    out = {}
    for src, tgt, g0, g1, val in tables.values():
        out[tgt] = out.get(tgt, 0.0) + bilinear_clamped(
            g0, g1, val, motor_pos[src[0]], motor_pos[src[1]])
    return out


# ---- the machine ----

def assess(name, G, corr, unit_um, offset=(0.0, 0.0)):
    """Residual of the controller's corrections against selfcald's map, and the error left on a
    stage whose error map is G (machine coordinates = map + offset)."""
    ox, oy = offset
    res, left, raw = [], [], []
    worst = (0.0, None)
    for (x, y) in G.samples():
        cx, cy = corr(x + ox, y + oy)
        gx, gy = G.g(x, y)
        for r in (cx - gx, cy - gy):
            res.append(r)
            if abs(r) > worst[0]:
                worst = (abs(r), (x, y))
        # the encoder goes to t + c, the stage stands G short of it
        px, py = x + cx * 1e-3, y + cy * 1e-3
        hx, hy = G.g(px, py)
        left += [cx - hx, cy - hy]
        raw += [-gx, -gy]
    rms = lambda v: math.sqrt(sum(a * a for a in v) / len(v))  # noqa: E731
    return {"rms": rms(res), "max": worst[0], "at": worst[1], "left_rms": rms(left),
            "left_max": max(abs(a) for a in left), "raw_rms": rms(raw), "unit": unit_um}


def sign_checks(got, what):
    """got[negate] = assess(...) with the default sign and with --negate: the right sign removes
    the error (below 1 % of it), the wrong one doubles it (RMS ratio 2 within 1 %)."""
    if len(got) != 2:
        return  # an export failed: already reported
    ratio = got[True]["left_rms"] / got[True]["raw_rms"]
    check(abs(ratio - 2.0) < 0.02, f"{what}: the wrong sign doubles the error ({ratio})")
    check(got[False]["left_rms"] < 0.01 * got[False]["raw_rms"],
          f"{what}: the right sign removes it ({got[False]['left_rms']})")


def printed_residual(out):
    m = re.search(r"residual \(controller table - map\) over (\d+) samples: rms ([0-9.]+) um, "
                  r"max ([0-9.]+) um", out)
    return (float(m.group(2)), float(m.group(3))) if m else None


# The maps: the demo's and a stitched rectangular stage.
precision_maps(E)
maps = {"demo": SelfcaldMap(path("demo.csv"), "demo"),
        "stitched": SelfcaldMap(path("stitch.csv"), "stitch")}
check(len(maps["stitched"].xs) == 41 and len(maps["stitched"].ys) == 31, "a 41 x 31 stitched map")
LUT_Q = 0.5e-4  # lut dump's 0.1 nm against the map the exporter read

for mname, G in maps.items():
    csv = path("demo.csv" if mname == "demo" else "stitch.csv")
    # ---- Automation1 ----
    offset = (100.0, -50.0) if mname == "stitched" else (0.0, 0.0)
    axes = (3, 5) if mname == "stitched" else (1, 2)
    got = {}
    for negate in (False, True):
        out_name = f"{mname}{'-neg' if negate else ''}.cal"
        args = ["--format", "aerotech-a1", "--map", csv, "-o", path(out_name),
                "--axis-numbers", f"{axes[0]},{axes[1]}",
                "--offset", f"{offset[0]},{offset[1]}"] + (["--negate"] if negate else [])
        rc, out, err = run(*args)
        check(rc == 0 and err == "", f"aerotech-a1 {mname}: {rc} {err}")
        if rc != 0:
            continue
        corr, hdr = read_a1(out_name)
        check(hdr["row_axis"] == axes[1] and hdr["col_axis"] == axes[0]
              and hdr["out"] == axes, f"{out_name}: rows y, columns x, outputs x and y ({hdr})")
        check(hdr["nrows"] == len(G.ys) and hdr["ncols"] == len(G.xs), f"{out_name}: the map's nodes")

        def c_xy(x, y, corr=corr):
            c = corr({axes[0]: x, axes[1]: y})
            return c[axes[0]], c[axes[1]]
        got[negate] = a = assess(out_name, G, c_xy, 0.5e-4, offset)
        pr = printed_residual(out)
        print(f"aerotech-a1 {mname}{' --negate' if negate else ''}: residual against selfcald's "
              f"map rms {a['rms']:.6f} um, max {a['max']:.6f} um at {a['at']}; printed "
              f"{pr}; error left rms {a['left_rms']:.6f} um (max {a['left_max']:.6f}), "
              f"uncorrected rms {a['raw_rms']:.4f} um")
        check("2-D table of" in out and "unit 0.0001 um" in out and "nearest end point" in out,
              f"aerotech summary line: {out}")
        if not negate:
            check(a["max"] <= 0.5e-4 + LUT_Q + 1e-9,
                  f"aerotech {mname}: residual {a['max']} within the 0.1 nm unit and the lut's")
            check(pr is not None and abs(pr[1] - a["max"]) <= 1e-4 + LUT_Q + 1e-9,
                  f"aerotech {mname}: printed residual {pr} agrees with {a['max']}")
    sign_checks(got, f"aerotech {mname}")

    # ---- Power PMAC ----
    upm = (10000.0, 20000.0) if mname == "stitched" else (1.0, 1.0)
    motors = (4, 7) if mname == "stitched" else (1, 2)
    got = {}
    for negate in (False, True):
        out_name = f"{mname}{'-neg' if negate else ''}.pmc"
        args = ["--format", "powerpmac", "--map", csv, "-o", path(out_name),
                "--axis-numbers", f"{motors[0]},{motors[1]}", "--first-table", "2"]
        if mname == "stitched":
            args += ["--steps-per-mm", f"{upm[0]:g},{upm[1]:g}"]
        rc, out, err = run(*(args + (["--negate"] if negate else [])))
        check(rc == 0 and err == "", f"powerpmac {mname}: {rc} {err}")
        if rc != 0:
            continue
        tables = read_pmac(out_name)
        check(sorted(tables) == [2, 3], f"{out_name}: CompTable[2] and [3]")
        check(sorted(t[1] for t in tables.values()) == sorted(motors),
              f"{out_name}: targets the two motors")

        def c_xy(x, y, tables=tables):
            c = pmac_corrections(tables, {motors[0]: x * upm[0], motors[1]: y * upm[1]})
            return c.get(motors[0], 0.0) / upm[0] * 1e3, c.get(motors[1], 0.0) / upm[1] * 1e3
        unit = 0.5e-6 / min(upm)
        got[negate] = a = assess(out_name, G, c_xy, unit)
        pr = printed_residual(out)
        print(f"powerpmac {mname}{' --negate' if negate else ''}: residual against selfcald's "
              f"map rms {a['rms']:.6f} um, max {a['max']:.6f} um at {a['at']}; printed {pr}; "
              f"error left rms {a['left_rms']:.6f} um (max {a['left_max']:.6f}), uncorrected "
              f"rms {a['raw_rms']:.4f} um")
        check("CompTable[2] (x) and [3] (y)" in out and "motor units" in out,
              f"powerpmac summary line: {out}")
        if not negate:
            check(a["max"] <= unit + LUT_Q + 1e-9,
                  f"powerpmac {mname}: residual {a['max']} within its unit and the lut's")
            check(pr is not None and abs(pr[1] - a["max"]) <= 1e-4 + LUT_Q + 1e-9,
                  f"powerpmac {mname}: printed residual {pr} agrees with {a['max']}")
    sign_checks(got, f"powerpmac {mname}")

# Measure mode's first-order inverse, p - G(p), against the exact one (q + G(q) = p, iterated to
# convergence here): its error is G·grad G. The size on the demo's map, and that it is there.
for mname, G in maps.items():
    errs = []
    for (x, y) in G.samples(margin=0.0, sub=4):
        gx, gy = G.g(x, y)
        qx, qy = x, y
        for _ in range(30):
            hx, hy = G.g(qx, qy)
            qx, qy = x - hx * 1e-3, y - hy * 1e-3
        errs += [(x - gx * 1e-3 - qx) * 1e6, (y - gy * 1e-3 - qy) * 1e6]
    rms = math.sqrt(sum(e * e for e in errs) / len(errs))
    print(f"{mname}: measure mode's first-order error G·grad G: rms {rms:.3f} nm, max "
          f"{max(abs(e) for e in errs):.3f} nm (measure-exact removes it)")
    check(0.05 < rms < 100, f"{mname}: G·grad G {rms} nm is of the size expected")

# Options that do not apply, bad values: exit 2, one line, no file.
for fmt, extra, what in (("aerotech-a1", ["--axis", "x"], "--axis"),
                         ("aerotech-a1", ["--interval", "2"], "interval"),
                         ("powerpmac", ["--steps-per-mm", "-5,1"], "steps"),
                         ("powerpmac", ["--at", "3"], "--at"),
                         ("aerotech-a1", ["--steps-per-mm", "100,100"], "steps")):
    bad = path("bad.out")
    if os.path.exists(bad):
        os.remove(bad)
    rc, out, err = run("--format", fmt, "--map", path("demo.csv"), "-o", bad, *extra)
    check(rc == 2 and len(err.strip().splitlines()) == 1 and not os.path.exists(bad),
          f"{fmt} {extra}: exit 2, one line, no file ({rc} {err!r})")

E.finish("export_precision")
