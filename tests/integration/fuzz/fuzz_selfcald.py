#!/usr/bin/env python3
"""Seeded fuzzing of selfcald's inputs (Python 3 standard library only).

usage: fuzz_selfcald.py CLI SELFCALD TARGET [--iterations N] [--seed S] [--work DIR]
TARGET:
  config   mutated copies of runtime/selfcald.conf.example (--config FILE): exit 2 with
           "selfcald: FILE:LINE: ..." first on stderr, or start (then SIGTERM -> exit 0)
  argv     mutated command lines: exit 0 (--help/--version), 2, or start and stop on SIGTERM
  table    mutated tables (size and CRC fixed up, so the range checks are reached) as --table
           and through a SIGHUP reload: never a crash; a refused reload keeps serving
  modbus   garbage over Modbus TCP that tests/integration/modbus does not send: wrong MBAP
           lengths (0, 1, 2, > 254, 65535), protocol ids != 0, oversized frames, slow-loris
           partial frames, half-closed sockets, pipelined junk — while a good client keeps
           getting answers equal to an independent evaluation of `selfcal lut dump`
"""
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import time
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "modbus"))
import fuzzlib  # noqa: E402
import sclib  # noqa: E402  (stdlib only: map writer, independent bilinear evaluation)

ap = fuzzlib.base_args(__doc__)
ap.add_argument("cli")
ap.add_argument("selfcald")
ap.add_argument("target", choices=["config", "argv", "table", "modbus"])
ap.add_argument("--example", default=os.path.join(HERE, "..", "..", "..", "runtime",
                                                   "selfcald.conf.example"))
A = ap.parse_args()
F = fuzzlib.Fuzz(A, "fuzz-selfcald-" + A.target)
W, rnd = F.work, F.rnd
TABLE, REF = sclib.make_table(A.cli, W, "base", profiles=("x:y",))


def start(args, label, inputs, expect=None, stop=True):
    """Run selfcald; wait until it is ready or exits. Returns (rc or 'ready', stderr text)."""
    log = os.path.join(W, "daemon.log")
    with open(log, "wb") as lf:
        p = subprocess.Popen([A.selfcald] + args, stdout=lf, stderr=lf, env=F.env,
                             stdin=subprocess.DEVNULL)
        deadline = time.time() + 15
        state = None
        while time.time() < deadline:
            rc = p.poll()
            text = open(log, "rb").read().decode("utf-8", "replace")
            if rc is not None:
                state = rc
                break
            if "ready" in text and "listening on" in text:
                state = "ready"
                break
            time.sleep(0.01)
        if state is None:
            p.kill()
            p.wait()
            F.fail("hang", "%s: neither ready nor exited in 15 s" % label, [A.selfcald] + args,
                   open(log, "rb").read(), inputs)
            return None, ""
        if state == "ready" and stop:
            p.send_signal(signal.SIGTERM)
            try:
                rc = p.wait(15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
                F.fail("hang", "%s: no exit 15 s after SIGTERM" % label, [A.selfcald] + args,
                       open(log, "rb").read(), inputs)
                return None, ""
            if rc != 0:
                F.fail("exit", "%s: exit %d after SIGTERM" % (label, rc), [A.selfcald] + args,
                       open(log, "rb").read(), inputs)
        text = open(log, "rb").read().decode("utf-8", "replace")
    F.stats[(label, state)] = F.stats.get((label, state), 0) + 1
    if any(m in text for m in fuzzlib.SAN_MARKERS) or (state not in ("ready",) and state not in (0, 1, 2)):
        F.fail("crash", "%s: exit %s, sanitizer/signal" % (label, state), [A.selfcald] + args,
               text, inputs)
    elif state == 1 and not any(w in text for w in ("cannot", "SocketCAN", "No such device",
                                                     "Address already in use", "error: CAN:",
                                                     "modbus-rtu:")):
        F.fail("exit", "%s: exit 1 that is not a system failure" % label, [A.selfcald] + args,
               text, inputs)
    elif state == 2:
        first = text.strip().splitlines()[0] if text.strip() else ""
        if not first.startswith("selfcald"):
            F.fail("message", "%s: exit 2 without a 'selfcald:' message" % label,
                   [A.selfcald] + args, text, inputs)
        elif expect and expect not in first:
            F.fail("message", "%s: exit 2, first line does not name %s" % (label, expect),
                   [A.selfcald] + args, text, inputs)
    return state, text


OVERRIDE = ["--modbus-tcp", "127.0.0.1:0", "--syslog=no", "--log-level=info"]


def config_ops():
    keys = ["table", "mode", "modbus-tcp", "unit-id", "word-order", "max-connections",
            "byte-timeout-ms", "idle-timeout-ms", "rtu-byte-timeout-ms", "busy-poll-us",
            "can-in-id", "can-status-period-ms", "syslog", "log-level", "syslog-socket", "config",
            "help", "", "=", "table table", "TABLE"]
    vals = ["", "0", "1", "-1", "255", "256", "79", "80", "65535", "65536", "0x7ff", "0x800",
            "4294967296", "18446744073709551616", "1e3", "yes", "no", "measure", "position",
            "high-first", "low-first", "debug", "x" * 300, "/nonexistent.lut", TABLE, " ",
            "127.0.0.1:0", ":0", "host:", "[::1]:0", "a" * 2000 + ":0", "=", "# c"]

    def kv(rnd, lines):
        k = rnd.choice(keys)
        v = rnd.choice(vals)
        fmt = rnd.choice(("%s = %s\n", "%s=%s\n", "%s%.0s\n", "  %s =%s  \n"))
        lines.insert(rnd.randrange(len(lines) + 1), (fmt % (k, v)).encode())
        return lines

    def uncomment(rnd, lines):
        i = rnd.randrange(len(lines))
        lines[i] = lines[i].lstrip(b"# ")
        return lines
    return (kv, kv, kv, uncomment)


def t_config():
    base = open(A.example, "rb").read().replace(b"/etc/selfcal/stage.lut", TABLE.encode())
    base = base.replace(b"127.0.0.1:1502", b"127.0.0.1:0")
    # The unmutated example (with this table) must start.
    cf = os.path.join(W, "base.conf")
    open(cf, "wb").write(base)
    st, text = start(["--config", cf], "config-base", [cf])
    if st != "ready":
        F.fail("exit", "the example configuration does not start", ["--config", cf], text, [cf])
    ops = config_ops()
    for t in range(A.iterations):
        cf = os.path.join(W, "c%d.conf" % t)
        data = fuzzlib.mutate_text(rnd, base, ops)
        # Long lines are the point of one mutation; NUL bytes another.
        open(cf, "wb").write(data)
        args = ["--config", cf] + OVERRIDE if rnd.random() < 0.8 else ["--config=" + cf] + OVERRIDE
        if rnd.random() < 0.3:
            args += ["--table", TABLE]
        st, text = start(args, "config", [cf], expect=None)
        if st == 2:
            first = text.strip().split("\n")[0]
            if not re.match(r"selfcald: %s:\d+: " % re.escape(cf), first):
                F.soft(re.sub(re.escape(cf), "CONF", re.sub(re.escape(W), "W", first))[:110])
        os.unlink(cf)


def t_argv():
    opts = ["--table", "--mode", "--modbus-tcp", "--modbus-rtu", "--can", "--config", "--unit-id",
            "--word-order", "--max-connections", "--byte-timeout-ms", "--idle-timeout-ms",
            "--rtu-byte-timeout-ms", "--busy-poll-us", "--can-in-id", "--can-out-id",
            "--can-status-id", "--can-status-period-ms", "--syslog", "--syslog-socket",
            "--log-level", "--", "-", "--x", "--=", "--table=", "--unit-id=300", "-h",
            "--" + "k" * 100, "--help", "--version"]
    vals = ["", "0", "1", "-1", "255", "256", "80", "0x7ff", "0x800", "99999999999999999999",
            "measure", "position", "low-first", "debug", TABLE, "/nonexistent", "/dev/null",
            "/dev/nonexistent-tty", "127.0.0.1:0", "127.0.0.1:99999", "x" * 5000, "nan",
            "/tmp:9600:E:8:1", "/dev/null:50:N:5:2", "/dev/null:1:Q", "lo", "can0", W]
    for t in range(A.iterations):
        args = ["--table", TABLE] if rnd.random() < 0.7 else []
        for _ in range(rnd.randrange(1, 5)):
            o = rnd.choice(opts)
            args.append(o)
            if rnd.random() < 0.85:
                args.append(rnd.choice(vals))
        args += ["--modbus-tcp", "127.0.0.1:0"] if rnd.random() < 0.7 else []
        if "--help" in args or "-h" in args or "--version" in args:
            rc, out, err = F.run([A.selfcald] + args, timeout=15)
            if rc is None or rc not in (0, 2):
                F.fail("exit", "argv --help/--version: exit %s" % rc, [A.selfcald] + args, err, [])
            continue
        if any(a.startswith("--syslog") for a in args) or any(
                a.startswith("--log-level") for a in args):
            args += ["--syslog=no", "--log-level=info"]
        if "--modbus-tcp" not in args and not any(a.startswith("--modbus-tcp=") for a in args):
            args += ["--modbus-tcp", "127.0.0.1:0"]
        start(args, "argv", [])


def fix_table(b):
    b = bytearray(b)
    if len(b) >= 20:
        b[12:16] = struct.pack("<I", len(b))
        b[-4:] = struct.pack("<I", zlib.crc32(bytes(b[:-4])) & 0xFFFFFFFF)
    return bytes(b)


def mbap(tid, pdu, unit=1, proto=0, length=None):
    return struct.pack(">HHHB", tid, proto, len(pdu) + 1 if length is None else length, unit) + pdu


def recv_exact(s, n):
    buf = b""
    while len(buf) < n:
        c = s.recv(n - len(buf))
        if not c:
            return None
        buf += c
    return buf


def good_roundtrip(port, s, tid, x, y):
    """Function 23 (write 0-3, read 4-9) through a raw socket; checks against the reference."""
    regs = sclib.i32_to_regs(x) + sclib.i32_to_regs(y)
    pdu = struct.pack(">BHHHHB", 23, 4, 6, 0, 4, 8) + struct.pack(">4H", *regs)
    s.sendall(mbap(tid, pdu))
    hdr = recv_exact(s, 7)
    if hdr is None:
        return "connection closed"
    tid2, proto, ln, unit = struct.unpack(">HHHB", hdr)
    body = recv_exact(s, ln - 1)
    if tid2 != tid or body is None or body[0] != 23 or body[1] != 12:
        return "bad reply %r %r" % (hdr, body)
    r = struct.unpack(">6H", body[2:14])
    gx, gy = sclib.regs_to_i32(r[0:2]), sclib.regs_to_i32(r[2:4])
    ex, ey, out = REF.correct_nm(x, y)
    if abs(gx - ex) > 1 or abs(gy - ey) > 1:
        return "wrong answer for (%d,%d): (%d,%d), expected (%.1f,%.1f)" % (x, y, gx, gy, ex, ey)
    return None


def t_table():
    bases = [open(TABLE, "rb").read()]
    live = os.path.join(W, "live.lut")
    for t in range(A.iterations):
        b = bytearray(rnd.choice(bases))
        for _ in range(rnd.choice((1, 2, 3))):
            i = rnd.randrange(len(b))
            c = rnd.randrange(4)
            if c == 0:
                b[i] ^= 1 << rnd.randrange(8)
            elif c == 1:
                b[i] = rnd.choice((0, 1, 2, 0x7F, 0x80, 0xFF))
            elif c == 2 and i < 64:
                b[i:i + 8] = struct.pack("<d", rnd.choice((0.0, 1e-9, 1e6, 1e7, float("nan"),
                                                           float("inf"), -1e300)))
            else:
                del b[i:i + rnd.randrange(1, 9)]
        data = fix_table(bytes(b)) if rnd.random() < 0.8 else bytes(b)
        open(live, "wb").write(data)
        args = ["--table", live] + OVERRIDE
        if rnd.random() < 0.5:
            st, text = start(args, "table-start", [live])
            continue
        # Start on the good table, then reload the mutated one: the good answers must stay.
        open(live, "wb").write(bases[0])
        log = os.path.join(W, "daemon.log")
        d = sclib.Daemon(A.selfcald, live, ["--syslog=no"], log_path=log)
        try:
            open(live + ".tmp", "wb").write(data)
            os.rename(live + ".tmp", live)
            d.signal(signal.SIGHUP)
            time.sleep(0.15)
            if d.p.poll() is not None:
                F.fail("crash", "table-reload: selfcald exited %s after SIGHUP" % d.p.returncode,
                       [A.selfcald] + args, d.text(), [live])
                continue
            s = socket.create_connection(("127.0.0.1", d.port), timeout=3)
            why = good_roundtrip(d.port, s, 1, 1_000_000, -2_000_000)
            s.close()
            text = d.text()
            if why and "reload failed" in text:
                F.fail("exit", "table-reload: refused reload but answers changed: " + why,
                       [A.selfcald] + args, text, [live])
            F.stats[("table-reload", "failed" if "reload failed" in text else "ok")] = \
                F.stats.get(("table-reload", "failed" if "reload failed" in text else "ok"), 0) + 1
        finally:
            rc = d.stop()
            if rc != 0 or any(m in d.text() for m in fuzzlib.SAN_MARKERS):
                F.fail("crash", "table-reload: exit %s" % rc, [A.selfcald] + args, d.text(), [live])


def garbage_frame(rnd, tid):
    c = rnd.randrange(10)
    pdu = bytes([rnd.choice((3, 4, 6, 16, 23, 43, 0, 0x80, 0xFF))]) + bytes(
        rnd.randrange(256) for _ in range(rnd.randrange(0, 20)))
    if c == 0:
        return mbap(tid, pdu, length=rnd.choice((0, 1, 2)))
    if c == 1:
        return mbap(tid, pdu, length=rnd.choice((254, 255, 256, 260, 1000, 65535)))
    if c == 2:
        return mbap(tid, pdu, proto=rnd.choice((1, 0xFFFF, 0x8000)))
    if c == 3:  # oversized frame, length consistent
        big = bytes([16]) + bytes(rnd.randrange(256) for _ in range(rnd.choice((253, 254, 300, 2000))))
        return mbap(tid, big)
    if c == 4:  # length says more than is sent, then the next frame (misframing)
        return mbap(tid, pdu, length=len(pdu) + 1 + rnd.randrange(1, 10))
    if c == 5:  # length says less than sent
        return mbap(tid, pdu + b"\0" * 5, length=max(2, len(pdu) - 2))
    if c == 6:  # fn 16/23 with byte counts that disagree with the quantity
        return mbap(tid, struct.pack(">BHHB", 16, 0, 4, rnd.choice((0, 7, 9, 255))) + b"\1" * 8)
    if c == 7:
        return mbap(tid, struct.pack(">BHHHHB", 23, rnd.choice((4, 0, 65535)),
                                     rnd.choice((6, 0, 126, 65535)), 0,
                                     rnd.choice((4, 0, 122, 65535)), rnd.choice((8, 0, 255))) +
                    b"\2" * rnd.randrange(0, 12))
    if c == 8:
        return bytes(rnd.randrange(256) for _ in range(rnd.randrange(1, 600)))
    return mbap(tid, pdu, unit=rnd.choice((0, 2, 247, 255)))


def t_modbus():
    log = os.path.join(W, "daemon.log")
    d = sclib.Daemon(A.selfcald, TABLE, ["--syslog=no", "--byte-timeout-ms", "300",
                                         "--max-connections", "16"], log_path=log)
    good = socket.create_connection(("127.0.0.1", d.port), timeout=3)
    good.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    tid, bad = 0, 0
    try:
        # Slow loris: 10 connections each trickling a request one byte every 100 ms. Each must
        # be closed by the byte timeout (300 ms; allow 2 s), and the good client meanwhile gets
        # prompt, right answers.
        loris = [socket.create_connection(("127.0.0.1", d.port), timeout=3) for _ in range(10)]
        frame = mbap(9, struct.pack(">BHH", 4, 0, 6))
        t0, closed, worst = time.time(), {}, 0.0
        for step in range(len(frame)):
            for k, s in enumerate(loris):
                if k in closed:
                    continue
                try:
                    s.send(frame[step:step + 1])
                    s.setblocking(False)
                    try:
                        if s.recv(64) == b"":
                            closed[k] = time.time() - t0
                    except BlockingIOError:
                        pass
                    s.setblocking(True)
                except (BrokenPipeError, ConnectionResetError):
                    closed[k] = time.time() - t0
            tid += 1
            t1 = time.time()
            why = good_roundtrip(d.port, good, tid, 5_000_000 - tid, tid * 1000)
            worst = max(worst, time.time() - t1)
            if why:
                F.fail("exit", "modbus slow-loris: good client: " + why, ["slow loris"], d.text(), [])
            time.sleep(0.1)
            if len(closed) == len(loris):
                break
        if len(closed) != len(loris) or max(closed.values()) > 2.0:
            F.fail("hang", "modbus slow-loris: %d of %d trickling connections closed (%s)" % (
                len(closed), len(loris), sorted(closed.values())), ["slow loris"], d.text(), [])
        if worst > 0.25:
            F.fail("hang", "modbus slow-loris: good client waited %.3f s" % worst, ["slow loris"],
                   d.text(), [])
        for s in loris:
            s.close()
        F.stats["slow-loris: all closed by (ms)"] = int(1000 * max(closed.values() or [0]))
        for t in range(A.iterations):
            mode = rnd.randrange(5)
            s = socket.create_connection(("127.0.0.1", d.port), timeout=1)
            try:
                if mode == 0:  # a burst of garbage frames, pipelined
                    s.sendall(b"".join(garbage_frame(rnd, k) for k in range(rnd.randrange(1, 20))))
                elif mode == 1:  # slow loris: a valid frame one byte at a time, too slowly
                    fr = mbap(7, struct.pack(">BHH", 4, 0, 6))
                    for ch in fr[: rnd.randrange(1, len(fr))]:
                        s.send(bytes([ch]))
                        time.sleep(rnd.choice((0.0, 0.05, 0.12)))
                elif mode == 2:  # half close after a partial frame
                    s.sendall(garbage_frame(rnd, 1)[: rnd.randrange(1, 8)])
                    s.shutdown(socket.SHUT_WR)
                elif mode == 3:  # one garbage frame, then a valid request on the same link
                    s.sendall(garbage_frame(rnd, 1))
                    s.sendall(mbap(2, struct.pack(">BHH", 4, 0, 6)))
                else:  # reset with unread data
                    s.sendall(garbage_frame(rnd, 3) * rnd.randrange(1, 50))
                    s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                # drain whatever comes back (replies or a close), briefly
                s.settimeout(0.02)
                try:
                    while s.recv(4096):
                        pass
                except (socket.timeout, OSError):
                    pass
            except (BrokenPipeError, ConnectionResetError):
                pass
            finally:
                s.close()
            # The good client, between every attack, and the daemon still alive.
            tid = (tid + 1) & 0xFFFF
            x, y = rnd.randint(-12_000_000, 12_000_000), rnd.randint(-12_000_000, 12_000_000)
            try:
                why = good_roundtrip(d.port, good, tid, x, y)
            except (socket.timeout, OSError) as e:
                why = "good client: %s" % e
            F.stats[("modbus", mode)] = F.stats.get(("modbus", mode), 0) + 1
            if why:
                bad += 1
                F.fail("exit", "modbus: the good client failed after attack mode %d: %s" % (mode, why),
                       ["(see fuzz_selfcald.py modbus, seed %d, case %d)" % (A.seed, t)], d.text(), [])
                if d.p.poll() is not None:
                    break
                good.close()
                good = socket.create_connection(("127.0.0.1", d.port), timeout=3)
    finally:
        good.close()
        rc = d.stop()
        text = d.text()
        if rc != 0 or any(m in text for m in fuzzlib.SAN_MARKERS):
            F.fail("crash", "modbus: selfcald exit %s" % rc, [A.selfcald], text, [])


{"config": t_config, "argv": t_argv, "table": t_table, "modbus": t_modbus}[A.target]()
F.finish()
