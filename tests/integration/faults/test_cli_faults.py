#!/usr/bin/env python3
"""Fault injection on the CLI (issue 15 items 2, 3 and 6): what a crash, a signal, a full disk, a
failing disk, a read-only folder, an unwritable stdout and oversized inputs leave behind.

1. kill -9 at random moments of `lut build`, `grid` and `profile` writing large outputs (KILLS in
   all): the output path is always the old file or a complete valid output;
2. SIGINT/SIGTERM during `grid --map --artifact --summary`: no *.tmp* file is left, and the three
   outputs are either all old or all new (never a mix);
3. a full file system (a small tmpfs in a private mount namespace), a read-only folder (the same
   tmpfs remounted read-only) and fsync failing with EIO or ENOSPC (an LD_PRELOAD shim): exit 1,
   one stderr line, no temporary file, the old file untouched;
4. stdout that cannot be written (`lut info`, `lut dump`, `plan` > /dev/full): exit 1, one line;
   an output that is one of the command's inputs, two outputs on one file, an empty output path:
   exit 2 before anything is written;
5. limits: a profile whose header declares N = 20 000 000 in a few hundred bytes, a map repeating
   its nodes over 20 MB, a 10 MB line, a 100 MB table: exit 2 with one line naming the file (and
   the line), peak memory far below what the claim would need.
usage: test_cli_faults.py SELFCAL_CLI FAULT_SHIM_SO WORKDIR [KILLS]"""
import glob
import os
import random
import resource
import shutil
import signal
import struct
import subprocess
import sys
import time
import zlib

cli, shim, work = sys.argv[1], sys.argv[2], sys.argv[3]
kills_total = int(sys.argv[4]) if len(sys.argv) > 4 else 100
os.makedirs(work, exist_ok=True)
rng = random.Random(15)
failures = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL:", msg, file=sys.stderr)


def run(args, **kw):
    return subprocess.run([cli] + args, capture_output=True, text=True, timeout=300, **kw)


def must(args):
    r = run(args)
    if r.returncode != 0:
        sys.exit(f"setup failed: selfcal {' '.join(args)}: {r.stderr}")
    return r


def one_line_error(r, code, what, needle=None):
    lines = r.stderr.strip().splitlines()
    check(r.returncode == code, f"{what}: exit {r.returncode}, expected {code}: {r.stderr!r}")
    check(len(lines) == 1 and lines[0].startswith("selfcal"), f"{what}: stderr {r.stderr!r}")
    if needle:
        check(needle in r.stderr, f"{what}: '{needle}' not in {r.stderr!r}")


def tmp_files(d):
    return [f for f in os.listdir(d) if ".tmp" in f]


def p(name):
    return os.path.join(work, name)


def table_valid(blob):
    """A complete selfcal table: magic, file size field = length, CRC-32 of all but the last 4."""
    if len(blob) < 24 or blob[:5] != b"SCLUT":
        return False
    size = struct.unpack_from("<I", blob, 12)[0]
    crc = struct.unpack_from("<I", blob, len(blob) - 4)[0]
    return size == len(blob) and crc == (zlib.crc32(blob[:-4]) & 0xFFFFFFFF)


# ---- inputs -------------------------------------------------------------------------------
must(["simulate", "profile", "--n", "30000", "--d1", "10", "--d2", "11", "--out", p("prof.csv"),
      "--truth", p("prof_truth.csv"), "--seed", "5"])
must(["simulate", "grid", "--plan", "ye", "--n", "31", "--pitch-mm", "1", "--out", p("grid.csv"),
      "--truth-map", p("grid_truth.csv")])
must(["grid", "--method", "ye", p("grid.csv"), "--map", p("map_ref.csv")])


def timed(args):
    t0 = time.time()
    must(args)
    return time.time() - t0


# ---- 1. kill -9 at random moments ----------------------------------------------------------
cases = [
    ("lut build", ["lut", "build", "--map", p("map_ref.csv"), "-o"], "out.lut", "table"),
    ("grid", ["grid", "--method", "ye", p("grid.csv"), "--map"], "out_map.csv", p("map_ref.csv")),
    ("profile", ["profile", "--method", "lsq", p("prof.csv"), "--out"], "out_prof.csv", None),
]
kdir = p("kill")
os.makedirs(kdir, exist_ok=True)
summary = []
for k, (name, args, out, ref) in enumerate(cases):
    target = os.path.join(kdir, out)
    if ref is None:  # the reference: a clean run
        must(args + [os.path.join(kdir, "ref_" + out)])
        ref = os.path.join(kdir, "ref_" + out)
    dur = timed(args + [target])
    refblob = open(ref, "rb").read() if ref != "table" else None
    old = b"OLD CONTENT\n"
    n = kills_total // len(cases) + (1 if k < kills_total % len(cases) else 0)
    seen = {"old": 0, "new": 0}
    for _ in range(n):
        for f in tmp_files(kdir):  # SIGKILL cannot be handled: its temporaries stay; clear them
            os.unlink(os.path.join(kdir, f))
        with open(target, "wb") as f:
            f.write(old)
        proc = subprocess.Popen([cli] + args + [target], stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        time.sleep(rng.uniform(0, dur * 1.2))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        got = open(target, "rb").read() if os.path.exists(target) else None
        if got == old:
            seen["old"] += 1
        elif got is not None and (table_valid(got) if refblob is None else got == refblob):
            seen["new"] += 1
        else:
            check(False, f"kill -9 during {name}: the output is neither the old file nor a "
                         f"complete one ({None if got is None else len(got)} bytes)")
    summary.append(f"{name}: {n} kills (run {dur:.2f} s): old file {seen['old']}, "
                   f"complete new file {seen['new']}")
print("kill -9:", "; ".join(summary))

# ---- 2. SIGINT / SIGTERM during a multi-output command -------------------------------------
sdir = p("sig")
os.makedirs(sdir, exist_ok=True)
outs = [os.path.join(sdir, n) for n in ("map.csv", "artifact.csv", "summary.json")]
gargs = ["grid", "--method", "ye", p("grid.csv"), "--map", outs[0], "--artifact", outs[1],
         "--summary", outs[2]]
dur = timed(gargs)
new = [open(o, "rb").read() for o in outs]
mix = {"old": 0, "new": 0}
for trial in range(20):
    for o in outs:
        with open(o, "wb") as f:
            f.write(b"OLD " + o.encode() + b"\n")
    proc = subprocess.Popen([cli] + gargs, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(rng.uniform(0, dur * 1.2))
    proc.send_signal(signal.SIGINT if trial % 2 else signal.SIGTERM)
    proc.wait()
    check(not tmp_files(sdir), f"signal: temporaries left: {tmp_files(sdir)}")
    state = ["old" if open(o, "rb").read().startswith(b"OLD ") else "new" for o in outs]
    check(len(set(state)) == 1, f"signal: a mixed set of outputs: {state}")
    if state[0] == "new":
        got = [open(o, "rb").read() for o in outs[:2]]
        check(got == new[:2], "signal: the new outputs differ from a clean run's")
    mix[state[0]] += 1
    for f in tmp_files(sdir):
        os.unlink(os.path.join(sdir, f))
print(f"SIGINT/SIGTERM during grid (3 outputs): all old {mix['old']}, all new {mix['new']}, "
      "never mixed, no temporaries")

# ---- 3. full disk, read-only folder, failing fsync ------------------------------------------
old = b"n,x_mm,f_um,uf_um,ey_um\nOLD\n"
unshare = shutil.which("unshare")
ns = None
for cand in (["unshare", "-m"], ["unshare", "-rm"]):
    if unshare and subprocess.run(cand + ["true"], capture_output=True).returncode == 0:
        ns = cand
        break
check(ns is not None, "no private mount namespace (unshare -m / -rm) on this host")
if ns is not None:
    mnt = p("mnt")
    os.makedirs(mnt, exist_ok=True)
    for what, mount_cmds in (
            ("full file system", f"mount -t tmpfs -o size=512k tmpfs {mnt}"),
            ("read-only folder", f"mount -t tmpfs -o size=512k tmpfs {mnt} && "
                                 f"printf '%s' '{old.decode()}' > {mnt}/out.csv && "
                                 f"mount -o remount,ro {mnt}")):
        script = (f"set -e; {mount_cmds}; "
                  f"[ -f {mnt}/out.csv ] || printf '%s' '{old.decode()}' > {mnt}/out.csv; "
                  f"set +e; {cli} profile --method lsq {p('prof.csv')} --out {mnt}/out.csv "
                  f"2> {p('ns_err.txt')}; echo $? > {p('ns_rc.txt')}; "
                  f"cat {mnt}/out.csv > {p('ns_after.txt')}; ls -a {mnt} > {p('ns_ls.txt')}")
        r = subprocess.run(ns + ["sh", "-c", script], capture_output=True, text=True, timeout=300)
        check(r.returncode == 0, f"{what}: namespace script: {r.stderr}")
        rc = int(open(p("ns_rc.txt")).read())
        err = open(p("ns_err.txt")).read()

        class R:
            pass
        res = R()
        res.returncode, res.stderr = rc, err
        one_line_error(res, 1, what)
        if what == "full file system":  # the reason, not just "write error"
            check("No space left on device" in err, f"{what}: the message gives no reason: {err!r}")
        check(open(p("ns_after.txt"), "rb").read() == old, f"{what}: the old file was changed")
        left = [f for f in open(p("ns_ls.txt")).read().split() if ".tmp" in f]
        check(not left, f"{what}: temporaries left: {left}")
        print(f"{what}: exit {rc}: {err.strip()}")

env_base = dict(os.environ)
env_base["ASAN_OPTIONS"] = env_base.get("ASAN_OPTIONS", "") + ":verify_asan_link_order=0"
fdir = p("fsync")
os.makedirs(fdir, exist_ok=True)
for errno_name, errno_val in (("EIO", 5), ("ENOSPC", 28)):
    target = os.path.join(fdir, "out.csv")
    with open(target, "wb") as f:
        f.write(old)
    env = dict(env_base, LD_PRELOAD=shim, SELFCAL_FAULT_FSYNC_ERRNO=str(errno_val))
    r = run(["profile", "--method", "lsq", p("prof.csv"), "--out", target], env=env)
    one_line_error(r, 1, f"fsync {errno_name}")
    check(open(target, "rb").read() == old, f"fsync {errno_name}: the old file was changed")
    check(not tmp_files(fdir), f"fsync {errno_name}: temporaries left: {tmp_files(fdir)}")
    print(f"fsync {errno_name}: exit {r.returncode}: {r.stderr.strip()}")

# the file size limit (ulimit -f): the write fails (EFBIG) like a full disk, SIGXFSZ does not
# kill the command with its temporary file left
ldir = p("fsize")
os.makedirs(ldir, exist_ok=True)
target = os.path.join(ldir, "out.csv")
with open(target, "wb") as f:
    f.write(old)
r = run(["profile", "--method", "lsq", p("prof.csv"), "--out", target],
        preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (4096, resource.RLIM_INFINITY)))
one_line_error(r, 1, "ulimit -f", "File too large")
check(open(target, "rb").read() == old, "ulimit -f: the old file was changed")
check(not tmp_files(ldir), f"ulimit -f: temporaries left: {tmp_files(ldir)}")

# a device that refuses the write (/dev/full): every writer gives the reason, not just "write error"
for args in (["plot", "map", p("map_ref.csv")], ["plot", "xy", p("map_ref.csv")],
             ["report", "grid", p("grid.csv")], ["export", "--format", "kmotion", "--map", p("map_ref.csv")],
             ["export", "--format", "beckhoff", "--axis", "x", "--map", p("map_ref.csv")],
             ["lut", "build", "--map", p("map_ref.csv")]):
    r = run(args + ["-o", "/dev/full"])
    one_line_error(r, 1, " ".join(args[:2]) + " -o /dev/full", "write error: No space left on device")
# simulate exports into a new folder whose files cannot be written: the folder is not left
r = subprocess.run(["sh", "-c", 'ulimit -f 1 && exec "$1" simulate exports "$2" --dir "$3"', "sh", cli,
                    p("grid.csv"), p("exports_new")], capture_output=True, text=True, timeout=120)
one_line_error(r, 1, "simulate exports under ulimit -f", "write error")
check(not os.path.exists(p("exports_new")), "simulate exports: the new folder was left behind")
# two outputs, the second refused: the first is not written either (all or none)
must(["simulate", "profile", "--n", "330", "--out", p("pa.csv"), "--truth", p("pa_t.csv")])
with open(p("pa_out.csv"), "w") as fh:
    fh.write("old\n")
r = run(["profile", "--method", "lsq", p("pa.csv"), "--out", p("pa_out.csv"), "--plot", "/dev/full", "--quiet"])
one_line_error(r, 1, "profile --plot /dev/full", "write error")
check(open(p("pa_out.csv")).read() == "old\n", "profile --plot /dev/full: --out was replaced")
r = run(["simulate", "profile", "--n", "330", "--out", p("pa_new.csv"), "--truth", "/dev/full"])
one_line_error(r, 1, "simulate profile --truth /dev/full", "write error")
check(not os.path.exists(p("pa_new.csv")), "simulate profile --truth /dev/full: --out was written")

# an output that is a symbolic link is written through: its file replaced, the link kept
sdir = p("links")
shutil.rmtree(sdir, ignore_errors=True)
os.makedirs(os.path.join(sdir, "versions"))
with open(os.path.join(sdir, "versions", "v1.lut"), "w") as f:
    f.write("old\n")
os.symlink("versions/v1.lut", os.path.join(sdir, "current.lut"))
must(["lut", "build", "--map", p("map_ref.csv"), "-o", os.path.join(sdir, "current.lut")])
check(os.path.islink(os.path.join(sdir, "current.lut")), "-o LINK: the link was replaced by a file")
check(open(os.path.join(sdir, "versions", "v1.lut"), "rb").read(4) != b"old\n",
      "-o LINK: the file it points to was not written")
check(not tmp_files(sdir) and not tmp_files(os.path.join(sdir, "versions")), "-o LINK: temporaries left")

# ... but not a link another user planted in a sticky world-writable folder (as the kernel's
# protected_symlinks refuses to open it): the file it points to stays (root only: chown -h)
if os.geteuid() == 0:
    tdir = p("sticky")
    shutil.rmtree(tdir, ignore_errors=True)
    os.makedirs(tdir)
    os.chmod(tdir, 0o1777)
    with open(os.path.join(tdir, "victim.csv"), "w") as f:
        f.write("secret\n")
    os.symlink(os.path.join(tdir, "victim.csv"), os.path.join(tdir, "planted.csv"))
    os.lchown(os.path.join(tdir, "planted.csv"), 65534, 65534)
    r = run(["lut", "build", "--map", p("map_ref.csv"), "-o", os.path.join(tdir, "planted.csv")])
    one_line_error(r, 1, "-o a planted link", "not followed")
    check(open(os.path.join(tdir, "victim.csv")).read() == "secret\n", "-o a planted link: its target was replaced")
    check(not tmp_files(tdir), "-o a planted link: temporaries left")

# a replaced file's new content is never readable beyond its old permissions: the temporary is
# created with them (strace shows the open's mode)
strace = shutil.which("strace")
check(strace is not None, "strace is not installed (scripts/install-deps.sh installs it)")
if strace:
    os.makedirs(p("modes"), exist_ok=True)
    secret = os.path.join(p("modes"), "secret.lut")
    with open(secret, "w") as f:
        f.write("old\n")
    os.chmod(secret, 0o600)
    r = subprocess.run([strace, "-f", "-e", "trace=openat,open", cli, "lut", "build", "--map",
                        p("map_ref.csv"), "-o", secret], capture_output=True, text=True, timeout=120)
    # named (secret.lut.tmpXXXXXX, O_CREAT) or anonymous in its folder (O_TMPFILE, issue 36)
    opens = [l for l in r.stderr.splitlines() if ("secret.lut.tmp" in l and "O_CREAT" in l) or
             ("O_TMPFILE" in l and p("modes") in l)]
    check(len(opens) == 1 and opens[0].rstrip().split(",")[-1].split(")")[0].strip() == "0600",
          f"the temporary of a 0600 file: {opens}")
    check(os.stat(secret).st_mode & 0o777 == 0o600, "secret.lut lost its mode")

# permissions: a new output gets 0666 less the umask, a replaced one keeps its own
mdir = p("modes")
os.makedirs(mdir, exist_ok=True)
for name in ("new.lut", "kept.lut"):
    if os.path.exists(os.path.join(mdir, name)):
        os.remove(os.path.join(mdir, name))
with open(os.path.join(mdir, "kept.lut"), "w") as f:
    f.write("old\n")
os.chmod(os.path.join(mdir, "kept.lut"), 0o640)
for name, mask, want in (("new.lut", 0o077, 0o600), ("kept.lut", 0o022, 0o640)):
    r = run(["lut", "build", "--map", p("map_ref.csv"), "-o", os.path.join(mdir, name)],
            preexec_fn=lambda m=mask: os.umask(m))
    check(r.returncode == 0, f"lut build -o {name}: {r.stderr}")
    mode = os.stat(os.path.join(mdir, name)).st_mode & 0o777
    check(mode == want, f"{name} under umask {mask:o}: mode {mode:o}, want {want:o}")

# ---- 4. stdout cannot be written ------------------------------------------------------------
must(["lut", "build", "--map", p("map_ref.csv"), "-o", p("t.lut")])
with open(p("plan.csv"), "w") as f:
    f.write("# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n# origin_mm = 0,0\n"
            "# view 0: rot=0 shift=0,0\n# view 1: rot=90 shift=0,0\n# view 2: rot=0 shift=1,0\n")
for args in (["lut", "info", p("t.lut")], ["lut", "dump", p("t.lut")], ["plan", p("plan.csv")]):
    with open("/dev/full", "w") as full:
        r = subprocess.run([cli] + args, stdout=full, stderr=subprocess.PIPE, text=True,
                           timeout=120)
    one_line_error(r, 1, f"{' '.join(args[:2])} > /dev/full")

# ---- 4b. an output that is an input, two outputs on one file, an empty output path ----------
# every command reads, then replaces its outputs: exit 2 before anything is written, the input
# untouched (checked byte for byte), no output file made
def digest(path):
    with open(path, "rb") as f:
        return zlib.crc32(f.read())


# files a command names after its output option: export's OUT-x, simulate exports' DIR/viewK.csv
shutil.copy(p("map_ref.csv"), p("plane-x.txt"))
os.makedirs(p("exports_dir"), exist_ok=True)
shutil.copy(p("grid.csv"), p("exports_dir/view1.csv"))
for what, args, victim in (
        ("export OUT-x is the map", ["export", "--format", "beckhoff", "--axis", "both", "--map",
                                     p("plane-x.txt"), "-o", p("plane.txt")], "plane-x.txt"),
        ("simulate exports DIR/view1.csv is IN", ["simulate", "exports", p("exports_dir/view1.csv"),
                                                  "--dir", p("exports_dir")], "exports_dir/view1.csv"),
        ("grid --map IN", ["grid", "--method", "lsq", p("grid.csv"), "--map", p("grid.csv")],
         "grid.csv"),
        ("profile --out IN", ["profile", "--method", "lsq", p("prof.csv"), "--out", p("prof.csv")],
         "prof.csv"),
        ("lut build -o MAP", ["lut", "build", "--map", p("map_ref.csv"), "-o", p("map_ref.csv")],
         "map_ref.csv"),
        ("lut build -o PROFILE", ["lut", "build", "--map", p("map_ref.csv"), "--profile",
                                  "x:y:" + p("prof_truth.csv") + "@0", "-o", p("prof_truth.csv")],
         "prof_truth.csv"),
        ("export -o MAP (another name)", ["export", "--format", "klipper", "--map", p("map_ref.csv"),
                                          "-o", os.path.join(work, ".", "map_ref.csv")], "map_ref.csv"),
        ("report grid -o IN", ["report", "grid", p("grid.csv"), "-o", p("grid.csv")], "grid.csv")):
    before = digest(p(victim))
    r = run(args)
    one_line_error(r, 2, what, "also an input")
    cmd = " ".join(args[:2]) if args[0] in ("lut", "report", "simulate", "import", "plot") else args[0]
    check(r.stderr.startswith(f"selfcal {cmd}: "), f"{what}: the message names the command: {r.stderr!r}")
    check(digest(p(victim)) == before, f"{what}: the input was changed")
r = run(["grid", "--method", "ye", p("grid.csv"), "--map", p("same.csv"), "--artifact",
         os.path.join(work, ".", "same.csv")])
one_line_error(r, 2, "grid --map X --artifact X", "name the same file")
check(not os.path.exists(p("same.csv")), "grid --map X --artifact X: an output was written")
r = run(["grid", "--method", "ye", p("grid.csv"), "--map", p("m_empty.csv"), "--summary", ""])
one_line_error(r, 2, "grid --summary ''", "--summary: the path is empty")
check(not os.path.exists(p("m_empty.csv")), "grid --summary '': the map was written")

# ---- 5. limits ----------------------------------------------------------------------------


def peak_rss_mb(args):
    """Run selfcal in a child that reports its own peak RSS (MiB) and result."""
    code = ("import resource, subprocess, sys\n"
            "r = subprocess.run(sys.argv[1:], capture_output=True, text=True)\n"
            "print(r.returncode)\n"
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss // 1024)\n"
            "sys.stdout.write(r.stderr)\n")
    out = subprocess.run([sys.executable, "-c", code, cli] + args, capture_output=True, text=True,
                         timeout=300).stdout.split("\n", 2)

    class R:
        pass
    res = R()
    res.returncode, rss, res.stderr = int(out[0]), int(out[1]), out[2]
    return res, rss


with open(p("huge_n.csv"), "w") as f:
    f.write("# selfcal-profile v1\n# N = 20000000\n# s_mm = 1\n# scan 1: d=3\n# scan 2: d=4\n"
            "scan,n,m1_um,m2_um,m3_urad\n1,0,0,0,0\n")
r, rss = peak_rss_mb(["profile", "--method", "lsq", p("huge_n.csv"), "--out", p("o.csv")])
one_line_error(r, 2, "profile declaring N = 2e7", "huge_n.csv:2:")
check(rss < 300, f"profile declaring N = 2e7: peak RSS {rss} MiB")
print(f"limit: a {os.path.getsize(p('huge_n.csv'))}-byte profile declaring N = 2e7: exit 2, "
      f"peak RSS {rss} MiB: {r.stderr.strip()}")

rows = open(p("map_ref.csv")).read().splitlines()
with open(p("repeated_map.csv"), "w") as f:
    f.write(rows[0] + "\n")
    body = "\n".join(rows[1:]) + "\n"
    while f.tell() < 20_000_000:
        f.write(body)
r, rss = peak_rss_mb(["lut", "build", "--map", p("repeated_map.csv"), "-o", p("o.lut")])
one_line_error(r, 2, "20 MB map repeating its nodes", "repeated_map.csv:")
check(rss < 300, f"20 MB repeated map: peak RSS {rss} MiB")
print(f"limit: a 20 MB map repeating a 31 x 31 grid: exit 2, peak RSS {rss} MiB: "
      f"{r.stderr.strip()}")

with open(p("long_line.csv"), "w") as f:
    f.write("i,j,x_mm,y_mm,gx_um,gy_um\n0,0," + "1" * 10_000_000 + ",0,0,0\n")
r, rss = peak_rss_mb(["lut", "build", "--map", p("long_line.csv"), "-o", p("o.lut")])
one_line_error(r, 2, "10 MB line", "long_line.csv:2")
check(rss < 300, f"10 MB line: peak RSS {rss} MiB")
print(f"limit: a 10 MB line: exit 2, peak RSS {rss} MiB: {r.stderr.strip()}")

with open(p("big.lut"), "wb") as f:
    f.write(open(p("t.lut"), "rb").read())
    f.truncate(100_000_000)
r, rss = peak_rss_mb(["lut", "info", p("big.lut")])
one_line_error(r, 2, "100 MB table")
check(rss < 300, f"100 MB table: peak RSS {rss} MiB")
print(f"limit: a 100 MB table: exit 2, peak RSS {rss} MiB: {r.stderr.strip()}")
# whole-file errors name a line: a map whose x_mm decreases along j
with open(p("decreasing.csv"), "w") as f:
    f.write("i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,0,0\n0,1,-1,0,0,0\n1,0,0,1,0,0\n1,1,-1,1,0,0\n")
r = run(["lut", "build", "--map", p("decreasing.csv"), "-o", p("o.lut")])
one_line_error(r, 2, "x_mm decreasing along j", "decreasing.csv:3: x_mm does not increase")
for f in ("repeated_map.csv", "long_line.csv", "big.lut"):
    os.unlink(p(f))

# ---- 5b. values beyond any measuring set-up: refused up front (exit 2), not an internal error,
# a NaN output or a file the next command refuses (found by a fuzzing audit) ------------------
src = open(p("grid.csv")).read()
with open(p("tiny_pitch.csv"), "w") as f:  # pitch 1e-170 mm: the arithmetic underflows
    f.write(src.replace("# pitch_mm = 1\n", "# pitch_mm = 1e-170\n"))
check("# pitch_mm = 1e-170" in open(p("tiny_pitch.csv")).read(), "tiny_pitch.csv was made")
for m in ("lsq", "ye"):
    r = run(["grid", "--method", m, p("tiny_pitch.csv"), "--map", p("o_tiny.csv")])
    one_line_error(r, 2, f"grid --method {m} on a 1e-170 mm pitch", "tiny_pitch.csv:")
    check("pitch" in r.stderr, f"the pitch named: {r.stderr!r}")
with open(p("tiny_sigma.csv"), "w") as f:  # sigma_um=1e-80: weights beyond the doubles' range
    f.write(src.replace("shift=0,0\n", "shift=0,0 sigma_um=1e-80\n", 1))
r = run(["grid", "--method", "lsq", p("tiny_sigma.csv"), "--map", p("o_tiny.csv")])
one_line_error(r, 2, "sigma_um=1e-80", "sigma_um")
for what, args, needle in (
        ("simulate grid --pitch-mm 1e-200",
         ["simulate", "grid", "--plan", "ye", "--n", "9", "--pitch-mm", "1e-200", "--out",
          p("o_sim.csv"), "--truth-map", p("o_simt.csv")], "pitch"),
        ("simulate profile --s-mm 1e-7",
         ["simulate", "profile", "--s-mm", "1e-7", "--out", p("o_sim.csv"), "--truth",
          p("o_simt.csv")], "--s-mm"),
        ("simulate profile d1 = d2 = 2",
         ["simulate", "profile", "--n", "40", "--d1", "2", "--d2", "2", "--out", p("o_sim.csv"),
          "--truth", p("o_simt.csv")], "common divisor"),
        ("import profile --sigma-angle-urad 1e7",
         ["import", "profile", "--spacing-mm", "10", p("grid.csv"), "--spacing-mm", "11",
          p("grid.csv"), "--sigma-angle-urad", "1e7", "-o", p("o_sim.csv")], "sigma-angle-urad")):
    r = run(args)
    one_line_error(r, 2, what, needle)
    check(not os.path.exists(p("o_sim.csv")) and not os.path.exists(p("o_simt.csv")),
          f"{what}: an output was written")
with open(p("big_stage.csv"), "w") as f:  # the covariance limit before the solve
    f.write("# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n# stage = 45,45\n"
            "# view 0: rot=0 shift=0,0\nview,i,j,x_mm,y_mm\n0,0,0,-2,-2\n")
r = run(["grid", "--method", "lsq", p("big_stage.csv"), "--map", p("o_cov.csv"), "--covariance",
         p("o_cov.npy")])
one_line_error(r, 2, "--covariance on 45 x 45 nodes", "--covariance: 2025 stage nodes")

# 6. An address space limit (ulimit -v) too small for the sparse solver: OpenBLAS, loaded with
# CHOLMOD, retried its buffer forever and hung at exit; the least squares must say it lacks
# memory (exit 1, one line) instead. Not under AddressSanitizer, which cannot start in it.
asan = b"__asan_init" in subprocess.run(["nm", "-D", cli], capture_output=True).stdout
if not asan:
    must(["simulate", "grid", "--plan", "ye", "--n", "9", "--out", p("uv.csv"), "--truth-map",
          p("uv_t.csv")])
    for limit_kb in (150000, 300000):
        for method in ("lsq", "ye"):
            r = subprocess.run(["sh", "-c", 'ulimit -v "$1" && exec "$2" grid --method "$3" "$4" --map "$5"',
                                "sh", str(limit_kb), cli, method, p("uv.csv"), p("uv_m.csv")],
                               capture_output=True, text=True, timeout=120)
            if method == "lsq":
                one_line_error(r, 1, f"grid --method lsq under ulimit -v {limit_kb}",
                               "out of memory: the address space limit")
            else:  # the closed form needs no solver: its map, without the noise estimate
                check(r.returncode == 0 and os.path.exists(p("uv_m.csv")),
                      f"grid --method ye under ulimit -v {limit_kb}: exit {r.returncode} {r.stderr!r}")
    print("ulimit -v: the grid solver refuses, no hang")
else:
    print("ulimit -v: not tried under AddressSanitizer")

if failures:
    print(f"{len(failures)} failure(s)", file=sys.stderr)
    sys.exit(1)
print("PASS cli faults")
