#!/usr/bin/env python3
"""No temporary file outlives a killed writer (issue 36, item 4). `selfcal lut build` is killed
with SIGKILL at each step of its write (strace -e inject=SYSCALL:signal=KILL, so the step is
exact, not a race): at the temporary file's write, at its fsync, at the linkat that names it,
at the rename that puts it in place; once where the file system has O_TMPFILE (the temporary is
anonymous: nothing may be left), once where it has not (the open with O_TMPFILE made to fail
with EOPNOTSUPP: the named temporary stays, as any SIGKILL leaves it). Every time the old table
is intact, and the next successful `lut build` removes every stale "T.lut.tmpXXXXXX" of ours,
but not a live writer's (flocked) nor files not of our naming.
usage: test_tmp_kill.py SELFCAL_CLI WORKDIR"""
import fcntl
import os
import shutil
import subprocess
import sys

cli, work = sys.argv[1], sys.argv[2]
strace = shutil.which("strace")


def check(cond, msg):
    if not cond:
        print("FAIL:", msg, file=sys.stderr)
        sys.exit(1)


check(strace is not None, "strace is not installed (scripts/install-deps.sh installs it)")
os.makedirs(work, exist_ok=True)
kdir = os.path.join(work, "kill")
shutil.rmtree(kdir, ignore_errors=True)
os.makedirs(kdir)
mp = os.path.join(kdir, "map.csv")
with open(mp, "w") as f:
    f.write("i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n")
    for i in range(9):
        for j in range(9):
            f.write(f"{i},{j},{j * 2.0:.3f},{i * 2.0:.3f},{0.1 * i - 0.05 * j:.4f},"
                    f"{0.02 * i * j:.4f},,\n")
mp2 = os.path.join(kdir, "map2.csv")  # what the killed writers write: another table
with open(mp) as f, open(mp2, "w") as g:
    for n, line in enumerate(f):
        c = line.rstrip("\n").split(",")
        if n:
            c[4] = f"{float(c[4]) * 3 + 0.5:.4f}"
        g.write(",".join(c) + "\n")
table = os.path.join(kdir, "T.lut")
env = dict(os.environ, ASAN_OPTIONS="detect_leaks=0")  # LeakSanitizer cannot run under ptrace
build = [cli, "lut", "build", "--map", mp, "--created", "1700000000", "-o", table]
killed = [cli, "lut", "build", "--map", mp2, "--created", "1700000000", "-o", table]


def tmps():
    return sorted(f for f in os.listdir(kdir) if f.startswith("T.lut.tmp"))


def good_build():
    r = subprocess.run(build, capture_output=True, text=True, timeout=120, env=env)
    check(r.returncode == 0, f"lut build: {r.stderr}")


# Which open creates the temporary (its index among the openat calls), for the runs without
# O_TMPFILE.
r = subprocess.run([strace, "-f", "-qq", "-e", "trace=openat"] + killed, capture_output=True,
                   text=True, timeout=120, env=env)
opens = [l for l in r.stderr.splitlines() if l.lstrip("[pid 0123456789]").startswith("openat(")
         or "openat(" in l]
idx = [k for k, l in enumerate(opens) if "O_TMPFILE" in l]
have_tmpfile = len(idx) == 1
print("O_TMPFILE here:", "yes" if have_tmpfile else "no (named temporary files only)")
good_build()  # (the run above wrote map2's table)
old = open(table, "rb").read()

results = []
for anon in ([True, False] if have_tmpfile else [False]):
    for step in ("write", "fsync", "linkat", "rename"):
        if step == "linkat" and not anon:
            continue  # a named temporary is never linked
        args = [strace, "-f", "-qq", "-o", os.devnull, "-e", f"trace={step},openat",
                "-e", f"inject={step}:signal=KILL:when=1"]
        if have_tmpfile and not anon:
            args += ["-e", f"inject=openat:error=EOPNOTSUPP:when={idx[0] + 1}"]
        r = subprocess.run(args + killed, capture_output=True, text=True, timeout=120, env=env)
        check(r.returncode != 0 and "table" not in r.stdout, f"not killed at {step}: {r.stdout}")
        check(open(table, "rb").read() == old, f"killed at {step}: the old table changed")
        left = tmps()
        # what a SIGKILL may leave: a named temporary file (never an anonymous one before it has
        # a name)
        expect_left = 0 if anon and step in ("write", "fsync", "linkat") else 1
        check(len(left) == expect_left,
              f"killed at {step} ({'O_TMPFILE' if anon else 'named'}): left {left}")
        results.append(f"{'anonymous' if anon else 'named'} at {step}: {len(left)} left")
        # a stale temporary of ours is removed by the next write; not a live writer's, nor other
        # names
        if left:
            stale_age = os.path.getsize(os.path.join(kdir, left[0]))
            live = os.path.join(kdir, "T.lut.tmpLIVE01")
            others = ["T.lut.tmpABC", "T.lut.tmpABCDEFG", "U.lut.tmpABCDEF", "T.lut.tmp_x_y_"]
            for name in [live] + [os.path.join(kdir, o) for o in others]:
                with open(name, "w") as f:
                    f.write("x")
            lf = open(live, "rb")
            fcntl.flock(lf, fcntl.LOCK_EX)  # a writer still at work
            good_build()
            fcntl.flock(lf, fcntl.LOCK_UN)
            lf.close()
            now = sorted(os.listdir(kdir))
            check(left[0] not in now, f"the stale {left[0]} ({stale_age} bytes) was not removed")
            check(os.path.basename(live) in now, "a live writer's temporary file was removed")
            for o in others:
                check(o in now, f"{o} (not our naming) was removed")
            os.unlink(live)
            for o in others:
                os.unlink(os.path.join(kdir, o))
            # and the flock is the test: unlocked, the same file is stale
            with open(live, "w") as f:
                f.write("x")
            good_build()
            check(not os.path.exists(live), "an unlocked stale temporary file was not removed")
        check(open(table, "rb").read() == old, "the rebuilt table differs")
print("killed writers:", "; ".join(results))
check(tmps() == [], f"temporaries left at the end: {tmps()}")
print("tmp kill: ok")
