#!/usr/bin/env python3
"""`selfcal export` options for machine controllers (issue 12's paper cuts), through the command
line: `--axis both` writes one file per axis (both or none), `--offset` moves the nominal positions
into the machine's homed coordinates, the LinuxCNC file ends with ONE comment line (LinuxCNC's
loader reads triplets up to the first line that is not one) and the command says loudly that it
needs COMP_FILE_TYPE = 1, Beckhoff's default sign is ISG's (actual - setpoint = -G),
`--target 828d` holds the SINUMERIK 828D's 8 tables x 200 points.

usage: test_export_cli.py SELFCAL_CLI WORKDIR"""
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from exportlib import Export, read_beckhoff_plane  # noqa: E402

cli, work = sys.argv[1], sys.argv[2]
E = Export(cli, work)
check, run, path = E.check, E.run, E.path


def write_map(name, nx, ny, x0, y0, px, py):
    truth = {}
    with open(path(name), "w") as f:
        f.write("i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n")
        for i in range(ny):
            for j in range(nx):
                x, y = x0 + j * px, y0 + i * py
                gx = 1.5 + 0.02 * x - 0.01 * y + 0.3 * ((i * 7 + j * 3) % 5 - 2)
                gy = -0.7 + 0.01 * x + 0.015 * y + 0.2 * ((i * 5 + j * 11) % 7 - 3)
                f.write(f"{i},{j},{x:.6f},{y:.6f},{gx:.6f},{gy:.6f},,\n")
                truth[(i, j)] = (x, y, round(gx, 6), round(gy, 6))
    return truth


truth = write_map("M.csv", 11, 9, -25.0, 40.0, 5.0, 5.0)

# LinuxCNC, both axes, machine offset.
for f in ("J-x.comp", "J-y.comp"):
    if os.path.exists(path(f)):
        os.remove(path(f))
rc, out, err = run("--format", "linuxcnc", "--map", path("M.csv"), "--axis", "both",
                   "--offset", "100,-50", "-o", path("J.comp"))
check(rc == 0, f"linuxcnc both: {err}")
check(out.count("COMP_FILE_TYPE = 1") == 2 and "IMPORTANT" in out, f"loud COMP_FILE_TYPE: {out}")
for axis, name, n_other in ((0, "J-x.comp", 9), (1, "J-y.comp", 11)):
    check(os.path.exists(path(name)), f"{name} written")
    if not os.path.exists(path(name)):
        continue
    lines = open(path(name)).read().splitlines()
    check(lines[-1].startswith("#") and "COMP_FILE_TYPE = 1" in lines[-1]
          and not any(ln.startswith("#") for ln in lines[:-1]), f"{name}: one trailing comment")
    # Nominals in machine coordinates: the map's plus the offset; no entry beyond the map
    # (LinuxCNC holds the first trim below the first entry: motion/command.c, SET_JOINT_COMP).
    rows = [list(map(float, ln.split())) for ln in lines[:-1]]
    check(len(rows) == (11 if axis == 0 else 9), f"{name}: {len(rows)} map entries")
    for k, r in enumerate(rows):
        if axis == 0:
            mean = sum(truth[(i, k)][2] for i in range(9)) / 9
            nominal = -25.0 + 5.0 * k + 100.0
        else:
            mean = sum(truth[(k, j)][3] for j in range(11)) / 11
            nominal = 40.0 + 5.0 * k - 50.0
        check(abs(r[0] - nominal) < 1e-9 and abs(1e3 * r[1] - mean) <= 0.5e-3 + 1e-9,
              f"{name} row {k}: {r} (nominal {nominal}, trim {mean} um)")

# Without --axis, the one-axis formats write x and say so; with it, no note.
for fmt in ("beckhoff", "linuxcnc"):
    rc, out, err = run("--format", fmt, "--map", path("M.csv"), "-o", path("noaxis." + fmt))
    check(rc == 0 and "note: no --axis: the x axis's table only" in out and err == "",
          f"{fmt} without --axis: {rc} {out!r} {err!r}")
    rc, out, err = run("--format", fmt, "--map", path("M.csv"), "--axis", "x", "-o", path("axis." + fmt))
    check(rc == 0 and "note:" not in out, f"{fmt} --axis x: {out!r}")

# Both or none: x fits 256 entries, y does not -> no file at all.
write_map("L.csv", 11, 101, 0.0, 0.0, 1.0, 5.0)
for f in ("L-x.comp", "L-y.comp"):
    if os.path.exists(path(f)):
        os.remove(path(f))
rc, out, err = run("--format", "linuxcnc", "--map", path("L.csv"), "--axis", "both",
                   "--interval", "1.5", "-o", path("L.comp"))
check(rc == 2 and "256" in err and len(err.strip().splitlines()) == 1, f"both-or-none: {rc} {err}")
check(not os.path.exists(path("L-x.comp")) and not os.path.exists(path("L-y.comp")),
      "both-or-none: no file left")

# Beckhoff: ISG's sign by default (value = actual - setpoint = -G), +G with --negate; both axes.
for negate in (False, True):
    args = ["--format", "beckhoff", "--map", path("M.csv"), "--axis", "both", "-o",
            path("B.lis")] + (["--negate"] if negate else [])
    rc, out, err = run(*args)
    check(rc == 0, f"beckhoff both: {err}")
    for axis, name in ((0, "B-x.lis"), (1, "B-y.lis")):
        tab, hdr = read_beckhoff_plane(path(name))
        check(hdr.get("kopf.log_achs_name") == ("X", "Y")[axis], f"{name}: slave axis")
        iv = int(hdr["kw.crosscomp2.interval"])
        s1 = int(hdr["kw.crosscomp2.start_position_master1"])
        s2 = int(hdr["kw.crosscomp2.start_position_master2"])
        sign = 1.0 if negate else -1.0
        worst = 0.0
        for (i, j), v in truth.items():
            a, b = round((v[0] * 1e4 - s1) / iv), round((v[1] * 1e4 - s2) / iv)
            worst = max(worst, abs(0.1 * tab[(b, a)] - sign * v[2 + axis]))
        check(worst <= 0.05 + 1e-9, f"{name} negate={negate}: nodes within 0.05 um ({worst})")
    check(("+G" if negate else "-G (ISG") in out, f"beckhoff sign reported: {out}")

# Siemens 828D: 8 tables x 200 points.
rc, out, err = run("--format", "siemens-cec", "--map", path("M.csv"), "--target", "828d",
                   "-o", path("S.mpf"))
check(rc == 0 and "828D" in open(path("S.mpf")).read(), f"828d: {err}")
for args, want in ((["--interval", "0.2"], "200"), (["--first-table", "5"], "828D")):
    if os.path.exists(path("S2.mpf")):
        os.remove(path("S2.mpf"))
    rc, out, err = run("--format", "siemens-cec", "--map", path("M.csv"), "--target", "828d",
                       *args, "-o", path("S2.mpf"))
    check(rc == 2 and want in err and not os.path.exists(path("S2.mpf")),
          f"828d {args}: {rc} {err}")
rc, out, err = run("--format", "siemens-cec", "--map", path("M.csv"), "--interval", "0.2",
                   "-o", path("S3.mpf"))
check(rc == 0 and "828D holds 200" in out, f"840d takes 250 points, with a note for 828D: {err} {out}")
rc, out, err = run("--format", "linuxcnc", "--map", path("M.csv"), "--target", "828d",
                   "-o", path("S4.mpf"))
check(rc == 2 and len(err.strip().splitlines()) == 1, f"--target for linuxcnc: {rc} {err}")

# Straightness profiles as Siemens CEC tables (input AXIS -> output DIR), Siemens' sign (-ey).
with open(path("P.csv"), "w") as f:
    f.write("n,x_mm,f_um,uf_um,ey_um\n")
    ey = []
    for k in range(41):
        x = -30.0 + 1.5 * k
        e = round(0.8 * ((k * 7) % 11 - 5) / 5 + 0.01 * x, 6)
        ey.append((x, e))
        f.write(f"{k},{x:.6f},0,0,{e:.6f}\n")
rc, out, err = run("--format", "siemens-cec", "--map", path("M.csv"), "--profile",
                   "x:y:" + path("P.csv"), "--axis-names", "X1,Y1", "-o", path("SP.mpf"))
check(rc == 0, f"siemens profile: {err}")
if rc == 0:
    text = open(path("SP.mpf")).read()
    tabs = {}
    for m in re.finditer(r"^\$AN_CEC\[(\d+),(\d+)\]=(-?[0-9.]+)$", text, re.M):
        tabs.setdefault(int(m.group(1)), {})[int(m.group(2))] = float(m.group(3))
    check(sorted(tabs) == [0, 1, 2, 3, 4], f"siemens profile: 5 tables, got {sorted(tabs)}")
    kv = dict(re.findall(r"^\$(AN_CEC_\w+\[4\])=(\S+)$", text, re.M))
    check(kv.get("AN_CEC_INPUT_AXIS[4]") == "(X1)" and kv.get("AN_CEC_OUTPUT_AXIS[4]") == "(Y1)",
          f"profile table axes: {kv}")
    check(abs(float(kv["AN_CEC_MIN[4]"]) + 30.0) < 1e-9
          and abs(float(kv["AN_CEC_STEP[4]"]) - 1.5) < 1e-9, f"profile table range: {kv}")
    worst = max(abs(1e3 * tabs[4][k] + e) for k, (x, e) in enumerate(ey))
    check(len(tabs[4]) == 41 and worst <= 0.5e-3 + 1e-9, f"profile values = -ey ({worst})")
    check("straightness profile" in text and "profile tables: max" in out, f"profile reported: {out}")
for args, want in ((["--profile", "x:x:" + path("P.csv")], "DIR != AXIS"),
                   (["--profile", "x:y:" + path("P.csv"), "--target", "828d", "--first-table",
                     "4"], "828D")):
    if os.path.exists(path("SP2.mpf")):
        os.remove(path("SP2.mpf"))
    rc, out, err = run("--format", "siemens-cec", "--map", path("M.csv"), *args,
                       "-o", path("SP2.mpf"))
    check(rc == 2 and want in err and not os.path.exists(path("SP2.mpf")), f"{args}: {rc} {err}")
rc, out, err = run("--format", "linuxcnc", "--map", path("M.csv"), "--profile",
                   "x:y:" + path("P.csv"), "-o", path("SP3.comp"))
check(rc == 2 and "HAL component" in err, f"profile for linuxcnc: {rc} {err}")

# Dynomotion KMotionCNC: the whole 2-D map. KMotion's own GeoCorrect (KMotionX
# GCodeInterpreter/Kinematics.cpp) applied to the file: cell by floor(), clamped to the table,
# fractions not clamped (extrapolation), bilinear over the tabulated actuator positions (inches).
rc, out, err = run("--format", "kmotion", "--map", path("M.csv"), "--offset", "100,-50", "-o",
                   path("K.geo"))
check(rc == 0, f"kmotion: {err}")
if rc == 0:
    ln = open(path("K.geo")).read().split("\n")
    nrows, ncols = map(int, ln[0].split(","))
    sx, sy = map(float, ln[1].split(","))
    ox, oy = map(float, ln[2].split(","))
    tab = {}
    for line in ln[3:]:
        if line.strip():
            r, c, X, Y, Z = line.split(",")
            tab[(int(r), int(c))] = (float(X), float(Y), float(Z))
    check(len(tab) == nrows * ncols and 2 <= nrows <= 4000 and 2 <= ncols <= 4000,
          f"kmotion: {nrows} x {ncols} entries")

    def geocorrect(x, y):
        col, row = math.floor((x - ox) / sx), math.floor((y - oy) / sy)
        col, row = min(max(col, 0), ncols - 2), min(max(row, 0), nrows - 2)
        fx, fy = (x - (col * sx + ox)) / sx, (y - (row * sy + oy)) / sy
        bl, br, tl, tr = (tab[(row, col)], tab[(row, col + 1)], tab[(row + 1, col)],
                          tab[(row + 1, col + 1)])
        out = []
        for q in (0, 1):
            b = bl[q] + (br[q] - bl[q]) * fx
            t = tl[q] + (tr[q] - tl[q]) * fx
            out.append(b + (t - b) * fy)
        return out

    def g_map(x, y):
        """Bilinear G of M.csv at map coordinates, clamped outside (um)."""
        u = min(max((x + 25.0) / 5.0, 0.0), 10.0)
        v = min(max((y - 40.0) / 5.0, 0.0), 8.0)
        j, i = min(int(u), 9), min(int(v), 7)
        fu, fv = u - j, v - i
        res = []
        for q in (2, 3):
            res.append((1 - fv) * ((1 - fu) * truth[(i, j)][q] + fu * truth[(i, j + 1)][q])
                       + fv * ((1 - fu) * truth[(i + 1, j)][q] + fu * truth[(i + 1, j + 1)][q]))
        return res

    worst = 0.0
    for a in range(-6, 8 * 4 + 7):          # beyond the map on every side too
        for b in range(-6, 10 * 4 + 7):
            xm, ym = -25.0 + 1.25 * b, 40.0 + 1.25 * a      # map coordinates
            xs, ys = xm + 100.0, ym - 50.0                   # machine coordinates (--offset)
            cx, cy = geocorrect(xs / 25.4, ys / 25.4)
            gx, gy = g_map(xm, ym)
            worst = max(worst, abs((cx * 25.4 - xs) * 1e3 - gx), abs((cy * 25.4 - ys) * 1e3 - gy))
    check(worst <= 1e-3, f"kmotion: KMotion's correction = +G within 1 nm ({worst} um), "
                         "clamped outside the map")
    check(all(v[2] == 0 for v in tab.values()), "kmotion: Z offsets 0")
rc, out, err = run("--format", "kmotion", "--map", path("M.csv"), "--axis", "x", "-o",
                   path("K2.geo"))
check(rc == 2 and len(err.strip().splitlines()) == 1 and not os.path.exists(path("K2.geo")),
      f"kmotion --axis: {rc} {err}")

E.finish("export CLI options")
