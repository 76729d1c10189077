#!/usr/bin/env python3
"""tools/doctest.py on small documents: what passes, what fails, what --list-skips lists.
usage: doctest_self_test.py DOCTEST.py WORKDIR"""
import os
import shutil
import subprocess
import sys

tool, work = sys.argv[1], sys.argv[2]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
F = "```"


def run(name, text, *args):
    doc = os.path.join(work, name + ".md")
    with open(doc, "w", encoding="utf-8") as f:
        f.write(text)
    listing = "--list-skips" in args
    p = subprocess.run([sys.executable, tool] + list(args) + [doc] +
                       ([] if listing else [os.path.join(work, name)]),
                       capture_output=True, text=True, timeout=60)
    return p.returncode, p.stdout + p.stderr


def expect(name, text, want_ok, needle=None, *args):
    rc, out = run(name, text, *args)
    if (rc == 0) != want_ok or (needle and needle not in out):
        sys.exit("FAIL: %s: status %d, output:\n%s" % (name, rc, out))
    print("ok:", name)


good = f"""# doc
{F}sh
printf 'a\\nb\\n' > f.txt
X=3
{F}

{F}sh
wc -l < f.txt
echo "time 12.5 s, x=$X"
{F}
{F}text output
2
time ... s, x=3
{F}

{F}console
$ cat f.txt
a
b
$ echo one; \\
  echo two
one
two
{F}

{F}python
print(open("f.txt").read().split())
{F}
{F}text output
['a', 'b']
{F}

{F}sh skip: needs a CAN interface
candump can0
{F}

{F}text
not run: exit 1
{F}
"""
expect("good", good, True, "5 steps ran, 4 outputs compared, 1 blocks skipped")
# the same document with one command broken, one output changed, one console output changed
expect("broken_command", good.replace("wc -l < f.txt", "wc -l < no_such_file.txt"), False,
       "broken_command.md:7: the block stopped with status 1")
expect("wrong_output", good.replace("time ... s, x=3", "time ... s, x=4"), False,
       "the output differs")
expect("wrong_console", good.replace("one\ntwo", "one\nthree"), False, "the output differs")
expect("ellipsis_lines", good.replace("2\ntime", "...\ntime"), True)
expect("python_fails", good.replace('print(open("f.txt")', 'print(open("g.txt")'), False,
       "FileNotFoundError")
expect("skip_without_reason", good.replace("skip: needs a CAN interface", "skip:"), False,
       "without a reason")
expect("unknown_mark", good.replace(F + "sh skip", F + "sh skipped"), False, "unknown word")
expect("unterminated", good + F + "sh\nls\n", False, "unterminated fence")
expect("output_alone", "# x\n" + F + "text output\n1\n" + F + "\n", False,
       "follows no runnable block")
expect("list_skips", good, True, "list_skips.md:33: sh skip: needs a CAN interface", "--list-skips")
# a daemon a block leaves running is stopped with the document, and a timeout fails
expect("timeout", f"{F}sh\nsleep 300 &\nsleep 30\n{F}\n", False, "timeout (2 s)", "--timeout", "2")
print("all ok")
