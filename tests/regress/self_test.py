#!/usr/bin/env python3
"""The regression driver's own test: on a copy of one case, a changed stdout line, a changed
status, a missing and an extra expected file each fail with a diff naming them; --rebuild writes
back exactly the committed expectations; a command that is not selfcal is refused (status 2).

    self_test.py SELFCAL TMPDIR
"""
import filecmp
import os
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
CASE = "grid_lsq"


def run(selfcal, cases, work, *extra):
    p = subprocess.run([sys.executable, os.path.join(HERE, "run.py"), selfcal, "--cases", cases,
                        "--work", work, *extra, CASE], capture_output=True, text=True, timeout=300)
    return p.returncode, p.stdout + p.stderr


def expect(cond, what, out):
    if not cond:
        print(f"self_test: FAILED: {what}\n{out}")
        sys.exit(1)
    print(f"self_test: ok: {what}")


def main():
    selfcal, tmp = sys.argv[1], os.path.abspath(sys.argv[2])
    shutil.rmtree(tmp, ignore_errors=True)
    cases, work = os.path.join(tmp, "cases"), os.path.join(tmp, "work")
    orig = os.path.join(HERE, "cases", CASE)
    case = os.path.join(cases, CASE)
    shutil.copytree(orig, case)

    rc, out = run(selfcal, cases, work)
    expect(rc == 0 and "ok" in out, "the committed case passes", out)

    stdout = os.path.join(case, "stdout")
    text = open(stdout).read()
    open(stdout, "w").write(text.replace("method: lsq", "method: ye", 1))
    rc, out = run(selfcal, cases, work)
    expect(rc == 1 and "-method: ye" in out and "+method: lsq" in out,
           "a changed stdout line fails with its diff", out)
    open(stdout, "w").write(text)

    status = os.path.join(case, "status")
    open(status, "w").write("0\n2\n")
    rc, out = run(selfcal, cases, work)
    expect(rc == 1 and "expected/status" in out, "a changed exit status fails", out)

    gone = os.path.join(case, "files", "A.csv")
    os.remove(gone)
    rc, out = run(selfcal, cases, work)
    expect(rc == 1 and "files/A.csv: not expected" in out, "a file the run makes unexpectedly", out)
    open(os.path.join(case, "files", "extra.csv"), "w").write("x\n")
    rc, out = run(selfcal, cases, work)
    expect(rc == 1 and "files/extra.csv: expected, but the run did not make it" in out,
           "an expected file the run does not make", out)

    rc, out = run(selfcal, cases, work, "--rebuild")
    same = filecmp.dircmp(orig, case)
    expect(rc == 0 and not same.diff_files and not same.left_only and not same.right_only and
           not filecmp.dircmp(os.path.join(orig, "files"), os.path.join(case, "files")).diff_files
           and not filecmp.dircmp(os.path.join(orig, "files"),
                                  os.path.join(case, "files")).right_only,
           "--rebuild writes the committed expectations back", out)
    rc, out = run(selfcal, cases, work)
    expect(rc == 0, "the rebuilt case passes", out)

    with open(os.path.join(case, "cmd"), "a") as f:
        f.write("rm -rf /\n")
    rc, out = run(selfcal, cases, work)
    expect(rc == 2 and "BROKEN" in out and "begins with 'selfcal'" in out,
           "a command that is not selfcal is refused", out)
    shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
