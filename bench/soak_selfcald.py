#!/usr/bin/env python3
"""Soak benchmark of selfcald (issue 15 item 4; not a CI test): SECONDS (default 600) of 64 Modbus
TCP clients streaming positions (function 23) while reload storms hit the daemon every 2 s (50
SIGHUPs cycling through a valid table A, a corrupt table, a missing table and a valid table B).

Every answer is checked against an independent evaluation of both tables (`selfcal lut dump`,
bilinear, within 1 nm): it must be the correction of A or of B, with the table-loaded bit set.
Printed: requests answered, wrong answers, lost requests (a timeout, a closed connection or a
malformed reply), reloads, and the daemon's resident memory (VmRSS) sampled every 5 s: its first
sample after warm-up, its last, and the largest change. The goal: 0 wrong, 0 lost, RSS flat.
usage: soak_selfcald.py SELFCAL_CLI SELFCALD [SECONDS] [CLIENTS]"""
import os
import random
import signal
import socket
import struct
import sys
import tempfile
import threading
import time

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "tests", "integration", "modbus"))
from sclib import (Daemon, i32_to_regs, recv_exact,  # noqa: E402
                   regs_to_i32, reload_step, replace_file, storm_tables)

cli, selfcald = sys.argv[1], sys.argv[2]
seconds = float(sys.argv[3]) if len(sys.argv) > 3 else 600.0
nclients = int(sys.argv[4]) if len(sys.argv) > 4 else 64
work = tempfile.mkdtemp(prefix="selfcal-soak-")
ref_a, ref_b, blob_a, blob_b, corrupt, live = storm_tables(cli, work)


def ok(ref, x, y, gx, gy):
    ex, ey, _ = ref.correct_nm(x, y)
    return abs(gx - ex) <= 1 and abs(gy - ey) <= 1


stop = threading.Event()
lock = threading.Lock()
totals = {"answered": 0, "wrong": 0, "lost": 0, "max_lat": 0.0}


def client(port, seed):
    rnd = random.Random(seed)
    answered = wrong = lost = 0
    max_lat = 0.0
    s = None
    tid = 0
    while not stop.is_set():
        try:
            if s is None:
                s = socket.create_connection(("127.0.0.1", port))
                s.settimeout(5)
            x, y = rnd.randint(-9_000_000, 9_000_000), rnd.randint(-9_000_000, 9_000_000)
            vals = i32_to_regs(x) + i32_to_regs(y)
            pdu = struct.pack(">BHHHHB", 23, 4, 6, 0, 4, 8) + struct.pack(">4H", *vals)
            t0 = time.time()
            s.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, 1) + pdu)
            rtid, _, ln, _ = struct.unpack(">HHHB", recv_exact(s, 7))
            r = recv_exact(s, ln - 1)
            max_lat = max(max_lat, time.time() - t0)
            if rtid != tid or r[0] != 23 or len(r) != 14:
                raise ValueError("malformed reply")
            regs = struct.unpack(">6H", r[2:14])
            gx, gy = regs_to_i32(regs[0:2]), regs_to_i32(regs[2:4])
            answered += 1
            if not (regs[4] & 1) or not (ok(ref_a, x, y, gx, gy) or ok(ref_b, x, y, gx, gy)):
                wrong += 1
            tid = (tid + 1) & 0xFFFF
        except (OSError, ValueError, ConnectionError):
            if stop.is_set():
                break
            lost += 1
            if s is not None:
                s.close()
            s = None
    if s is not None:
        s.close()
    with lock:
        totals["answered"] += answered
        totals["wrong"] += wrong
        totals["lost"] += lost
        totals["max_lat"] = max(totals["max_lat"], max_lat)


def rss_kib(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return -1


replace_file(live, blob_a)
# all 64 clients come from 127.0.0.1: no per-peer limit (the default would be 19)
d = Daemon(selfcald, live, ["--log-level", "notice", "--max-connections", "79",
                            "--max-per-peer", "0"])
reloads = 0
samples = []
try:
    threads = [threading.Thread(target=client, args=(d.port, k)) for k in range(nclients)]
    for t in threads:
        t.start()
    t_start = time.time()
    next_storm = t_start + 2
    next_sample = t_start + 5
    k = 0
    while time.time() - t_start < seconds:
        now = time.time()
        if now >= next_storm:
            for _ in range(50):
                reload_step(k, live, blob_a, corrupt, blob_b)
                d.signal(signal.SIGHUP)
                reloads += 1
                k += 1
                time.sleep(0.002)
            next_storm = now + 2
        if now >= next_sample:
            samples.append((now - t_start, rss_kib(d.p.pid)))
            next_sample = now + 5
        time.sleep(0.05)
    stop.set()
    for t in threads:
        t.join()
    alive = d.p.poll() is None
finally:
    rc = d.stop()
elapsed = time.time() - t_start
warm = [r for t, r in samples if t >= min(30.0, seconds / 4)] or [r for _, r in samples]
print(f"selfcald soak: {elapsed:.0f} s, {nclients} clients, {reloads} reloads (storms of 50 every "
      "2 s: valid A, corrupt, missing, valid B)")
print("| seconds | clients | answered | req/s | wrong | lost | reloads | max latency (ms) | "
      "RSS first (KiB) | RSS last (KiB) | RSS change max-min (KiB) | exit |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
print(f"| {elapsed:.0f} | {nclients} | {totals['answered']} | {totals['answered'] / elapsed:.0f} | "
      f"{totals['wrong']} | {totals['lost']} | {reloads} | {totals['max_lat'] * 1e3:.1f} | "
      f"{warm[0] if warm else -1} | {warm[-1] if warm else -1} | "
      f"{(max(warm) - min(warm)) if warm else -1} | {rc} |")
good = totals["wrong"] == 0 and totals["lost"] == 0 and alive and rc == 0 and \
    (max(warm) - min(warm) <= 64 if warm else True)
print("goal: 0 wrong, 0 lost, RSS flat (within 64 KiB after warm-up):", "met" if good else "NOT met")
sys.exit(0 if good else 1)
