#!/usr/bin/env python3
"""Run the commands a Markdown document shows, so that the document cannot drift from the program.

usage: doctest.py [--bindir DIR] [--python PY] [--cflags FLAGS] [--timeout S] DOC.md WORKDIR
       doctest.py --list-skips DOC.md...
       doctest.py --list DOC.md...

Which fenced blocks run (the convention is described in docs/testing.md, "Documentation that runs"):
  ```sh            a shell block: its lines run in bash (set -euo pipefail)
  ```console       `$ ` lines are commands (a line ending in `\\` continues); the lines after one,
                   up to the next `$ `, are its expected output (stdout and stderr together)
  ```python        written to doc_LINE.py (or file=NAME) in the folder and run with --python
  ```c             written to doc_LINE.c (or file=NAME); compiled with `cc -fsyntax-only` when
                   --cflags is given (a later sh block may build and run it)
  ```text output   (or ```console output) the expected output of the block just before it
  ```sh skip: REASON   (any of the four) not run: the reason says why (hardware, sudo, a daemon
                   left running, the installed library); --list-skips lists them
  `test` after the language is accepted and ignored (docs/guide.md's older mark).
Blocks with another or no info string (file samples, tables, synopses) are not run.
All blocks of one document run in document order in one bash process (shell variables and files
carry over) in an empty WORKDIR, with BINDIR first on PATH. The test fails on a non-zero exit, on
output that differs from a shown output, on an unknown word in a runnable block's info string or an
unterminated fence, or after --timeout seconds (default 600).
In a shown output `...` stands for any text within a line, and a line that is only `...` for any
number of lines (times, hashes, paths); trailing spaces and a trailing empty line are ignored.
"""
import argparse
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys

LANGS = ("sh", "console", "python", "c")


class Block:
    def __init__(self, doc, line, info, lines):
        self.doc, self.line, self.lines = doc, line, lines
        words = info.split()
        self.lang = words[0] if words else ""
        self.rest = words[1:]
        self.skip = None
        self.output = False
        self.file = None
        self.expect = None          # expected output (list of lines) or None
        if self.lang in LANGS or (self.lang == "text" and "output" in self.rest):
            m = re.match(r"^\S+\s+skip:\s*(.*)$", info.strip())
            if m:
                self.skip = m.group(1).strip()
                if not self.skip:
                    raise SyntaxError("%s:%d: `skip:` without a reason" % (doc, line))
                return
            for w in self.rest:
                if w == "test":
                    continue
                if w == "output":
                    self.output = True
                elif w.startswith("file=") and self.lang in ("python", "c") and len(w) > 5:
                    self.file = w[5:]
                else:
                    raise SyntaxError("%s:%d: unknown word %r in the info string %r"
                                      % (doc, line, w, info))

    @property
    def runs(self):
        return self.lang in LANGS and self.skip is None and not self.output

    def where(self):
        return "%s:%d" % (os.path.basename(self.doc), self.line)


def parse(doc):
    """The fenced blocks of a document, in order."""
    blocks, cur = [], None
    with open(doc, encoding="utf-8") as f:
        for no, raw in enumerate(f, 1):
            s = raw.rstrip("\n")
            m = re.match(r"^(\s*)(`{3,}|~{3,})(.*)$", s)
            if cur is None:
                if m:
                    cur = (no, m.group(1), m.group(2), m.group(3).strip(), [])
            elif m and m.group(2)[0] == cur[2][0] and len(m.group(2)) >= len(cur[2]) \
                    and not m.group(3).strip():
                no0, indent, _, info, lines = cur
                lines = [l[len(indent):] if l.startswith(indent) else l.lstrip() for l in lines]
                blocks.append(Block(doc, no0, info, lines))
                cur = None
            else:
                cur[4].append(s)
    if cur is not None:
        raise SyntaxError("%s:%d: unterminated fence" % (doc, cur[0]))
    # an output block belongs to the runnable block just before it
    steps = []
    for b in blocks:
        if b.output and b.skip is None:
            if not steps or steps[-1].expect is not None or not blocks_adjacent(blocks, steps[-1], b):
                raise SyntaxError("%s: an output block that follows no runnable block" % b.where())
            steps[-1].expect = b.lines
        elif b.runs:
            if b.lang == "console":
                steps += console_steps(b)
            else:
                steps.append(b)
    return blocks, steps


def blocks_adjacent(blocks, prev, b):
    i = blocks.index(b)
    return i > 0 and (blocks[i - 1] is prev or (blocks[i - 1].lang == "console"
                                                  and blocks[i - 1].line == prev.line))


def console_steps(b):
    """A console block: one step per `$ ` command, with the lines after it as its output."""
    steps, cmd, out, start = [], None, [], b.line
    lines = b.lines + ["$ "]
    i = 0
    while i < len(lines):
        l = lines[i]
        if l.startswith("$ ") or l == "$":
            if cmd is not None and "".join(cmd).strip():
                s = Block(b.doc, start, "sh", cmd)
                s.lang, s.console = "sh", True
                while out and not out[-1].strip():
                    out.pop()
                s.expect = out or None
                steps.append(s)
            cmd, out, start = [l[2:]], [], b.line + 1 + i
            while cmd[-1].endswith("\\") and i + 1 < len(lines):
                i += 1
                cmd.append(lines[i])
        elif cmd is None:
            if l.strip():
                raise SyntaxError("%s:%d: a console block's text before its first `$ ` prompt"
                                  % (b.doc, b.line + 1 + i))
        else:
            out.append(l)
        i += 1
    if not steps:
        raise SyntaxError("%s: a console block without a `$ ` command" % b.where())
    for s in steps:
        s.line_block = b.line
    return steps


def pattern(expect):
    """A regular expression for a shown output, `...` standing for variable text."""
    lines = [l.rstrip() for l in expect]
    while lines and not lines[-1]:
        lines.pop()
    parts = []
    for l in lines:
        if l.strip() == "...":
            parts.append(r"(?:[^\n]*\n)*?")
        else:
            parts.append(".*?".join(re.escape(p) for p in l.split("...")) + r"[ \t]*\n")
    return re.compile("".join(parts) + r"\s*\Z")


def matches(expect, got):
    text = "\n".join(l.rstrip() for l in got.split("\n")).rstrip("\n") + "\n"
    return pattern(expect).match(text) is not None


def run(doc, work, bindir, python, cflags, timeout):
    blocks, steps = parse(doc)
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    outdir = os.path.join(work, ".doctest")
    os.makedirs(outdir)
    script = ["set -euo pipefail", "exec 3>&1 4>&2"]
    ran = []
    for k, b in enumerate(steps):
        out = os.path.join(outdir, "%d.out" % k)
        script.append("printf '>>> %%s\\n' %s >&3" % shlex.quote(b.where()))
        script.append("exec >%s 2>&1" % shlex.quote(out))
        if b.lang == "sh":
            script += b.lines
        elif b.lang == "python":
            name = b.file or "doc_%d.py" % b.line
            with open(os.path.join(work, name), "w", encoding="utf-8") as f:
                f.write("\n".join(b.lines) + "\n")
            script.append("%s %s" % (shlex.quote(python), shlex.quote(name)))
        elif b.lang == "c":
            name = b.file or "doc_%d.c" % b.line
            with open(os.path.join(work, name), "w", encoding="utf-8") as f:
                f.write("\n".join(b.lines) + "\n")
            if cflags is not None:
                script.append("cc -std=c11 -Wall -Wextra -Werror -fsyntax-only %s %s"
                              % (cflags, shlex.quote(name)))
        ran.append((b, out))
    script.append("exec 1>&3 2>&4")
    path = os.path.join(outdir, "doc.sh")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(script) + "\n")
    env = dict(os.environ)
    if bindir:
        env["PATH"] = os.path.abspath(bindir) + os.pathsep + env.get("PATH", "")
    # its own process group, so that a daemon a block starts cannot outlive a failing step
    logpath = os.path.join(outdir, "log")
    with open(logpath, "w") as logf:
        p = subprocess.Popen(["bash", path], cwd=work, env=env, start_new_session=True,
                             stdin=subprocess.DEVNULL, stdout=logf, stderr=subprocess.STDOUT)
        try:
            rc = p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            rc = "timeout (%d s)" % timeout
    try:
        os.killpg(p.pid, signal.SIGKILL if rc != 0 else signal.SIGTERM)
    except ProcessLookupError:
        pass
    p.wait()
    log = open(logpath, encoding="utf-8", errors="replace").read()
    reached = log.count(">>> ")
    # the shown outputs of the blocks that ran to the end
    for k, (b, out) in enumerate(ran[:reached]):
        if b.expect is None or (k == reached - 1 and rc != 0):
            continue
        got = open(out, encoding="utf-8", errors="replace").read()
        if not matches(b.expect, got):
            sys.stderr.write("FAIL: %s: the output differs from the document's\n--- shown\n%s\n"
                             "--- got\n%s" % (b.where(), "\n".join(b.expect), got))
            return 1
    if rc != 0:
        b, out = ran[reached - 1] if reached else (None, None)
        got = open(out, encoding="utf-8", errors="replace").read() if out and \
            os.path.exists(out) else ""
        sys.stderr.write("FAIL: %s: the block stopped with status %s; its output:\n%s"
                         % (b.where() if b else doc, rc, got))
        return 1
    skips = sum(1 for b in blocks if b.skip is not None)
    print("ok: %s: %d steps ran, %d outputs compared, %d blocks skipped"
          % (doc, len(ran), sum(1 for b, _ in ran if b.expect is not None), skips))
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bindir", help="the built programs' folder, put first on PATH")
    ap.add_argument("--python", default=sys.executable,
                    help="the interpreter for python blocks (one that has the selfcal package)")
    ap.add_argument("--cflags", help="compile c blocks with these flags (-I... for the headers)")
    ap.add_argument("--timeout", type=int, default=600, help="seconds for the whole document")
    ap.add_argument("--list-skips", action="store_true", help="list the blocks marked skip:")
    ap.add_argument("--list", action="store_true", help="list the steps that would run")
    ap.add_argument("docs", nargs="+")
    a = ap.parse_args()
    try:
        if a.list_skips or a.list:
            for doc in a.docs:
                blocks, steps = parse(doc)
                if a.list_skips:
                    for b in blocks:
                        if b.skip is not None:
                            print("%s:%d: %s skip: %s" % (doc, b.line, b.lang, b.skip))
                else:
                    for b in steps:
                        print("%s:%d: %s%s" % (doc, b.line, b.lang,
                                               " (output compared)" if b.expect is not None else ""))
            return 0
        if len(a.docs) != 2:
            ap.error("give one document and a work folder")
        return run(a.docs[0], a.docs[1], a.bindir, a.python, a.cflags, a.timeout)
    except SyntaxError as e:
        sys.stderr.write("FAIL: %s\n" % e)
        return 2
    except OSError as e:
        sys.stderr.write("FAIL: %s\n" % e)
        return 2


if __name__ == "__main__":
    sys.exit(main())
