"""What the export tests share: the command line, `selfcal export ARGS`, and a failure list that
lets one run report every problem before it fails."""
import os
import re
import subprocess
import sys


class Export:
    def __init__(self, cli, work):
        self.cli, self.work = cli, work
        os.makedirs(work, exist_ok=True)
        self.failures = []

    def check(self, cond, what):
        if not cond:
            self.failures.append(what)
            print("FAIL:", what, file=sys.stderr)

    def run(self, *args):
        p = subprocess.run([self.cli, "export", *args], capture_output=True, text=True,
                           timeout=60)
        return p.returncode, p.stdout, p.stderr

    def finish(self, name):
        if self.failures:
            print(f"{len(self.failures)} failure(s)")
            sys.exit(1)
        print(f"{name}: all checks passed")


def read_beckhoff_plane(path):
    """A Beckhoff/ISG plane compensation file (kw.crosscomp2) as (table, header): table maps
    (index master2, index master1) to the correction, header each kw.crosscomp2.* and kopf.*
    key to its text value."""
    tab, hdr = {}, {}
    with open(path) as f:
        for line in f:
            m = re.match(r"kw\.crosscomp2\.table\[\s*(\d+)\]\[\s*(\d+)\]\.correction\s+(-?\d+)",
                         line)
            if m:
                tab[(int(m.group(1)), int(m.group(2)))] = int(m.group(3))
                continue
            m = re.match(r"(kw\.crosscomp2\.\w+|kopf\.\w+)\s+(\S+)", line)
            if m:
                hdr[m.group(1)] = m.group(2)
    return tab, hdr
