#!/usr/bin/env python3
"""selfcald attacked (issue 15 item 2), over Modbus TCP with raw sockets:

1. a SIGHUP storm: RELOADS reloads cycling through a valid table A, a corrupt table, a missing
   table and a valid table B while 4 clients stream positions: every request is answered, and
   every answer is the correction of A or of B (each within 1 nm of an independent evaluation of
   `selfcal lut dump`) with the table-loaded bit set; after the storm the last valid table is in
   force;
2. 1000 connections opened at once (cap 64) while a client is being served: the cap holds (the
   daemon never holds more than 64 client sockets), the served client is never evicted and keeps
   its latency (every request within 2 s: typically 30 ms, the margin is for a loaded CI machine);
3. 50 half-open connections (half a request, then silence) and a client sending one byte a second:
   each is closed by the byte timeout while a good client is served;
4. SIGTERM under load (8 streaming clients): exit 0 within 5 s.
usage: test_daemon_storm.py SELFCAL_CLI SELFCALD WORKDIR [RELOADS]"""
import os
import random
import signal
import socket
import struct
import sys
import threading
import time

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "modbus"))
from sclib import (Daemon, check, i32_to_regs, recv_exact,  # noqa: E402
                   regs_to_i32, reload_step, replace_file, storm_tables)

cli, selfcald, work = sys.argv[1], sys.argv[2], sys.argv[3]
reloads = int(sys.argv[4]) if len(sys.argv) > 4 else 1000
os.makedirs(work, exist_ok=True)
ref_a, ref_b, blob_a, blob_b, corrupt, live = storm_tables(cli, work)


def correct(s, tid, x, y):
    vals = i32_to_regs(x) + i32_to_regs(y)
    pdu = struct.pack(">BHHHHB", 23, 4, 6, 0, 4, 8) + struct.pack(">4H", *vals)
    s.sendall(struct.pack(">HHHB", tid & 0xFFFF, 0, len(pdu) + 1, 1) + pdu)
    rtid, _, ln, _ = struct.unpack(">HHHB", recv_exact(s, 7))
    r = recv_exact(s, ln - 1)
    if rtid != tid & 0xFFFF or r[0] != 23:
        raise AssertionError(f"bad reply {rtid} {r!r}")
    regs = struct.unpack(">6H", r[2:14])
    return regs_to_i32(regs[0:2]), regs_to_i32(regs[2:4]), regs[4]


def matches(ref, x, y, gx, gy):
    ex, ey, _ = ref.correct_nm(x, y)
    return abs(gx - ex) <= 1 and abs(gy - ey) <= 1


def streamer(port, seed, stop, stats, allowed, max_lat):
    rnd = random.Random(seed)
    try:
        s = socket.create_connection(("127.0.0.1", port))
        s.settimeout(5)
        tid = 0
        while not stop.is_set():
            x, y = rnd.randint(-9_000_000, 9_000_000), rnd.randint(-9_000_000, 9_000_000)
            t0 = time.time()
            gx, gy, st = correct(s, tid, x, y)
            lat = time.time() - t0
            stats["max_lat"] = max(stats["max_lat"], lat)
            tid += 1
            stats["answered"] += 1
            if not (st & 1) or not any(matches(r, x, y, gx, gy) for r in allowed):
                stats["wrong"] += 1
            if lat > max_lat:
                stats["slow"] += 1
        s.close()
    except Exception as e:  # noqa: BLE001 - any failure is a lost request
        stats["errors"].append(repr(e))


def new_stats():
    return {"answered": 0, "wrong": 0, "slow": 0, "errors": [], "max_lat": 0.0}


def daemon_fds(pid):
    return len(os.listdir(f"/proc/{pid}/fd"))


# 1. SIGHUP storm.
replace_file(live, blob_a)
d = Daemon(selfcald, live, ["--log-level", "notice", "--max-connections", "64",
                            "--byte-timeout-ms", "300", "--max-per-peer", "0"])  # one address
try:
    stop = threading.Event()
    stats = [new_stats() for _ in range(4)]
    threads = [threading.Thread(target=streamer, args=(d.port, k, stop, stats[k], (ref_a, ref_b),
                                                       2.0)) for k in range(4)]
    for t in threads:
        t.start()
    t0 = time.time()
    for k in range(reloads):
        reload_step(k, live, blob_a, corrupt, blob_b)
        d.signal(signal.SIGHUP)
        time.sleep(0.002)
    storm_s = time.time() - t0
    time.sleep(0.3)
    stop.set()
    for t in threads:
        t.join()
    answered = sum(s["answered"] for s in stats)
    wrong = sum(s["wrong"] for s in stats)
    errors = [e for s in stats for e in s["errors"]]
    check(not errors, f"storm: requests lost: {errors[:3]}")
    check(wrong == 0, f"storm: {wrong} of {answered} answers match neither table")
    check(answered > 100, f"storm: only {answered} answers")
    replace_file(live, blob_b)
    d.signal(signal.SIGHUP)
    time.sleep(0.3)
    s = socket.create_connection(("127.0.0.1", d.port))
    s.settimeout(5)
    gx, gy, st = correct(s, 1, 3_000_000, -1_000_000)
    check(matches(ref_b, 3_000_000, -1_000_000, gx, gy) and not st & 8,
          "after the storm the last valid table is not in force")
    s.close()
    print(f"SIGHUP storm: {reloads} reloads (valid A, corrupt, missing, valid B) in {storm_s:.1f} s "
          f"while 4 clients streamed: {answered} requests answered, 0 lost, {wrong} wrong, "
          f"max latency {max(x['max_lat'] for x in stats) * 1e3:.1f} ms")
finally:
    check(d.stop() == 0, "exit status after the storm")

# 2-4. Connection floods, half-open and trickling clients, SIGTERM under load.
replace_file(live, blob_a)
d = Daemon(selfcald, live, ["--log-level", "notice", "--max-connections", "64",
                            "--byte-timeout-ms", "300", "--max-per-peer", "0"])  # one address
try:
    pid = d.p.pid
    base_fds = daemon_fds(pid)
    stop = threading.Event()
    good = new_stats()
    gt = threading.Thread(target=streamer, args=(d.port, 99, stop, good, (ref_a,), 2.0))
    gt.start()
    time.sleep(0.2)
    flood, peak = [], 0
    for k in range(1000):
        try:
            c = socket.socket()
            c.setblocking(False)
            c.connect_ex(("127.0.0.1", d.port))
            flood.append(c)
        except OSError as e:
            check(False, f"flood: cannot open connection {k}: {e}")
            break
        if k % 50 == 0:
            peak = max(peak, daemon_fds(pid) - base_fds)
    time.sleep(0.5)
    peak = max(peak, daemon_fds(pid) - base_fds)
    # 64 client sockets (the good client's among them), plus one for an instant: a newcomer is
    # accepted before the connection it evicts is closed
    check(peak <= 64 + 1, f"flood: the daemon held {peak} more descriptors than at rest (cap 64)")
    for c in flood:
        c.close()
    # half-open connections and a one-byte-a-second client
    half = []
    for k in range(50):
        c = socket.create_connection(("127.0.0.1", d.port))
        c.sendall(bytes([0, 1, 0, 0, 0, 6, 1, 4]))  # 8 of 12 bytes
        c.settimeout(3)
        half.append(c)
    slow = socket.create_connection(("127.0.0.1", d.port))
    slow.settimeout(0.1)
    req = struct.pack(">HHHBBHH", 7, 0, 6, 1, 4, 0, 6)
    slow_closed = None
    t0 = time.time()
    for k, byte in enumerate(req):
        try:
            slow.send(bytes([byte]))
        except OSError:
            slow_closed = time.time() - t0
            break
        try:
            if slow.recv(64) == b"":
                slow_closed = time.time() - t0
                break
        except socket.timeout:
            pass
        time.sleep(0.9)
    check(slow_closed is not None and slow_closed < 3,
          f"one-byte-a-second client not closed by the byte timeout ({slow_closed})")
    closed = 0
    for c in half:
        try:
            closed += c.recv(16) == b""
        except (socket.timeout, ConnectionResetError):
            pass
        c.close()
    check(closed == 50, f"half-open: {closed} of 50 closed by the byte timeout")
    stop.set()
    gt.join()
    check(not good["errors"], f"flood: the served client failed: {good['errors'][:2]}")
    check(good["slow"] == 0 and good["wrong"] == 0,
          f"flood: served client: {good['slow']} slow, {good['wrong']} wrong answers")
    print(f"1000 connections at once: the daemon held at most {peak} client sockets (cap 64, +1 while evicting); the "
          f"served client: {good['answered']} answers, max latency {good['max_lat'] * 1e3:.1f} ms; "
          f"50 half-open and a 1-byte/s client closed by the byte timeout "
          f"(the trickler after {slow_closed:.1f} s)")
    # SIGTERM under load
    stop = threading.Event()
    load = [new_stats() for _ in range(8)]
    ts = [threading.Thread(target=streamer, args=(d.port, 200 + k, stop, load[k], (ref_a,), 5.0))
          for k in range(8)]
    for t in ts:
        t.start()
    time.sleep(0.5)
    t0 = time.time()
    d.signal(signal.SIGTERM)
    rc = d.p.wait(5)
    dt = time.time() - t0
    stop.set()
    for t in ts:
        t.join()
    check(rc == 0, f"SIGTERM under load: exit {rc}")
    check(sum(x["wrong"] for x in load) == 0, "SIGTERM under load: wrong answers before the stop")
    print(f"SIGTERM under load (8 clients, {sum(x['answered'] for x in load)} answers): exit {rc} "
          f"in {dt * 1e3:.0f} ms")
finally:
    d.stop()
print("PASS daemon storm")
