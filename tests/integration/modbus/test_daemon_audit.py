#!/usr/bin/env python3
"""The availability findings of the outside audit (issue 15 item 6), each attacked as found:

1. a log sink that stops draining (stderr a full pipe nobody reads) while garbage connections
   each log a line: the loop must keep answering (logging drops and counts, never blocks);
2. a FIFO at the table path, then SIGHUP: the reload is refused at once, clients keep being
   answered from the old table (status bit 3 set);
3. the listen address: 0127.0.0.1 and other legacy numeric forms are refused (exit 2, one line);
   `localhost` binds 127.0.0.1 and says so; [::1] serves IPv6 (when the host has it);
4. function 17 (report server id) is answered by selfcald ("selfcal", the unit id, running), never
   with the library's version; a function code >= 0x80 gets exception 01 with its own code.
Raw sockets only (the wire bytes are what is checked).
usage: test_daemon_audit.py SELFCAL_CLI SELFCALD WORKDIR"""
import fcntl
import os
import re
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sclib import Daemon, check, i32_to_regs, make_table, recv_exact, regs_to_i32  # noqa: E402

cli, selfcald, work = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(work, exist_ok=True)
table, ref = make_table(cli, work, "audit", n=7, pitch=2.0)


def transact(s, tid, pdu, unit=1):
    """One Modbus TCP request; returns the response PDU (checks the MBAP echo)."""
    s.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu)
    rtid, proto, ln, runit = struct.unpack(">HHHB", recv_exact(s, 7))
    check(rtid == tid and proto == 0 and runit == unit, f"MBAP echo {rtid} {proto} {runit}")
    return recv_exact(s, ln - 1)


def correct(s, tid, x, y, unit=1):
    """Function 23: write 0-3, read 4-9; returns (x, y, status)."""
    vals = i32_to_regs(x) + i32_to_regs(y)
    pdu = struct.pack(">BHHHHB", 23, 4, 6, 0, 4, 8) + struct.pack(">4H", *vals)
    r = transact(s, tid, pdu, unit)
    check(r[0] == 23 and r[1] == 12, f"fn23 reply {r!r}")
    regs = struct.unpack(">6H", r[2:14])
    return regs_to_i32(regs[0:2]), regs_to_i32(regs[2:4]), regs[4]


def timed_correct(s, tid, x, y, limit_s):
    t0 = time.time()
    out = correct(s, tid, x, y)
    dt = time.time() - t0
    check(dt < limit_s, f"request took {dt:.3f} s (limit {limit_s} s): the loop stalled")
    return out


# 1. A log sink that stops draining.
r_fd, w_fd = os.pipe()
p = subprocess.Popen([selfcald, "--table", table, "--modbus-tcp", "127.0.0.1:0", "--log-level",
                      "debug"], stderr=w_fd, stdout=subprocess.DEVNULL)
os.close(w_fd)
try:
    text = b""
    deadline = time.time() + 10
    port = None
    while time.time() < deadline and (port is None or b"ready" not in text):
        text += os.read(r_fd, 4096)
        m = re.search(rb"listening on [0-9.]+:(\d+)", text)
        port = int(m.group(1)) if m else None
    check(port is not None and b"ready" in text, f"daemon not ready: {text!r}")
    # From here on nobody reads the pipe. Fill it to the brim (a stalled journal) through a
    # second descriptor on the same pipe.
    w2 = os.open(f"/proc/{p.pid}/fd/2", os.O_WRONLY | os.O_NONBLOCK)
    filled = 0
    try:
        while True:
            filled += os.write(w2, b"x" * 4096)
    except BlockingIOError:
        pass
    try:
        while True:
            filled += os.write(w2, b"x")
    except BlockingIOError:
        pass
    os.close(w2)
    good = socket.create_connection(("127.0.0.1", port))
    good.settimeout(5)
    x, y = 1_000_000, -2_000_000
    ex, ey, _ = ref.correct_nm(x, y)
    for k in range(300):
        g = socket.create_connection(("127.0.0.1", port))
        g.sendall(b"GET / HTTP/1.0\r\n\r\n")  # not Modbus: closed, and a line is logged
        g.close()
        if k % 10 == 0:
            gx, gy, st = timed_correct(good, k, x, y, 1.0)
            check(abs(gx - ex) <= 1 and abs(gy - ey) <= 1, f"wrong answer {gx},{gy}")
    check(p.poll() is None, "daemon died with a full log pipe")
    good.close()
    p.send_signal(signal.SIGTERM)
    # Drain now, so the last lines can go out; the daemon must stop cleanly either way.
    fcntl.fcntl(r_fd, fcntl.F_SETFL, os.O_NONBLOCK)
    end = time.time() + 10
    rest = b""
    while p.poll() is None and time.time() < end:
        try:
            rest += os.read(r_fd, 65536)
        except BlockingIOError:
            time.sleep(0.01)
    check(p.poll() == 0, f"exit status {p.poll()} after SIGTERM with a stalled log")
    print(f"log pipe: {filled} bytes pre-filled; daemon served through it")
finally:
    if p.poll() is None:
        p.kill()
    os.close(r_fd)

# 2. A FIFO at the table path: SIGHUP must not block the loop.
live = os.path.join(work, "live.lut")
shutil.copyfile(table, live)
d = Daemon(selfcald, live)
try:
    s = socket.create_connection(("127.0.0.1", d.port))
    s.settimeout(5)
    x, y = 2_500_000, 1_500_000
    before = correct(s, 1, x, y)
    os.unlink(live)
    os.mkfifo(live)
    d.signal(signal.SIGHUP)
    time.sleep(0.2)
    for k in range(5):
        after = timed_correct(s, 2 + k, x, y, 1.0)
    check(after[:2] == before[:2], f"answers changed after a refused reload: {before} {after}")
    check(after[2] & 8, f"status {after[2]}: reload-failed bit clear")
    check("not a regular file" in d.text(), "the FIFO reload was not refused as such")
    os.unlink(live)
    shutil.copyfile(table, live)
    d.signal(signal.SIGHUP)
    time.sleep(0.3)
    check(not correct(s, 10, x, y)[2] & 8, "a valid reload did not clear the failed bit")
    s.close()
finally:
    check(d.stop() == 0, "exit status")

# 3. The listen address.
for bad in ["0127.0.0.1:0", "127.1:0", "0x7f.0.0.1:0", "1.2.3.4.5:0", "::1:0", "[::1:0"]:
    r = subprocess.run([selfcald, "--table", table, "--modbus-tcp", bad], capture_output=True,
                       text=True, timeout=10)
    check(r.returncode == 2, f"--modbus-tcp {bad}: exit {r.returncode}, expected 2")
    lines = r.stderr.strip().splitlines()
    check(len(lines) == 1 and "modbus-tcp" in lines[0], f"--modbus-tcp {bad}: {r.stderr!r}")
d = Daemon(selfcald, table, ["--modbus-tcp", "localhost:0"], tcp=False)
try:
    m = re.search(r"listening on ([0-9.]+):(\d+)", d.text())
    check(m is not None and m.group(1) == "127.0.0.1", f"localhost bound: {d.text()}")
    s = socket.create_connection(("127.0.0.1", int(m.group(2))))
    s.settimeout(5)
    correct(s, 1, 0, 0)
    s.close()
finally:
    check(d.stop() == 0, "exit status (localhost)")
has_v6 = True
try:
    t = socket.socket(socket.AF_INET6, socket.SOCK_STREAM)
    t.bind(("::1", 0))
    t.close()
except OSError:
    has_v6 = False
if has_v6:
    d = Daemon(selfcald, table, ["--modbus-tcp", "[::1]:0"], tcp=False)
    try:
        m = re.search(r"listening on \[::1\]:(\d+)", d.text())
        check(m is not None, f"[::1] bound: {d.text()}")
        s = socket.create_connection(("::1", int(m.group(1))))
        s.settimeout(5)
        correct(s, 1, 0, 0)
        s.close()
    finally:
        check(d.stop() == 0, "exit status (::1)")
else:
    print("no IPv6 loopback here: [::1] not tried")

# 4. Function 17 and function codes >= 0x80.
d = Daemon(selfcald, table, ["--unit-id", "7"])
try:
    s = socket.create_connection(("127.0.0.1", d.port))
    s.settimeout(5)
    r = transact(s, 1, bytes([0x11]), unit=7)
    check(r[0] == 0x11 and r[1] == len(r) - 2, f"fn17 reply {r!r}")
    check(r[2] == 7 and r[3] == 0xFF and r[4:] == b"selfcal", f"fn17 content {r!r}")
    check(b"LMB" not in r, "fn17 discloses the library version")
    for fn in (0x80, 0x85, 0xAB, 0xFF, 0x2B, 0x08):
        r = transact(s, 2, bytes([fn, 0, 0, 0, 1]), unit=7)
        check(r == bytes([fn | 0x80, 1]), f"fn {fn:#x}: reply {r!r}, expected exception 01")
    # A PDU longer or shorter than its function and counts say: exception 03, nothing changed
    # (the MBAP length carries the extra byte, so the framing itself stays in step).
    odd = [bytes([0x03, 0, 0, 0, 2, 0]), bytes([0x04, 0, 0, 0, 2, 0xAA]), bytes([0x04, 0, 0, 0]),
           bytes([0x11, 0]), bytes([0x11, 1, 2, 3]), bytes([0x06, 0, 0, 0, 5, 9]),
           bytes([0x16, 0, 0, 0xFF, 0xFF, 0, 0, 1]),
           struct.pack(">BHHB", 16, 0, 1, 2) + b"\0\1\2",
           struct.pack(">BHHHHB", 23, 4, 6, 0, 4, 8) + bytes(9),
           bytes([0x01, 0, 0, 0, 1, 0]), bytes([0x0F, 0, 0, 0, 8, 1, 0xFF, 0])]
    before = transact(s, 4, struct.pack(">BHH", 3, 0, 10), unit=7)
    for k, pdu in enumerate(odd):
        r = transact(s, 10 + k, pdu, unit=7)
        check(r == bytes([pdu[0] | 0x80, 3]), f"fn {pdu[0]:#x} with {len(pdu)} bytes: reply {r!r}, "
              f"expected exception 03")
    check(transact(s, 5, struct.pack(">BHH", 3, 0, 10), unit=7) == before,
          "a malformed request changed registers")
    check(correct(s, 3, 0, 0, unit=7)[2] & 1, "still serving after the odd requests")
finally:
    d.stop()
print("audit findings: all closed")
