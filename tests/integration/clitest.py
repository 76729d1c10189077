"""clitest.py — the preamble the CLI integration tests share (grid_cli, grid_real, import_cli,
report): the command line `TEST.py CLI TMPDIR CASE [args]`, a failure that ends the test with
one FAIL line, a run of selfcal that must exit as expected, a fresh scratch folder per case;
and for the grid tests a CSV's rows, a simulated grid with its truth files, and a map's largest
difference from the truth.

Use:  sys.path.insert(0, <tests/integration>); import clitest
      CLI, TMP, CASE = clitest.setup("grid_cli_")
"""
import csv
import os
import shutil
import subprocess
import sys

CLI = None
TMP = None
_prefix = ""
_timeout = 300


def setup(prefix, timeout=300):
    """Read CLI, TMPDIR and CASE from the command line; fresh_dir names start with prefix and a
    run may take timeout seconds. Returns (CLI, TMP, CASE)."""
    global CLI, TMP, _prefix, _timeout
    CLI, TMP = sys.argv[1], sys.argv[2]
    _prefix, _timeout = prefix, timeout
    return CLI, TMP, sys.argv[3]


def fail(msg):
    print("FAIL: " + msg)
    sys.exit(1)


def run(*args, expect=0):
    p = subprocess.run([CLI] + [str(a) for a in args], capture_output=True, text=True,
                       timeout=_timeout)
    if p.returncode != expect:
        fail("selfcal %s: exit %d (want %d)\nstdout: %s\nstderr: %s"
             % (" ".join(map(str, args)), p.returncode, expect, p.stdout, p.stderr))
    return p


def fresh_dir(name):
    d = os.path.join(TMP, _prefix + name)
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    return d


def rows(path):
    """A CSV file's rows as dicts (its header line names the fields)."""
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def simulate(d, name, *args):
    """`selfcal simulate grid ARGS` into folder d: the input NAME.csv and the truth (G, A and the
    JSON summary); returns their paths (inp, g, a, t)."""
    f = dict(inp=os.path.join(d, name + ".csv"), g=os.path.join(d, name + "_G.csv"),
             a=os.path.join(d, name + "_A.csv"), t=os.path.join(d, name + "_T.json"))
    run("simulate", "grid", "--out", f["inp"], "--truth-map", f["g"], "--truth-artifact", f["a"],
        "--truth-summary", f["t"], *args)
    return f


def map_error(got, truth):
    """The largest |G - G_true| component of map got against map truth, um (the same nodes)."""
    t = {(r["i"], r["j"]): r for r in rows(truth)}
    g = rows(got)
    if len(g) != len(t):
        fail("%s: %d rows, truth %d" % (got, len(g), len(t)))
    return max(max(abs(float(r["gx_um"]) - float(t[(r["i"], r["j"])]["gx_um"])),
                   abs(float(r["gy_um"]) - float(t[(r["i"], r["j"])]["gy_um"]))) for r in g)
