#!/usr/bin/env python3
"""Simulated traffic through selfcald: a raster and a circle trajectory at set rates (pipelined,
and with two generators at once), every answer checked by traffic.py.
usage: test_traffic.py SELFCAL_CLI SELFCALD WORKDIR"""
import os
import subprocess
import sys

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
from sclib import Daemon, check, make_table  # noqa: E402

cli, selfcald, work = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(work, exist_ok=True)
table, _ = make_table(cli, work, "traffic", n=15, pitch=1.5, scale_um=3.0)
dump = os.path.join(work, "traffic_dump.csv")
with open(dump, "w") as f:
    subprocess.run([cli, "lut", "dump", table], stdout=f, check=True)
d = Daemon(selfcald, table)
try:
    gen = [sys.executable, os.path.join(here, "traffic.py"), "--port", str(d.port), "--dump", dump]
    runs = [
        ["--pattern", "raster", "--points", "3000", "--rate", "3000", "--window", "1"],
        ["--pattern", "circle", "--points", "3000", "--rate", "5000", "--window", "8"],
    ]
    for r in runs:
        p = subprocess.run(gen + r, capture_output=True, text=True, timeout=60)
        print(p.stdout, end="")
        check(p.returncode == 0, f"traffic {r}: {p.stdout} {p.stderr}")
    # Two generators at once: each answer is still the one for its own request.
    # (The shared counter then advances by 2 between a client's answers: check values only.)
    procs = [subprocess.Popen(gen + ["--pattern", pat, "--points", "1500", "--rate", "2000",
                                     "--window", "1"], stdout=subprocess.PIPE, text=True)
             for pat in ("raster", "circle")]
    for p in procs:
        out, _ = p.communicate(timeout=60)
        print(out, end="")
        check(" lost 0 out-of-order 0 wrong 0" in out, f"concurrent traffic: {out}")
finally:
    rc = d.stop()
check(rc == 0, f"selfcald exit status {rc}")
# The same traffic through a daemon that busy-polls after each request: same answers.
d = Daemon(selfcald, table, extra=("--busy-poll-us", "2000"))
try:
    gen = [sys.executable, os.path.join(here, "traffic.py"), "--port", str(d.port), "--dump", dump]
    p = subprocess.run(gen + ["--pattern", "raster", "--points", "2000", "--rate", "4000",
                              "--window", "1"], capture_output=True, text=True, timeout=60)
    print("busy-poll:", p.stdout, end="")
    check(p.returncode == 0 and " lost 0 out-of-order 0 wrong 0" in p.stdout,
          f"traffic with --busy-poll-us: {p.stdout} {p.stderr}")
finally:
    rc = d.stop()
check(rc == 0, f"selfcald (busy-poll) exit status {rc}")
print("traffic: ok")
