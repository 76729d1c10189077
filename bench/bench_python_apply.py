"""Table.apply from Python against the correction core's own speed (bench_core_apply), in one run.

usage: bench_python_apply.py SELFCAL_CLI BENCH_CORE_APPLY   (with the package installed)
Prints million points per second for 10^6 random points: new output arrays per call, reused
output arrays (out=), and the C core's figure from bench_core_apply measured just before.
"""
import subprocess
import sys
import tempfile
import time

import numpy as np

import selfcal

cli, core = sys.argv[1], sys.argv[2]
with tempfile.TemporaryDirectory() as d:
    def run(*a):
        subprocess.run([cli, *a], check=True, capture_output=True)

    run("simulate", "grid", "--plan", "double-shift", "--n", "25", "--out", f"{d}/in.csv",
        "--truth-map", f"{d}/Gt.csv")
    run("grid", "--method", "lsq", f"{d}/in.csv", "--map", f"{d}/G.csv", "--quiet")
    run("simulate", "profile", "--n", "330", "--out", f"{d}/s.csv", "--truth", f"{d}/t.csv")
    run("profile", "--method", "lsq", f"{d}/s.csv", "--out", f"{d}/P.csv", "--quiet")
    run("lut", "build", "--map", f"{d}/G.csv", "--profile", f"x:y:{d}/P.csv@-12", "-o", f"{d}/T.lut")
    t = selfcal.Table(f"{d}/T.lut")
    out = subprocess.run([core], capture_output=True, text=True).stdout
    n = 1_000_000
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-12, 12, n), rng.uniform(-12, 12, n)
    best_new = best_reused = float("inf")
    buf = None
    for _ in range(7):
        t0 = time.perf_counter()
        t.apply(x, y)
        best_new = min(best_new, time.perf_counter() - t0)
        t0 = time.perf_counter()
        buf = t.apply(x, y, out=buf)
        best_reused = min(best_reused, time.perf_counter() - t0)
core_ns = next((float(l.split()[-2]) for l in out.splitlines()
                if l.startswith("apply measure (~64% outside)")), float("nan"))
print("Table.apply, 10^6 random points on a 25 x 25 map + one profile (best of 7)")
print(f"  new output arrays     {n / best_new / 1e6:7.1f} M points/s")
print(f"  reused (out=)         {n / best_reused / 1e6:7.1f} M points/s")
print(f"  C core, bench_core_apply in the same run: {1e3 / core_ns:7.1f} M points/s "
      f"({core_ns:.2f} ns per correction)")
print(f"  ratio Python (out=) / C core: {(n / best_reused) / (1e9 / core_ns):.2f}")
