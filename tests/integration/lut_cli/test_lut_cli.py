#!/usr/bin/env python3
"""Integration test of `selfcal lut build|dump|info` (SPEC §3) through the command line.

Writes a simulated stage error map and two profile files (the truth), builds a table, and checks
that `lut dump` reproduces them within the quantization the table states; that bad input exits 2
with file:line on stderr and leaves no output (an existing output file untouched); that corrupted
tables (bit flips, truncations) are refused with a reason. Standard library only.
usage: test_lut_cli.py SELFCAL_BINARY WORK_DIR
"""
import hashlib
import os
import random
import re
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "export_fw"))
from exportlib import Checks, parse_lut_dump, read_beckhoff_plane  # noqa: E402

SELFCAL, WORK = sys.argv[1], sys.argv[2]
C = Checks(SELFCAL, WORK, stream=sys.stdout)
check, run, path = C.check, C.run, C.path


rng = random.Random(20261121)

# ---- truth: a 25 x 25 map (rectangular variant below) and two profiles ----
def write_map(name, nx, ny, x0, y0, px, py, amp, shuffle=True):
    rows, truth = [], {}
    for i in range(ny):
        for j in range(nx):
            gx, gy = rng.gauss(0, amp), rng.gauss(0, amp)
            truth[(i, j)] = (x0 + j * px, y0 + i * py, round(gx, 6), round(gy, 6))
            rows.append(f"{i},{j},{x0 + j * px:.6f},{y0 + i * py:.6f},{gx:.6f},{gy:.6f},0.002,0.002")
    if shuffle:
        rng.shuffle(rows)
    with open(path(name), "w") as f:
        f.write("i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n" + "\n".join(rows) + "\n")
    return truth


def write_profile(name, n_total, n_valid, s_mm, amp):
    vals = []
    with open(path(name), "w") as f:
        f.write("n,x_mm,f_um,uf_um,ey_um\n")
        for n in range(n_total):
            ey = ""
            if n < n_valid:
                v = round(rng.gauss(0, amp), 6)
                vals.append((n * s_mm, v))
                ey = f"{v:.6f}"
            f.write(f"{n},{n * s_mm:.6f},{rng.gauss(0, 1):.6f},0.01,{ey}\n")
    return vals


def parse_dump(text):
    return parse_lut_dump(text, check)


def quantization_nm(table):
    rc, out, _ = run("lut", "info", table)
    check(rc == 0, "lut info")
    return float(re.search(r"grid encoding: \w+, \d+ pm per code, quantization <= ([0-9.]+) nm", out).group(1))


# ---- 1. build -> dump reproduces the input ----
truth = write_map("G.csv", 25, 25, -12.0, -12.0, 1.0, 1.0, 0.8)
p1 = write_profile("P1.csv", 330, 320, 1.0, 0.3)
p2 = write_profile("P2.csv", 330, 319, 1.0, 0.1)
rc, out, err = run("lut", "build", "--map", path("G.csv"), "--profile", "x:y:" + path("P1.csv"),
                   "--profile", "Y:Z:" + path("P2.csv"), "-o", path("T.lut"), "--method", "double-shift",
                   "--sigma", "0.015")
check(rc == 0, f"lut build exit {rc}: {err}")
size = os.path.getsize(path("T.lut"))
print(f"table size: {size} bytes (25 x 25 map + profiles of {len(p1)} and {len(p2)} points)")
check(size <= 8192, f"table of {size} bytes exceeds 8 KiB")
q_um = quantization_nm(path("T.lut")) * 1e-3
rc, out, err = run("lut", "dump", path("T.lut"))
check(rc == 0, f"lut dump exit {rc}: {err}")
grid, profiles = parse_dump(out)
check(len(grid) == 625, f"dump has {len(grid)} nodes")
worst = 0.0
for key, (x, y, gx, gy) in truth.items():
    dx, dy, dgx, dgy = grid[key]
    check(abs(dx - x) < 1e-9 and abs(dy - y) < 1e-9, f"node {key} position")
    worst = max(worst, abs(dgx - gx), abs(dgy - gy))
print(f"map: worst |dump - input| = {worst * 1e3:.4f} nm, stated quantization {q_um * 1e3:.4f} nm")
check(worst <= q_um + 1e-9, "map reproduced within the stated quantization")
check(len(profiles) == 2, "two profiles")
for (axis, dirn, rows), vals, want in zip(profiles, (p1, p2), (("x", "y"), ("y", "z"))):
    check((axis, dirn) == want, f"profile axis/dir {axis},{dirn}")
    check(len(rows) == len(vals), f"profile length {len(rows)} vs {len(vals)} (trailing empties dropped)")
    for (n, pos, e), (tpos, tv) in zip(rows, vals):
        check(abs(pos - tpos) < 1e-9, "profile position")
        check(abs(e - tv) <= 0.5e-3, "profile value within 0.5 nm")
rc, out, _ = run("lut", "info", path("T.lut"))
for k, f in enumerate(("G.csv", "P1.csv", "P2.csv")):
    h = hashlib.sha256(open(path(f), "rb").read()).hexdigest()
    check(f"source {k} sha256: {h}" in out, f"provenance hash of {f}")
check("method: double-shift" in out and "sigma_um: 0.015" in out, "provenance method and sigma")
# "FILE@text" where FILE is a file and FILE@text none is a mistyped offset: a usage error, no table
if os.path.exists(path("bad.lut")):
    os.remove(path("bad.lut"))
rc, out, err = run("lut", "build", "--map", path("G.csv"), "--profile", "x:y:" + path("P1.csv") + "@abc",
                   "-o", path("bad.lut"))
check(rc == 2 and "OFFSET_MM" in err and not os.path.exists(path("bad.lut")), f"--profile @abc: {rc} {err}")
# DIR = AXIS is allowed (SPEC §3 names no restriction) with a warning: an error along the axis
rc, out, err = run("lut", "build", "--map", path("G.csv"), "--profile", "x:x:" + path("P1.csv"),
                   "-o", path("xx.lut"))
check(rc == 0 and "warning" in err and "DIR = AXIS" in err, f"--profile x:x: {rc} {err}")

# Rectangular grid, non-zero origin, large errors (int32 encoding), no profiles.
truth = write_map("R.csv", 9, 4, 100.0, -50.0, 12.5, 7.5, 80.0)
rc, out, err = run("lut", "build", "--map", path("R.csv"), "-o", path("R.lut"))
check(rc == 0, f"rectangular build: {err}")
q_um = quantization_nm(path("R.lut")) * 1e-3
grid, profiles = parse_dump(run("lut", "dump", path("R.lut"))[1])
check(len(grid) == 36 and not profiles, "rectangular dump")
worst = max(max(abs(grid[k][2] - v[2]), abs(grid[k][3] - v[3])) for k, v in truth.items())
check(worst <= q_um + 1e-9, f"rectangular map within quantization ({worst} > {q_um})")

# ---- 2. bad input: exit 2, file:line on stderr, no output file, existing file untouched ----
def expect_bad(args, needle, label):
    out_path = path("bad.lut")
    if os.path.exists(out_path):
        os.remove(out_path)
    rc, out, err = run("lut", "build", *args, "-o", out_path)
    check(rc == 2, f"{label}: exit {rc} (want 2), stderr {err!r}")
    check(re.search(needle, err) is not None, f"{label}: stderr {err!r} lacks {needle!r}")
    check(len(err.strip().splitlines()) == 1, f"{label}: one line on stderr")
    check(not os.path.exists(out_path), f"{label}: output file was created")
    leftovers = [f for f in os.listdir(WORK) if f.startswith("bad.lut") or ".tmp" in f]
    check(not leftovers, f"{label}: temporary files left: {leftovers}")


with open(path("G.csv")) as f:
    good = f.read().splitlines()
def variant(name, lines):
    with open(path(name), "w") as f:
        f.write("\n".join(lines) + "\n")
    return path(name)

missing = variant("missing.csv", good[:100] + good[101:])
expect_bad(["--map", missing], r"missing\.csv.*missing", "missing node")
dup = variant("dup.csv", good + [good[5]])
expect_bad(["--map", dup], r"dup\.csv:%d: .*repeats" % (len(good) + 1), "duplicate node")
f = good[7].split(",")
f[2] = str(float(f[2]) + 0.3)
irr = variant("irr.csv", good[:7] + [",".join(f)] + good[8:])
expect_bad(["--map", irr], r"irr\.csv:8: .*irregular", "irregular grid")
f = good[9].split(",")
f[4] = "1.2.3"
junk = variant("junk.csv", good[:9] + [",".join(f)] + good[10:])
expect_bad(["--map", junk], r"junk\.csv:10: .*gx_um", "non-number")
expect_bad(["--map", path("nope.csv")], r"nope\.csv", "nonexistent map")
with open(path("P1.csv")) as fh:
    pl = fh.read().splitlines()
f = pl[50].split(",")
f[4] = ""
mid = variant("mid.csv", pl[:50] + [",".join(f)] + pl[51:])
expect_bad(["--map", path("G.csv"), "--profile", "x:y:" + mid], r"mid\.csv:51: .*empty", "empty ey in the middle")
expect_bad(["--map", path("G.csv"), "--profile", "w:y:" + path("P1.csv")], r"AXIS:DIR", "bad axis")
expect_bad(["--map", path("G.csv"), "--profile", path("P1.csv")], r"AXIS:DIR", "no axis")

# An existing table stays as it was when a rebuild fails.
before = open(path("T.lut"), "rb").read()
rc, _, _ = run("lut", "build", "--map", missing, "-o", path("T.lut"))
check(rc == 2 and open(path("T.lut"), "rb").read() == before, "failed build left the old table intact")

# ---- 3. corrupted tables: refused with a reason, exit 2 ----
def expect_refused(data, label):
    with open(path("corrupt.lut"), "wb") as fh:
        fh.write(data)
    rc, out, err = run("lut", "dump", path("corrupt.lut"))
    check(rc == 2, f"{label}: exit {rc}")
    check(out == "", f"{label}: printed something")
    check(re.search(r"corrupt\.lut: not a valid table: \S", err) is not None, f"{label}: {err!r}")
    return err

reasons = set()
for _ in range(60):
    b = rng.randrange(len(before))
    bit = rng.randrange(8)
    data = bytearray(before)
    data[b] ^= 1 << bit
    reasons.add(expect_refused(bytes(data), f"flip byte {b} bit {bit}").split("not a valid table: ")[-1].strip())
for n in sorted(set([0, 1, 7, 63, 64, 67, len(before) - 4, len(before) - 1] + [rng.randrange(len(before)) for _ in range(15)])):
    reasons.add(expect_refused(before[:n], f"truncated to {n}").split("not a valid table: ")[-1].strip())
reasons.add(expect_refused(before + b"\0", "one byte appended").split("not a valid table: ")[-1].strip())
print("reasons seen:", sorted(reasons))
check(any("checksum" in r for r in reasons) and any("truncated" in r for r in reasons), "reasons named")

# ---- 4. selfcal export: re-read each controller file, compare with the map in its units ----
def bilinear(truth, nx, ny, x0, y0, px, py, comp, x, y):
    j = min(max(int((x - x0) // px), 0), nx - 2)
    i = min(max(int((y - y0) // py), 0), ny - 2)
    tx, ty = (x - (x0 + j * px)) / px, (y - (y0 + i * py)) / py
    g = lambda a, b: truth[(a, b)][2 + comp]
    return ((1 - tx) * (1 - ty) * g(i, j) + tx * (1 - ty) * g(i, j + 1)
            + (1 - tx) * ty * g(i + 1, j) + tx * ty * g(i + 1, j + 1))

truth = write_map("E.csv", 11, 9, -25.0, 40.0, 5.0, 5.0, 2.0)
rc, out, err = run("export", "--format", "beckhoff", "--map", path("E.csv"), "--axis", "y", "-o", path("E.lis"))
check(rc == 0, f"export beckhoff: {err}")
check(re.search(r"residual .* rms [0-9.]+ um, max [0-9.]+ um", out) is not None, f"beckhoff report: {out}")
tab, hdr = read_beckhoff_plane(path("E.lis"))
check(hdr.get("kw.crosscomp2.unit") == "1" and hdr.get("kopf.log_achs_name") == "Y", "beckhoff header")
iv = int(hdr["kw.crosscomp2.interval"])
s1, s2 = int(hdr["kw.crosscomp2.start_position_master1"]), int(hdr["kw.crosscomp2.start_position_master2"])
check(len(tab) == (int(hdr["kw.crosscomp2.last_index_master1"]) + 1) * (int(hdr["kw.crosscomp2.last_index_master2"]) + 1), "beckhoff table complete")
worst = 0.0
for (i, j), v in truth.items():
    x, y = v[0], v[1]
    a, b = round((x * 1e4 - s1) / iv), round((y * 1e4 - s2) / iv)
    worst = max(worst, abs(0.1 * tab[(b, a)] + v[3]))  # ISG's sign: actual - setpoint = -G
check(worst <= 0.05 + 1e-9, f"beckhoff nodes within 0.05 um ({worst})")

rc, out, err = run("export", "--format", "siemens-cec", "--map", path("E.csv"), "-o", path("E.mpf"))
check(rc == 0, f"export siemens: {err}")
text = open(path("E.mpf")).read().splitlines()
check(text[0] == "%_N_NC_CEC_INI" and text[-1] == "M17", "siemens framing")
vals = {}
for line in text:
    m = re.match(r"\$AN_CEC\[(\d+),(\d+)\]=(-?[0-9.]+)$", line)
    if m:
        vals.setdefault(int(m.group(1)), []).append(float(m.group(3)))
check(sorted(vals) == [0, 1, 2, 3], "siemens: four tables")
check(all(len(v) == n for v, n in zip((vals[0], vals[1], vals[2], vals[3]), (11, 9, 11, 9))), "siemens table sizes")
rep = re.search(r"max ([0-9.]+) um", out)
# Sum of the X tables at a node minus the map: the reported max residual bounds it.
worst = max(abs(1e3 * (vals[0][j] + vals[1][i]) + v[2]) for (i, j), v in truth.items())  # -G
check(worst <= float(rep.group(1)) + 1e-3, f"siemens residual at nodes {worst} vs reported {rep.group(1)}")

rc, out, err = run("export", "--format", "linuxcnc", "--map", path("E.csv"), "--axis", "x", "-o", path("E.comp"))
check(rc == 0, f"export linuxcnc: {err}")
lines = open(path("E.comp")).read().splitlines()
check(lines[-1].startswith("#") and "COMP_FILE_TYPE = 1" in lines[-1]
      and not any(l.startswith("#") for l in lines[:-1]), "linuxcnc: one trailing comment line")
rows = [list(map(float, l.split())) for l in lines[:-1]]
check(len(rows) == 11 and all(len(r) == 3 and r[1] == r[2] for r in rows), "linuxcnc triplets")
check(rows[0][0] == -25.0, "linuxcnc: the first entry is the map's first node (LinuxCNC holds the first trim below it)")
for j, r in enumerate(rows):
    mean = sum(truth[(i, j)][2] for i in range(9)) / 9
    check(abs(r[0] - (-25.0 + 5.0 * j)) < 1e-9 and abs(1e3 * r[1] - mean) <= 0.5e-3 + 1e-9, "linuxcnc entry")
if os.path.exists(path("bad.comp")):
    os.remove(path("bad.comp"))
rc, out, err = run("export", "--format", "linuxcnc", "--map", path("E.csv"), "--interval", "0.1", "-o", path("bad.comp"))
check(rc == 2 and "256" in err and not os.path.exists(path("bad.comp")), "linuxcnc 256-entry limit")
rc, out, err = run("export", "--format", "fanuc", "--map", path("E.csv"), "-o", path("bad.comp"))
check(rc == 2, "unknown format")
rc, out, err = run("export", "--format", "beckhoff", "--map", missing, "-o", path("bad.comp"))
check(rc == 2 and "missing.csv" in err and not os.path.exists(path("bad.comp")), "export of a bad map")

# ---- large maps: a table holds 101 x 101 nodes; --max-nodes fits a coarser one ----
# A smooth map of 151 x 131 nodes (pitch 0.5 mm) with a little node-scale roughness.
import math  # noqa: E402
nx_big, ny_big = 151, 131
big = {}
with open(path("B.csv"), "w") as f:
    f.write("i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n")
    for i in range(ny_big):
        for j in range(nx_big):
            x, y = -37.5 + 0.5 * j, -32.5 + 0.5 * i
            gx = 0.8 * math.sin(x / 9.0) * math.cos(y / 13.0) + rng.gauss(0, 0.01)
            gy = 0.5 * math.cos(x / 11.0 + y / 7.0) + rng.gauss(0, 0.01)
            big[(i, j)] = (x, y, round(gx, 6), round(gy, 6))
            f.write(f"{i},{j},{x:.6f},{y:.6f},{gx:.6f},{gy:.6f},0.003,0.003\n")
expect_bad(["--map", path("B.csv")], r"B\.csv: the map has 151 x 131 nodes; a table holds at most "
           r"101 x 101 .*--max-nodes", "map over 101 nodes")
expect_bad(["--map", path("B.csv"), "--max-nodes", "102"], r"--max-nodes: 2\.\.101", "--max-nodes 102")
expect_bad(["--map", path("B.csv"), "--max-nodes", "1"], r"--max-nodes: 2\.\.101", "--max-nodes 1")
rc, out, err = run("lut", "build", "--map", path("B.csv"), "--max-nodes", "101", "-o", path("B.lut"))
check(rc == 0, f"lut build --max-nodes: exit {rc}: {err}")
m = re.search(r"map \S*B\.csv: 151 x 131 nodes fitted by a 101 x 101 table \(least squares, pitch "
              r"0\.750000 x 0\.650000 mm\): table - map at the map's nodes rms ([0-9.]+) um, max "
              r"([0-9.]+) um at \((-?[0-9.]+), (-?[0-9.]+)\) mm", out)
check(m is not None, f"fit report line: {out!r}")
grid, _ = parse_dump(run("lut", "dump", path("B.lut"))[1])
check(len(grid) == 101 * 101, f"fitted table has {len(grid)} nodes")
check(abs(grid[(0, 0)][0] + 37.5) < 1e-9 and abs(grid[(100, 100)][0] - 37.5) < 1e-9
      and abs(grid[(0, 0)][1] + 32.5) < 1e-9 and abs(grid[(100, 100)][1] - 32.5) < 1e-9,
      "the fitted table spans the map exactly")


def table_at(g, n, x0, y0, px, py, x, y):
    u, v = (x - x0) / px, (y - y0) / py
    j, i = min(int(u), n - 2), min(int(v), n - 2)
    fu, fv = u - j, v - i
    return [(1 - fv) * ((1 - fu) * g[(i, j)][c] + fu * g[(i, j + 1)][c])
            + fv * ((1 - fu) * g[(i + 1, j)][c] + fu * g[(i + 1, j + 1)][c]) for c in (2, 3)]


errs = []
for (i, j), (x, y, gx, gy) in big.items():
    tx, ty = table_at(grid, 101, -37.5, -32.5, 0.75, 0.65, x, y)
    errs.append(math.hypot(tx - gx, ty - gy))
rms = math.sqrt(sum(e * e for e in errs) / len(errs))
if m:
    print(f"151 x 131 map in a 101 x 101 table: rms {rms * 1e3:.2f} nm, max {max(errs) * 1e3:.2f} nm "
          f"(reported {m.group(1)} / {m.group(2)} um)")
    check(abs(rms - float(m.group(1))) < 2e-4 and abs(max(errs) - float(m.group(2))) < 2e-4,
          "the reported fit error is the table's at the map's nodes")
# the fit follows the smooth part: what is left is about the 10 nm roughness (sqrt(2) * 10 nm
# RMS as a vector; the table interpolates part of it away)
check(rms < 0.02, f"fitted table within 20 nm RMS of a smooth map ({rms * 1e3:.2f} nm)")
# the same through export (here Beckhoff's plane list of x)
if os.path.exists(path("B.beckhoff")):
    os.remove(path("B.beckhoff"))  # from an earlier run
rc, out, err = run("export", "--format", "beckhoff", "--axis", "x", "--map", path("B.csv"), "-o",
                   path("B.beckhoff"))
check(rc == 2 and "--max-nodes" in err and not os.path.exists(path("B.beckhoff")),
      f"export of a large map without --max-nodes: exit {rc} {err!r}")
rc, out, err = run("export", "--format", "beckhoff", "--axis", "x", "--map", path("B.csv"),
                   "--max-nodes", "101", "-o", path("B.beckhoff"))
check(rc == 0 and "fitted by a 101 x 101 table" in out and os.path.exists(path("B.beckhoff")),
      f"export --max-nodes: exit {rc} {err!r}")

C.finish("lut CLI")
