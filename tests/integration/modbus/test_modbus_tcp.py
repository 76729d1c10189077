#!/usr/bin/env python3
"""selfcald over Modbus TCP on loopback, driven by pymodbus (a peer we did not write).

Every corrected position is compared with an independent bilinear evaluation of the table as
printed by `selfcal lut dump`; exceptions, unit id, word order, function 23 atomicity with
concurrent clients, byte timeout against a stalled client, the connection cap and SIGHUP reload
(corrupt table kept out, valid table swapped in) are checked, and function 22 (mask write) on the
Modbus specification's own example.
usage: test_modbus_tcp.py SELFCAL_CLI SELFCALD WORKDIR"""
import os
import random
import shutil
import signal
import socket
import struct
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sclib import Daemon, check, i32_to_regs, make_table, regs_to_i32  # noqa: E402

from pymodbus.client import ModbusTcpClient  # noqa: E402

cli, selfcald, work = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(work, exist_ok=True)
rng = random.Random(20261121)
table, ref = make_table(cli, work, "tcp", n=11, pitch=2.0, scale_um=1.5)
table2, ref2 = make_table(cli, work, "tcp2", n=11, pitch=2.0, scale_um=-2.5, phase=0.7)
live = os.path.join(work, "live.lut")
shutil.copyfile(table, live)

ILLEGAL_ADDRESS = 2
worst = 0.0


def expect_ok(r, what):
    check(not r.isError(), f"{what}: {r}")
    return r


def expect_exc(r, code, what):
    check(r.isError() and getattr(r, "exception_code", None) == code,
          f"{what}: expected exception {code}, got {r}")


def roundtrip(c, x, y, hf=True, unit=1):
    """One function 23: write 0-3, read 4-9."""
    r = expect_ok(c.readwrite_registers(read_address=4, read_count=6, write_address=0,
                                        values=i32_to_regs(x, hf) + i32_to_regs(y, hf),
                                        device_id=unit), "fn23")
    reg = r.registers
    return regs_to_i32(reg[0:2], hf), regs_to_i32(reg[2:4], hf), reg[4], reg[5]


def check_point(x, y, got_x, got_y, status, r=ref, mode="measure"):
    global worst
    ex, ey, out = r.correct_nm(x, y, mode)
    err = max(abs(got_x - ex), abs(got_y - ey))
    worst = max(worst, err)
    # The table stores the grid exactly as dumped; the core interpolates in single precision and
    # rounds to the nearest nm: within 1 nm of the exact evaluation.
    check(err <= 1.0, f"({x},{y}) -> ({got_x},{got_y}), expected ({ex:.2f},{ey:.2f})")
    check(status & 1, f"status {status}: table-loaded bit clear")
    check(bool(status & 2) == out, f"({x},{y}): outside bit {status & 2} but outside={out}")


# every client comes from 127.0.0.1: no per-peer limit here (it_tcp_defaults tests it)
d = Daemon(selfcald, live, ["--byte-timeout-ms", "300", "--max-connections", "12",
                            "--max-per-peer", "0"])
try:
    c = ModbusTcpClient("127.0.0.1", port=d.port, timeout=2, retries=0)
    check(c.connect(), "connect")
    # 1. function 16 then function 4 (input registers) and function 3 (holding mirror).
    count = None
    for k in range(300):
        x = rng.randint(-12_500_000, 12_500_000)  # grid spans +-10 mm: some points outside
        y = rng.randint(-12_500_000, 12_500_000)
        expect_ok(c.write_registers(0, i32_to_regs(x) + i32_to_regs(y)), "fn16")
        inp = expect_ok(c.read_input_registers(0, count=6), "fn4").registers
        hold = expect_ok(c.read_holding_registers(0, count=10), "fn3").registers
        check(hold[4:10] == inp, f"holding 4-9 {hold[4:10]} != input 0-5 {inp}")
        check(regs_to_i32(hold[0:2]) == x and regs_to_i32(hold[2:4]) == y, "holding 0-3 echo")
        check_point(x, y, regs_to_i32(inp[0:2]), regs_to_i32(inp[2:4]), inp[4])
        if count is not None:
            check(inp[5] == (count + 1) & 0xFFFF, f"count {inp[5]} after {count}")
        count = inp[5]
    # 2. function 23 round trips, extremes included.
    pts = [(0, 0), (10_000_000, -10_000_000), (-10_000_000, 10_000_000), (2**31 - 1, -2**31),
           (1, -1), (9_999_999, 9_999_999)] + [(rng.randint(-11_000_000, 11_000_000),
                                                 rng.randint(-11_000_000, 11_000_000))
                                                for _ in range(500)]
    for x, y in pts:
        gx, gy, st, cnt = roundtrip(c, x, y)
        count = (count + 1) & 0xFFFF
        check(cnt == count, f"fn23 count {cnt} != {count}")
        if abs(x) < 2**30:
            check_point(x, y, gx, gy, st)
        else:
            check(st & 2, "extreme input: outside bit")
    # 3. Partial writes of 0-3 do not compute.
    expect_ok(c.write_registers(0, [0, 5]), "partial fn16")
    expect_ok(c.write_register(3, 7), "fn6 to 3")
    check(expect_ok(c.read_input_registers(5, count=1), "fn4").registers[0] == count,
          "a partial write computed")
    # 3b. Function 22 (mask write register), the Modbus specification's own example: register
    # holding 0x0012, AND mask 0x00F2, OR mask 0x0025 -> (0x12 AND 0xF2) OR (0x25 AND NOT 0xF2)
    # = 0x0017, read back with function 3. A mask write of one register of 0-3 computes nothing.
    for a in range(4):
        expect_ok(c.write_register(a, 0x0012), f"fn6 0x12 to {a}")
        r = expect_ok(c.mask_write_register(address=a, and_mask=0x00F2, or_mask=0x0025), "fn22")
        check((r.address, r.and_mask, r.or_mask) == (a, 0x00F2, 0x0025), f"fn22 echo {r}")
        got = expect_ok(c.read_holding_registers(a, count=1), "fn3").registers[0]
        check(got == 0x0017, f"fn22 on holding {a}: 0x{got:04X}, expected 0x0017")
    # AND 0 OR v sets v; AND 0xFFFF keeps the register whatever the OR mask
    expect_ok(c.mask_write_register(address=1, and_mask=0x0000, or_mask=0xBEEF), "fn22 set")
    expect_ok(c.mask_write_register(address=1, and_mask=0xFFFF, or_mask=0x1234), "fn22 keep")
    got = expect_ok(c.read_holding_registers(1, count=1), "fn3").registers[0]
    check(got == 0xBEEF, f"fn22 set/keep: 0x{got:04X}, expected 0xBEEF")
    expect_exc(c.mask_write_register(address=4, and_mask=0, or_mask=1), ILLEGAL_ADDRESS,
               "fn22 to 4")
    check(expect_ok(c.read_input_registers(5, count=1), "fn4").registers[0] == count,
          "a mask write computed")
    # 3b'. Function 23 at its smallest: one register read, one written (holding 3: no correction)
    r = expect_ok(c.readwrite_registers(read_address=9, read_count=1, write_address=3,
                                        values=[0x0102]), "fn23 one register")
    check(len(r.registers) == 1, f"fn23 one register: {r.registers}")
    check(expect_ok(c.read_holding_registers(3, count=1), "fn3").registers[0] == 0x0102,
          "fn23 wrote one register")
    # 3c. The responses' exact bytes on a raw socket (pymodbus accepts a response with a byte too
    # many): function 22 echoes its request; function 17 (report server id) is function, byte
    # count, then that many bytes (unit id, run indicator 0xFF, the id text).
    with socket.create_connection(("127.0.0.1", d.port), timeout=2) as s:
        req = struct.pack(">HHHBBHHH", 0x4301, 0, 8, 1, 22, 2, 0x00F2, 0x0025)
        s.sendall(req)
        got = s.recv(64)
        check(got == req, f"fn22 raw: {got.hex()} is not the echo {req.hex()}")
        s.sendall(struct.pack(">HHHBB", 0x4302, 0, 2, 1, 17))
        got = s.recv(300)
        ln, fn, bc = struct.unpack(">H", got[4:6])[0], got[7], got[8]
        check(fn == 17 and len(got) == 6 + ln and ln == 3 + bc and got[10] == 0xFF,
              f"fn17 raw: {got.hex()}")
        # the quantity's limits come first (exception 3 beyond them), then the address range
        # (exception 2): reads of 1..125 registers, writes of 1..123 (124 do not fit a frame)
        for tid, pdu, code in ((0x4303, struct.pack(">BHH", 3, 0, 125), 2),
                               (0x4304, struct.pack(">BHH", 3, 0, 126), 3),
                               (0x4305, struct.pack(">BHH", 4, 0, 125), 2),
                               (0x4306, struct.pack(">BHH", 4, 0, 126), 3),
                               (0x4307, struct.pack(">BHHB", 16, 0, 123, 246) + bytes(246), 2)):
            s.sendall(struct.pack(">HHHB", tid, 0, 1 + len(pdu), 1) + pdu)
            got = s.recv(64)
            check(got[7] == (pdu[0] | 0x80) and got[8] == code,
                  f"fn{pdu[0]} quantity {struct.unpack('>H', pdu[3:5])[0]}: {got.hex()}, "
                  f"expected exception {code}")
    # 4. Exceptions: illegal data address.
    expect_exc(c.read_holding_registers(0, count=11), ILLEGAL_ADDRESS, "read holding 0-10")
    expect_exc(c.read_holding_registers(10, count=1), ILLEGAL_ADDRESS, "read holding 10")
    expect_exc(c.read_input_registers(0, count=7), ILLEGAL_ADDRESS, "read input 0-6")
    expect_exc(c.read_input_registers(6, count=1), ILLEGAL_ADDRESS, "read input 6")
    for a in range(4, 10):
        expect_exc(c.write_register(a, 1), ILLEGAL_ADDRESS, f"fn6 write {a}")
    expect_exc(c.write_registers(2, [0, 0, 0, 0]), ILLEGAL_ADDRESS, "fn16 write 2-5")
    expect_exc(c.write_registers(4, [0] * 6), ILLEGAL_ADDRESS, "fn16 write 4-9")
    expect_exc(c.write_registers(10, [0]), ILLEGAL_ADDRESS, "fn16 write 10")
    expect_exc(c.readwrite_registers(read_address=4, read_count=6, write_address=4,
                                     values=[0, 0, 0, 0]), ILLEGAL_ADDRESS, "fn23 write 4-7")
    expect_exc(c.readwrite_registers(read_address=4, read_count=7, write_address=0,
                                     values=[0, 0, 0, 0]), ILLEGAL_ADDRESS, "fn23 read 4-10")
    expect_exc(c.read_coils(0, count=1), ILLEGAL_ADDRESS, "coils")
    check(expect_ok(c.read_input_registers(5, count=1), "fn4").registers[0] == count,
          "an exception request computed")
    # 5. Another unit id: gateway exception (0x0B), nothing computed.
    expect_exc(c.read_input_registers(0, count=6, device_id=7), 11, "unit 7")
    for unit in (255, 0):  # "this device" on TCP: always accepted
        gx, gy, st, cnt = roundtrip(c, 1000, 2000, unit=unit)
        count = (count + 1) & 0xFFFF
        check(cnt == count, f"unit {unit} served")

    # 6. Concurrent clients with function 23: each gets the answer to its own write.
    errors = []

    def worker(seed):
        r = random.Random(seed)
        cc = ModbusTcpClient("127.0.0.1", port=d.port, timeout=2, retries=0)
        if not cc.connect():
            errors.append("connect")
            return
        try:
            for _ in range(150):
                x, y = r.randint(-9_000_000, 9_000_000), r.randint(-9_000_000, 9_000_000)
                gx, gy, st, _ = roundtrip(cc, x, y)
                ex, ey, _ = ref.correct_nm(x, y)
                if abs(gx - ex) > 1 or abs(gy - ey) > 1:
                    errors.append(f"client {seed}: ({x},{y}) -> ({gx},{gy})")
        except SystemExit:
            errors.append(f"client {seed}: bad reply")
        finally:
            cc.close()

    # 7. ... while a stalled client holds half a request: it must not delay them, and it is
    # dropped after the byte timeout.
    stall = socket.create_connection(("127.0.0.1", d.port))
    stall.sendall(bytes([0, 1, 0, 0, 0, 6, 1, 4]))  # 8 of 12 bytes of a read
    t0 = time.time()
    threads = [threading.Thread(target=worker, args=(s,)) for s in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    check(not errors, "; ".join(errors[:5]))
    stall.settimeout(3)
    try:
        got = stall.recv(16)
    except socket.timeout:
        got = b"timeout"
    check(got == b"", f"stalled client not dropped: {got!r}")
    check(time.time() - t0 < 6, "stalled client delayed the others")
    stall.close()
    count = None

    # 8. Connection cap (12): a 13th client is served, and the longest-idle connection (the
    # first of the 12, silent for more than 1 s since its request) is closed to make room; the
    # rest stay served.
    oldest = socket.create_connection(("127.0.0.1", d.port))
    oldest.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 4, 0, 1))
    oldest.settimeout(3)
    check(len(oldest.recv(64)) == 11, "cap: first connection not served")
    # a served connection is evicted only once silent for 1 s (issue 36: a connect burst never
    # resets a client being served)
    time.sleep(1.2)
    roundtrip(c, 5, 5)
    socks = [ModbusTcpClient("127.0.0.1", port=d.port, timeout=2, retries=0) for _ in range(10)]
    for s in socks:
        check(s.connect(), "cap: connect")
        roundtrip(s, 5, 5)
    extra = socket.create_connection(("127.0.0.1", d.port))
    extra.settimeout(3)
    extra.sendall(struct.pack(">HHHBBHH", 2, 0, 6, 1, 4, 0, 1))
    check(len(extra.recv(64)) == 11, "13th connection not served at the cap")
    check(oldest.recv(1) == b"", "the longest-idle connection was not the one closed")
    for s in socks:
        roundtrip(s, 5, 5)
    roundtrip(c, 5, 5)
    check("evicted" in d.text(), "eviction not logged")
    extra.close()
    oldest.close()
    for s in socks:
        s.close()
    time.sleep(0.1)

    # 9. SIGHUP: a corrupt table is refused (old one kept, status bit 3), a valid one swapped in.
    x, y = 3_333_333, -4_444_444
    gx0, gy0, st0, _ = roundtrip(c, x, y)
    blob = bytearray(open(table2, "rb").read())
    blob[len(blob) // 2] ^= 0x10
    open(live, "wb").write(blob)
    d.signal(signal.SIGHUP)
    time.sleep(0.3)
    gx1, gy1, st1, _ = roundtrip(c, x, y)
    check((gx1, gy1) == (gx0, gy0), "corrupt reload changed the answers")
    check(st1 & 8 and st1 & 1, f"status after failed reload: {st1}")
    check("reload failed" in d.text(), "failed reload not logged")
    os.unlink(live)
    d.signal(signal.SIGHUP)
    time.sleep(0.3)
    check(roundtrip(c, x, y)[:2] == (gx0, gy0), "missing table changed the answers")
    shutil.copyfile(table2, live + ".tmp")
    os.rename(live + ".tmp", live)
    d.signal(signal.SIGHUP)
    time.sleep(0.3)
    gx2, gy2, st2, _ = roundtrip(c, x, y)
    check_point(x, y, gx2, gy2, st2, r=ref2)
    check(not st2 & 8, "reload-failed bit not cleared")
    c.close()
finally:
    rc = d.stop()
check(rc == 0, f"selfcald exit status {rc} on SIGTERM")

# 10. Word order low-first, unit id 5, position mode.
shutil.copyfile(table, live)
d = Daemon(selfcald, live, ["--word-order", "low-first", "--unit-id", "5", "--mode", "position"])
try:
    c = ModbusTcpClient("127.0.0.1", port=d.port, timeout=2, retries=0)
    check(c.connect(), "connect")
    for _ in range(200):
        x, y = rng.randint(-10_000_000, 10_000_000), rng.randint(-10_000_000, 10_000_000)
        gx, gy, st, _ = roundtrip(c, x, y, hf=False, unit=5)
        check_point(x, y, gx, gy, st, mode="position")
    expect_exc(c.read_input_registers(0, count=6, device_id=1), 11, "unit 1 with --unit-id 5")
    c.close()
finally:
    rc = d.stop()
check(rc == 0, f"selfcald exit status {rc}")

# 11. A table with straightness profiles (y error along x, x error along y): grid + offsets.
table3, ref3 = make_table(cli, work, "tcp3", n=11, pitch=2.0, profiles=("x:y", "y:x"))
check(len(ref3.profiles) == 2, "lut dump shows the profiles")
d = Daemon(selfcald, table3)
try:
    c = ModbusTcpClient("127.0.0.1", port=d.port, timeout=2, retries=0)
    check(c.connect(), "connect")
    for _ in range(300):
        x, y = rng.randint(-16_000_000, 16_000_000), rng.randint(-16_000_000, 16_000_000)
        gx, gy, st, _ = roundtrip(c, x, y)
        check_point(x, y, gx, gy, st, r=ref3)
    c.close()
finally:
    rc = d.stop()
check(rc == 0, f"selfcald exit status {rc}")
# 12. Garbage: random PDUs in well-formed MBAP frames (every function code, random lengths), and
# random bytes; the daemon answers or drops the connection, never crashes (ASan build), and still
# serves correctly afterwards.
d = Daemon(selfcald, table)
try:
    answered = 0
    for burst in range(40):
        s = socket.create_connection(("127.0.0.1", d.port))
        s.settimeout(0.5)
        try:
            for k in range(50):
                if burst % 10 == 9:
                    s.sendall(bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300))))
                    continue
                pdu = bytes([rng.randrange(1, 130)]) + bytes(
                    rng.randrange(256) for _ in range(rng.randrange(0, 40)))
                s.sendall(struct.pack(">HHHB", k, 0, len(pdu) + 1, 1) + pdu)
                hdr = s.recv(7)
                if len(hdr) < 7:
                    break
                ln = struct.unpack(">H", hdr[4:6])[0]
                body = b""
                while len(body) < ln - 1:
                    chunk = s.recv(ln - 1 - len(body))
                    if not chunk:
                        break
                    body += chunk
                check(struct.unpack(">H", hdr[0:2])[0] == k, "garbage: transaction id echoed")
                answered += 1
        except (socket.timeout, ConnectionResetError, BrokenPipeError):
            pass
        s.close()
    check(d.p.poll() is None, "selfcald died on garbage")
    c = ModbusTcpClient("127.0.0.1", port=d.port, timeout=2, retries=0)
    check(c.connect(), "connect after garbage")
    x, y = 1_234_567, -7_654_321
    expect_ok(c.write_registers(0, i32_to_regs(x) + i32_to_regs(y)), "fn16 after garbage")
    inp = expect_ok(c.read_input_registers(0, count=6), "fn4 after garbage").registers
    check_point(x, y, regs_to_i32(inp[0:2]), regs_to_i32(inp[2:4]), inp[4])
    c.close()
finally:
    rc = d.stop()
check(rc == 0, f"selfcald exit status {rc} after garbage")
check(answered > 500, f"only {answered} garbage requests answered")
print(f"modbus tcp (pymodbus): ok; worst |corrected - independent| = {worst:.3f} nm")
