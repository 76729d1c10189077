#!/usr/bin/env python3
"""Whole-run regression cases (after gpsd's regress-driver): each folder tests/regress/cases/NAME/
holds the command lines of one case and what they must produce, and this one driver runs them.

    run.py SELFCAL [--work DIR] [--cases DIR] [--rebuild] [--list] [NAME...]

A case folder holds:
  cmd      the command lines, one a line, run in order in an empty folder; `#` lines and blank
           lines are skipped. Each line is split as a shell would split it (no pipes, no
           redirection); its first word is `selfcal` (the binary under test). $DATA names
           tests/data, $CASE the case's own folder (inputs of its own).
  stdout   what the commands wrote on stdout, each command's output after a line `$ COMMAND`
  stderr   the same for stderr
  status   the exit status of each command, one a line
  files/   every file the commands left in their folder, byte for byte (none: no files/ folder)

Runs with SOURCE_DATE_EPOCH=1700000000 (tables and reports carry that creation time), LC_ALL=C
and TZ=UTC. The only normalisation: the absolute paths of the run's folder, tests/data and the
case folder are written $WORK, $DATA and $CASE in stdout, stderr and text files.

Without NAME every case runs. Exit 0 when all match; 1 with a diff of every difference; 2 on a
broken case (no cmd, a command that is not selfcal). --rebuild writes stdout, stderr, status and
files/ from the binary given (only for a change of output that is meant: docs/testing.md).
"""
import argparse
import difflib
import os
import shlex
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
CASES = os.path.join(HERE, "cases")
DATA = os.path.normpath(os.path.join(HERE, "..", "data"))
EPOCH = "1700000000"
TIMEOUT_S = 120  # one command; generous for ASan on a loaded machine
MAX_DIFF_LINES = 60


class CaseError(Exception):
    pass


def read_commands(case_dir):
    path = os.path.join(case_dir, "cmd")
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise CaseError(f"{path}: cannot read: {e.strerror}")
    commands = []
    for number, line in enumerate(lines, 1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        try:
            words = shlex.split(text)
        except ValueError as e:
            raise CaseError(f"{path}:{number}: {e}")
        if words[0] != "selfcal":
            raise CaseError(f"{path}:{number}: a command begins with 'selfcal', not '{words[0]}'")
        commands.append((text, words))
    if not commands:
        raise CaseError(f"{path}: no command")
    return commands


def expand(word, case_dir):
    return word.replace("$DATA", DATA).replace("$CASE", case_dir)


def normalise(data, work, case_dir):
    """Absolute paths of this run written as names that do not depend on where it ran."""
    for path, name in ((work, "$WORK"), (case_dir, "$CASE"), (DATA, "$DATA")):
        data = data.replace(path.encode(), name.encode())
    return data


def is_text(data):
    if b"\0" in data:
        return False
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


def run_case(selfcal, case_dir, work):
    """Runs the case in the empty folder work; returns {relative name: bytes}."""
    commands = read_commands(case_dir)
    env = dict(os.environ, SOURCE_DATE_EPOCH=EPOCH, LC_ALL="C", TZ="UTC")
    out, err, status = [], [], []
    for text, words in commands:
        argv = [selfcal] + [expand(w, case_dir) for w in words[1:]]
        try:
            p = subprocess.run(argv, cwd=work, env=env, stdin=subprocess.DEVNULL,
                               capture_output=True, timeout=TIMEOUT_S)
            code, so, se = p.returncode, p.stdout, p.stderr
        except subprocess.TimeoutExpired as e:
            code, so, se = "timeout", e.stdout or b"", e.stderr or b""
        header = f"$ {text}\n".encode()
        out.append(header + so)
        err.append(header + se)
        status.append(f"{code}\n".encode())
    got = {"stdout": b"".join(out), "stderr": b"".join(err), "status": b"".join(status)}
    for root, _dirs, files in os.walk(work):
        for name in files:
            full = os.path.join(root, name)
            got["files/" + os.path.relpath(full, work)] = open(full, "rb").read()
    return {k: (normalise(v, work, case_dir) if k in ("stdout", "stderr") or is_text(v) else v)
            for k, v in got.items()}


def expected_of(case_dir):
    want = {}
    for name in ("stdout", "stderr", "status"):
        path = os.path.join(case_dir, name)
        if os.path.isfile(path):
            want[name] = open(path, "rb").read()
    files = os.path.join(case_dir, "files")
    for root, _dirs, names in os.walk(files):
        for name in names:
            full = os.path.join(root, name)
            want["files/" + os.path.relpath(full, files)] = open(full, "rb").read()
    return want


def describe(name, want, got):
    """A readable account of one difference."""
    if want is None:
        return [f"{name}: not expected, but the run made it ({len(got)} bytes)"]
    if got is None:
        return [f"{name}: expected, but the run did not make it"]
    if is_text(want) and is_text(got):
        diff = list(difflib.unified_diff(want.decode().splitlines(), got.decode().splitlines(),
                                         "expected/" + name, "got/" + name, lineterm="", n=2))
        if len(diff) > MAX_DIFF_LINES:
            diff = diff[:MAX_DIFF_LINES] + [f"... ({len(diff) - MAX_DIFF_LINES} more diff lines)"]
        return diff
    at = next((i for i, (a, b) in enumerate(zip(want, got)) if a != b), min(len(want), len(got)))
    return [f"{name}: binary files differ: {len(want)} bytes expected, {len(got)} made, "
            f"first difference at byte {at}"]


def check(case_dir, got):
    want = expected_of(case_dir)
    report = []
    for name in sorted(set(want) | set(got)):
        if want.get(name) != got.get(name):
            report += describe(name, want.get(name), got.get(name))
    return report


def rebuild(case_dir, got):
    for name in ("stdout", "stderr", "status"):
        with open(os.path.join(case_dir, name), "wb") as f:
            f.write(got[name])
    files = os.path.join(case_dir, "files")
    shutil.rmtree(files, ignore_errors=True)
    for name, data in got.items():
        if name.startswith("files/"):
            path = os.path.join(case_dir, name)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "wb") as f:
                f.write(data)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("selfcal", nargs="?", help="the selfcal binary under test")
    ap.add_argument("names", nargs="*", help="cases to run (all without)")
    ap.add_argument("--work", help="folder for the runs (a temporary one without)")
    ap.add_argument("--rebuild", action="store_true",
                    help="write the expectations from this binary instead of checking")
    ap.add_argument("--list", action="store_true", help="print the case names and stop")
    ap.add_argument("--cases", default=CASES, help="the folder of cases (tests/regress/cases)")
    a = ap.parse_intermixed_args()
    cases = os.path.abspath(a.cases)
    names = sorted(d for d in os.listdir(cases) if os.path.isdir(os.path.join(cases, d)))
    if a.list:
        print("\n".join(names))
        return 0
    if not a.selfcal:
        ap.error("the selfcal binary is needed")
    selfcal = os.path.abspath(a.selfcal)
    if not os.access(selfcal, os.X_OK):
        print(f"regress: {a.selfcal}: not an executable", file=sys.stderr)
        return 2
    unknown = [n for n in a.names if n not in names]
    if unknown:
        print(f"regress: no such case: {', '.join(unknown)} (in {cases})", file=sys.stderr)
        return 2
    base = a.work or tempfile.mkdtemp(prefix="selfcal-regress-")
    failed, broken = [], []
    for name in a.names or names:
        case_dir = os.path.join(cases, name)
        work = os.path.join(os.path.abspath(base), name)
        shutil.rmtree(work, ignore_errors=True)
        os.makedirs(work)
        try:
            got = run_case(selfcal, case_dir, work)
        except CaseError as e:
            print(f"regress: {name}: BROKEN: {e}")
            broken.append(name)
            continue
        if a.rebuild:
            rebuild(case_dir, got)
            print(f"regress: {name}: rebuilt ({len(got) - 3} files)")
            continue
        report = check(case_dir, got)
        if report:
            print(f"regress: {name}: FAILED (the run is kept in {work})")
            print("\n".join("  " + line for line in report))
            failed.append(name)
        else:
            print(f"regress: {name}: ok")
            shutil.rmtree(work, ignore_errors=True)
    if not a.work and not failed:
        shutil.rmtree(base, ignore_errors=True)
    if broken:
        return 2
    if failed:
        print(f"regress: {len(failed)} case(s) failed: {' '.join(failed)}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
