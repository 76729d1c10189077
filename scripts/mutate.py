#!/usr/bin/env python3
"""Mutation testing of selfcal (issue 43): the driver behind scripts/mutate.sh.

Each mutant is one realistic bug made by one operator at one place of a source file: a
comparison off by one (< for <=), a flipped sign, + for -, && for ||, a constant off by one or
halved, a negation dropped. The driver works on a copy of the tracked sources (WORK/src, so the
checkout and any build running beside it are never touched), builds it once in WORK/build (Release,
no sanitizers, ccache), checks that the tests of each file pass unmutated, then for each mutant:
writes it into the copy, rebuilds only the targets its tests need, runs only those tests (the map
tests/mutation/modules.txt says which) with a time limit, and puts the file back. A mutant is
killed when a test fails or the time limit stops them, survives when they all pass, and is
stillborn (not counted) when it does not compile. Mutants listed in tests/mutation/equivalent.txt
with their explanation are equivalent (they cannot change any behaviour): shown, not run, not
counted. Mutants are named by file, the line's text and the mutated text, never by line number,
so the lists keep working while the sources change around them.

Prints one line per mutant, then the score per module (killed / (killed + survived)) and every
survivor. Exit status: 0, or 1 if a non-equivalent mutant survived (with --fail-on-survivor),
2 for bad usage or tests that fail unmutated.
"""
import argparse
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
MAP = os.path.join(ROOT, "tests", "mutation", "modules.txt")
EQUIV = os.path.join(ROOT, "tests", "mutation", "equivalent.txt")

# ---- the source: what may be mutated -----------------------------------------------------------


def mask_source(text):
    """The text with comments, string and character literals and preprocessor lines blanked
    (same length, newlines kept): operators are looked for in code only."""
    out = list(text)
    i, n = 0, len(text)
    line_start = True
    while i < n:
        c = text[i]
        if line_start and c == "#" or (line_start and c in " \t" and text[i:].lstrip(" \t").startswith("#")):
            # a preprocessor line, with its continuations
            while i < n:
                if text[i] == "\\" and i + 1 < n and text[i + 1] == "\n":
                    out[i] = " "
                    i += 2
                    continue
                if text[i] == "\n":
                    break
                out[i] = " "
                i += 1
            continue
        line_start = c == "\n"
        if text.startswith("//", i):
            while i < n and text[i] != "\n":
                out[i] = " "
                i += 1
            continue
        if text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            for k in range(i, j):
                if text[k] != "\n":
                    out[k] = " "
            i = j
            continue
        if c in "\"'":
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            for k in range(i, min(j + 1, n)):
                out[k] = " "
            i = j + 1
            continue
        i += 1
    return "".join(out)


# operator name, regex on the masked text (group 1: what is replaced), replacements
_SP = r"(?<=[ ])"       # the project's style: binary operators have a space on both sides
OPERATORS = [
    ("ROR", _SP + r"(<=|>=|==|!=|<|>)(?=[ ])",
     {"<": ["<="], "<=": ["<"], ">": [">="], ">=": [">"], "==": ["!="], "!=": ["=="]}),
    ("AOR", _SP + r"([-+*/])(?=[ ])", {"+": ["-"], "-": ["+"], "*": ["/"], "/": ["*"]}),
    ("ASR", _SP + r"(\+=|-=|\*=|/=)(?=[ ])", {"+=": ["-="], "-=": ["+="], "*=": ["/="], "/=": ["*="]}),
    ("LCR", _SP + r"(&&|\|\|)(?=[ ])", {"&&": ["||"], "||": ["&&"]}),
    ("BOR", _SP + r"(&|\||\^|<<|>>)(?=[ ])", {"&": ["|"], "|": ["&"], "^": ["|"], "<<": [">>"], ">>": ["<<"]}),
    ("SGN", r"(?:(?<=[(\[,=?:])|(?<=[(\[,=?:] )|(?<=return ))(-)(?=[A-Za-z_(])", {"-": [""]}),
    ("NEG", r"(?<![!=<>])(!)(?=[A-Za-z_(])", {"!": [""]}),
    ("CST", r"(?<![\w.])((?:0[xX][0-9a-fA-F]+|\d+\.\d*(?:[eE][-+]?\d+)?|\d+(?:[eE][-+]?\d+)?)[uUlLfF]*)(?![\w.])",
     None),
]


def constant_mutations(tok):
    m = re.match(r"^(0[xX][0-9a-fA-F]+|[\d.]+(?:[eE][-+]?\d+)?)([uUlLfF]*)$", tok)
    if not m:
        return []
    lit, suf = m.groups()
    if lit.lower().startswith("0x"):
        v = int(lit, 16)
        return ["0x%X%s" % (v + 1, suf)] + (["0x%X%s" % (v - 1, suf)] if v > 0 else [])
    if re.fullmatch(r"\d+", lit):
        v = int(lit)
        return ["%d%s" % (v + 1, suf)] + (["%d%s" % (v - 1, suf)] if v > 0 else [])
    v = float(lit)
    return [repr(v / 2) + suf] if v != 0 else ["1.0" + suf]


class Mutant:
    __slots__ = ("file", "line", "func", "op", "start", "end", "new", "orig_line", "mut_line", "module",
                 "occurrence")

    def key(self):
        """FILE | ORIGINAL => MUTATED, and ` @k` for the k-th (k >= 2) mutant of a file with the
        same two texts (a line that repeats in the file)."""
        k = getattr(self, "occurrence", 1)
        return "%s | %s => %s%s" % (self.file, self.orig_line, self.mut_line, " @%d" % k if k > 1 else "")

    def short(self):
        return "%s:%d (%s, %s) %s  ->  %s" % (self.file, self.line, self.func, self.op,
                                              self.orig_line, self.mut_line)


_DECL_SIZE = re.compile(r"^\s*(?:(?:static|const|unsigned|struct)\s+)*[A-Za-z_]\w*\s+\**[A-Za-z_]\w*\s*\[\s*$")
_FUNC = re.compile(r"^[A-Za-z_][\w \t*]*?\b([A-Za-z_]\w*)\s*\(")


def enumerate_mutants(rel, text, funcs=None):
    """Every mutant of one file, in a fixed order: code inside function bodies only (not the
    constants of file-scope tables and enums). funcs: a regex of function names to keep."""
    masked = mask_source(text)
    lines = text.split("\n")
    mlines = masked.split("\n")
    out = []
    depth = 0
    func = "<file scope>"
    offset = 0
    for ln, (line, mline) in enumerate(zip(lines, mlines), 1):
        if depth == 0:
            m = _FUNC.match(mline)
            if m and not mline.rstrip().endswith(";"):
                func = m.group(1)
        if depth > 0 and func != "<file scope>" and mline.strip() and "static_assert" not in mline \
                and (funcs is None or re.search(funcs, func)):
            for op, rx, table in OPERATORS:
                for m in re.finditer(rx, mline):
                    tok = m.group(1)
                    news = constant_mutations(tok) if table is None else table.get(tok, [])
                    if op == "CST" and re.match(r"^\s*return -$", mline[:m.start(1)]):
                        continue  # an error return (-1): its callers test the sign, not the value
                    if op == "CST" and _DECL_SIZE.match(mline[:m.start(1)]):
                        continue  # an array's size in its declaration: a bigger one changes nothing
                    for new in news:
                        mu = Mutant()
                        mu.file, mu.line, mu.func, mu.op = rel, ln, func, op
                        mu.start, mu.end, mu.new = offset + m.start(1), offset + m.end(1), new
                        mu.orig_line = line.strip()
                        mu.mut_line = (line[:m.start(1)] + new + line[m.end(1):]).strip()
                        out.append(mu)
        for ch in mline:
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth = max(0, depth - 1)
                if depth == 0:
                    func = "<file scope>"
        offset += len(line) + 1
    seen = {}
    for mu in out:
        mu.occurrence = seen[(mu.orig_line, mu.mut_line)] = seen.get((mu.orig_line, mu.mut_line), 0) + 1
    return out


def hand_made(key, by_file):
    """A listed mutant no operator makes (`FILE | ORIGINAL LINE => MUTATED LINE`): the first line
    of FILE whose text is ORIGINAL LINE, replaced by MUTATED LINE (the indentation kept)."""
    rel, _, rest = key.partition(" | ")
    orig, _, new = rest.partition(" => ")
    if rel not in by_file or not orig or not new:
        return None
    text = open(os.path.join(ROOT, rel), encoding="utf-8").read()
    offset = 0
    for ln, line in enumerate(text.split("\n"), 1):
        if line.strip() == orig:
            mu = Mutant()
            mu.file, mu.line, mu.func, mu.op, mu.module = rel, ln, "-", "HAND", by_file[rel]["module"]
            lead = len(line) - len(line.lstrip())
            mu.start, mu.end = offset + lead, offset + lead + len(orig)
            mu.new, mu.orig_line, mu.mut_line = new, orig, new
            return mu
        offset += len(line) + 1
    return None


# ---- configuration -----------------------------------------------------------------------------


def read_map(path):
    """modules.txt: MODULE FILE TESTS [TARGETS]; TESTS and TARGETS comma lists."""
    files = []
    for raw in open(path, encoding="utf-8"):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        f = line.split()
        if len(f) not in (3, 4):
            sys.exit("%s: bad line: %s" % (path, raw.rstrip()))
        tests = f[2].split(",")
        targets = [t for t in tests if t.startswith("test_")]
        if len(f) == 4:
            targets += f[3].split(",")
        files.append(dict(module=f[0], file=f[1], tests=tests, targets=targets))
    return files


def read_keyed_blocks(path):
    """Blocks of `mutant: FILE | ORIGINAL LINE => MUTATED LINE` then `why: ...` lines
    (equivalent.txt), or bare `mutant:` lines (a sample list). Returns {key: explanation}."""
    out, key = {}, None
    if not os.path.exists(path):
        return out
    for raw in open(path, encoding="utf-8"):
        line = raw.rstrip("\n")
        if line.startswith("mutant:"):
            f, _, rest = line[len("mutant:"):].partition(" | ")
            orig, _, new = rest.partition(" => ")
            key = "%s | %s => %s" % (f.strip(), orig.strip(), new.strip())
            out[key] = ""
        elif key and line.startswith(("why:", "  ")):
            out[key] = (out[key] + " " + line.split(":", 1)[1].strip() if line.startswith("why:")
                        else out[key] + " " + line.strip()).strip()
    return out


# ---- running -----------------------------------------------------------------------------------


def sh(cmd, cwd, timeout=None, env=None):
    try:
        p = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           timeout=timeout, env=env)
        return p.returncode, p.stdout.decode("utf-8", "replace")
    except subprocess.TimeoutExpired as e:
        return None, (e.stdout or b"").decode("utf-8", "replace")


def copy_tree(work):
    """WORK/src: the tracked files of the checkout as they are now (or every file but build
    folders when it is not a git checkout); unchanged files keep their time stamps, changed ones
    get the time of the copy (the checkout's may be older than the copy's build)."""
    src = os.path.join(work, "src")
    try:
        files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, check=True,
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL).stdout.decode().split("\0")
    except (OSError, subprocess.CalledProcessError):
        files = []
        for d, dirs, names in os.walk(ROOT):
            dirs[:] = [x for x in dirs if not (d == ROOT and (x.startswith("build") or x.startswith(".")))]
            files += [os.path.relpath(os.path.join(d, x), ROOT) for x in names]
    for f in files:
        if not f or not os.path.isfile(os.path.join(ROOT, f)):
            continue
        a, b = os.path.join(ROOT, f), os.path.join(src, f)
        if os.path.exists(b) and open(a, "rb").read() == open(b, "rb").read():
            continue
        os.makedirs(os.path.dirname(b), exist_ok=True)
        shutil.copy(a, b)  # a new time stamp: the build redoes what depends on it
    # files the checkout no longer has (renamed, deleted) leave the copy too: a build that globs
    # its sources would still compile them
    tracked = {os.path.normpath(f) for f in files if f}
    for d, dirs, names in os.walk(src):
        dirs[:] = [x for x in dirs if not (d == src and x in (".venv", ".cache"))]
        for x in names:
            rel = os.path.normpath(os.path.relpath(os.path.join(d, x), src))
            if rel not in tracked:
                os.remove(os.path.join(d, x))
    # what scripts/install-deps.sh put in the checkout: the Modbus tests' Python (.venv, pymodbus)
    # and the vcan tests' kernel (.cache/kernel)
    for extra in (".venv", ".cache"):
        have = os.path.join(ROOT, extra)
        if os.path.isdir(have) and not os.path.lexists(os.path.join(src, extra)):
            os.symlink(os.path.realpath(have), os.path.join(src, extra))
    return src


def main():
    ap = argparse.ArgumentParser(prog="scripts/mutate.sh", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="*", help="source files (as in modules.txt); default: all of them")
    ap.add_argument("--module", action="append", help="only the files of this module (repeatable)")
    ap.add_argument("--func", help="only mutants inside functions whose name matches this regex")
    ap.add_argument("--per-module", type=int, default=0,
                    help="a seeded random sample of this many mutants per module (0: every mutant)")
    ap.add_argument("--seed", type=int, default=43, help="seed of the sample (default 43)")
    ap.add_argument("--sample-file", help="run exactly the mutants listed in this file (mutant: lines)")
    ap.add_argument("--list", action="store_true", help="list the mutants and stop (nothing built)")
    ap.add_argument("--work", default=None,
                    help="work folder: the copy of the sources and its build (default build-mutate)")
    ap.add_argument("--timeout", type=float, default=0,
                    help="seconds allowed to a mutant's tests (default: 5x their unmutated time + 30)")
    ap.add_argument("--fail-on-survivor", action="store_true",
                    help="exit 1 if a non-equivalent mutant survives (CI)")
    ap.add_argument("--jobs", type=int, default=1, help="build jobs (default 1)")
    ap.add_argument("--sanitize", action="store_true",
                    help="build with ASan and UBSan (default work folder build-mutate-asan): for "
                         "survivors that write out of bounds, which only a sanitizer sees")
    a = ap.parse_args()

    if a.work is None:
        a.work = os.path.join(ROOT, "build-mutate-asan" if a.sanitize else "build-mutate")
    cfg = read_map(MAP)
    if a.module:
        cfg = [c for c in cfg if c["module"] in a.module]
    if a.files:
        want = {os.path.normpath(f) for f in a.files}
        unknown = want - {c["file"] for c in cfg}
        if unknown:
            print("mutate: not in %s: %s" % (os.path.relpath(MAP, ROOT), " ".join(sorted(unknown))),
                  file=sys.stderr)
            return 2
        cfg = [c for c in cfg if c["file"] in want]
    if not cfg:
        print("mutate: no file selected", file=sys.stderr)
        return 2
    equiv = read_keyed_blocks(EQUIV)
    by_file = {c["file"]: c for c in cfg}

    # the mutants, per module, then the selection
    mutants = []
    for c in cfg:
        text = open(os.path.join(ROOT, c["file"]), encoding="utf-8").read()
        for mu in enumerate_mutants(c["file"], text, a.func):
            mu.module = c["module"]
            mutants.append(mu)
    if a.sample_file:
        wanted = read_keyed_blocks(a.sample_file)
        found = {}
        for mu in mutants:
            if mu.key() in wanted and mu.key() not in found:
                found[mu.key()] = mu
        for k in wanted:
            if k not in found:
                mu = hand_made(k, by_file)
                if mu:
                    found[k] = mu
                else:
                    print("mutate: not found (the line changed?): %s" % k)
        mutants = list(found.values())
        if not mutants:
            print("mutate: none of the listed mutants is in the sources", file=sys.stderr)
            return 2
    elif a.per_module > 0:
        chosen = []
        for mod in dict.fromkeys(m.module for m in mutants):
            rng = random.Random("%d:%s" % (a.seed, mod))  # a module's sample is its own
            pool = [m for m in mutants if m.module == mod]
            chosen += sorted(rng.sample(pool, min(a.per_module, len(pool))),
                             key=lambda m: (m.file, m.start))
        mutants = chosen
    if a.list:
        for mu in mutants:
            print(("EQUIVALENT " if mu.key() in equiv else "") + mu.short())
        print("%d mutants" % len(mutants))
        return 0

    # the copy and its build
    os.makedirs(a.work, exist_ok=True)
    work = os.path.abspath(a.work)
    src = copy_tree(work)
    bld = os.path.join(work, "build")
    env = dict(os.environ)
    env.setdefault("CCACHE_BASEDIR", work)  # the same cache entries for every work folder
    if a.sanitize:
        env.setdefault("ASAN_OPTIONS", "detect_leaks=1:abort_on_error=1")
        env.setdefault("UBSAN_OPTIONS", "print_stacktrace=1:halt_on_error=1")
    cc = ["-DCMAKE_C_COMPILER_LAUNCHER=ccache", "-DCMAKE_CXX_COMPILER_LAUNCHER=ccache"] \
        if shutil.which("ccache") else []
    if not os.path.exists(os.path.join(bld, "build.ninja")):
        rc, out = sh(["cmake", "-S", src, "-B", bld, "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release",
                      "-DSELFCAL_BUILD_BENCH=OFF", "-DSELFCAL_SANITIZE=%s" % ("ON" if a.sanitize else "OFF")]
                     + cc, work, env=env)
        if rc != 0:
            print(out)
            print("mutate: configuring %s failed" % bld, file=sys.stderr)
            return 2
    files_used = sorted({m.file for m in mutants})
    targets = sorted({t for f in files_used for t in by_file[f]["targets"]})
    t0 = time.time()
    rc, out = sh(["ninja", "-C", bld, "-j%d" % a.jobs] + targets, work, env=env)
    if rc != 0:
        print(out[-4000:])
        print("mutate: the unmutated build failed", file=sys.stderr)
        return 2
    print("mutate: built %s in %.0f s" % (" ".join(targets), time.time() - t0), flush=True)

    def run_tests(tests, timeout):
        regex = "^(%s)$" % "|".join(re.escape(t) for t in tests)
        return sh(["ctest", "-j1", "--stop-on-failure", "-R", regex, "--timeout", "%d" % max(timeout, 10)],
                  bld, timeout=timeout, env=env)

    # the tests pass unmutated (each run once), and how long they take
    every = sorted({t for f in files_used for t in by_file[f]["tests"]})
    rc, out = run_tests(every, 3600)
    took = {m.group(1): float(m.group(2))
            for m in re.finditer(r"Test +#\d+: (\S+) \.+ +Passed +([\d.]+) sec", out)}
    missing = [t for t in every if t not in took]
    if rc != 0 or missing:
        print(out[-4000:])
        print("mutate: tests fail unmutated or do not exist: %s" % " ".join(missing or ["(see above)"]),
              file=sys.stderr)
        return 2
    limit = {f: a.timeout or 5 * sum(took[t] for t in by_file[f]["tests"]) + 30 for f in files_used}
    print("mutate: the unmutated tests pass (%.0f s)" % sum(took.values()), flush=True)

    results = []  # (mutant, status)
    start = time.time()
    for k, mu in enumerate(mutants, 1):
        if mu.key() in equiv:
            results.append((mu, "equivalent"))
            print("[%d/%d] equivalent  %s" % (k, len(mutants), mu.short()), flush=True)
            continue
        path = os.path.join(src, mu.file)
        orig = open(path, encoding="utf-8").read()
        mutated = orig[:mu.start] + mu.new + orig[mu.end:]
        t0 = time.time()
        try:
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(mutated)
            rc, out = sh(["ninja", "-C", bld, "-j%d" % a.jobs] + by_file[mu.file]["targets"], work, env=env)
            if rc != 0:
                status = "stillborn"
            else:
                rc, out = run_tests(by_file[mu.file]["tests"], limit[mu.file])
                status = "timeout" if rc is None else ("killed" if rc != 0 else "SURVIVED")
        finally:
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(orig)
        if status in ("killed", "timeout"):
            failed = re.findall(r"\d+ - (\S+) \(", out)
            detail = " by " + ",".join(failed) if failed else ""
        else:
            detail = ""
        results.append((mu, status))
        print("[%d/%d] %-10s %s  (%.0f s%s)" % (k, len(mutants), status, mu.short(), time.time() - t0,
                                                detail), flush=True)
    # put the build back to the unmutated sources
    sh(["ninja", "-C", bld, "-j%d" % a.jobs] + targets, work, env=env)

    print("\nscore per module (killed / (killed + survived); a timeout is a kill; stillborn and "
          "equivalent not counted), %.0f s:" % (time.time() - start))
    print("| module | mutants | killed | survived | stillborn | equivalent | score |")
    print("|---|---|---|---|---|---|---|")
    survivors = []
    for mod in dict.fromkeys(m.module for m, _ in results):
        st = [s for m, s in results if m.module == mod]
        killed = st.count("killed") + st.count("timeout")
        surv = st.count("SURVIVED")
        score = "%.1f %%" % (100.0 * killed / (killed + surv)) if killed + surv else "-"
        print("| %s | %d | %d | %d | %d | %d | %s |" % (mod, len(st), killed, surv, st.count("stillborn"),
                                                       st.count("equivalent"), score))
        survivors += [m for m, s in results if m.module == mod and s == "SURVIVED"]
    if survivors:
        print("\nsurvivors (kill them with a test, or explain them in tests/mutation/equivalent.txt):")
        for m in survivors:
            print("mutant: %s\n  at %s:%d in %s (%s)" % (m.key(), m.file, m.line, m.func, m.op))
        listed = os.path.join(work, "survivors.txt")
        with open(listed, "w", encoding="utf-8") as fh:
            fh.write("".join("mutant: %s\n" % m.key() for m in survivors))
        if not a.sanitize:
            print("\nan out-of-bounds mutant survives here and fails under the sanitizers: "
                  "scripts/mutate.sh --sanitize --sample-file %s" % os.path.relpath(listed, os.getcwd()))
    else:
        print("\nno survivor")
    return 1 if survivors and a.fail_on_survivor else 0


if __name__ == "__main__":
    # stopped (SIGTERM): through the finally that puts the mutated file back in the copy
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    try:
        sys.exit(main())
    except BrokenPipeError:  # --list into head
        sys.exit(0)
