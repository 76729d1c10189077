#!/usr/bin/env python3
"""selfcal(1)'s option lists are those the commands' option tables make, and --help's option
list is the table's (tools/man_options.py --check); the check fails on a page whose list was
edited by hand or dropped, on a table option the page lacks, and on a --help whose list lost a
row, a help text or a default.
usage: man_options_test.py MAN_OPTIONS.py SELFCAL MAN.in WORKDIR"""
import os
import subprocess
import sys

script, selfcal, man, work = sys.argv[1:5]
os.makedirs(work, exist_ok=True)
text = open(man, encoding="utf-8").read()


def check(page_text, name, prog=None):
    path = os.path.join(work, name)
    with open(path, "w", encoding="utf-8") as f:
        f.write(page_text)
    p = subprocess.run([sys.executable, script, "--check", prog or selfcal, path],
                       capture_output=True, text=True, timeout=300)
    return p.returncode, p.stdout + p.stderr


def wrapper(name, old, new):
    """A selfcal whose `grid --help` has old replaced by new (once): --help drifted from the
    table."""
    path = os.path.join(work, name)
    with open(path, "w", encoding="utf-8") as f:
        f.write("#!%s\nimport subprocess, sys\n"
                "p = subprocess.run([%r] + sys.argv[1:], capture_output=True, text=True)\n"
                "out = p.stdout\n"
                "if sys.argv[1:] == ['grid', '--help']:\n"
                "    out = out.replace(%r, %r, 1)\n"
                "sys.stdout.write(out); sys.stderr.write(p.stderr); sys.exit(p.returncode)\n"
                % (sys.executable, os.path.abspath(selfcal), old, new))
    os.chmod(path, 0o755)
    return path


problems = []
rc, out = check(text, "selfcal.1.in")
if rc != 0:
    problems.append("the man page's option lists are not the tables':\n" + out)
begin = '.\\" OPTIONS grid '
if begin not in text:
    problems.append("no generated option list for grid in the man page")
else:
    # an edited default, a dropped row, a dropped list: each must fail the check
    a = text.index(begin)
    b = text.index('.\\" END OPTIONS', a)
    grid = text[a:b]
    edited = grid.replace("default: 0.05", "default: 0.01")
    dropped = grid.replace(".TP\n\\fB\\-\\-quiet\\fR\n", "", 1)
    for what, new in (("an edited default", edited), ("a dropped row", dropped),
                      ("a dropped list", "")):
        if new == grid:
            problems.append("test setup: %s changed nothing" % what)
            continue
        rc, out = check(text[:a] + new + text[b:], "broken.1.in")
        if rc == 0:
            problems.append("the check passed a page with %s" % what)
# --help's option list is the table's: a row dropped, an edited help, an edited default fail
grid_help = subprocess.run([selfcal, "grid", "--help"], capture_output=True, text=True,
                           timeout=60).stdout
for what, old, new in (("a dropped row", "  --quiet                 no summary on stdout\n", ""),
                       ("an edited help", "no summary on stdout", "no summary"),
                       ("an edited default", "(default: auto)", "(default: full)")):
    if old not in grid_help:
        problems.append("test setup: grid --help has no %r" % old)
        continue
    rc, out = check(text, "selfcal.1.in", wrapper("selfcal-drifted", old, new))
    if rc == 0 or "grid --help" not in out:
        problems.append("the check passed a grid --help with %s:\n%s" % (what, out))
for p in problems:
    print("FAIL:", p)
if problems:
    sys.exit(1)
print("ok: the man page's and --help's option lists are the tables'; edited, dropped rows and "
      "lists are caught")
