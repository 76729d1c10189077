"""What the export tests share: the command line, `selfcal export ARGS`, and a failure list that
lets one run report every problem before it fails."""
import os
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
