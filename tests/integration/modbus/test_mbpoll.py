#!/usr/bin/env python3
"""selfcald over Modbus TCP driven by mbpoll (Debian's Modbus master; 1-based references by
default, -0 for PDU addressing, -B for high-word-first 32-bit values). Each corrected position is
compared with an independent bilinear evaluation of `selfcal lut dump`.
usage: test_mbpoll.py SELFCAL_CLI SELFCALD WORKDIR"""
import os
import random
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sclib import Daemon, check, make_table  # noqa: E402

cli, selfcald, work = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(work, exist_ok=True)
table, ref = make_table(cli, work, "mbpoll", n=9, pitch=2.5, scale_um=2.0)


def mbpoll(port, *args, ok=True):
    """mbpoll with options args; values to write follow a "--" in args."""
    args = list(args)
    vals = []
    if "--" in args:
        k = args.index("--")
        args, vals = args[:k], args[k:]
    p = subprocess.run(["mbpoll", "-m", "tcp", "-p", str(port), "-1", "-o", "2", *args,
                        "127.0.0.1", *vals],
                       capture_output=True, text=True, timeout=20)
    if ok:
        check(p.returncode == 0, f"mbpoll {args}: {p.stdout} {p.stderr}")
    return p


def values(out):
    return {int(m.group(1)): int(m.group(2)) for m in re.finditer(r"\[(\d+)\]:\s+(-?\d+)", out)}


rng = random.Random(7)
worst = 0.0
d = Daemon(selfcald, table)
try:
    pts = [(0, 0), (-12_000_000, 12_000_000)] + [
        (rng.randint(-11_000_000, 11_000_000), rng.randint(-11_000_000, 11_000_000))
        for _ in range(14)]
    count = 0
    for k, (x, y) in enumerate(pts):
        if k % 2 == 0:   # 1-based references: holding 1..4 are registers 0-3
            mbpoll(d.port, "-t", "4:int", "-B", "-r", "1", "--", str(x), str(y))
            out = values(mbpoll(d.port, "-t", "3:int", "-B", "-r", "1", "-c", "2").stdout)
            gx, gy = out[1], out[3]
            st = values(mbpoll(d.port, "-t", "3", "-r", "5", "-c", "2").stdout)
            status, cnt = st[5], st[6]
        else:            # PDU addressing (-0), the read-only mirror in holding 4-9
            mbpoll(d.port, "-0", "-t", "4:int", "-B", "-r", "0", "--", str(x), str(y))
            out = values(mbpoll(d.port, "-0", "-t", "4:int", "-B", "-r", "4", "-c", "2").stdout)
            gx, gy = out[4], out[6]
            st = values(mbpoll(d.port, "-0", "-t", "4", "-r", "8", "-c", "2").stdout)
            status, cnt = st[8], st[9]
        count += 1
        ex, ey, outside = ref.correct_nm(x, y)
        err = max(abs(gx - ex), abs(gy - ey))
        worst = max(worst, err)
        check(err <= 1.0, f"({x},{y}) -> ({gx},{gy}); expected ({ex:.2f},{ey:.2f})")
        check(status & 1 and bool(status & 2) == outside, f"status {status} for ({x},{y})")
        check(cnt == count, f"count {cnt} != {count}")
    # Writes to the read-only mirror and reads past the map: illegal data address.
    p = mbpoll(d.port, "-0", "-t", "4", "-r", "5", "--", "1", ok=False)
    check(p.returncode != 0 and "Illegal data address" in p.stdout + p.stderr,
          f"write to holding 5: {p.stdout} {p.stderr}")
    p = mbpoll(d.port, "-0", "-t", "3", "-r", "6", ok=False)
    check(p.returncode != 0 and "Illegal data address" in p.stdout + p.stderr,
          f"read input 6: {p.stdout} {p.stderr}")
    # Little-endian word order on the client against a high-word-first server: garbage, as a
    # word-order mistake should be (the test would not notice a swapped map otherwise).
    mbpoll(d.port, "-0", "-t", "4:int", "-r", "0", "--", "1000000", "2000000")
    out = values(mbpoll(d.port, "-0", "-t", "4:int", "-B", "-r", "0", "-c", "2").stdout)
    check(out[0] != 1000000, "word order not honoured")
finally:
    rc = d.stop()
check(rc == 0, f"selfcald exit status {rc}")
print(f"modbus tcp (mbpoll): ok; worst |corrected - independent| = {worst:.3f} nm")
