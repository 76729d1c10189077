#!/usr/bin/env python3
"""Traffic generator: plays a stage trajectory (raster or circle) through selfcald over Modbus TCP
at a set rate and checks every answer: nothing lost, nothing out of order, every value right.

Each point is one function 23 request (write holding 0-3, read 4-9) framed here on a plain socket,
with up to --window requests in flight; the answers must come back in transaction-id order, with
the correction counter advancing by exactly one per request, and each corrected position within
1 nm of an independent bilinear evaluation of `selfcal lut dump` output.

usage: traffic.py --port P --dump DUMP.csv [--pattern raster|circle] [--points N] [--rate HZ]
                  [--window W] [--host H] [--unit U]"""
import argparse
import math
import os
import socket
import struct
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sclib import Table  # noqa: E402


def raster(table, n, margin_mm=1.0):
    """Serpentine lines over the grid, one pitch beyond its edges (so some points are outside)."""
    x0, x1 = table.x0 - margin_mm, table.x0 + (table.nx - 1) * table.px + margin_mm
    y0, y1 = table.y0 - margin_mm, table.y0 + (table.ny - 1) * table.py + margin_mm
    lines = max(2, int(math.sqrt(n / 4)))
    per = max(2, n // lines)
    pts = []
    for k in range(lines):
        y = y0 + (y1 - y0) * k / (lines - 1)
        xs = [x0 + (x1 - x0) * m / (per - 1) for m in range(per)]
        if k % 2:
            xs.reverse()
        pts += [(x, y) for x in xs]
    return pts[:n]


def circle(table, n):
    cx = table.x0 + (table.nx - 1) * table.px / 2
    cy = table.y0 + (table.ny - 1) * table.py / 2
    r = 0.45 * min((table.nx - 1) * table.px, (table.ny - 1) * table.py)
    return [(cx + r * math.cos(2 * math.pi * k / n * 3), cy + r * math.sin(2 * math.pi * k / n * 3))
            for k in range(n)]


def fn23(tid, unit, x_nm, y_nm):
    vals = struct.pack(">ii", x_nm, y_nm)
    pdu = struct.pack(">BHHHHB", 23, 4, 6, 0, 4, 8) + vals
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu


def run(host, port, table, pts_mm, rate_hz, window, unit=1, mode="measure"):
    s = socket.create_connection((host, port))
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    s.settimeout(5)
    n = len(pts_mm)
    pts = [(int(round(x * 1e6)), int(round(y * 1e6))) for x, y in pts_mm]
    sent_at = [0.0] * n
    lat = []
    stats = dict(sent=0, answered=0, lost=0, out_of_order=0, wrong=0, bad_count=0, worst_nm=0.0)
    first_msg = []
    buf = b""
    nxt_send = nxt_recv = 0
    last_count = None
    t0 = time.perf_counter()
    period = 1.0 / rate_hz if rate_hz > 0 else 0.0
    while nxt_recv < n:
        now = time.perf_counter()
        while (nxt_send < n and nxt_send - nxt_recv < window and
               now >= t0 + nxt_send * period):
            x, y = pts[nxt_send]
            s.sendall(fn23(nxt_send & 0xFFFF, unit, x, y))
            sent_at[nxt_send] = time.perf_counter()
            nxt_send += 1
            stats["sent"] += 1
        if nxt_recv == nxt_send:
            wait = t0 + nxt_send * period - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            continue
        try:
            data = s.recv(65536)
        except socket.timeout:
            break
        if not data:
            break
        buf += data
        while len(buf) >= 6:
            ln = struct.unpack(">H", buf[4:6])[0]
            if len(buf) < 6 + ln:
                break
            frame, buf = buf[:6 + ln], buf[6 + ln:]
            tid, _, _, _, fn = struct.unpack(">HHHBB", frame[:8])
            k = nxt_recv
            nxt_recv += 1
            stats["answered"] += 1
            lat.append(time.perf_counter() - sent_at[k])
            if tid != (k & 0xFFFF):
                stats["out_of_order"] += 1
                first_msg.append(f"answer {k}: transaction id {tid}")
                continue
            if fn != 23 or frame[8] != 12:
                stats["wrong"] += 1
                first_msg.append(f"answer {k}: function {fn:#x} {frame[8:].hex()}")
                continue
            gx, gy, st, cnt = struct.unpack(">iiHH", frame[9:21])
            if last_count is not None and cnt != (last_count + 1) & 0xFFFF:
                stats["bad_count"] += 1
                first_msg.append(f"answer {k}: count {cnt} after {last_count}")
            last_count = cnt
            ex, ey, out = table.correct_nm(pts[k][0], pts[k][1], mode)
            err = max(abs(gx - ex), abs(gy - ey))
            stats["worst_nm"] = max(stats["worst_nm"], err)
            if err > 1.0 or not st & 1 or bool(st & 2) != out:
                stats["wrong"] += 1
                first_msg.append(f"answer {k}: ({gx},{gy}) st {st}, expected ({ex:.1f},{ey:.1f})")
    elapsed = time.perf_counter() - t0
    s.close()
    stats["lost"] = n - stats["answered"]
    stats["rate_hz"] = stats["answered"] / elapsed if elapsed > 0 else 0.0
    lat.sort()
    stats["p50_us"] = lat[len(lat) // 2] * 1e6 if lat else 0.0
    stats["p99_us"] = lat[min(len(lat) - 1, int(len(lat) * 0.99))] * 1e6 if lat else 0.0
    return stats, first_msg[:5]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--dump", required=True, help="output of `selfcal lut dump TABLE`")
    ap.add_argument("--pattern", choices=["raster", "circle"], default="raster")
    ap.add_argument("--points", type=int, default=2000)
    ap.add_argument("--rate", type=float, default=1000.0, help="points per second (0: flat out)")
    ap.add_argument("--window", type=int, default=4, help="requests in flight")
    ap.add_argument("--unit", type=int, default=1)
    ap.add_argument("--mode", choices=["measure", "position"], default="measure")
    a = ap.parse_args()
    table = Table(open(a.dump).read())
    pts = raster(table, a.points) if a.pattern == "raster" else circle(table, a.points)
    st, msgs = run(a.host, a.port, table, pts, a.rate, a.window, a.unit, a.mode)
    print(f"{a.pattern}: sent {st['sent']} answered {st['answered']} lost {st['lost']} "
          f"out-of-order {st['out_of_order']} wrong {st['wrong']} count-gaps {st['bad_count']} "
          f"worst {st['worst_nm']:.3f} nm, {st['rate_hz']:.0f} points/s, "
          f"latency p50 {st['p50_us']:.0f} us p99 {st['p99_us']:.0f} us")
    for m in msgs:
        print("  ", m)
    ok = st["lost"] == 0 and st["out_of_order"] == 0 and st["wrong"] == 0 and st["bad_count"] == 0
    return 0 if ok and st["sent"] == len(pts) else 1


if __name__ == "__main__":
    sys.exit(main())
