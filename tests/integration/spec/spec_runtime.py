#!/usr/bin/env python3
"""SPEC §3 (lut build/dump) and §4 (runtime correction over Modbus TCP) conformance, black box.

usage: spec_runtime.py SELFCAL SELFCALD TMPDIR {lut|modbus|position|count}

The Modbus client is written here on top of the socket module (no pymodbus); expected corrections
are computed from `selfcal lut dump` with this file's own bilinear / linear interpolation.
"""
import math
import os
import random
import socket
import struct
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from spec_common import *  # noqa

SELFCAL, SELFCALD, BASE, MODE = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
QUANT_UM = 5.5e-5  # the table's stated map quantization is <= 0.05 nm (selfcal lut info)

# ------------------------------------------------------------------ table inputs written here
N, PITCH, ORIGIN = 5, 2.0, (10.0, 6.0)  # grid x in [6, 14] mm, y in [2, 10] mm


def make_inputs(d):
    rng = random.Random(5)
    c = (N - 1) // 2
    gmap = {}
    lines = ["i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um"]
    for i in range(N):
        for j in range(N):
            gx = round(rng.uniform(-3, 3), 6)
            gy = round(rng.uniform(-3, 3), 6)
            gmap[(i, j)] = (gx, gy)
            lines.append("%d,%d,%r,%r,%r,%r,0.01,0.01" % (i, j, ORIGIN[0] + (j - c) * PITCH, ORIGIN[1] + (i - c) * PITCH, gx, gy))
    mp = os.path.join(d, "G.csv")
    with open(mp, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    profs = []
    # (axis, dir, n, s, d1): profile output files, ey empty where n >= N - d1
    for k, (axis, dr, n, s, d1) in enumerate((("x", "y", 40, 0.5, 3), ("y", "x", 30, 0.25, 2), ("x", "z", 12, 1.0, 2))):
        rows = ["n,x_mm,f_um,uf_um,ey_um"]
        ey = []
        for i in range(n):
            e = round(0.8 * math.sin(i / 5.0 + k) + rng.uniform(-0.1, 0.1), 6)
            if i < n - d1:
                ey.append((i * s, e))
            rows.append("%d,%r,%r,0.001,%s" % (i, i * s, rng.uniform(-1, 1), repr(e) if i < n - d1 else ""))
        p = os.path.join(d, "P%d.csv" % k)
        with open(p, "w") as fh:
            fh.write("\n".join(rows) + "\n")
        profs.append((axis, dr, p, ey))
    return mp, gmap, profs


def build_table(d):
    mp, gmap, profs = make_inputs(d)
    T = os.path.join(d, "stage.lut")
    argv = [SELFCAL, "lut", "build", "--map", mp]
    for axis, dr, p, ey in profs:
        argv += ["--profile", "%s:%s:%s" % (axis, dr, p)]
    argv += ["-o", T]
    rc, out, err = run(argv)
    if not check(rc == 0, "lut build: exit %d %s" % (rc, err.strip())):
        finish("spec_runtime " + MODE)
    return T, gmap, profs


def parse_dump(text):
    """SPEC §3 lut dump: grid CSV, then per profile '# profile k: axis=A dir=D', header, rows."""
    lines = text.splitlines()
    check(lines and lines[0] == "i,j,x_mm,y_mm,gx_um,gy_um", "lut dump: first line %r, SPEC: i,j,x_mm,y_mm,gx_um,gy_um"
          % (lines[0] if lines else None))
    grid = {}
    k = 1
    while k < len(lines) and not lines[k].startswith("#"):
        f = lines[k].split(",")
        check(len(f) == 6, "lut dump: grid row %r" % lines[k])
        grid[(int(f[0]), int(f[1]))] = tuple(float(v) for v in f[2:6])
        k += 1
    profiles = []
    while k < len(lines):
        m = re.match(r"^# profile (\d+): axis=([xyz]) dir=([xyz])$", lines[k])
        check(m is not None, "lut dump: profile line %r, SPEC: '# profile k: axis=AXIS dir=DIR'" % lines[k])
        if m is None:
            break
        check(k + 1 < len(lines) and lines[k + 1] == "n,pos_mm,err_um", "lut dump: profile header %r" % lines[k + 1:k + 2])
        k += 2
        pts = []
        while k < len(lines) and not lines[k].startswith("#"):
            f = lines[k].split(",")
            check(len(f) == 3 and int(f[0]) == len(pts), "lut dump: profile row %r" % lines[k])
            pts.append((float(f[1]), float(f[2])))
            k += 1
        profiles.append((int(m.group(1)), m.group(2), m.group(3), pts))
    return grid, profiles


import re  # noqa: E402


def dump_table(T):
    rc, out, err = run([SELFCAL, "lut", "dump", T])
    check(rc == 0, "lut dump: exit %d %s" % (rc, err))
    return parse_dump(out)


class Model:
    """Independent evaluation of SPEC §4 from a parsed dump."""

    def __init__(self, grid, profiles):
        self.xs = sorted({v[0] for v in grid.values()})
        self.ys = sorted({v[1] for v in grid.values()})
        self.g = {(round((v[1] - self.ys[0]) / (self.ys[1] - self.ys[0])), round((v[0] - self.xs[0]) / (self.xs[1] - self.xs[0]))):
                  (v[2], v[3]) for v in grid.values()}
        self.profiles = profiles

    def G(self, x_mm, y_mm):
        nx, ny = len(self.xs), len(self.ys)
        px = (self.xs[-1] - self.xs[0]) / (nx - 1)
        py = (self.ys[-1] - self.ys[0]) / (ny - 1)
        outside = x_mm < self.xs[0] or x_mm > self.xs[-1] or y_mm < self.ys[0] or y_mm > self.ys[-1]
        fx = min(max((x_mm - self.xs[0]) / px, 0.0), nx - 1.0)
        fy = min(max((y_mm - self.ys[0]) / py, 0.0), ny - 1.0)
        j0, i0 = min(int(math.floor(fx)), nx - 2), min(int(math.floor(fy)), ny - 2)
        tx, ty = fx - j0, fy - i0
        res = []
        for comp in (0, 1):
            a = self.g[(i0, j0)][comp]
            b = self.g[(i0, j0 + 1)][comp]
            c = self.g[(i0 + 1, j0)][comp]
            d = self.g[(i0 + 1, j0 + 1)][comp]
            res.append((1 - ty) * ((1 - tx) * a + tx * b) + ty * ((1 - tx) * c + tx * d))
        return res[0], res[1], outside

    @staticmethod
    def lin(pts, p):
        if p <= pts[0][0]:
            return pts[0][1]
        if p >= pts[-1][0]:
            return pts[-1][1]
        for (p0, e0), (p1, e1) in zip(pts, pts[1:]):
            if p0 <= p <= p1:
                return e0 + (e1 - e0) * (p - p0) / (p1 - p0)

    def correct(self, x_nm, y_nm, mode):
        x, y = x_nm * 1e-6, y_nm * 1e-6
        gx, gy, outside = self.G(x, y)
        ex, ey = gx, gy
        for _, axis, dr, pts in self.profiles:
            a = {"x": x, "y": y, "z": 0.0}[axis]
            e = self.lin(pts, a)
            if dr == "x":
                ex += e
            elif dr == "y":
                ey += e
        sgn = -1.0 if mode == "measure" else 1.0
        return x_nm + sgn * ex * 1000.0, y_nm + sgn * ey * 1000.0, outside


# ------------------------------------------------------------------ lut
def test_lut():
    d = tmpdir(BASE, "lut")
    T, gmap, profs = build_table(d)
    grid, profiles = dump_table(T)
    c = (N - 1) // 2
    check(len(grid) == N * N, "lut dump: %d grid rows, want %d" % (len(grid), N * N))
    err = 0.0
    for (i, j), (gx, gy) in gmap.items():
        v = grid.get((i, j))
        if not check(v is not None, "lut dump: node %d,%d missing" % (i, j)):
            continue
        check(abs(v[0] - (ORIGIN[0] + (j - c) * PITCH)) < 1e-6 and abs(v[1] - (ORIGIN[1] + (i - c) * PITCH)) < 1e-6,
              "lut dump: node %d,%d at %r,%r" % (i, j, v[0], v[1]))
        err = max(err, abs(v[2] - gx), abs(v[3] - gy))
    check(err <= QUANT_UM, "lut dump: grid differs from the map by %g um (> quantization)" % err)
    check(len(profiles) == len(profs), "lut dump: %d profiles, built with %d" % (len(profiles), len(profs)))
    ks = [p[0] for p in profiles]
    check(ks == list(range(len(ks))) or ks == list(range(1, len(ks) + 1)), "lut dump: profile numbers %r" % ks)
    perr = 0.0
    for (k, axis, dr, pts), (axis0, dr0, _, ey) in zip(profiles, profs):
        check((axis, dr) == (axis0, dr0), "lut dump: profile %d axis/dir %s/%s, built as %s/%s" % (k, axis, dr, axis0, dr0))
        check(len(pts) == len(ey), "lut dump: profile %d has %d points; the ey_um column has %d values" % (k, len(pts), len(ey)))
        for (p, e), (p0, e0) in zip(pts, ey):
            check(abs(p - p0) < 1e-6, "lut dump: profile %d pos_mm %r, file x_mm %r" % (k, p, p0))
            perr = max(perr, abs(e - e0))
    check(perr <= QUANT_UM, "lut dump: profile values differ from ey_um by %g um" % perr)
    print("lut dump: grid max diff %.2e um, profiles max diff %.2e um" % (err, perr))
    # every dumped value is a number, with a newline-terminated output
    rc, out, _ = run([SELFCAL, "lut", "dump", T])
    check(out.endswith("\n"), "lut dump: output not newline-terminated")


# ------------------------------------------------------------------ Modbus TCP client (socket only)
class ModbusError(Exception):
    def __init__(self, fn, code):
        super().__init__("exception fn %d code %d" % (fn, code))
        self.fn, self.code = fn, code


class Client:
    def __init__(self, port, unit=1):
        self.s = socket.create_connection(("127.0.0.1", port), timeout=5)
        self.s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.tid = 0
        self.unit = unit

    def _recv(self, n):
        b = b""
        while len(b) < n:
            chunk = self.s.recv(n - len(b))
            if not chunk:
                raise ConnectionError("closed")
            b += chunk
        return b

    def request(self, pdu):
        self.tid = (self.tid + 1) & 0xFFFF
        self.s.sendall(struct.pack(">HHHB", self.tid, 0, len(pdu) + 1, self.unit) + pdu)
        return self.response(self.tid, pdu[0])

    def response(self, tid, fn):
        hdr = self._recv(7)
        rtid, pid, ln, unit = struct.unpack(">HHHB", hdr)
        body = self._recv(ln - 1)
        if rtid != tid or pid != 0 or unit != self.unit:
            raise AssertionError("MBAP mismatch: tid %d/%d pid %d unit %d" % (rtid, tid, pid, unit))
        if body[0] == fn | 0x80:
            raise ModbusError(fn, body[1])
        if body[0] != fn:
            raise AssertionError("function %d answered with %d" % (fn, body[0]))
        return body

    def read(self, fn, addr, qty):
        body = self.request(struct.pack(">BHH", fn, addr, qty))
        if body[1] != 2 * qty:
            raise AssertionError("byte count %d for %d registers" % (body[1], qty))
        return list(struct.unpack(">%dH" % qty, body[2:2 + 2 * qty]))

    def write_multiple(self, addr, regs):
        body = self.request(struct.pack(">BHHB", 16, addr, len(regs), 2 * len(regs)) + struct.pack(">%dH" % len(regs), *regs))
        a, q = struct.unpack(">HH", body[1:5])
        if (a, q) != (addr, len(regs)):
            raise AssertionError("fn16 echo %d,%d" % (a, q))

    def write_single(self, addr, val):
        self.request(struct.pack(">BHH", 6, addr, val))

    def rw(self, raddr, rqty, waddr, regs):
        pdu = struct.pack(">BHHHHB", 23, raddr, rqty, waddr, len(regs), 2 * len(regs)) + struct.pack(">%dH" % len(regs), *regs)
        body = self.request(pdu)
        if body[1] != 2 * rqty:
            raise AssertionError("fn23 byte count %d" % body[1])
        return list(struct.unpack(">%dH" % rqty, body[2:2 + 2 * rqty]))


def i32_regs(v):
    v &= 0xFFFFFFFF
    return [v >> 16, v & 0xFFFF]


def regs_i32(hi, lo):
    v = (hi << 16) | lo
    return v - (1 << 32) if v & 0x80000000 else v


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


class Daemon:
    def __init__(self, table, extra=()):
        for attempt in range(5):
            self.port = free_port()
            self.log = open(os.path.join(os.path.dirname(table), "selfcald_%d.log" % self.port), "w")
            self.p = subprocess.Popen([SELFCALD, "--table", table, "--modbus-tcp", "127.0.0.1:%d" % self.port] + list(extra),
                                      stdout=self.log, stderr=subprocess.STDOUT)
            t0 = time.time()
            while time.time() - t0 < 15:
                if self.p.poll() is not None:
                    break
                try:
                    socket.create_connection(("127.0.0.1", self.port), timeout=1).close()
                    return
                except OSError:
                    time.sleep(0.05)
            self.stop()
        raise RuntimeError("selfcald did not start")

    def stop(self):
        if self.p.poll() is None:
            self.p.terminate()
            try:
                self.p.wait(10)
            except subprocess.TimeoutExpired:
                self.p.kill()
                self.p.wait()
        self.log.close()
        return self.p.returncode


def test_points(model):
    xs, ys = model.xs, model.ys
    pts = []
    for i in range(len(ys)):
        for j in range(len(xs)):
            pts.append((xs[j], ys[i]))  # nodes: exact
    rng = random.Random(9)
    for _ in range(40):
        pts.append((rng.uniform(xs[0], xs[-1]), rng.uniform(ys[0], ys[-1])))
    # cell edges, and outside in every direction and at the corners
    pts += [(xs[1], rng.uniform(ys[0], ys[-1])), (rng.uniform(xs[0], xs[-1]), ys[2]),
            (xs[0] - 0.3, ys[1] + 0.7), (xs[-1] + 5.0, ys[2] + 0.1), (xs[1] + 0.4, ys[0] - 1.0), (xs[2] + 0.4, ys[-1] + 2.5),
            (xs[0] - 1, ys[0] - 1), (xs[-1] + 1, ys[-1] + 1), (-500.0, 700.0), (0.0, 0.0), (2000.0, -2000.0)]
    return [(int(round(x * 1e6)), int(round(y * 1e6))) for (x, y) in pts]


def run_modbus(mode):
    d = tmpdir(BASE, "mb" + mode)
    T, gmap, profs = build_table(d)
    grid, profiles = dump_table(T)
    model = Model(grid, profiles)
    extra = ["--mode", mode] if mode == "position" else []
    dm = Daemon(T, extra)
    worst = 0.0
    worst_round = 0.0
    try:
        cl = Client(dm.port)
        st = cl.read(4, 0, 6)
        check(st[4] & 1 == 1, "%s: status bit 0 (table loaded) not set at start: %r" % (mode, st))
        count0 = st[5]
        check(count0 == 0, "%s: count %d before any correction" % (mode, count0))
        count = count0
        for n_pt, (x, y) in enumerate(test_points(model)):
            ex, ey, outside = model.correct(x, y, mode)
            regs = i32_regs(x) + i32_regs(y)
            use23 = n_pt % 2 == 1
            if use23:
                r = cl.rw(4, 6, 0, regs)
            else:
                cl.write_multiple(0, regs)
                r = cl.read(4, 0, 6)
            count = (count + 1) & 0xFFFF
            gx_, gy_ = regs_i32(r[0], r[1]), regs_i32(r[2], r[3])
            dev = max(abs(gx_ - ex), abs(gy_ - ey))
            worst = max(worst, dev)
            worst_round = max(worst_round, abs(gx_ - round(ex)), abs(gy_ - round(ey)))
            check(dev <= 1.0 + 1e-6, "%s fn%s: input (%d,%d) nm -> (%d,%d), expected (%.3f,%.3f) from lut dump"
                  % (mode, "23" if use23 else "16+4", x, y, gx_, gy_, ex, ey))
            check(((r[4] >> 1) & 1) == int(outside), "%s: input (%d,%d) nm: status %#x, outside-grid bit should be %d"
                  % (mode, x, y, r[4], int(outside)))
            check(r[4] & 1 == 1 and (r[4] >> 2) & 1 == 0, "%s: status %#x (table loaded, valid input)" % (mode, r[4]))
            check(r[5] == count, "%s: count %d, expected %d" % (mode, r[5], count))
            # holding 4-9 mirror input 0-5
            h = cl.read(3, 4, 6)
            check(h == r, "%s: holding 4-9 %r != input 0-5 %r" % (mode, h, r))
            # holding 0-3 hold the input position
            h03 = cl.read(3, 0, 4)
            check(h03 == regs, "%s: holding 0-3 %r, written %r" % (mode, h03, regs))
        # back inside after an outside position: the outside bit clears
        r = cl.rw(4, 6, 0, i32_regs(int(model.xs[1] * 1e6)) + i32_regs(int(model.ys[1] * 1e6)))
        check((r[4] >> 1) & 1 == 0, "%s: outside-grid bit still set for an inside position after an outside one" % mode)
        count = (count + 1) & 0xFFFF
        print("%s: %d points, max |got - expected| = %.3f nm (vs nearest integer %.0f nm)"
              % (mode, len(test_points(model)), worst, worst_round))
        if mode == "measure":
            exceptions(cl, model)
            # a second client sees the same register map
            c2 = Client(dm.port)
            a = cl.read(4, 0, 6)
            b = c2.read(4, 0, 6)
            check(a == b, "two clients see different input registers: %r %r" % (a, b))
            c2.s.close()
            concurrency(dm.port, model)
            partial_writes(cl)
        cl.s.close()
    finally:
        rc = dm.stop()
    check(rc == 0, "selfcald exit status %r after SIGTERM" % rc)


def exceptions(cl, model):
    before = cl.read(4, 0, 6)
    cases = [
        ("fn16 write 4-5", lambda: cl.write_multiple(4, [0, 1])),
        ("fn16 write 4-9", lambda: cl.write_multiple(4, [0] * 6)),
        ("fn16 write 2-5", lambda: cl.write_multiple(2, [0] * 4)),
        ("fn16 write 10-11", lambda: cl.write_multiple(10, [0, 0])),
        ("fn6 write 4", lambda: cl.write_single(4, 1)),
        ("fn6 write 9", lambda: cl.write_single(9, 1)),
        ("fn4 read 0-6", lambda: cl.read(4, 0, 7)),
        ("fn4 read 6", lambda: cl.read(4, 6, 1)),
        ("fn4 read 100", lambda: cl.read(4, 100, 2)),
        ("fn3 read 4-10", lambda: cl.read(3, 4, 7)),
        ("fn3 read 10", lambda: cl.read(3, 10, 1)),
        ("fn23 write 4-7", lambda: cl.rw(4, 6, 4, [0] * 4)),
        ("fn23 read 4-10", lambda: cl.rw(4, 7, 0, [0] * 4)),
    ]
    for label, fn in cases:
        try:
            fn()
            check(False, "%s: no exception; SPEC: illegal data address (2)" % label)
        except ModbusError as e:
            check(e.code == 2, "%s: exception code %d, SPEC: 2 (illegal data address)" % (label, e.code))
    after = cl.read(4, 0, 6)
    check(after == before, "rejected requests changed the registers: %r -> %r" % (before, after))


def concurrency(port, model):
    """SPEC §4: a function 23 request is atomic, its read returns the result of its own write."""
    import threading
    bad = []

    def worker(seed):
        c = Client(port)
        rng = random.Random(seed)
        for _ in range(250):
            x, y = rng.randint(6000000, 14000000), rng.randint(2000000, 10000000)
            r = c.rw(4, 6, 0, i32_regs(x) + i32_regs(y))
            ex, ey, _ = model.correct(x, y, "measure")
            if abs(regs_i32(r[0], r[1]) - ex) > 1 or abs(regs_i32(r[2], r[3]) - ey) > 1:
                bad.append((x, y, r))
        c.s.close()

    ts = [threading.Thread(target=worker, args=(s,)) for s in range(4)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    print("concurrent fn23: %d clients x 250 requests, %d wrong" % (len(ts), len(bad)))
    check(not bad, "concurrent fn23 (4 clients x 250): %d answers were not the result of their own write, e.g. %r"
          % (len(bad), bad[:1]))


def partial_writes(cl):
    """SPEC §4: 'A write of registers 0-3 in one request ... computes the correction' - a write of
    only part of 0-3 stores the registers but computes nothing."""
    r0 = cl.read(4, 0, 6)
    cl.write_multiple(0, i32_regs(8000000))
    cl.write_multiple(2, i32_regs(5000000))
    r1 = cl.read(4, 0, 6)
    check(r1 == r0, "partial writes of 0-1 and 2-3 changed the outputs/count: %r -> %r" % (r0, r1))


def test_count():
    d = tmpdir(BASE, "mbcount")
    T, gmap, profs = build_table(d)
    dm = Daemon(T)
    try:
        cl = Client(dm.port)
        total = 65536 + 5
        regs = i32_regs(10000000) + i32_regs(6000000)
        # pipelined fn16 requests in batches (Modbus TCP transaction ids); answers read in order
        pdu = struct.pack(">BHHB", 16, 0, 4, 8) + struct.pack(">4H", *regs)
        sent = 0
        t0 = time.time()
        while sent < total:
            b = min(200, total - sent)
            msgs = b"".join(struct.pack(">HHHB", (sent + k) & 0xFFFF, 0, len(pdu) + 1, 1) + pdu for k in range(b))
            cl.s.sendall(msgs)
            for k in range(b):
                cl.response((sent + k) & 0xFFFF, 16)
            sent += b
        r = cl.read(4, 0, 6)
        check(r[5] == total % 65536, "count after %d corrections: %d, SPEC: modulo 65536 = %d" % (total, r[5], total % 65536))
        print("count: %d corrections in %.1f s, register 5 = %d" % (total, time.time() - t0, r[5]))
        cl.s.close()
    finally:
        dm.stop()


{"lut": test_lut, "modbus": lambda: run_modbus("measure"), "position": lambda: run_modbus("position"),
 "count": test_count}[MODE]()
finish("spec_runtime " + MODE)
