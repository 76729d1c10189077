#!/usr/bin/env python3
"""The LinuxCNC HAL component selfcal_xy (SPEC §7) under LinuxCNC's own halrun, in POSIX
non-realtime mode.

A table is built with the real CLI (a grid and two straightness profiles). halrun loads the
component, sets x-in and y-in, and reads x-out, y-out and status back with `halcmd getp`; the
outputs are compared with an independent Python evaluation of `selfcal lut dump` (bilinear,
clamped, linear profiles: tests/integration/modbus/sclib.py) and with what selfcald answers over
Modbus TCP for the same table, mode and positions. Bad loads (missing, corrupt and truncated
table, no table, an unknown mode) must make loadrt fail with the reason in the log.

`halcmd getp` prints 7 significant digits, which for a position of 10 mm is 1 um: too coarse. So
the correction itself is also read, through LinuxCNC's sum2 component computing
1000 * (out - in) in double precision in the same thread: 7 digits of a correction of a few um are
picometres.

halrun refuses to run as root and rtapi_app loads modules only from its fixed module folder
(`loadrt` takes no paths). As root, the test runs halrun as the unprivileged user `nobody`
(created with useradd if missing) in a private mount namespace where the module folder is an
overlay of our build's module over the system's (nothing outside the namespace changes). An
unprivileged user with password-less sudo (a CI runner) gets the same namespace through sudo and
runs halrun as itself. Otherwise it runs only if the installed module is this build's (else
exit 77: skipped).

usage: test_hal.py SELFCAL_CLI SELFCAL_XY_SO WORKDIR [SELFCALD]"""
import fcntl
import filecmp
import math
import os
import pwd
import random
import re
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "modbus"))
from sclib import Daemon, check, i32_to_regs, make_table, regs_to_i32  # noqa: E402

MODULE_DIR = "/usr/lib/linuxcnc/modules"  # rtapi_app's fixed folder (Debian linuxcnc-uspace)

cli, module, work = sys.argv[1], sys.argv[2], sys.argv[3]
# One HAL session per machine (one shared memory, one rtapi_app): other builds' runs of this test
# on the same machine wait here (CTest's RESOURCE_LOCK only covers one ctest process).
machine_lock = os.open("/tmp/selfcal-linuxcnc-hal.lock", os.O_RDONLY | os.O_CREAT, 0o644)
fcntl.flock(machine_lock, fcntl.LOCK_EX)  # read-only is enough for flock, whoever made the file
selfcald = sys.argv[4] if len(sys.argv) > 4 else None
os.makedirs(work, exist_ok=True)

# A world-readable scratch folder (the build folder may not be readable by the HAL user).
scratch = tempfile.mkdtemp(prefix="selfcal-hal-")
os.chmod(scratch, 0o755)
mods = os.path.join(scratch, "modules")
os.mkdir(mods)
shutil.copy(module, os.path.join(mods, "selfcal_xy.so"))
os.chmod(os.path.join(mods, "selfcal_xy.so"), 0o644)
home = os.path.join(scratch, "home")
os.mkdir(home)


def hal_user():
    """The unprivileged user halrun runs as: nobody, created if this machine has none."""
    try:
        return pwd.getpwnam("nobody")
    except KeyError:
        subprocess.run(["useradd", "--system", "--no-create-home", "--shell", "/usr/sbin/nologin",
                        "nobody"], check=True)
        return pwd.getpwnam("nobody")


def can_sudo():
    try:
        return subprocess.run(["sudo", "-n", "true"], capture_output=True, timeout=20).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def namespaced(prefix, user):
    """halrun as `user` in a private mount namespace where the module folder is an overlay of
    this build's module over the system's; prefix: [] as root, ["sudo", "-n"] otherwise."""
    def argv(hal_file):
        inner = (f"mount -t overlay overlay -o lowerdir={mods}:{MODULE_DIR} {MODULE_DIR} && "
                 f"exec setpriv --reuid={user.pw_uid} --regid={user.pw_gid} --clear-groups "
                 f"env HOME={home} halrun -f {hal_file}")
        return prefix + ["unshare", "--mount", "--propagation", "private", "sh", "-c", inner]
    return argv


installed = os.path.join(MODULE_DIR, "selfcal_xy.so")
if os.geteuid() == 0:
    user = hal_user()
    os.chown(home, user.pw_uid, user.pw_gid)
    halrun_argv = namespaced([], user)
elif can_sudo():
    # An unprivileged user with sudo (a CI runner): the namespace needs root, halrun runs as us.
    halrun_argv = namespaced(["sudo", "-n"], pwd.getpwuid(os.getuid()))
elif os.path.exists(installed) and filecmp.cmp(installed, module, shallow=False):
    def halrun_argv(hal_file):
        return ["env", f"HOME={home}", "halrun", "-f", hal_file]
else:
    print(f"SKIP: not root, no sudo, and {installed} is not this build's module "
          "(rtapi_app loads modules from that folder only)")
    shutil.rmtree(scratch)
    sys.exit(77)


def halrun(lines, name):
    """Runs a .hal script with halrun; returns (exit status, stdout, stderr)."""
    path = os.path.join(scratch, name + ".hal")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    os.chmod(path, 0o644)
    p = subprocess.run(halrun_argv(path), capture_output=True, text=True, timeout=120)
    with open(os.path.join(work, name + ".log"), "w") as f:
        f.write(f"exit {p.returncode}\n--- stdout\n{p.stdout}\n--- stderr\n{p.stderr}")
    return p.returncode, p.stdout, p.stderr


def public(path):
    dst = os.path.join(scratch, os.path.basename(path))
    shutil.copyfile(path, dst)
    os.chmod(dst, 0o644)
    return dst


# The table: a grid of +-10 mm (11 x 11, pitch 2 mm) and two profiles that extend beyond it.
table, ref = make_table(cli, work, "hal", profiles=("x:y", "y:x"), n=11, pitch=2.0, scale_um=3.0)
table = public(table)
check(len(ref.profiles) == 2, "the table has two profiles")

rng = random.Random(20261123)
points = [(0, 0), (2_000_000, -4_000_000), (1_000_000, 3_000_000),    # nodes, cell middle
          (9_999_999, -9_999_999), (10_000_000, 10_000_000),          # the grid's corner
          (13_500_001, 2_250_000), (-11_000_000, -12_345_678),        # outside: clamped
          (-3_000_000, 14_000_123)]
points += [(rng.randint(-10_000_000, 10_000_000), rng.randint(-10_000_000, 10_000_000))
           for _ in range(24)]

FLOAT = r"[-+]?(?:\d+\.?\d*(?:[eE][-+]?\d+)?|nan|inf)"


def hal_session(mode, pts, settle_s):
    """One halrun session: every point of pts through the component. Returns, per point,
    (x_out_mm, y_out_mm, cx_um, cy_um, status) or None where the servo thread had not yet run
    with that point's inputs (the machine is shared: a non-realtime thread may be late), and
    the NaN check's three values. Freshness: a token is set after the inputs and copied by
    sum2.2, which runs first in each period, so when its output shows the point's token, the
    component has run on that point's inputs."""
    lines = [f"loadrt selfcal_xy table={table}" + ("" if mode is None else f" mode={mode}"),
             "loadrt sum2 count=3",
             "loadrt threads name1=servo period1=1000000",
             "addf sum2.2 servo", "addf selfcal-xy.0 servo", "addf sum2.0 servo",
             "addf sum2.1 servo",
             "net xin selfcal-xy.0.x-in sum2.0.in1", "net yin selfcal-xy.0.y-in sum2.1.in1",
             "net xout selfcal-xy.0.x-out sum2.0.in0", "net yout selfcal-xy.0.y-out sum2.1.in0",
             "net tok sum2.2.in0",
             "setp sum2.0.gain0 1000", "setp sum2.0.gain1 -1000",
             "setp sum2.1.gain0 1000", "setp sum2.1.gain1 -1000",
             "start"]
    for k, (x, y) in enumerate(pts):
        lines += [f"sets xin {x * 1e-6:.6f}", f"sets yin {y * 1e-6:.6f}", f"sets tok {k + 1}",
                  f"loadusr -w sleep {settle_s}", "getp sum2.2.out",
                  "getp selfcal-xy.0.x-out", "getp selfcal-xy.0.y-out",
                  "getp sum2.0.out", "getp sum2.1.out", "getp selfcal-xy.0.status"]
    # NaN input: passed through with the invalid bit.
    lines += ["sets xin nan", "sets yin 1", "sets tok -1", f"loadusr -w sleep {settle_s}",
              "getp sum2.2.out", "getp selfcal-xy.0.x-out", "getp selfcal-xy.0.y-out",
              "getp selfcal-xy.0.status", "stop"]
    rc, out, err = halrun(lines, f"session_{mode}")
    check(rc == 0, f"halrun mode={mode} failed ({rc}):\n{out}\n{err}")
    vals = [v for v in out.split() if re.fullmatch(FLOAT, v, re.IGNORECASE)]
    check(len(vals) == 6 * len(pts) + 4,
          f"mode={mode}: expected {6 * len(pts) + 4} values from getp, got {len(vals)}:\n{out}")
    res = []
    for k in range(len(pts)):
        v = vals[6 * k: 6 * k + 6]
        fresh = float(v[0]) == k + 1
        res.append((float(v[1]), float(v[2]), float(v[3]), float(v[4]), int(v[5])) if fresh
                   else None)
    return res, vals[-4:]


def hal_outputs(mode):
    """Every point through the component; a point read before the thread ran on it is run again
    in a new session with a longer wait (up to 4 sessions)."""
    got = [None] * len(points)
    settle = 0.02
    for attempt in range(4):
        todo = [k for k in range(len(points)) if got[k] is None]
        if not todo:
            break
        res, nan = hal_session(mode, [points[k] for k in todo], settle)
        for k, r in zip(todo, res):
            got[k] = r
        if float(nan[0]) == -1:
            check(math.isnan(float(nan[1])) and float(nan[2]) == 1.0 and int(nan[3]) == 5,
                  f"mode={mode}: NaN input: got {nan[1:]}, want nan 1 5")
            nan_checked[mode] = True
        settle *= 5
    check(all(g is not None for g in got), f"mode={mode}: the servo thread never ran in time")
    check(nan_checked.get(mode), f"mode={mode}: the NaN check never ran in time")
    return got


nan_checked = {}

# the status pin says "table loaded" from loadrt on, before the function has run
rc, out, err = halrun([f"loadrt selfcal_xy table={table}", "getp selfcal-xy.0.status"], "status_at_load")
check(rc == 0 and out.split()[-1:] == ["1"], f"status right after loadrt: {out!r} {err!r}, want 1")


def sig7(v):
    """Half a unit of the 7th significant digit of v (the resolution of halcmd getp)."""
    return 0.5 * 10 ** (math.floor(math.log10(abs(v))) - 6) if v else 1e-300


def daemon_answers(mode):
    """selfcald's corrected positions (nm) and status for every point, or None without it."""
    if not selfcald:
        return None
    from pymodbus.client import ModbusTcpClient
    d = Daemon(selfcald, table, extra=("--mode", mode),
               log_path=os.path.join(work, f"daemon_{mode}.log"))
    c = ModbusTcpClient("127.0.0.1", port=d.port, timeout=2, retries=0)
    check(c.connect(), "connect to selfcald")
    ans = []
    for x, y in points:
        r = c.readwrite_registers(read_address=4, read_count=6, write_address=0,
                                  values=i32_to_regs(x) + i32_to_regs(y), device_id=1)
        check(not r.isError(), f"selfcald fn23: {r}")
        reg = r.registers
        ans.append((regs_to_i32(reg[0:2]), regs_to_i32(reg[2:4]), reg[4]))
    c.close()
    check(d.stop() == 0, "selfcald stopped cleanly")
    return ans


worst_py = worst_d = 0.0
for mode in (None, "position", "measure", "measure-exact"):
    eff = mode or "position"  # SPEC §7: position by default
    hal = hal_outputs(mode)
    dmn = daemon_answers(eff)
    for k, (x, y) in enumerate(points):
        xo, yo, cx, cy, st = hal[k]
        ex, ey, outside = ref.correct_nm(x, y, eff)   # independent evaluation (nm)
        want_st = 1 | (2 if outside else 0)
        check(st == want_st, f"mode={eff} ({x},{y}) nm: status {st}, want {want_st}")
        # The outputs themselves, to getp's 7 digits.
        check(abs(xo * 1e6 - ex) <= sig7(xo) * 1e6 + 1e-3 and
              abs(yo * 1e6 - ey) <= sig7(yo) * 1e6 + 1e-3,
              f"mode={eff} ({x},{y}) nm: out ({xo}, {yo}) mm, want ({ex}, {ey}) nm")
        # The correction, sharp: the table's values are the dump's (9 decimals, um), and the
        # interpolation is in double precision in both: agreement to 1e-5 um (10 pm).
        ecx, ecy = (ex - x) * 1e-3, (ey - y) * 1e-3
        err = max(abs(cx - ecx), abs(cy - ecy))
        worst_py = max(worst_py, err)
        check(err <= 1e-5 + sig7(max(abs(cx), abs(cy), 1e-9)),
              f"mode={eff} ({x},{y}) nm: correction ({cx}, {cy}) um, want ({ecx}, {ecy}) um")
        if dmn:
            dx, dy, dst = dmn[k]
            # selfcald answers whole nanometres of the same core's result: the component's
            # output rounds to the same integer (1 pm margin for getp's digits at a .5 tie).
            hx, hy = x + cx * 1e3, y + cy * 1e3
            dev = max(abs(hx - dx), abs(hy - dy))
            worst_d = max(worst_d, dev)
            check(dev <= 0.5 + 1e-3,
                  f"mode={eff} ({x},{y}) nm: component ({hx:.4f}, {hy:.4f}) nm, selfcald "
                  f"({dx}, {dy}) nm")
            check(dst & 0x3 == st & 0x3, f"mode={eff} ({x},{y}): status {st} vs selfcald {dst}")
print(f"component vs independent evaluation: max |dc| = {worst_py * 1e6:.3f} pm over "
      f"{4 * len(points)} points; vs selfcald: max {worst_d:.4f} nm"
      + ("" if selfcald else " (selfcald not built: not compared)"))


# Two instances of one load, one per mode (docs/linuxcnc.md: commanded positions through
# position mode, feedback through measure mode): each follows its own mode.
def two_instances():
    x, y = 3_456_789, -7_654_321
    for settle in (0.05, 0.25, 1.0, 4.0):
        lines = [f"loadrt selfcal_xy count=2 table={table} mode=position,measure",
                 "loadrt threads name1=servo period1=1000000",
                 "addf selfcal-xy.0 servo", "addf selfcal-xy.1 servo", "start"]
        for k in (0, 1):
            lines += [f"setp selfcal-xy.{k}.x-in {x * 1e-6:.6f}",
                      f"setp selfcal-xy.{k}.y-in {y * 1e-6:.6f}"]
        lines += [f"loadusr -w sleep {settle}"]
        lines += [f"getp selfcal-xy.{k}.{p}" for k in (0, 1) for p in ("x-out", "y-out", "status")]
        rc, out, err = halrun(lines, "two_instances")
        check(rc == 0, f"two instances: halrun failed:\n{out}\n{err}")
        v = [float(t) for t in out.split() if re.fullmatch(FLOAT, t, re.IGNORECASE)]
        check(len(v) == 6, f"two instances: expected 6 values:\n{out}")
        if v[2] == 0 or v[5] == 0:
            continue  # the thread has not run yet
        for k, mode in ((0, "position"), (1, "measure")):
            ex, ey, _ = ref.correct_nm(x, y, mode)
            xo, yo = v[3 * k], v[3 * k + 1]
            check(abs(xo * 1e6 - ex) <= sig7(xo) * 1e6 + 1e-3 and
                  abs(yo * 1e6 - ey) <= sig7(yo) * 1e6 + 1e-3,
                  f"instance {k} ({mode}): ({xo}, {yo}) mm, want ({ex}, {ey}) nm")
        return
    check(False, "two instances: the servo thread never ran")


two_instances()
print("count=2 mode=position,measure: each instance follows its own mode")


# Bad loads: loadrt fails, the reason is logged.
def bad_load(args, want, name):
    rc, out, err = halrun([f"loadrt selfcal_xy {args}".rstrip()], name)
    log = out + err
    check(rc != 0, f"{name}: loadrt selfcal_xy {args} succeeded")
    check(want in log, f"{name}: the log does not say {want!r}:\n{log}")


raw = open(table, "rb").read()
corrupt = os.path.join(scratch, "corrupt.lut")
with open(corrupt, "wb") as f:
    f.write(raw[:100] + bytes([raw[100] ^ 0x40]) + raw[101:])
truncated = os.path.join(scratch, "truncated.lut")
with open(truncated, "wb") as f:
    f.write(raw[:-10])
notatable = public(os.path.join(work, "hal_map.csv"))
for p in (corrupt, truncated):
    os.chmod(p, 0o644)
missing = os.path.join(scratch, "missing.lut")
bad_load(f"table={missing}", f"selfcal_xy: table={missing}: cannot open: No such file", "missing")
bad_load(f"table={corrupt}", "checksum mismatch", "corrupt")
bad_load(f"table={truncated}", "truncated or wrong length", "truncated")
bad_load(f"table={notatable}", "not a selfcal table", "csv")
bad_load("", "selfcal_xy: no table", "no_table")
bad_load(f"table={table} mode=positon", "selfcal_xy: mode=positon: unknown mode", "bad_mode")
bad_load(f"count=2 table={table} mode=position,Measure", "selfcal_xy: mode=Measure: unknown mode",
         "bad_mode_2")
print("bad loads: missing, corrupt, truncated, not a table, no table, unknown mode: refused")

shutil.rmtree(scratch)
print("PASS")
