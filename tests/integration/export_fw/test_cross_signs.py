#!/usr/bin/env python3
"""The vendors' own sign rules applied to exported files, through the command line.

1. Beckhoff/ISG cross compensation of a real straightness profile (a DABAM mirror profile run
   through `selfcal simulate profile` and `selfcal profile --method lsq`, whose e_y is the stage's
   straightness error): the list is read with an independent reader of ISG's format (setpoints
   ascending, last_index = count - 1, slave and master axis numbers), ISG's linear interpolation of
   the written integers is applied with ISG's sign rule (the value is actual - setpoint, the CNC
   takes it off the setpoint: a value moves the slave axis by -value), and the slave axis' true
   position is compared with the command on a machine whose straightness error is the profile as
   selfcald applies it (`selfcal lut build` + `lut dump`: linear, clamped). Right sign: the 0.1 um
   quantization; --negate: twice the error. --travel adds the end points, without it a warning;
   the 1000-point limit and bad input give exit 2, one line, no file.
2. Siemens CEC, by Siemens' sentence for sag compensation (K3: a positive compensation value
   moves the machine axis in the negative direction): an additive map exported with the default
   sign leaves the CEC quantization; --negate doubles the error.

usage: test_cross_signs.py SELFCAL_CLI WORKDIR DABAM_DAT"""
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from exportlib import Export, interp_clamped  # noqa: E402

cli, work, dabam = sys.argv[1], sys.argv[2], sys.argv[3]
E = Export(cli, work)
check, run, path, selfcal = E.check, E.run, E.path, E.selfcal


def read_isg(name):
    """An ISG cross compensation list: header values and the table (setpoints, corrections),
    as ISG's ASCII format defines it: '# ' comment lines, 'name value' lines, end-of-line
    comments after a space."""
    hdr, sp, corr = {}, {}, {}
    for line in open(path(name)):
        if line.startswith("#") or not line.strip() or line.strip() == "End":
            continue
        key, value = line.split()[:2]
        m = re.fullmatch(r"kw\.crosscomp\.table\[(\d+)\]\.(setpoint|correction)", key)
        if m:
            (sp if m.group(2) == "setpoint" else corr)[int(m.group(1))] = int(value)
        else:
            hdr[key] = value
    return hdr, sp, corr


# A map (the plane list is written beside the cross list) and a real profile.
with open(path("M.csv"), "w") as f:
    f.write("i,j,x_mm,y_mm,gx_um,gy_um\n")
    for i in range(9):
        for j in range(9):
            x, y = -160 + 40 * j, -160 + 40 * i
            f.write(f"{i},{j},{x},{y},{0.3 * math.sin(x / 50):.6f},{0.2 * math.cos(y / 70):.6f}\n")
selfcal("simulate", "profile", "--profile", dabam, "--out", path("PIN.csv"), "--truth",
        path("PT.csv"), "--ey-um", "2", "--seed", "4")
selfcal("profile", "--method", "lsq", path("PIN.csv"), "--out", path("P.csv"))
OFF = -150.0  # the profile's x_mm = 0 at machine x = -150 mm
PROF = f"x:y:{path('P.csv')}@{OFF}"
selfcal("lut", "build", "--map", path("M.csv"), "--profile", PROF, "-o", path("P.lut"))
dump = selfcal("lut", "dump", path("P.lut")).splitlines()
k = dump.index("# profile 0: axis=x dir=y")
rows = [list(map(float, ln.split(","))) for ln in dump[k + 2:] if ln and not ln.startswith("#")]
px, pe = [r[1] for r in rows], [r[2] for r in rows]   # selfcald's profile: error of y along x
check(len(px) > 100 and max(abs(e) for e in pe) > 1.0, f"a real profile ({len(px)} points)")


def e_selfcald(x):
    return interp_clamped(px, pe, x)


def machine_error(name, travel):
    """Slave y's true - command position over the master's travel with ISG's compensation from
    the list: the command becomes setpoint - value (ISG: value = actual - setpoint), the axis then
    lands short of it by the straightness error e (indicated - true). Returns (rms, max, list)."""
    hdr, sp, corr = read_isg(name)
    n = int(hdr["kw.crosscomp.last_index"]) + 1
    xs = [sp[i] * 1e-4 for i in range(n)]
    vs = [corr[i] * 0.1 for i in range(n)]
    lo, hi = travel
    ss, worst, cnt = 0.0, 0.0, 0
    for q in range(0, 8001):
        x = lo + (hi - lo) * q / 8000
        value = interp_clamped(xs, vs, x)
        true_minus_cmd = -value - e_selfcald(x)
        ss += true_minus_cmd ** 2
        worst = max(worst, abs(true_minus_cmd))
        cnt += 1
    return math.sqrt(ss / cnt), worst, (hdr, sp, corr)


# Without --travel: the list spans the profile; a warning says ISG leaves the rest undocumented.
rc, out, err = run("--format", "beckhoff", "--map", path("M.csv"), "--profile", PROF,
                   "-o", path("B.lis"))
check(rc == 0 and os.path.exists(path("B-cross-y.lis")), f"cross list written: {rc} {err}")
check("warning" in err and "--travel" in err and "ISG does not document" in err,
      f"warning without --travel: {err}")
span = (px[0], px[-1])
rms0, max0, (hdr, sp, corr) = machine_error("B-cross-y.lis", span)
n = len(sp)
check(sorted(sp) == list(range(n)) and sorted(corr) == list(range(n)), "indices 0..n-1, each once")
check(int(hdr["kw.crosscomp.last_index"]) == n - 1, f"last_index = count - 1 ({hdr})")
check(all(sp[i] < sp[i + 1] for i in range(n - 1)), "setpoints ascend")
check(n == len(px) and sp[0] == round(px[0] * 1e4) and sp[n - 1] == round(px[-1] * 1e4),
      f"the profile's own points: {n} vs {len(px)}")
check(hdr.get("kopf.achs_nr") == "2" and hdr.get("kopf.log_achs_name") == "Y"
      and hdr.get("kw.crosscomp.master_ax_nr") == "1" and hdr.get("kw.crosscomp.unit") == "1",
      f"slave y (2), master x (1), unit 0.1 um: {hdr}")
check(max0 <= 0.05 + 1e-6 and rms0 > 0.01, f"ISG's rule, default sign: the 0.1 um quantization "
                                             f"(rms {rms0:.4f}, max {max0:.4f} um)")
m = re.search(r"residual \(controller table - profile\) over (\d+) samples: rms ([0-9.]+) um, "
              r"max ([0-9.]+) um at x = (-?[0-9.]+) mm", out)
check(m is not None and abs(float(m.group(3)) - max0) <= 2e-3
      and abs(float(m.group(2)) - rms0) <= 0.005, f"reported residual {out}")
# Sign: --negate doubles the error.
rc, out, err = run("--format", "beckhoff", "--map", path("M.csv"), "--profile", PROF, "--negate",
                   "-o", path("BN.lis"))
rmsn, maxn, _ = machine_error("BN-cross-y.lis", span)
rms_e = math.sqrt(sum(e_selfcald(span[0] + (span[1] - span[0]) * q / 8000) ** 2
                      for q in range(8001)) / 8001)
check(rc == 0 and abs(rmsn / rms_e - 2.0) < 0.01, f"--negate doubles the error: rms {rmsn:.4f} vs "
                                                  f"2 x {rms_e:.4f} um")

# With --travel: two points added at the travel ends holding the end values; the residual over
# the whole travel is the quantization.
T = (-200.0, 250.0)
rc, out, err = run("--format", "beckhoff", "--map", path("M.csv"), "--profile", PROF,
                   "--travel", f"{T[0]},{T[1]}", "--axis-numbers", "4,5", "-o", path("BT.lis"))
check(rc == 0 and "warning" not in err and "2 added at the travel ends" in out,
      f"--travel: {rc} {out} {err}")
rmst, maxt, (hdr, sp, corr) = machine_error("BT-cross-y.lis", T)
check(len(sp) == len(px) + 2 and sp[0] == -2000000 and sp[len(sp) - 1] == 2500000
      and corr[0] == corr[1] and corr[len(sp) - 1] == corr[len(sp) - 2],
      f"travel points carry the end values ({len(sp)} points)")
check(maxt <= 0.05 + 1e-6, f"over the travel: the quantization ({maxt:.4f} um)")
check(hdr.get("kopf.achs_nr") == "5" and hdr.get("kw.crosscomp.master_ax_nr") == "4",
      f"--axis-numbers: {hdr}")

# Two profiles with different master axes, one travel each (--travel AXIS:MIN,MAX): y along x
# and x along y, two lists.
rc, out, err = run("--format", "beckhoff", "--map", path("M.csv"), "--profile", PROF,
                   "--profile", f"y:x:{path('P.csv')}@-170", "--travel", "x:-200,250",
                   "--travel", "y:-180,160", "-o", path("B2.lis"))
check(rc == 0 and "warning" not in err, f"two travels: {rc} {err}")
if rc == 0:
    for name, ends, slave, master in (("B2-cross-y.lis", (-200, 250), "2", "1"),
                                      ("B2-cross-x.lis", (-180, 160), "1", "2")):
        hdr, sp, corr = read_isg(name)
        check(sp[0] == ends[0] * 10000 and sp[len(sp) - 1] == ends[1] * 10000
              and hdr["kopf.achs_nr"] == slave and hdr["kw.crosscomp.master_ax_nr"] == master,
              f"{name}: its own travel and axes ({sp[0]}, {sp[len(sp) - 1]}, {hdr})")

# ISG's 1000 points: a longer profile is refused (one line, no file), a coarser table fits.
selfcal("simulate", "profile", "--n", "1100", "--out", path("LIN.csv"), "--truth",
        path("LT.csv"), "--seed", "2")
selfcal("profile", "--method", "lsq", path("LIN.csv"), "--out", path("L.csv"))
for f in ("BL.lis", "BL-cross-y.lis"):
    if os.path.exists(path(f)):
        os.remove(path(f))
rc, out, err = run("--format", "beckhoff", "--map", path("M.csv"), "--profile",
                   f"x:y:{path('L.csv')}@-500", "-o", path("BL.lis"))
check(rc == 2 and len(err.strip().splitlines()) == 1 and "1000" in err
      and "--profile-interval" in err, f"1000 points: {rc} {err}")
check(not os.path.exists(path("BL.lis")) and not os.path.exists(path("BL-cross-y.lis")),
      "1000 points: no file at all")
rc, out, err = run("--format", "beckhoff", "--map", path("M.csv"), "--profile",
                   f"x:y:{path('L.csv')}@-500", "--profile-interval", "1.5", "-o", path("BL.lis"))
hdr, sp, corr = read_isg("BL-cross-y.lis") if rc == 0 else ({}, {}, {})
check(rc == 0 and len(sp) <= 1000 and all(sp[i] < sp[i + 1] for i in range(len(sp) - 1)),
      f"--profile-interval 1.5: {rc} {err} {len(sp)} points")

# Bad input: exit 2, one line, no file.
bad = [
    (["--profile", f"x:y:{path('missing.csv')}"], "missing"),
    (["--profile", f"x:y:{path('P.csv')}@5000"], "do not overlap"),
    (["--profile", PROF, "--travel", "0,100"], "does not contain"),
    (["--profile", PROF, "--travel", "100,-100"], "--travel"),
    (["--profile", PROF, "--travel", "abc"], "--travel"),
    (["--travel", "-200,250"], "--travel"),
    (["--profile", PROF, "--travel", "y:-200,250"], "no profile has master axis y"),
    (["--profile", PROF, "--profile", f"z:y:{path('P.csv')}"], "one master"),
]
for args, want in bad:
    for f in ("BB.lis", "BB-cross-y.lis"):
        if os.path.exists(path(f)):
            os.remove(path(f))
    rc, out, err = run("--format", "beckhoff", "--map", path("M.csv"), *args, "-o", path("BB.lis"))
    check(rc == 2 and len(err.strip().splitlines()) == 1 and want in err
          and not os.path.exists(path("BB.lis")) and not os.path.exists(path("BB-cross-y.lis")),
          f"bad {args}: {rc} {err}")

# Siemens takes the same placement: @OFFSET_MM moves the profile's table, and a profile beside
# the map is refused there too.
rc, out, err = run("--format", "siemens-cec", "--map", path("M.csv"), "--profile", PROF,
                   "-o", path("SP.mpf"))
minx = re.search(r"^\$AN_CEC_MIN\[4\]=(\S+)$", open(path("SP.mpf")).read(), re.M) if rc == 0 else None
check(minx is not None and abs(float(minx.group(1)) - px[0]) < 1e-6, f"siemens @OFFSET_MM: {err}")
if os.path.exists(path("SB.mpf")):
    os.remove(path("SB.mpf"))
rc, out, err = run("--format", "siemens-cec", "--map", path("M.csv"), "--profile",
                   f"x:y:{path('P.csv')}@5000", "-o", path("SB.mpf"))
check(rc == 2 and "do not overlap" in err and len(err.strip().splitlines()) == 1
      and not os.path.exists(path("SB.mpf")), f"siemens profile beside the map: {rc} {err}")

# Siemens CEC, by Siemens' own sentence: a positive value moves the axis negative, so the axis
# moves by -(sum of the tables of its output axis). An additive map (A(x) + B(y) per component):
# the CEC tables hold it exactly, up to their 1 nm unit.
with open(path("A.csv"), "w") as f:
    f.write("i,j,x_mm,y_mm,gx_um,gy_um\n")
    GA = {}
    for i in range(7):
        for j in range(9):
            x, y = -40 + 10 * j, 20 + 10 * i
            gx = 1.2 * math.sin(x / 17) + 0.8 * math.cos(y / 9) + 2e-2 * y
            gy = -0.9 * math.cos(x / 13) + 0.5 * math.sin(y / 11) - 1e-2 * x
            GA[(x, y)] = (round(gx, 6), round(gy, 6))
            f.write(f"{i},{j},{x},{y},{gx:.6f},{gy:.6f}\n")


def siemens_error(name):
    """True - commanded position of X and Y at the nodes with the CEC tables of the file active:
    commanded c lands at c - G(c) (G = indicated - true), and the compensation moves the axis by
    -value (Siemens K3). Returns the largest |error| and the RMS."""
    text = open(path(name)).read()
    tabs = {}
    for mm in re.finditer(r"^\$AN_CEC\[(\d+),(\d+)\]=(-?[0-9.]+)$", text, re.M):
        tabs.setdefault(int(mm.group(1)), {})[int(mm.group(2))] = float(mm.group(3))
    kv = dict(re.findall(r"^\$(AN_CEC_\w+\[\d+\])=(\S+)$", text, re.M))
    worst, ss, cnt = 0.0, 0.0, 0
    for (x, y), g in GA.items():
        for comp, name_out in ((0, "(AX1)"), (1, "(AX2)")):
            value_mm = 0.0
            for t, vals in tabs.items():
                if kv[f"AN_CEC_OUTPUT_AXIS[{t}]"] != name_out:
                    continue
                pos = x if kv[f"AN_CEC_INPUT_AXIS[{t}]"] == "(AX1)" else y
                lo, st = float(kv[f"AN_CEC_MIN[{t}]"]), float(kv[f"AN_CEC_STEP[{t}]"])
                xs = [lo + st * q for q in range(len(vals))]
                value_mm += interp_clamped(xs, [vals[q] for q in range(len(vals))], pos)
            err_um = -g[comp] - 1e3 * value_mm
            worst, ss, cnt = max(worst, abs(err_um)), ss + err_um ** 2, cnt + 1
    return worst, math.sqrt(ss / cnt)


rms_g = math.sqrt(sum(g[0] ** 2 + g[1] ** 2 for g in GA.values()) / (2 * len(GA)))
rc, out, err = run("--format", "siemens-cec", "--map", path("A.csv"), "-o", path("S.mpf"))
worst, rms = siemens_error("S.mpf") if rc == 0 else (1e9, 1e9)
check(rc == 0 and worst <= 1.5e-3, f"Siemens' rule, default sign: within the 1 nm unit "
                                   f"({worst * 1e3:.3f} nm)")
rc, out, err = run("--format", "siemens-cec", "--map", path("A.csv"), "--negate", "-o",
                   path("SN.mpf"))
worst, rms = siemens_error("SN.mpf") if rc == 0 else (0, 0)
check(rc == 0 and abs(rms / rms_g - 2.0) < 0.01, f"Siemens --negate doubles the error: rms "
                                                 f"{rms:.4f} vs 2 x {rms_g:.4f} um")

E.finish("export signs (ISG cross compensation, Siemens CEC)")
