#!/usr/bin/env python3
"""The example machine examples/linuxcnc (selfcal_sim.ini) run by LinuxCNC itself: milltask,
motion, the trajectory planner and a 1 ms servo thread (POSIX non-realtime), driven headless by
its DISPLAY program selfcal_drive.py through the `linuxcnc` Python module (Debian's
linuxcnc-uspace), with this build's selfcal_xy.so (run as test_hal.py runs halrun: halenv.py).

The table is built from examples/linuxcnc/stage_map.csv with the CLI. The machine is started
twice, from two power-up positions of its simulated stage (0, 0) and (3.3, -2.7) mm; each time the
driver homes both axes on their home switches, ramps the correction in and moves to one machine
position; the first time it also runs selfcal_sim.ngc (23 dwells, 20 inside and 3 outside the map,
then lines at F1000 across the map and its edge), recording every servo period. Asserted:
- the home offsets are exact: motor-offset = switch - power-up position - HOME_OFFSET (1 nm);
- homing saw uncorrected positions (f = 0 until all joints are homed), then the correction
  ramped in by one period / RAMP_MS per period, without a step;
- the same frame after both power-ups: the stage at the same machine position within 1 nm;
- at every dwell the correction (x-out - x-in) matches an independent bilinear evaluation of
  `selfcal lut dump` to 1 nm, and so does every period on the lines; no step on a line (the
  change per period within the map's largest slope times the distance moved);
- the following error at rest is at most 1 nm (feedback through measure-exact);
- outside the map, status bit 1; unhomed at the end: the correction ramps out (f = 0, bit 3);
- a missing table stops LinuxCNC with selfcal_xy's message in ~/linuxcnc_debug.txt.

usage: test_machine.py SELFCAL_CLI SELFCAL_XY_SO WORKDIR"""
import configparser
import json
import math
import os
import re
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "modbus"))
from halenv import HalEnv  # noqa: E402
from sclib import Table  # noqa: E402

cli, module, work = sys.argv[1], sys.argv[2], sys.argv[3]
EXAMPLE = os.path.join(HERE, "..", "..", "..", "examples", "linuxcnc")
if not shutil.which("linuxcnc") or not os.path.exists("/usr/lib/python3/dist-packages/linuxcnc."
                                                      "cpython-311-x86_64-linux-gnu.so") and \
        subprocess.run(["/usr/bin/python3", "-c", "import linuxcnc"], capture_output=True).returncode:
    print("SKIP: LinuxCNC (the linuxcnc script and its Python module) is not installed")
    sys.exit(77)
env = HalEnv(module, work)
failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print("FAIL:", what)


ini = configparser.ConfigParser(inline_comment_prefixes=("#",), strict=False)
ini.read(os.path.join(EXAMPLE, "selfcal_sim.ini"))
HOME_OFFSET = [float(ini["JOINT_0"]["HOME_OFFSET"]), float(ini["JOINT_1"]["HOME_OFFSET"])]
RAMP_MS = float(ini["SELFCAL"]["RAMP_MS"])
PERIOD_MS = float(ini["EMCMOT"]["SERVO_PERIOD"]) * 1e-6


def machine(name, powerup, program, table=None):
    """Copies the example, builds its table, runs `linuxcnc selfcal_sim.ini` as the HAL user;
    returns (exit status, the driver's result or None, the samples, the config folder)."""
    cfg = os.path.join(env.scratch, name)
    shutil.copytree(EXAMPLE, cfg)
    subprocess.run([cli, "lut", "build", "--map", os.path.join(cfg, "stage_map.csv"), "-o",
                    os.path.join(cfg, "stage.lut")], check=True, capture_output=True)
    if table is not None:
        text = open(os.path.join(cfg, "selfcal_sim.ini")).read()
        text = re.sub(r"(?m)^TABLE = .*$", f"TABLE = {table}", text)
        open(os.path.join(cfg, "selfcal_sim.ini"), "w").write(text)
    for root, dirs, files in os.walk(cfg):
        for d in dirs:
            os.chmod(os.path.join(root, d), 0o777)
        for f in files:
            os.chmod(os.path.join(root, f), 0o666 if not f.endswith(".py") else 0o777)
    os.chmod(cfg, 0o777)
    run_env = dict(os.environ, SELFCAL_POWERUP_MM=powerup, SELFCAL_PROGRAM=program,
                   PATH="/usr/bin:/bin:/usr/sbin:/sbin")
    for k in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV"):
        run_env.pop(k, None)
    p = subprocess.run(env.argv("linuxcnc selfcal_sim.ini", cwd=cfg), capture_output=True,
                       text=True, timeout=240, env=run_env)
    keep = os.path.join(work, name)
    shutil.rmtree(keep, ignore_errors=True)
    shutil.copytree(cfg, keep, ignore=shutil.ignore_patterns("*.samples"))
    with open(os.path.join(work, name + ".log"), "w") as f:
        f.write(f"exit {p.returncode}\n--- stdout\n{p.stdout}\n--- stderr\n{p.stderr}")
    res_path = os.path.join(cfg, "selfcal_drive.json")
    res = json.load(open(res_path)) if os.path.exists(res_path) else None
    # samples: [x-in mm, y-in mm, cx um, cy um, x f-error nm, y f-error nm, f, x stage mm,
    # status, sample number]; a gap in the numbers is samples lost (halsampler read too late)
    samples = []
    sp = os.path.join(cfg, "selfcal_drive.samples")
    if os.path.exists(sp):
        for line in open(sp):
            t = line.split()
            if len(t) == 10:
                samples.append([float(v) for v in t[1:9]] + [int(t[9]), int(t[0])])
        lost = sum(b[9] - a[9] - 1 for a, b in zip(samples, samples[1:]))
        print(f"run {name}: {len(samples)} samples recorded, {lost} lost")
        if lost:
            shutil.copy(sp, os.path.join(work, name + ".samples"))
    return p, res, samples, cfg


lut = os.path.join(work, "stage.lut")
subprocess.run([cli, "lut", "build", "--map", os.path.join(EXAMPLE, "stage_map.csv"), "-o", lut],
               check=True, capture_output=True)
ref = Table(subprocess.run([cli, "lut", "dump", lut], check=True, capture_output=True,
                           text=True).stdout)
info = subprocess.run([cli, "lut", "info", lut], check=True, capture_output=True, text=True).stdout
SLOPE = float(re.search(r"slope <= (\S+)", info).group(1))

runs = {}
for name, powerup, program in (("a", "0,0", "selfcal_sim.ngc"), ("b", "3.3,-2.7", "none")):
    p, res, samples, cfg = machine(name, powerup, program)
    check(p.returncode == 0 and res and res.get("ok"),
          f"run {name}: linuxcnc exit {p.returncode}, driver {res and res.get('error')}:\n"
          f"{p.stdout[-2000:]}\n{p.stderr[-2000:]}")
    if not res or not res.get("ok"):
        continue
    runs[name] = (res, samples)
    p0 = [float(v) for v in powerup.split(",")]
    # the home offsets: the switch's stage position - the power-up position - HOME_OFFSET
    for j, sw in ((0, "x-home-sw.in0"), (1, "y-home-sw.in0")):
        want = res["homed"][sw] - p0[j] - HOME_OFFSET[j]
        got = res["homed"][f"joint.{j}.motor-offset"]
        check(abs(got - want) <= 1e-6, f"run {name}: joint {j} motor-offset {got!r}, want {want!r}")
    fr = res["frame"]
    check(abs(fr["joint.0.f-error"]) <= 1e-6 and abs(fr["joint.1.f-error"]) <= 1e-6,
          f"run {name}: following error at rest {fr['joint.0.f-error']}, {fr['joint.1.f-error']} mm")
    check(res["unhomed"]["selfcal-xy.0.fraction"] == 0 and res["unhomed"]["selfcal-xy.0.status"] & 8,
          f"run {name}: unhomed: {res['unhomed']}")
    # homing saw uncorrected positions: from the first period with f = 0 (the thread may have run
    # before the HAL file connected enable) to the ramp, f = 0 and status bit 3
    fr_col = [s[6] for s in samples]
    check(len(samples) > 1000, f"run {name}: {len(samples)} samples")
    if len(samples) > 1000:
        k0 = fr_col.index(0.0)
        k1 = next(k for k in range(k0, len(fr_col)) if fr_col[k] > 0)
        check(all(s[8] & 8 for s in samples[k0:k1]), f"run {name}: status bit 3 while f = 0")
        # the ramp in: f grows by one period / RAMP_MS per period, the correction with it
        step = PERIOD_MS / RAMP_MS
        t_end = samples[k1 - 1][9] + int(round(1 / step))  # the period the ramp ends in
        k2 = next((k for k in range(k1, len(samples)) if samples[k][9] >= t_end), len(samples) - 1)
        ramp = samples[k1 - 1: k2 + 1]
        fs = [s[6] for s in ramp]
        # per period (n: periods between two samples, 1 unless samples were lost)
        check(all(abs((b[6] - a[6]) - n * step) <= 1e-6 or (b[6] == 1.0 and a[6] < 1.0)
                  for a, b in zip(ramp, ramp[1:]) if a[6] < 1.0 for n in [b[9] - a[9]]),
              f"run {name}: ramp in {fs[:5]} ... {fs[-5:]}")
        check(fs[-1] == 1.0, f"run {name}: f = {fs[-1]} after the ramp")
        cmax = max(abs(c) for s in ramp for c in s[2:4])
        check(all(abs(b[2] - a[2]) <= n * step * cmax + 1e-5 and
                  abs(b[3] - a[3]) <= n * step * cmax + 1e-5
                  for a, b in zip(ramp, ramp[1:]) for n in [b[9] - a[9]]),
              f"run {name}: a step in the ramp")
        print(f"run {name}: power-up {powerup}: home offsets exact, f = 0 while homing "
              f"({k1 - k0} periods), ramp in over {ramp[-1][9] - ramp[0][9] - 1} periods")

if "a" in runs and "b" in runs:
    fa, fb = runs["a"][0]["frame"], runs["b"][0]["frame"]
    dx = (fa["x-stage.out"] - fb["x-stage.out"]) * 1e6
    dy = (fa["y-stage.out"] - fb["y-stage.out"]) * 1e6
    check(abs(dx) <= 1 and abs(dy) <= 1, f"frames after two power-ups differ by ({dx}, {dy}) nm")
    print(f"two power-ups, homed on switches: the same frame within ({dx:.2e}, {dy:.2e}) nm")

if "a" in runs:
    samples = runs["a"][1]
    # every period with the full correction: the correction matches the map (1 nm)
    worst = 0.0
    n_full = 0
    for s in samples:
        if s[6] != 1.0:
            continue
        n_full += 1
        ex, ey, outside = ref.correct_nm(s[0] * 1e6, s[1] * 1e6, "position")
        ecx, ecy = ex * 1e-3 - s[0] * 1e3, ey * 1e-3 - s[1] * 1e3
        # x-in is recorded to 1 nm: the map moves by at most SLOPE x 0.5 nm under it
        err = max(abs(s[2] - ecx), abs(s[3] - ecy))
        worst = max(worst, err)
        if err > 1e-3:
            check(False, f"correction at ({s[0]}, {s[1]}) mm: ({s[2]}, {s[3]}) um, want "
                  f"({ecx}, {ecy}) um")
            break
        check(bool(s[8] & 2) == outside, f"status {s[8]} at ({s[0]}, {s[1]}): outside {outside}")
    print(f"{n_full} periods with the full correction: within {worst * 1e6:.2f} pm of the map")
    # dwells: 100 or more periods at one commanded position (the program dwells 400 ms of task time;
    # a loaded machine may run fewer servo periods in it)
    dwells, k = [], 0
    while k < len(samples):
        m = k
        while m + 1 < len(samples) and samples[m + 1][0:2] == samples[k][0:2]:
            m += 1
        if samples[m][9] - samples[k][9] >= 100 and samples[k][6] == 1.0:
            dwells.append((k, m))
        k = m + 1
    prog = [tuple(float(v) for v in re.findall(r"X(\S+) Y(\S+)", ln)[0])
            for ln in open(os.path.join(EXAMPLE, "selfcal_sim.ngc")) if ln.startswith("G1 X")
            and "F2400" in ln]
    seen = {(round(samples[k][0], 4), round(samples[k][1], 4)) for k, _ in dwells}
    missing = [pt for pt in prog if (round(pt[0], 4), round(pt[1], 4)) not in seen]
    check(len(prog) == 23 and not missing, f"dwells of the program not recorded: {missing} "
          f"(dwells seen: {sorted(seen)})")
    n_out = sum(1 for k, _ in dwells if samples[k][8] & 2)
    check(n_out >= 3, f"{n_out} dwells outside the map, want 3")
    worst_fe = 0.0
    for k, m in dwells:
        for s in samples[k + 20: m + 1]:  # at rest: from 20 periods into the dwell
            worst_fe = max(worst_fe, abs(s[4]), abs(s[5]))
    check(worst_fe <= 1.0, f"following error at rest up to {worst_fe} nm")
    print(f"{len(dwells)} dwells ({n_out} outside the map): following error at rest <= "
          f"{worst_fe:.4f} nm")
    # no step on the lines: per period, the correction changes by at most the map's largest
    # slope times the distance moved (plus the recording's 1 nm rounding of the position)
    worst_ratio, n_moving = 0.0, 0
    for a, b in zip(samples, samples[1:]):
        if a[6] != 1.0 or b[6] != 1.0 or a[0:2] == b[0:2] or b[9] != a[9] + 1:
            continue
        n_moving += 1
        dist_um = (abs(b[0] - a[0]) + abs(b[1] - a[1])) * 1e3
        bound = SLOPE * (dist_um + 2e-3) + 1e-5
        jump = max(abs(b[2] - a[2]), abs(b[3] - a[3]))
        worst_ratio = max(worst_ratio, jump / bound)
        if jump > bound:
            check(False, f"a step of {jump} um between ({a[0]}, {a[1]}) and ({b[0]}, {b[1]})")
            break
    check(n_moving > 3000, f"only {n_moving} moving periods recorded")
    print(f"{n_moving} moving periods: no step (largest change {worst_ratio:.3f} of slope x "
          f"distance, slope {SLOPE:.3e})")

# a missing table: LinuxCNC stops at loadrt, selfcal_xy's message in ~/linuxcnc_debug.txt
p, res, samples, cfg = machine("c", "0,0", "none", table="/nonexistent/stage.lut")
dbg = os.path.join(env.home, "linuxcnc_debug.txt")
text = open(dbg).read() if os.path.exists(dbg) else ""
with open(os.path.join(work, "c_linuxcnc_debug.txt"), "w") as f:
    f.write(text)
check(res is None, "run c: the driver ran with a missing table")
check("selfcal_xy: table=/nonexistent/stage.lut: cannot open" in text,
      f"run c: linuxcnc_debug.txt does not have selfcal_xy's message:\n{text[-1500:]}\n"
      f"{p.stdout[-1000:]}\n{p.stderr[-1000:]}")
print("missing table: LinuxCNC stops, the reason in ~/linuxcnc_debug.txt")

env.close()
if failures:
    print(f"{len(failures)} failure(s)")
    sys.exit(1)
print("PASS")
