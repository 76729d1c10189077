#!/usr/bin/env python3
"""`selfcal lut info`'s correction bounds (docs/linuxcnc.md, "Margins"): the largest |G|, the
largest slope of G, and the per-coordinate bounds of the whole correction (grid and profiles).

Maps with a known largest slope and |G| are built with the CLI; the printed values are compared
with the same quantities computed here from `selfcal lut dump` (the table's own nodes: the
quantization is in both) and with the values the maps were made with (to the quantization).
Standard library only.
usage: test_lut_bounds.py SELFCAL_BINARY WORK_DIR
"""
import math
import os
import re
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "export_fw"))
from exportlib import Checks, parse_lut_dump  # noqa: E402

SELFCAL, WORK = sys.argv[1], sys.argv[2]
C = Checks(SELFCAL, WORK, stream=sys.stdout)
check, run, path = C.check, C.run, C.path


def write_map(name, n, pitch, gfun):
    c = (n - 1) / 2
    with open(path(name), "w") as f:
        f.write("i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n")
        for i in range(n):
            for j in range(n):
                x, y = (j - c) * pitch, (i - c) * pitch
                gx, gy = gfun(x, y)
                f.write(f"{i},{j},{x:.6f},{y:.6f},{gx:.6f},{gy:.6f},,\n")


def write_profile(name, n, step, efun):
    with open(path(name), "w") as f:
        f.write("n,x_mm,f_um,uf_um,ey_um\n")
        for k in range(n):
            f.write(f"{k},{k * step:.6f},0,0,{efun(k * step):.6f}\n")


def info(table):
    rc, out, err = run("lut", "info", table)
    check(rc == 0, f"lut info {table}: exit {rc} {err}")
    g = re.search(r"^largest \|G\|: ([0-9.]+) um$", out, re.M)
    s = re.search(r"^largest slope of G: ([0-9.e+-]+) \(um per um\)$", out, re.M)
    c = re.search(r"^correction bounds \(grid and profiles\): \|cx\| <= ([0-9.]+) um, "
                  r"\|cy\| <= ([0-9.]+) um, slope <= ([0-9.e+-]+)$", out, re.M)
    check(g and s and c, f"lut info prints the bounds:\n{out}")
    return float(g.group(1)), float(s.group(1)), tuple(float(v) for v in c.groups())


def dump(table):
    rc, out, err = run("lut", "dump", table)
    check(rc == 0, f"lut dump: {err}")
    grid, profiles = parse_lut_dump(out, check)
    return grid, [(a, d, [(pos, e) for _, pos, e in rows]) for a, d, rows in profiles]


def bounds_from_dump(grid, profiles):
    """|G|max, largest slope of G between neighbouring nodes, and the correction's bounds."""
    gmax = max(math.hypot(v[2], v[3]) for v in grid.values())
    cx = max(abs(v[2]) for v in grid.values())
    cy = max(abs(v[3]) for v in grid.values())
    sl = {0: 0.0, 1: 0.0}
    for (i, j), (x, y, gx, gy) in grid.items():
        for nb in ((i, j + 1), (i + 1, j)):
            if nb in grid:
                x2, y2, gx2, gy2 = grid[nb]
                d_um = 1e3 * math.hypot(x2 - x, y2 - y)
                sl[0] = max(sl[0], abs(gx2 - gx) / d_um)
                sl[1] = max(sl[1], abs(gy2 - gy) / d_um)
    slope_g = max(sl.values())
    c = {"x": cx, "y": cy, "z": 0.0}
    s = {"x": sl[0], "y": sl[1], "z": 0.0}
    for _axis, d, pts in profiles:
        c[d] += max(abs(e) for _, e in pts)
        s[d] += max(abs(pts[k + 1][1] - pts[k][1]) / (1e3 * (pts[k + 1][0] - pts[k][0]))
                    for k in range(len(pts) - 1))
    return gmax, slope_g, (c["x"], c["y"], max(s.values()))


def close(a, b, rel=1e-5, abs_=1e-9):
    return abs(a - b) <= max(rel * max(abs(a), abs(b)), abs_)


# 1. A map with slopes of 0.01 (a sine of 10 um amplitude and 1/mm wavenumber along x in gx):
# the largest slope between nodes is just below 0.01; |G| is at most hypot(10, 6) um.
write_map("s.csv", 41, 0.25, lambda x, y: (10.0 * math.sin(x), 6.0 * math.cos(0.5 * y + 0.2 * x)))
rc, out, err = run("lut", "build", "--map", path("s.csv"), "-o", path("s.lut"))
check(rc == 0, f"lut build: {err}")
g, s, c = info(path("s.lut"))
want = bounds_from_dump(*dump(path("s.lut")))
check(close(g, want[0]) and close(s, want[1]) and all(close(a, b) for a, b in zip(c, want[2])),
      f"sine map: lut info {g, s, c}, from the dump {want}")
# the map's own numbers: slope 10 um/mm * sin(0.25/2)/(0.25/2) = 0.00997 (a chord of the sine)
check(abs(s - 0.01 * math.sin(0.125) / 0.125) < 2e-5, f"sine map: slope {s}, want ~0.00997")
check(9.9 < c[0] <= 10.0 + 1e-3 and 5.9 < c[1] <= 6.0 + 1e-3, f"sine map: bounds {c}")
print(f"slope-0.01 map: |G| max {g:.4f} um, slope {s:.6f}, bounds {c}")

# 2. A plane (G linear): slope = its gradient exactly; plus two profiles that add to the bounds.
write_map("p.csv", 11, 2.0, lambda x, y: (0.5 * x - 0.25 * y, 0.125 * y))
write_profile("px.csv", 61, 0.5, lambda t: 0.2 * math.sin(t))      # error of y along x
write_profile("py.csv", 61, 0.5, lambda t: 0.003 * t * t)           # error of x along y
rc, out, err = run("lut", "build", "--map", path("p.csv"), "--profile", "x:y:" + path("px.csv"),
                   "--profile", "y:x:" + path("py.csv"), "-o", path("p.lut"))
check(rc == 0, f"lut build with profiles: {err}")
g, s, c = info(path("p.lut"))
want = bounds_from_dump(*dump(path("p.lut")))
check(close(g, want[0]) and close(s, want[1]) and all(close(a, b) for a, b in zip(c, want[2])),
      f"plane + profiles: lut info {g, s, c}, from the dump {want}")
check(abs(s - 0.5e-3) < 1e-8, f"plane: slope {s}, want 5e-4 (0.5 um per mm)")
# |G| is largest at the corners (10, -10) and (-10, 10): hypot(7.5, 1.25) um
check(abs(g - math.hypot(7.5, 1.25)) < 1e-5, f"plane: |G| max {g}, want {math.hypot(7.5, 1.25)}")
# the profiles add their largest |error| to their coordinate: x 7.5 + 2.7 um, y 1.25 + ~0.2 um
check(abs(c[0] - 10.2) < 1e-5 and 1.44 < c[1] < 1.4501, f"plane + profiles: bounds {c}")

# 3. A flat map: zeros.
write_map("z.csv", 5, 1.0, lambda x, y: (0.0, 0.0))
rc, out, err = run("lut", "build", "--map", path("z.csv"), "-o", path("z.lut"))
g, s, c = info(path("z.lut"))
check(g == 0 and s == 0 and c == (0.0, 0.0, 0.0), f"flat map: {g, s, c}")

C.finish("lut info bounds")
