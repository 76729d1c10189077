#!/usr/bin/env python3
"""The function-size rule of docs/architecture.md, checked: no function of the library, the
runtime or the CLI over 80 lines or with a cyclomatic complexity (CCN) over 25, as lizard counts
them. Prints every offender (file:line, name, figures) and exits 1 when there is one; exits 77
(CTest's SKIP_RETURN_CODE) when lizard is not installed, saying so.

    code_metrics.py SOURCE_DIR [LIZARD]

LIZARD is the lizard program to run; without it the project's .venv/bin/lizard (installed by
scripts/install-deps.sh from tests/requirements.txt), then lizard on PATH.
"""
import os
import re
import shutil
import subprocess
import sys

MAX_CCN = 25
MAX_LENGTH = 80
FOLDERS = ("libselfcal", "runtime", "tools/selfcal")
SKIP = 77


def find_lizard(src, given):
    for cand in (given, os.path.join(src, ".venv", "bin", "lizard"), shutil.which("lizard")):
        if cand and os.path.isfile(cand) and os.access(cand, os.X_OK):
            return cand
    return None


def pinned_version(src):
    try:
        with open(os.path.join(src, "tests", "requirements.txt"), encoding="utf-8") as f:
            for line in f:
                m = re.match(r"\s*lizard==(\S+)", line)
                if m:
                    return m.group(1)
    except OSError:
        pass
    return None


def main():
    if len(sys.argv) not in (2, 3):
        print("usage: code_metrics.py SOURCE_DIR [LIZARD]", file=sys.stderr)
        return 2
    src = os.path.abspath(sys.argv[1])
    lizard = find_lizard(src, sys.argv[2] if len(sys.argv) == 3 else None)
    if lizard is None:
        print("code_metrics: SKIPPED: lizard is not installed (scripts/install-deps.sh puts the "
              "version pinned in tests/requirements.txt into .venv)")
        return SKIP
    version = subprocess.run([lizard, "--version"], capture_output=True, text=True).stdout.strip()
    pinned = pinned_version(src)
    if pinned and version != pinned:
        print(f"code_metrics: note: lizard {version}, the project pins {pinned}")
    folders = [os.path.join(src, d) for d in FOLDERS]
    missing = [d for d in folders if not os.path.isdir(d)]
    if missing:
        print(f"code_metrics: no such folder: {', '.join(missing)}", file=sys.stderr)
        return 2
    cmd = [lizard, "-C", str(MAX_CCN), "-L", str(MAX_LENGTH), "-w"] + folders
    run = subprocess.run(cmd, capture_output=True, text=True, cwd=src)
    offenders = [line for line in run.stdout.splitlines() if ": warning: " in line]
    if run.returncode not in (0, 1) or (run.returncode == 1 and not offenders):
        print(f"code_metrics: lizard failed (status {run.returncode}):\n{run.stdout}{run.stderr}",
              file=sys.stderr)
        return 2
    if offenders:
        print(f"code_metrics: {len(offenders)} function(s) over {MAX_LENGTH} lines or CCN "
              f"{MAX_CCN} (lizard {version}):")
        for line in offenders:
            print("  " + (line[len(src) + 1:] if line.startswith(src + os.sep) else line))
        return 1
    print(f"code_metrics: no function over {MAX_LENGTH} lines or CCN {MAX_CCN} in "
          f"{', '.join(FOLDERS)} (lizard {version})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
