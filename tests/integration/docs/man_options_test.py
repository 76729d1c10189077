#!/usr/bin/env python3
"""selfcal(1)'s option lists are those the commands' option tables make, and --help names the
tables' options (tools/man_options.py --check); the check fails on a page whose list was edited
by hand or dropped, and on a table option the page lacks.
usage: man_options_test.py MAN_OPTIONS.py SELFCAL MAN.in WORKDIR"""
import os
import subprocess
import sys

script, selfcal, man, work = sys.argv[1:5]
os.makedirs(work, exist_ok=True)
text = open(man, encoding="utf-8").read()


def check(page_text, name):
    path = os.path.join(work, name)
    with open(path, "w", encoding="utf-8") as f:
        f.write(page_text)
    p = subprocess.run([sys.executable, script, "--check", selfcal, path], capture_output=True,
                       text=True, timeout=300)
    return p.returncode, p.stdout + p.stderr


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
for p in problems:
    print("FAIL:", p)
if problems:
    sys.exit(1)
print("ok: the man page's option lists are the tables'; edited, dropped rows and lists are caught")
