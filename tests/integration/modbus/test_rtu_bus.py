#!/usr/bin/env python3
"""selfcald (unit 3) as one slave on a simulated multi-drop Modbus RTU line: one end of a socat
pseudo-terminal pair is the daemon's serial device; on the other this test plays the master and a
second slave (unit 2). Between our function-23 requests the master talks to unit 2 and unit 2
answers: function-3 requests and responses, an exception (83 02), a function-0x2B request and
response (no length known from the function), function-16 and function-23 traffic addressed to
unit 2 (valid requests for our register map: must stay unanswered), broadcasts and a read for
unit 4, each frame after the specification's minimal gap t3.5 (Modbus over Serial Line V1.02
§2.5.1.1: 3.5 characters of 11 bits, 1.75 ms above 19 200 baud) plus 0.3 ms.

A pty has no baud timing: a frame written in one write() arrives in one piece, and the gaps the
test sleeps are the gaps on the line, though a late reader (ASan, ctest -j2) may see two frames
in one read. So the framing must hold both ways: split by silence, and cut by length and CRC
within one read. A second phase writes the other traffic and our request back to back in one
write(), the extreme of a late read.

Checks, at 9 600, 19 200 and 115 200 baud: >= 999 of 1000 of our requests answered with the
right correction (within 1 nm of an independent evaluation of `selfcal lut dump`), and every byte
the daemon sent is one of those answers (nothing answered that was not ours).
usage: test_rtu_bus.py SELFCAL_CLI SELFCALD WORKDIR [N]"""
import os
import random
import select
import struct
import sys
import time
import tty

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sclib import Daemon, check, make_table, pty_pair, regs_to_i32  # noqa: E402

UNIT, OTHER = 3, 2


def crc16(b):
    c = 0xFFFF
    for x in b:
        c ^= x
        for _ in range(8):
            c = (c >> 1) ^ 0xA001 if c & 1 else c >> 1
    return c


def frame(*parts):
    b = bytes(parts[0]) if len(parts) == 1 else bytes(parts)
    return b + struct.pack("<H", crc16(b))


def regs_be(vals):
    return b"".join(struct.pack(">H", v & 0xFFFF) for v in vals)


def i32_regs(v):
    u = v & 0xFFFFFFFF
    return [u >> 16, u & 0xFFFF]


def our_request(x, y):
    """function 23: write holding 0-3 (x, y), read holding 4-9 (the result)."""
    vals = i32_regs(x) + i32_regs(y)
    return frame(bytes([UNIT, 23, 0, 4, 0, 6, 0, 0, 0, 4, 8]) + regs_be(vals))


def other_traffic(rng, k):
    """The master's exchange with unit 2 (or a broadcast / unit 4) of kind k: a list of frames."""
    kind = k % 7
    if kind == 0:  # read holding registers from unit 2, and its 9-byte response
        return [frame(bytes([OTHER, 3, 0, 0, 0, 2])),
                frame(bytes([OTHER, 3, 4]) + bytes(rng.randrange(256) for _ in range(4)))]
    if kind == 1:  # the same request, answered by an exception (illegal data address)
        return [frame(bytes([OTHER, 3, 0, 100, 0, 2])), frame(bytes([OTHER, 0x83, 2]))]
    if kind == 2:  # function 0x2B (read device identification): no length from the function
        name = bytes(rng.choice(b"ABCDEFGH") for _ in range(rng.randrange(3, 30)))
        return [frame(bytes([OTHER, 0x2B, 0x0E, 1, 0])),
                frame(bytes([OTHER, 0x2B, 0x0E, 1, 1, 0, 0, 1, 0, len(name)]) + name)]
    if kind == 3:  # function 23 to unit 2: a request our map would answer
        vals = [rng.randrange(65536) for _ in range(4)]
        return [frame(bytes([OTHER, 23, 0, 4, 0, 6, 0, 0, 0, 4, 8]) + regs_be(vals)),
                frame(bytes([OTHER, 23, 12]) + bytes(rng.randrange(256) for _ in range(12)))]
    if kind == 4:  # function 16 to unit 2 and its echo
        vals = [rng.randrange(65536) for _ in range(4)]
        return [frame(bytes([OTHER, 16, 0, 0, 0, 4, 8]) + regs_be(vals)),
                frame(bytes([OTHER, 16, 0, 0, 0, 4]))]
    if kind == 5:  # a broadcast write (nobody answers)
        return [frame(bytes([0, 16, 0, 0, 0, 2, 4]) + regs_be([1, 2]))]
    # a read for unit 4, which is not on the line (no answer)
    return [frame(bytes([4, 4, 0, 0, 0, 6]))]


class Line:
    def __init__(self, path):
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            tty.setraw(self.fd)
        except Exception:
            pass
        self.rx = b""

    def write(self, b):
        while b:
            try:
                n = os.write(self.fd, b)
            except BlockingIOError:
                select.select([], [self.fd], [], 0.1)
                continue
            b = b[n:]

    def read_until(self, n, timeout):
        """Read until the buffer holds n bytes or timeout s pass."""
        end = time.monotonic() + timeout
        while len(self.rx) < n:
            left = end - time.monotonic()
            if left <= 0:
                break
            r, _, _ = select.select([self.fd], [], [], left)
            if r:
                try:
                    self.rx += os.read(self.fd, 4096)
                except BlockingIOError:
                    pass

    def close(self):
        os.close(self.fd)


def sleep_at_least(s):
    end = time.monotonic() + s
    while True:
        left = end - time.monotonic()
        if left <= 0:
            return
        time.sleep(left)


def run(baud, n, back_to_back, line, ref, rng):
    """n of our requests with the other traffic between them; returns (answered, corrections)."""
    t35 = 0.00175 if baud > 19200 else 3.5 * 11 / baud
    gap = t35 + 0.0003
    answered = 0
    for k in range(n):
        frames = other_traffic(rng, k)
        x, y = rng.randint(-10_500_000, 10_500_000), rng.randint(-10_500_000, 10_500_000)
        req = our_request(x, y)
        if back_to_back:
            line.write(b"".join(frames) + req)
        else:
            for f in frames:
                line.write(f)
                sleep_at_least(gap)
            line.write(req)
        line.read_until(17, 1.0)
        if len(line.rx) < 17:
            check(line.rx == b"", f"{baud} baud, request {k}: a partial answer {line.rx.hex()}")
            print(f"  {baud} baud: request {k} (after kind {k % 7}) not answered", file=sys.stderr)
            continue
        resp, line.rx = line.rx[:17], line.rx[17:]
        check(resp[:3] == bytes([UNIT, 23, 12]) and crc16(resp[:15]) == struct.unpack("<H", resp[15:])[0],
              f"{baud} baud, request {k}: not our answer: {resp.hex()}")
        regs = list(struct.unpack(">6H", resp[3:15]))
        gx, gy = regs_to_i32(regs[0:2]), regs_to_i32(regs[2:4])
        ex, ey, _ = ref.correct_nm(x, y)
        check(max(abs(gx - ex), abs(gy - ey)) <= 1.0,
              f"{baud} baud, request {k}: ({x},{y}) -> ({gx},{gy}), expected ({ex:.2f},{ey:.2f})")
        check(line.rx == b"", f"{baud} baud, request {k}: more than our answer: {line.rx.hex()}")
        answered += 1
        sleep_at_least(gap)
    # anything late (an answer to a frame that was not ours) shows up here
    line.read_until(1, 0.3)
    check(line.rx == b"", f"{baud} baud: answered something that was not ours: {line.rx.hex()}")
    return answered


def main():
    cli, selfcald, work = sys.argv[1], sys.argv[2], sys.argv[3]
    n = int(sys.argv[4]) if len(sys.argv) > 4 else 1000
    os.makedirs(work, exist_ok=True)
    table, ref = make_table(cli, work, "bus", n=7, pitch=3.0, scale_um=1.0)
    rng = random.Random(36)
    for baud in (9600, 19200, 115200):
        a, b, socat = pty_pair(work, baud)
        d = None
        try:
            d = Daemon(selfcald, table, ["--modbus-rtu", f"{a}:{baud}:E:8:1", "--unit-id",
                                         str(UNIT)], tcp=False,
                       log_path=os.path.join(work, f"bus{baud}.log"))
            line = Line(b)
            t0 = time.monotonic()
            got = run(baud, n, False, line, ref, rng)
            t1 = time.monotonic()
            check(got >= n - n // 1000, f"{baud} baud: {got} of {n} answered")
            m = max(n // 10, 10)
            got2 = run(baud, m, True, line, ref, rng)
            check(got2 >= m - m // 1000, f"{baud} baud, back to back: {got2} of {m} answered")
            line.close()
            print(f"rtu bus at {baud} baud: {got} of {n} answered between other traffic "
                  f"({(t1 - t0) / n * 1000:.1f} ms a round), {got2} of {m} back to back")
        finally:
            rc = d.stop() if d else 0
            socat.terminate()
            socat.wait()
        check(rc == 0, f"selfcald exit status {rc}")
    print("rtu bus: ok")


main()
