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
        k = 1
        while k < len(lines) and lines[k].strip() and not lines[k].startswith("#"):
            i, j, x, y, gx, gy = lines[k].split(",")
            rows.append((int(i), int(j), float(x), float(y), float(gx), float(gy)))
            k += 1
        # Profiles: "# profile k: axis=AXIS dir=DIR", header "n,pos_mm,err_um", rows.
        self.profiles = []
        axes = {"x": 0, "y": 1, "z": 2}
        while k < len(lines):
            ln = lines[k].strip()
            k += 1
            if not ln.startswith("# profile"):
                continue
            kv = dict(f.split("=") for f in ln.split(":", 1)[1].split())
            assert lines[k].strip() == "n,pos_mm,err_um", lines[k]
            k += 1
            pos, err = [], []
            while k < len(lines) and lines[k].strip() and not lines[k].startswith("#"):
                _, pmm, e = lines[k].split(",")
                pos.append(float(pmm))
                err.append(float(e))
                k += 1
            self.profiles.append((axes[kv["axis"].lower()], axes[kv["dir"].lower()], pos, err))
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

    def profile_um(self, coords_mm):
        """Sum of the profile offsets per coordinate (linear, clamped to each profile's range)."""
        off = [0.0, 0.0, 0.0]
        for axis, d, pos, err in self.profiles:
            s = min(max(coords_mm[axis], pos[0]), pos[-1])
            step = (pos[-1] - pos[0]) / (len(pos) - 1)
            q = min(int(math.floor((s - pos[0]) / step)), len(pos) - 2)
            f = (s - pos[0]) / step - q
            off[d] += (1 - f) * err[q] + f * err[q + 1]
        return off

    def correct_nm(self, x_nm, y_nm, mode="measure"):
        """Expected corrected position (float nm) and the expected outside flag. measure-exact:
        the q with q + C(q) = p, solved here by iterating to convergence (40 steps)."""
        if mode == "measure-exact":
            px, py = x_nm * 1e-6, y_nm * 1e-6
            qx, qy, out_p = px, py, self.g_um(px, py)[2]
            for _ in range(40):
                gx, gy, out = self.g_um(qx, qy)
                off = self.profile_um((qx, qy, 0.0))
                qx, qy = px - (gx + off[0]) * 1e-3, py - (gy + off[1]) * 1e-3
            return qx * 1e6, qy * 1e6, out_p or out
        gx, gy, out = self.g_um(x_nm * 1e-6, y_nm * 1e-6)
        off = self.profile_um((x_nm * 1e-6, y_nm * 1e-6, 0.0))
        gx += off[0]
        gy += off[1]
        s = -1.0 if mode == "measure" else 1.0
        return x_nm + s * gx * 1e3, y_nm + s * gy * 1e3, out


def write_profile(path, n=60, x0=-14.0, step=0.5, amp_um=0.4):
    """A SPEC §2 profile output file whose ey_um column is a known smooth error (um)."""
    with open(path, "w") as f:
        f.write("n,x_mm,f_um,uf_um,ey_um\n")
        for k in range(n):
            x = x0 + k * step
            f.write(f"{k},{x:.6f},0,0,{amp_um * math.sin(0.3 * x) + 0.01 * x:.6f}\n")


def make_table(cli, workdir, name="t", profiles=(), **kw):
    """Map CSV (+ profiles "AXIS:DIR") -> `selfcal lut build` -> table; returns (table path,
    Table from `lut dump`)."""
    m = os.path.join(workdir, name + "_map.csv")
    t = os.path.join(workdir, name + ".lut")
    write_map(m, **kw)
    args = [cli, "lut", "build", "--map", m, "-o", t]
    for k, spec in enumerate(profiles):
        pf = os.path.join(workdir, f"{name}_profile{k}.csv")
        write_profile(pf, amp_um=0.4 + 0.2 * k)
        args += ["--profile", f"{spec}:{pf}"]
    subprocess.run(args, check=True)
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


def pty_pair(work, tag=""):
    """Two linked pseudo-terminals made by socat, WORK/ptyA<tag> and WORK/ptyB<tag> (a serial
    line with a device at each end): (a, b, the socat process, which the caller terminates and
    waits for). The test fails if they are not there within 5 s."""
    a, b = os.path.join(work, f"ptyA{tag}"), os.path.join(work, f"ptyB{tag}")
    for p in (a, b):
        if os.path.lexists(p):
            os.unlink(p)
    socat = subprocess.Popen(["socat", f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"],
                             stderr=subprocess.DEVNULL)
    deadline = time.time() + 5
    while not (os.path.exists(a) and os.path.exists(b)) and time.time() < deadline:
        time.sleep(0.02)
    if not (os.path.exists(a) and os.path.exists(b)):
        socat.terminate()
        socat.wait()
        check(False, "socat did not create the pty pair")
    return a, b, socat


def recv_exact(s, n):
    """n bytes from socket s; ConnectionError if the daemon closes the connection first."""
    b = b""
    while len(b) < n:
        c = s.recv(n - len(b))
        if not c:
            raise ConnectionError("closed by the daemon")
        b += c
    return b


def replace_file(path, blob):
    """Write blob to path atomically: a .new file renamed over it (what an operator's deploy does)."""
    tmp = path + ".new"
    with open(tmp, "wb") as f:
        f.write(blob)
    os.replace(tmp, path)


def reload_step(k, live, good_a, corrupt, good_b):
    """Step k of the reload storm's cycle at path live: table A, a corrupt table, no table, table B.
    The caller sends SIGHUP after it."""
    step = k % 4
    if step == 0:
        replace_file(live, good_a)
    elif step == 1:
        replace_file(live, bytes(corrupt))
    elif step == 2:
        if os.path.exists(live):
            os.unlink(live)
    else:
        replace_file(live, good_b)


def storm_tables(cli, work):
    """The reload storm's tables in work: two valid ones (A, B) with their references, B with one
    bit flipped (its CRC no longer matches), and the live path selfcald serves.
    Returns ref_a, ref_b, blob_a, blob_b, corrupt, live."""
    table_a, ref_a = make_table(cli, work, "a", n=9, pitch=2.0, scale_um=1.5)
    table_b, ref_b = make_table(cli, work, "b", n=9, pitch=2.0, scale_um=-2.0, phase=0.9)
    with open(table_a, "rb") as f:
        blob_a = f.read()
    with open(table_b, "rb") as f:
        blob_b = f.read()
    corrupt = bytearray(blob_b)
    corrupt[len(corrupt) // 2] ^= 0x40
    return ref_a, ref_b, blob_a, blob_b, corrupt, os.path.join(work, "live.lut")
