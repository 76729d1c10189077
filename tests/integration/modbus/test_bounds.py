#!/usr/bin/env python3
"""Plausibility bounds of a table (issue 36, item 2), with the real CLI and daemon:
- the audit's table: a valid table whose grid scale field is patched to 10^9 pm per code and
  its CRC-32 recomputed (every answer saturated at +-2.1 m before): `lut info` and `lut dump`
  refuse it (exit 2, the scale named), selfcald refuses to start on it (exit 2), and a SIGHUP onto
  it keeps the table in use (logged reason, status bit 3, answers unchanged);
- `lut build` and `lut info` print the bounds (max correction, max gradient), checked against
  an independent computation from `lut dump`;
- `--max-correction-um` and `--max-gradient-um-per-mm` (flags and configuration file): a table
  beyond them is refused at start (exit 2, the message names the option) and on reload (the old
  one kept, the reason logged); a table within them loads.
usage: test_bounds.py SELFCAL_CLI SELFCALD WORKDIR"""
import os
import signal
import socket
import struct
import subprocess
import sys
import time
import zlib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sclib import (Daemon, check, i32_to_regs, make_table, recv_exact,  # noqa: E402
                   regs_to_i32, replace_file)

cli, selfcald, work = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(work, exist_ok=True)


def run(*args):
    return subprocess.run(list(args), capture_output=True, text=True, timeout=60)


def bounds_of_dump(text):
    """(max correction um, max gradient um/mm) from `lut dump` text (grid only here)."""
    nodes = {}
    for line in text.splitlines():
        if line[:1].isdigit():
            i, j, x, y, gx, gy = line.split(",")
            nodes[int(i), int(j)] = (float(x), float(y), float(gx), float(gy))
    corr = max(max(abs(v[2]), abs(v[3])) for v in nodes.values())
    grad = 0.0
    for (i, j), (x, y, gx, gy) in nodes.items():
        for di, dj in ((0, 1), (1, 0)):
            o = nodes.get((i + di, j + dj))
            if o:
                d = abs(o[0] - x) + abs(o[1] - y)
                grad = max(grad, abs(o[2] - gx) / d, abs(o[3] - gy) / d)
    return corr, grad


def printed_bounds(out):
    line = [l for l in out.splitlines() if l.startswith("bounds:")]
    check(len(line) == 1, f"no bounds line in:\n{out}")
    w = line[0].split()
    return float(w[3]), float(w[7])


def transact(s, tid, pdu, unit=1):
    s.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu)
    rtid, proto, ln, runit = struct.unpack(">HHHB", recv_exact(s, 7))
    check(rtid == tid and runit == unit, "MBAP echo")
    return recv_exact(s, ln - 1)


def correct(port, x, y):
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        vals = i32_to_regs(x) + i32_to_regs(y)
        r = transact(s, 1, struct.pack(">BHHHHB", 23, 4, 6, 0, 4, 8) + struct.pack(">4H", *vals))
        check(r[0] == 23 and r[1] == 12, f"fn23 reply {r!r}")
        regs = struct.unpack(">6H", r[2:14])
        return regs_to_i32(regs[0:2]), regs_to_i32(regs[2:4]), regs[4]


def wait_log(d, text, timeout=10):
    end = time.time() + timeout
    while time.time() < end:
        if text in d.text():
            return
        time.sleep(0.02)
    check(False, f"'{text}' not in the log:\n{d.text()}")


# Tables: small (|G| about 1 um), large (about 60 um, steep), and the audit's (scale 1e9).
small, ref_small = make_table(cli, work, "small", n=7, pitch=2.0, scale_um=1.0)
large, ref_large = make_table(cli, work, "large", n=7, pitch=2.0, scale_um=60.0)
for t in (small, large):
    dump = run(cli, "lut", "dump", t).stdout
    want = bounds_of_dump(dump)
    for cmd in (["lut", "info", t],):
        got = printed_bounds(run(cli, *cmd).stdout)
        check(abs(got[0] - want[0]) <= 1e-6 and abs(got[1] - want[1]) <= 1e-5,
              f"{t}: lut info bounds {got}, from the dump {want}")
build = run(cli, "lut", "build", "--map", os.path.join(work, "large_map.csv"), "-o",
            os.path.join(work, "large2.lut"))
check(build.returncode == 0, build.stderr)
got = printed_bounds(build.stdout)
want = bounds_of_dump(run(cli, "lut", "dump", large).stdout)
check(abs(got[0] - want[0]) <= 1e-6 and abs(got[1] - want[1]) <= 1e-5,
      f"lut build bounds {got}, expected {want}")
check(want[0] > 30 and want[1] > 2, f"the large table is not large: {want}")
small_corr, small_grad = bounds_of_dump(run(cli, "lut", "dump", small).stdout)

blob = bytearray(open(small, "rb").read())
blob[56:60] = struct.pack("<I", 1_000_000_000)  # the grid's scale: 10^9 pm per code
blob[-4:] = struct.pack("<I", zlib.crc32(bytes(blob[:-4])) & 0xFFFFFFFF)
audit = os.path.join(work, "audit.lut")
open(audit, "wb").write(bytes(blob))

# 1. lut info / dump refuse the audit's table.
for sub in ("info", "dump"):
    r = run(cli, "lut", sub, audit)
    check(r.returncode == 2 and "scale" in r.stderr and r.stdout == "",
          f"lut {sub} of the audit's table: {r.returncode} {r.stderr!r}")

# 2. selfcald refuses to start on it, and on a table beyond its bounds.
for table, extra, word in ((audit, [], "scale"),
                           (large, ["--max-correction-um", "10"], "--max-correction-um"),
                           (large, ["--max-correction-um", "0", "--max-gradient-um-per-mm", "1.5"],
                            "--max-gradient-um-per-mm")):
    r = subprocess.run([selfcald, "--table", table, "--modbus-tcp", "127.0.0.1:0"] + extra,
                       capture_output=True, text=True, timeout=30)
    check(r.returncode == 2 and word in r.stderr and table in r.stderr,
          f"selfcald on {table} {extra}: {r.returncode} {r.stderr!r}")
# the defaults (1000 um, 100 um/mm) take the large table; the configuration file sets a bound
r = subprocess.run([selfcald, "--table", large, "--modbus-tcp", "127.0.0.1:0", "--version"],
                   capture_output=True, text=True, timeout=30)
check(r.returncode == 0, "selfcald --version")
conf = os.path.join(work, "bounds.conf")
with open(conf, "w") as f:
    f.write("max-correction-um = 20.5\nmax-gradient-um-per-mm = 50\n")
r = subprocess.run([selfcald, "--config", conf, "--table", large, "--modbus-tcp", "127.0.0.1:0"],
                   capture_output=True, text=True, timeout=30)
check(r.returncode == 2 and "--max-correction-um 20.5" in r.stderr, f"config bound: {r.stderr!r}")
for bad in ("-1", "abc", "2e6", "nan"):
    r = subprocess.run([selfcald, "--table", small, "--max-correction-um", bad],
                       capture_output=True, text=True, timeout=30)
    check(r.returncode == 2 and "--max-correction-um" in r.stderr, f"bound '{bad}': {r.stderr!r}")

# 3. Reloads: the old table stays for the audit's table and for one beyond the bound.
live = os.path.join(work, "live.lut")
replace_file(live, open(small, "rb").read())
d = Daemon(selfcald, live, ["--config", conf], log_path=os.path.join(work, "bounds.log"))
try:
    x, y = 1_234_567, -2_345_678
    ex, ey, _ = ref_small.correct_nm(x, y)
    gx, gy, st = correct(d.port, x, y)
    check(abs(gx - ex) <= 1 and abs(gy - ey) <= 1 and st == 1, f"small table: {gx} {gy} {st}")
    for k, (blob2, why) in enumerate(((bytes(blob), "scale"),
                                      (open(large, "rb").read(), "--max-correction-um 20.5"))):
        replace_file(live, blob2)
        d.signal(signal.SIGHUP)
        wait_log(d, "reload failed", 10)
        end = time.time() + 10
        while d.text().count("reload failed") < k + 1 and time.time() < end:
            time.sleep(0.02)
        last = [l for l in d.text().splitlines() if "reload failed" in l][-1]
        check(why in last and "keeping the previous table" in last, f"reload {k}: {last}")
        gx2, gy2, st2 = correct(d.port, x, y)
        check((gx2, gy2) == (gx, gy) and st2 & 8 and st2 & 1 and not st2 & 4,
              f"after refused reload {k}: {gx2} {gy2} status {st2}")
    replace_file(live, open(small, "rb").read())
    d.signal(signal.SIGHUP)
    wait_log(d, "reload: table", 10)
    gx3, gy3, st3 = correct(d.port, x, y)
    check((gx3, gy3) == (gx, gy) and st3 == 1, f"after a good reload: status {st3}")
finally:
    rc = d.stop()
check(rc == 0, f"selfcald exit {rc}")
print(f"bounds: ok (small table {small_corr:.3f} um, {small_grad:.3f} um/mm; large "
      f"{want[0]:.3f} um, {want[1]:.3f} um/mm; the audit's table refused by lut info, at start "
      f"and on reload)")
