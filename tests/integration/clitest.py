"""clitest.py — the preamble the CLI integration tests share (grid_cli, grid_real, import_cli,
report): the command line `TEST.py CLI TMPDIR CASE [args]`, a failure that ends the test with
one FAIL line, a run of selfcal that must exit as expected, a fresh scratch folder per case.

Use:  sys.path.insert(0, <tests/integration>); import clitest
      CLI, TMP, CASE = clitest.setup("grid_cli_")
"""
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
