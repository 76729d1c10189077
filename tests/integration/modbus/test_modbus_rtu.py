#!/usr/bin/env python3
"""selfcald as a Modbus RTU server on one end of a socat pseudo-terminal pair, pymodbus's RTU
client on the other. Checks corrected positions against an independent evaluation of
`selfcal lut dump`, exceptions, silence towards other unit ids, and recovery after line noise.
usage: test_modbus_rtu.py SELFCAL_CLI SELFCALD WORKDIR"""
import os
import random
import sys
import termios
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sclib import Daemon, check, i32_to_regs, make_table, pty_pair, regs_to_i32  # noqa: E402

import serial  # noqa: E402
from pymodbus.client import ModbusSerialClient  # noqa: E402
from pymodbus.exceptions import ModbusIOException  # noqa: E402


class PtySerial(serial.Serial):
    """Some sandboxes' pseudo-terminals refuse flock (pyserial's exclusive=True, which pymodbus
    always asks for) and the VMIN/VTIME change of inter_byte_timeout (EINVAL). Neither matters
    on a pty; tolerate both so the test runs there as on an ordinary Linux machine."""

    def _reconfigure_port(self, force_update=False):
        try:
            super()._reconfigure_port(force_update)
        except (OSError, serial.SerialException, termios.error):
            if not force_update and self._inter_byte_timeout is None:
                raise


_serial_for_url = serial.serial_for_url


def _pty_serial_for_url(url, *args, **kw):
    kw.pop("exclusive", None)
    kw.pop("do_not_open", None)
    return PtySerial(url, *args, **kw)


serial.serial_for_url = _pty_serial_for_url

cli, selfcald, work = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(work, exist_ok=True)
table, ref = make_table(cli, work, "rtu", n=7, pitch=3.0, scale_um=1.0)
a, b, socat = pty_pair(work)
d = None
try:
    d = Daemon(selfcald, table, ["--modbus-rtu", f"{a}:38400:E:8:1", "--unit-id", "3"],
               tcp=False, log_path=os.path.join(work, "rtu.log"))
    # Line noise first: random bytes and a frame with a bad CRC; the server must resynchronise.
    s = serial.Serial(b, 38400, parity="E", timeout=0.2)
    s.write(bytes(random.Random(1).randrange(256) for _ in range(40)))
    s.write(bytes([3, 4, 0, 0, 0, 6, 0x12, 0x34]))
    time.sleep(0.2)
    check(s.read(64) == b"", "answered noise")
    s.close()

    c = ModbusSerialClient(b, baudrate=38400, parity="E", timeout=1, retries=0)
    check(c.connect(), "serial connect")
    rng = random.Random(3)
    worst = 0.0
    count = 0
    for k in range(120):
        x, y = rng.randint(-10_500_000, 10_500_000), rng.randint(-10_500_000, 10_500_000)
        if k % 2:
            r = c.readwrite_registers(read_address=4, read_count=6, write_address=0,
                                      values=i32_to_regs(x) + i32_to_regs(y), device_id=3)
            check(not r.isError(), f"fn23: {r}")
            reg = r.registers
        else:
            check(not c.write_registers(0, i32_to_regs(x) + i32_to_regs(y),
                                        device_id=3).isError(), "fn16")
            r = c.read_input_registers(0, count=6, device_id=3)
            check(not r.isError(), f"fn4: {r}")
            reg = r.registers
        count += 1
        gx, gy = regs_to_i32(reg[0:2]), regs_to_i32(reg[2:4])
        ex, ey, outside = ref.correct_nm(x, y)
        err = max(abs(gx - ex), abs(gy - ey))
        worst = max(worst, err)
        check(err <= 1.0, f"({x},{y}) -> ({gx},{gy}), expected ({ex:.2f},{ey:.2f})")
        check(reg[4] & 1 and bool(reg[4] & 2) == outside, f"status {reg[4]}")
        check(reg[5] == count, f"count {reg[5]} != {count}")
    r = c.write_register(6, 1, device_id=3)
    check(r.isError() and r.exception_code == 2, f"write holding 6: {r}")
    r = c.read_holding_registers(8, count=3, device_id=3)
    check(r.isError() and r.exception_code == 2, f"read holding 8-10: {r}")
    c.close()
    # Another unit id: silence (a multi-drop line), then unit 3 still answers.
    c = ModbusSerialClient(b, baudrate=38400, parity="E", timeout=0.3, retries=0)
    check(c.connect(), "serial connect")
    try:
        r = c.read_input_registers(0, count=6, device_id=4)
        check(r.isError() and getattr(r, "exception_code", None) is None,
              f"unit 4 answered: {r}")
    except ModbusIOException:
        pass  # no response: what a device with another address does
    c.close()
    c = ModbusSerialClient(b, baudrate=38400, parity="E", timeout=1, retries=0)
    check(c.connect(), "serial connect")
    time.sleep(0.1)
    r = c.read_input_registers(5, count=1, device_id=3)
    check(not r.isError() and r.registers[0] == count, f"after unit 4: {r}")
    c.close()
    print(f"modbus rtu (pymodbus over socat ptys): ok; worst error {worst:.3f} nm")
finally:
    rc = d.stop() if d else 0
    socat.terminate()
    socat.wait()
check(rc == 0, f"selfcald exit status {rc}")
