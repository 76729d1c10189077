#!/usr/bin/env python3
"""Defaults that survive a hostile neighbour (issue 36, item 3), measured on loopback (the
clients bind their own 127.x.y.z source addresses; nothing leaves the machine):
1. one address holding 64 busy connections (each reconnecting at once when closed) while a
   10 Hz client polls from another address, with the default configuration: the per-peer limit
   (a quarter of the cap, 16) keeps the neighbour to its share; the 10 Hz client loses no poll
   and never reconnects;
2. a burst of 1000 connects from 125 addresses (8 each) in 10 waves of 100, every one sending a
   request at once and staying open, while 10 clients poll at 5 Hz: none of the 10, all
   answered before the burst, is ever reset (at the cap only connections never answered, or
   silent for 1 s, make room; else the newcomer is closed); how many of the burst were answered
   or closed is printed;
3. --allow CIDR[,CIDR...] (a configuration line and a flag add up): peers outside are closed at
   accept and counted in the log, peers inside served (IPv4 and ::1); bad lists are refused with
   exit status 2.
usage: test_tcp_defaults.py SELFCAL_CLI SELFCALD WORKDIR [SECONDS]"""
import os
import resource
import select
import socket
import struct
import subprocess
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sclib import Daemon, check, i32_to_regs, make_table, recv_exact  # noqa: E402

cli, selfcald, work = sys.argv[1], sys.argv[2], sys.argv[3]
seconds = float(sys.argv[4]) if len(sys.argv) > 4 else 6.0
os.makedirs(work, exist_ok=True)
table, ref = make_table(cli, work, "defaults", n=7, pitch=2.0)
soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
if soft < 2300:
    resource.setrlimit(resource.RLIMIT_NOFILE, (min(hard, 4096), hard))

REQ = struct.pack(">BHHHHB", 23, 4, 6, 0, 4, 8) + struct.pack(">4H", *(i32_to_regs(1000) * 2))


def connect(port, src, timeout=2.0):
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.settimeout(timeout)
    s.bind((src, 0))
    s.connect(("127.0.0.1", port))
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return s


def request(s, tid):
    s.sendall(struct.pack(">HHHB", tid & 0xFFFF, 0, len(REQ) + 1, 1) + REQ)
    h = recv_exact(s, 7)
    body = recv_exact(s, struct.unpack(">H", h[4:6])[0] - 1)
    check(body[:2] == bytes([23, 12]), f"reply {body!r}")


class Poller(threading.Thread):
    """One client polling every period s from src: counts polls, losses and reconnects."""

    def __init__(self, port, src, period, stop):
        super().__init__(daemon=True)
        self.port, self.src, self.period, self.stop = port, src, period, stop
        self.polls = self.lost = self.reconnects = 0
        self.s = connect(port, src)
        request(self.s, 0)  # answered before anything else starts

    def run(self):
        tid = 1
        while not self.stop.is_set():
            t0 = time.monotonic()
            try:
                request(self.s, tid)
                self.polls += 1
            except (OSError, ConnectionError):
                self.lost += 1
                self.reconnects += 1
                self.s.close()
                try:
                    self.s = connect(self.port, self.src)
                except OSError:
                    pass
            tid += 1
            time.sleep(max(0.0, self.period - (time.monotonic() - t0)))
        self.s.close()


def hostile(port, src, stop, counts):
    """A busy connection that reconnects at once whenever it is closed."""
    s = None
    while not stop.is_set():
        try:
            if s is None:
                s = connect(port, src, timeout=1.0)
                counts["connects"] += 1
            request(s, 7)
            counts["answers"] += 1
        except (OSError, ConnectionError):
            counts["closed"] += 1
            if s is not None:
                s.close()
            s = None
            time.sleep(0.002)
    if s is not None:
        s.close()


# 1. A hostile neighbour with the default configuration.
d = Daemon(selfcald, table, log_path=os.path.join(work, "neighbour.log"))
try:
    check("16 per peer" in d.text(), "the per-peer default (a quarter of 64) not in the log")
    stop = threading.Event()
    counts = {"connects": 0, "answers": 0, "closed": 0}
    threads = [threading.Thread(target=hostile, args=(d.port, "127.0.0.2", stop, counts),
                                daemon=True) for _ in range(64)]
    for t in threads:
        t.start()
    time.sleep(0.5)
    p = Poller(d.port, "127.0.0.1", 0.1, stop)
    p.start()
    time.sleep(seconds)
    stop.set()
    p.join(10)
    for t in threads:
        t.join(10)
    print(f"hostile neighbour (64 busy connections from 127.0.0.2, {seconds:.0f} s): the 10 Hz "
          f"client polled {p.polls} times, lost {p.lost}, reconnected {p.reconnects}; the "
          f"neighbour got {counts['answers']} answers, {counts['closed']} closes")
    check(p.lost == 0 and p.reconnects == 0 and p.polls >= seconds * 10 * 0.5,
          f"the 10 Hz client: {p.polls} polls, {p.lost} lost, {p.reconnects} reconnects")
    check("per-peer limit" in d.text(), "per-peer refusals not logged")
finally:
    rc = d.stop()
check(rc == 0, f"selfcald exit status {rc}")

# 2. A burst of 1000 connects while 10 clients are being served.
def burst_wave(port, first, n, keep):
    """n connects from their own addresses, each sending a request at once; the sockets stay open
    (answered and silent, like a flood that was served). Returns (answered, closed)."""
    socks = []
    for k in range(first, first + n):
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.bind((f"127.1.{k // 8 // 250}.{k // 8 % 250 + 1}", 0))
        s.setblocking(False)
        s.connect_ex(("127.0.0.1", port))
        socks.append(s)
    frame = struct.pack(">HHHB", 9, 0, len(REQ) + 1, 1) + REQ
    for s in socks:
        select.select([], [s], [], 2.0)
        try:
            s.send(frame)
        except OSError:
            pass
    answered = closed = 0
    left = set(socks)
    end = time.monotonic() + 5
    while left and time.monotonic() < end:
        r, _, _ = select.select(list(left), [], [], 0.2)
        for s in r:
            try:
                got = s.recv(64)
            except OSError:
                got = b""
            if got:
                answered += 1
            else:
                closed += 1
                s.close()
            left.discard(s)
    keep.extend(s for s in socks if s.fileno() >= 0)
    return answered, closed


d = Daemon(selfcald, table, ["--log-level", "notice"], log_path=os.path.join(work, "burst.log"))
keep = []
try:
    stop = threading.Event()
    pollers = [Poller(d.port, "127.0.0.1", 0.2, stop) for _ in range(10)]
    for p in pollers:
        p.start()
    time.sleep(0.5)
    answered = closed = 0
    for w in range(10):  # 10 waves of 100, back to back
        a, c = burst_wave(d.port, 100 * w, 100, keep)
        answered += a
        closed += c
    time.sleep(0.5)
    stop.set()
    for p in pollers:
        p.join(10)
    lost = sum(p.lost for p in pollers)
    polls = sum(p.polls for p in pollers)
    print(f"connect burst (1000 from 125 addresses in 10 waves, each sending a request and staying "
          f"open): {answered} answered, {closed} closed; the 10 clients (5 Hz) served before it: "
          f"{polls} polls, {lost} lost, {sum(p.reconnects for p in pollers)} reconnects")
    check(lost == 0, f"a client already answered was reset by the burst ({lost} polls lost)")
    check(answered >= 1, "nobody of the burst was answered")
finally:
    for s in keep:
        s.close()
    rc = d.stop()
check(rc == 0, f"selfcald exit status {rc}")

# 3. The allow-list.
for bad in ("10.0.0.0/33", "127.0.0.1/", "bogus", "", "::1/129", ",", "1.2.3.4,"):
    r = subprocess.run([selfcald, "--table", table, "--allow", bad], capture_output=True,
                       text=True, timeout=30)
    check(r.returncode == 2 and "--allow" in r.stderr, f"--allow '{bad}': {r.returncode} {r.stderr!r}")
conf = os.path.join(work, "allow.conf")
with open(conf, "w") as f:
    f.write("allow = 127.3.0.0/16\n")
# a configuration line and a flag add up (as IPAddressAllow= lines)
d = Daemon(selfcald, table, ["--config", conf, "--allow", "127.0.0.2/32, ::1"],
           log_path=os.path.join(work, "allow.log"))
try:
    for src in ("127.0.0.2", "127.3.200.1"):
        s = connect(d.port, src)
        request(s, 1)
        s.close()
    denied = 0
    for src in ("127.0.0.1", "127.0.0.3", "127.4.0.1"):
        s = connect(d.port, src)
        try:
            request(s, 1)
            check(False, f"{src} answered despite the allow-list")
        except (OSError, ConnectionError):
            denied += 1
        s.close()
    time.sleep(0.2)
    check(d.text().count("not in the allow-list") == 3, "denials not logged and counted")
    check("3 denied so far" in d.text(), "denials not counted")
finally:
    rc = d.stop()
check(rc == 0, f"selfcald exit status {rc}")
if socket.has_ipv6:
    try:
        d = Daemon(selfcald, table, ["--modbus-tcp", "[::1]:0", "--allow", "::1/128"], tcp=False,
                   log_path=os.path.join(work, "allow6.log"))
    except RuntimeError as e:
        d = None
        print(f"no IPv6 loopback here: {e}")
    if d is not None:
        try:
            import re
            port = int(re.search(r"listening on \[::1\]:(\d+)", d.text()).group(1))
            s = socket.create_connection(("::1", port), timeout=2)
            request(s, 1)
            s.close()
        finally:
            rc = d.stop()
        check(rc == 0, f"selfcald exit status {rc}")
print("tcp defaults: ok")
