"""Helpers shared by the selfcald integration tests: make a table with the real CLI, read it back
with `selfcal lut dump`, evaluate it independently (bilinear, clamped, SPEC §4), run the daemon."""
import math
import os
import re
import signal
import subprocess
import sys
import time


def write_map(path, n=11, pitch=2.0, scale_um=1.0, phase=0.0):
    """A SPEC §1 stage error map, n x n nodes centred on 0, with a smooth known G (um)."""
    c = (n - 1) / 2
    with open(path, "w") as f:
        f.write("i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n")
        for i in range(n):
            for j in range(n):
                x, y = (j - c) * pitch, (i - c) * pitch
                gx = scale_um * (0.8 * math.sin(0.21 * x + phase) + 0.004 * y * y - 0.01 * x * y)
                gy = scale_um * (-0.6 * math.cos(0.17 * y + phase) + 0.03 * x - 0.002 * x * x)
                f.write(f"{i},{j},{x:.6f},{y:.6f},{gx:.6f},{gy:.6f},,\n")


class Table:
    """The grid of a table as printed by `selfcal lut dump` (SPEC §3), evaluated here."""

    def __init__(self, dump_text):
        rows = []
        lines = dump_text.splitlines()
        assert lines[0].strip() == "i,j,x_mm,y_mm,gx_um,gy_um", lines[0]
        for ln in lines[1:]:
            if ln.startswith("#") or not ln.strip():
                break
            i, j, x, y, gx, gy = ln.split(",")
            rows.append((int(i), int(j), float(x), float(y), float(gx), float(gy)))
        self.ny = max(r[0] for r in rows) + 1
        self.nx = max(r[1] for r in rows) + 1
        assert len(rows) == self.nx * self.ny
        g = {(r[0], r[1]): r for r in rows}
        self.x0, self.y0 = g[(0, 0)][2], g[(0, 0)][3]
        self.px = (g[(0, self.nx - 1)][2] - self.x0) / (self.nx - 1)
        self.py = (g[(self.ny - 1, 0)][3] - self.y0) / (self.ny - 1)
        self.gx = [[g[(i, j)][4] for j in range(self.nx)] for i in range(self.ny)]
        self.gy = [[g[(i, j)][5] for j in range(self.nx)] for i in range(self.ny)]

    def g_um(self, x_mm, y_mm):
        """Bilinear G at (x, y), clamped to the edge outside; returns (gx, gy, outside)."""
        u = (x_mm - self.x0) / self.px
        v = (y_mm - self.y0) / self.py
        outside = u < 0 or v < 0 or u > self.nx - 1 or v > self.ny - 1
        u = min(max(u, 0.0), self.nx - 1.0)
        v = min(max(v, 0.0), self.ny - 1.0)
        j = min(int(math.floor(u)), self.nx - 2)
        i = min(int(math.floor(v)), self.ny - 2)
        fu, fv = u - j, v - i

        def bil(t):
            return ((1 - fv) * ((1 - fu) * t[i][j] + fu * t[i][j + 1])
                    + fv * ((1 - fu) * t[i + 1][j] + fu * t[i + 1][j + 1]))
        return bil(self.gx), bil(self.gy), outside

    def correct_nm(self, x_nm, y_nm, mode="measure"):
        """Expected corrected position (float nm) and the expected outside flag."""
        gx, gy, out = self.g_um(x_nm * 1e-6, y_nm * 1e-6)
        s = -1.0 if mode == "measure" else 1.0
        return x_nm + s * gx * 1e3, y_nm + s * gy * 1e3, out


def make_table(cli, workdir, name="t", **kw):
    """Map CSV -> `selfcal lut build` -> table; returns (table path, Table from `lut dump`)."""
    m = os.path.join(workdir, name + "_map.csv")
    t = os.path.join(workdir, name + ".lut")
    write_map(m, **kw)
    subprocess.run([cli, "lut", "build", "--map", m, "-o", t], check=True)
    dump = subprocess.run([cli, "lut", "dump", t], check=True, capture_output=True, text=True)
    return t, Table(dump.stdout)


class Daemon:
    """selfcald in the background on a free port (port 0; the bound port read from its log)."""

    def __init__(self, selfcald, table, extra=(), tcp=True, log_path=None):
        self.log_path = log_path or (table + ".daemon.log")
        self.log = open(self.log_path, "w+")
        args = [selfcald, "--table", table, "--log-level", "debug"]
        if tcp:
            args += ["--modbus-tcp", "127.0.0.1:0"]
        args += list(extra)
        self.p = subprocess.Popen(args, stderr=self.log, stdout=self.log)
        self.port = None
        deadline = time.time() + 10
        while time.time() < deadline:
            text = open(self.log_path).read()
            if tcp:
                m = re.search(r"listening on [0-9.]+:(\d+)", text)
                if m:
                    self.port = int(m.group(1))
            if "ready" in text and (self.port or not tcp):
                return
            if self.p.poll() is not None:
                raise RuntimeError("selfcald exited: " + text)
            time.sleep(0.02)
        raise RuntimeError("selfcald not ready: " + open(self.log_path).read())

    def text(self):
        return open(self.log_path).read()

    def signal(self, sig):
        self.p.send_signal(sig)

    def stop(self):
        if self.p.poll() is None:
            self.p.send_signal(signal.SIGTERM)
            try:
                rc = self.p.wait(10)
            except subprocess.TimeoutExpired:
                self.p.kill()
                rc = self.p.wait()
                raise RuntimeError("selfcald did not stop on SIGTERM")
        else:
            rc = self.p.returncode
        self.log.close()
        return rc


def i32_to_regs(v, high_first=True):
    u = v & 0xFFFFFFFF
    hi, lo = u >> 16, u & 0xFFFF
    return [hi, lo] if high_first else [lo, hi]


def regs_to_i32(r, high_first=True):
    hi, lo = (r[0], r[1]) if high_first else (r[1], r[0])
    u = (hi << 16) | lo
    return u - (1 << 32) if u & 0x80000000 else u


def check(cond, msg):
    if not cond:
        print("FAIL:", msg, file=sys.stderr)
        sys.exit(1)
