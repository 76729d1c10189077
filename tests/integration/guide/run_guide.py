#!/usr/bin/env python3
"""Run the commands of a Markdown guide in order, so the guide cannot drift from the program.

Usage: run_guide.py GUIDE.md BINDIR WORKDIR
Every fenced block whose info string is `sh test` is taken, in file order, into one bash script
(set -euo pipefail) that runs in an empty WORKDIR with BINDIR first on PATH. The test fails if
the guide has no such block, if a command fails, or if the script takes more than 5 minutes.
"""
import os
import shutil
import signal
import subprocess
import sys

guide, bindir, work = sys.argv[1], sys.argv[2], sys.argv[3]
blocks, cur, start = [], None, 0
with open(guide, encoding="utf-8") as f:
    for no, line in enumerate(f, 1):
        s = line.rstrip("\n")
        if cur is None and s.strip() == "```sh test":
            cur, start = [], no
        elif cur is not None and s.strip() == "```":
            blocks.append((start, cur))
            cur = None
        elif cur is not None:
            cur.append(s)
if cur is not None:
    sys.exit("FAIL: %s:%d: unterminated test block" % (guide, start))
if not blocks:
    sys.exit("FAIL: %s: no ```sh test blocks" % guide)

shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
script = ["set -euo pipefail"]
for start, lines in blocks:
    script.append("echo '>>> %s:%d'" % (os.path.basename(guide), start))
    script += lines
path = os.path.join(work, "guide.sh")
with open(path, "w") as f:
    f.write("\n".join(script) + "\n")
env = dict(os.environ, PATH=os.path.abspath(bindir) + os.pathsep + os.environ.get("PATH", ""))
# its own process group, so that a daemon the guide starts cannot outlive a failing step
p = subprocess.Popen(["bash", path], cwd=work, env=env, start_new_session=True)
try:
    rc = p.wait(timeout=300)
except subprocess.TimeoutExpired:
    rc = "timeout"
try:
    os.killpg(p.pid, signal.SIGTERM)
except ProcessLookupError:
    pass
if rc != 0:
    sys.exit("FAIL: the guide's commands stopped with status %s (the last '>>>' line names the "
             "block)" % rc)
print("ok: %d blocks of %s ran" % (len(blocks), guide))
