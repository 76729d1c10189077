#!/usr/bin/env python3
"""selfcal_xy's enable, ramp-ms and max-correction (SPEC §7a, docs/linuxcnc.md) and the exact
inverse of the command chain, under LinuxCNC's own halrun (POSIX non-realtime), run as
test_hal.py runs it (halenv.py).

Ramp: the servo thread is stopped (halcmd stop) whenever inputs change or outputs are read, and a
sum2 wired as a counter (out = previous out + 1, in the same thread) says how many periods ran in
between (halenv.run_periods runs the thread for at least N of them, however loaded the
machine), so the fraction f expected after them is exact: f moves by period / ramp-ms per period
towards enable's side. Checked: f = 0 and out = in from the first period when enable starts FALSE;
the ramp in (0 < f < 1, status bit 3, correction = f times the full one); f = 1 (bit 3 clear,
the full correction); the ramp out; ramp-ms 0 (at once, both ways); max-correction (the clamped
component, status bit 4). The correction is read as 1000 (out - in) through sum2 (picometres in
getp's 7 digits), against an independent evaluation of `selfcal lut dump` (sclib.py).

Exact inverse: a map with slopes of 0.01 (`lut info` says so); commanded positions go through a
position instance, its output (the drive's position) through a measure-exact instance; the chain's
error, fb - cmd, read in nanometres through sum2, must be <= 1 nm at every point, also while the
correction ramps and when it is clamped; through a measure instance it is G' G, here tens of
nanometres (the check that the test sees it).

usage: test_hal_ramp.py SELFCAL_CLI SELFCAL_XY_SO WORKDIR"""
import math
import os
import random
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "modbus"))
from halenv import HalEnv  # noqa: E402
from sclib import Table, check, make_table  # noqa: E402

cli, module, work = sys.argv[1], sys.argv[2], sys.argv[3]
env = HalEnv(module, work)
FLOAT = r"[-+]?(?:\d+\.?\d*(?:[eE][-+]?\d+)?|nan|inf)"
PERIOD_MS = 1.0


def values(out):
    return [t for t in out.split() if re.fullmatch(FLOAT, t, re.IGNORECASE)]


# ---------------------------------------------------------------- enable, ramp-ms, max-correction
table, ref = make_table(cli, work, "ramp", n=11, pitch=2.0, scale_um=3.0)
table = env.public(table)
X, Y = 3.3, -1.7  # mm: inside the grid
ex, ey, _ = ref.correct_nm(X * 1e6, Y * 1e6, "position")
CX, CY = (ex - X * 1e6) * 1e-3, (ey - Y * 1e6) * 1e-3  # the full correction, um
check(abs(CX) > 0.5 and abs(CY) > 0.5 and abs(abs(CX) - abs(CY)) > 0.2,
      f"the test point has a correction to see: ({CX}, {CY}) um")
RAMP_MS = 2000.0  # long: on a loaded machine run_periods may overshoot by hundreds of periods
LIM_UM = 0.5 * (abs(CX) + abs(CY))  # clamps the larger component only

# Each step: (pin settings while stopped, periods to run at least, what is expected afterwards).
steps = [
    (["setp selfcal-xy.0.enable 0"], 5, "off"),            # FALSE from the first period
    (["setp selfcal-xy.0.enable 1"], 20, "ramp_in"),
    ([], int(RAMP_MS / PERIOD_MS), "full"),
    (["setp selfcal-xy.0.enable 0"], 30, "ramp_out"),
    (["setp selfcal-xy.0.ramp-ms 0"], 1, "off"),           # the rest of the ramp at once
    (["setp selfcal-xy.0.enable 1"], 1, "full"),           # in at once
    ([f"setp selfcal-xy.0.max-correction {LIM_UM * 1e-3:.9f}"], 1, "clamped"),
    (["setp selfcal-xy.0.max-correction 0"], 1, "full"),
]
lines = [f"loadrt selfcal_xy table={table}", "loadrt sum2 count=3",
         "loadrt threads name1=servo period1=1000000",
         "addf sum2.2 servo", "addf selfcal-xy.0 servo", "addf sum2.0 servo", "addf sum2.1 servo",
         "net cnt sum2.2.out sum2.2.in0", "setp sum2.2.in1 1",        # period counter
         "net xin selfcal-xy.0.x-in sum2.0.in1", "net xout selfcal-xy.0.x-out sum2.0.in0",
         "net yin selfcal-xy.0.y-in sum2.1.in1", "net yout selfcal-xy.0.y-out sum2.1.in0",
         "setp sum2.0.gain0 1000", "setp sum2.0.gain1 -1000",
         "setp sum2.1.gain0 1000", "setp sum2.1.gain1 -1000",
         f"sets xin {X}", f"sets yin {Y}",
         "getp selfcal-xy.0.enable", "getp selfcal-xy.0.ramp-ms",
         "getp selfcal-xy.0.max-correction",                            # the defaults
         f"setp selfcal-xy.0.ramp-ms {RAMP_MS}"]
for settings, periods, _ in steps:
    lines += settings + [env.run_periods("sum2.2.out", periods),
                         "loadusr -w sleep 0.02",  # a period under way when stop came ends
                         "getp sum2.2.out", "getp selfcal-xy.0.fraction", "getp sum2.0.out",
                         "getp sum2.1.out", "getp selfcal-xy.0.status",
                         "getp selfcal-xy.0.x-out"]
rc, out, err = env.halrun(lines, "ramp")
check(rc == 0, f"halrun ramp failed ({rc}):\n{out}\n{err}")
toks = out.split()
check(toks[:3] == ["TRUE", "100", "0"], f"defaults enable, ramp-ms, max-correction: {toks[:3]}")
v = values(" ".join(toks[3:]))
check(len(v) == 6 * len(steps), f"expected {6 * len(steps)} values:\n{out}")


def sig7(x):
    return 0.5 * 10 ** (math.floor(math.log10(abs(x))) - 6) if x else 1e-300


f_model, ramp_ms, n_prev, enable = None, RAMP_MS, 0, True
for k, (settings, periods, what) in enumerate(steps):
    cnt, frac, cx, cy, st, xo = (float(t) for t in v[6 * k: 6 * k + 6])
    st = int(st)
    n = int(cnt) - n_prev
    n_prev = int(cnt)
    for s in settings:
        name, val = s.split()[1], s.split()[2]
        if name.endswith(".enable"):
            enable = val == "1"
        elif name.endswith(".ramp-ms"):
            ramp_ms = float(val)
    check(n >= periods, f"step {k} ({what}): the servo thread ran {n} periods, not {periods}")
    target = 1.0 if enable else 0.0
    if f_model is None:  # the first period starts f at enable's value
        f_model, n = target, n - 1
    step = 1.0 if ramp_ms <= 0 else PERIOD_MS / ramp_ms
    f_model = min(target, f_model + n * step) if f_model < target else max(target, f_model - n * step)
    check(abs(frac - f_model) <= 1e-6, f"step {k} ({what}): fraction {frac}, want {f_model} "
          f"after {n} periods")
    want_st = 1 | (8 if f_model < 1 else 0) | (16 if what == "clamped" else 0)
    check(st == want_st, f"step {k} ({what}): status {st}, want {want_st}")
    wcx, wcy = f_model * CX, f_model * CY
    if what == "clamped":
        wcx = math.copysign(min(abs(CX), LIM_UM), CX)
        wcy = math.copysign(min(abs(CY), LIM_UM), CY)
    for got, want, axis in ((cx, wcx, "x"), (cy, wcy, "y")):
        check(abs(got - want) <= 1e-5 + sig7(got), f"step {k} ({what}): correction {axis} {got} um, "
              f"want {want} um (f = {f_model})")
    if what == "off":
        check(xo == X, f"step {k}: disabled, x-out {xo} != x-in {X} exactly")
    if what == "ramp_in" or what == "ramp_out":
        check(0 < f_model < 1, f"step {k} ({what}): the ramp was over before the check "
              f"({n} periods)")
    if what == "full":
        check(f_model == 1, f"step {k}: f = {f_model} after {n} periods, not yet 1")
print(f"enable/ramp-ms/max-correction: {len(steps)} steps as SPEC §7a (full correction "
      f"({CX:.4f}, {CY:.4f}) um, ramp {RAMP_MS} ms, clamp {LIM_UM:.4f} um)")

# -------------------------------------------------------------- the exact inverse, slopes of 0.01
mp = os.path.join(work, "steep_map.csv")
with open(mp, "w") as f:
    f.write("i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n")
    for i in range(41):
        for j in range(41):
            x, y = (j - 20) * 0.25, (i - 20) * 0.25
            f.write(f"{i},{j},{x:.6f},{y:.6f},{10 * math.sin(x):.6f},"
                    f"{6 * math.cos(0.5 * y + 0.2 * x):.6f},,\n")
steep = os.path.join(work, "steep.lut")
subprocess.run([cli, "lut", "build", "--map", mp, "-o", steep], check=True, capture_output=True)
info = subprocess.run([cli, "lut", "info", steep], check=True, capture_output=True, text=True).stdout
slope = float(re.search(r"largest slope of G: (\S+)", info).group(1))
check(slope > 0.0099, f"the steep map's largest slope {slope}, want ~0.01")
steep_ref = Table(subprocess.run([cli, "lut", "dump", steep], check=True, capture_output=True,
                                 text=True).stdout)
steep = env.public(steep)
rng = random.Random(40)
pts = [(0.0, 0.0), (1.5707, 0.3), (-1.6, -2.2), (4.99, 4.99), (-4.2, 3.14)]
pts += [(round(rng.uniform(-4.9, 4.9), 6), round(rng.uniform(-4.9, 4.9), 6)) for _ in range(10)]
lines = [f"loadrt selfcal_xy count=3 table={steep} mode=position,measure-exact,measure",
         "loadrt sum2 count=5", "loadrt threads name1=servo period1=1000000",
         "addf sum2.4 servo", "addf selfcal-xy.0 servo", "addf selfcal-xy.1 servo",
         "addf selfcal-xy.2 servo", "addf sum2.0 servo", "addf sum2.1 servo", "addf sum2.2 servo",
         "addf sum2.3 servo",
         "net cnt sum2.4.out sum2.4.in0", "setp sum2.4.in1 1",
         # cmd -> position -> drive -> measure-exact (and measure) -> fb; fb - cmd in nm
         "net xcmd selfcal-xy.0.x-in sum2.0.in1 sum2.2.in1",
         "net ycmd selfcal-xy.0.y-in sum2.1.in1 sum2.3.in1",
         "net xdrive selfcal-xy.0.x-out selfcal-xy.1.x-in selfcal-xy.2.x-in",
         "net ydrive selfcal-xy.0.y-out selfcal-xy.1.y-in selfcal-xy.2.y-in",
         "net xfb selfcal-xy.1.x-out sum2.0.in0", "net yfb selfcal-xy.1.y-out sum2.1.in0",
         "net xfb1 selfcal-xy.2.x-out sum2.2.in0", "net yfb1 selfcal-xy.2.y-out sum2.3.in0"]
lines += [f"setp sum2.{k}.gain0 1e6\nsetp sum2.{k}.gain1 -1e6" for k in range(4)]
for x, y in pts:
    lines += [f"sets xcmd {x}", f"sets ycmd {y}", env.run_periods("sum2.4.out", 2),
              "loadusr -w sleep 0.02", "getp sum2.4.out"] + [f"getp sum2.{k}.out" for k in range(4)]
# the chain stays exact while the correction ramps (both instances at the same f) and when it is
# clamped: measure-exact inverts what the position instance outputs, t + f clamp(C(t))
x, y = pts[1]
lines += [f"sets xcmd {x}", f"sets ycmd {y}"]
for k in (0, 1):
    lines += [f"setp selfcal-xy.{k}.ramp-ms {RAMP_MS}", f"setp selfcal-xy.{k}.enable 0"]
lines += [env.run_periods("sum2.4.out", 60), "loadusr -w sleep 0.02", "getp selfcal-xy.0.fraction",
          "getp selfcal-xy.1.fraction", "getp sum2.0.out", "getp sum2.1.out"]
for k in (0, 1):
    lines += [f"setp selfcal-xy.{k}.max-correction 0.003", f"setp selfcal-xy.{k}.enable 1"]
lines += [env.run_periods("sum2.4.out", int(RAMP_MS / PERIOD_MS) + 100), "loadusr -w sleep 0.02",
          "getp selfcal-xy.0.fraction",
          "getp selfcal-xy.0.status", "getp sum2.0.out", "getp sum2.1.out"]
rc, out, err = env.halrun(lines, "exact_chain")
check(rc == 0, f"halrun exact chain failed ({rc}):\n{out}\n{err}")
v = [float(t) for t in values(out)]
check(len(v) == 5 * len(pts) + 8, f"exact chain: expected {5 * len(pts) + 8} values:\n{out}")
f0, f1, rx, ry, f_end, st_end, cx_end, cy_end = v[-8:]
check(0 < f0 < 1 and f0 == f1, f"ramping: fractions {f0}, {f1}, want equal and in (0, 1)")
check(math.hypot(rx, ry) <= 1.0, f"exact chain while ramping (f = {f0}): fb - cmd = ({rx}, {ry}) nm")
check(f_end == 1 and int(st_end) & 16, f"clamped: fraction {f_end}, status {st_end}")
check(math.hypot(cx_end, cy_end) <= 1.0, f"exact chain clamped to 3 um: ({cx_end}, {cy_end}) nm")
worst_exact = worst_first = 0.0
cnt_prev = 0
for k, (x, y) in enumerate(pts):
    cnt, ex_x, ex_y, m_x, m_y = v[5 * k: 5 * k + 5]
    check(cnt > cnt_prev, f"exact chain: the thread did not run for point {k}")
    cnt_prev = cnt
    e = math.hypot(ex_x, ex_y)
    worst_exact = max(worst_exact, e)
    check(e <= 1.0, f"exact chain at ({x}, {y}) mm: fb - cmd = ({ex_x}, {ex_y}) nm, over 1 nm")
    # the first-order chain's error is G' G: the independent evaluation says how much
    px, py, _ = steep_ref.correct_nm(x * 1e6, y * 1e6, "position")
    qx, qy, _ = steep_ref.correct_nm(px, py, "measure")
    check(abs(m_x - (qx - x * 1e6)) <= 1e-3 + sig7(m_x) and abs(m_y - (qy - y * 1e6)) <= 1e-3 + sig7(m_y),
          f"measure chain at ({x}, {y}): ({m_x}, {m_y}) nm, want ({qx - x * 1e6}, {qy - y * 1e6})")
    worst_first = max(worst_first, math.hypot(m_x, m_y))
check(worst_first > 20.0, f"the measure chain's error G' G should show on this map: {worst_first} nm")
print(f"map slope {slope:.5f}: cmd -> position -> measure-exact -> fb within {worst_exact:.4f} nm "
      f"over {len(pts)} points (measure: up to {worst_first:.1f} nm); while ramping (f = {f0}) "
      f"{math.hypot(rx, ry):.4f} nm, clamped {math.hypot(cx_end, cy_end):.4f} nm")
env.close()
print("PASS")
