#!/usr/bin/env python3
"""The layers of libselfcal/src that may not be crossed upwards (docs/architecture.md, "Folders"):
io/ (every file format) depends on common/ alone. A file of io/ may include only headers of io/
and common/ (and the public headers), and may call only functions defined in io/ or common/
(or outside the library: libc, iconv). A call is a name followed by '(' in the code, comments and
strings left out; a function's folder is the folder of the .c file that defines it with external
linkage. A public header selfcal/X.h counts as X.c's (the types of grid_calibrate.h are
grid/grid_calibrate.c's concept, not a format's).

    check_layers.py SRC_DIR            check libselfcal/src (exit 1 and one line per crossing)
    check_layers.py --self-test SRC    also show that a crossing put into a copy is found
"""
import os
import re
import shutil
import sys
import tempfile

RULES = {"io": {"io", "common"}}  # folder -> the folders it may use

DEF_RE = re.compile(r"^(?!static\b)[A-Za-z_][\w \t\*]*?\b([A-Za-z_]\w*)\s*\(")
CALL_RE = re.compile(r"\b([A-Za-z_]\w*)\s*\(")
INCLUDE_RE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
KEYWORDS = {"if", "for", "while", "switch", "return", "sizeof", "defined", "_Static_assert"}


def strip(code):
    """The code without comments, string and character literals."""
    code = re.sub(r"/\*.*?\*/", " ", code, flags=re.S)
    code = re.sub(r"//[^\n]*", " ", code)
    code = re.sub(r'"(\\.|[^"\\\n])*"', '""', code)
    return re.sub(r"'(\\.|[^'\\\n])*'", "''", code)


def sources(src):
    for folder in sorted(os.listdir(src)):
        d = os.path.join(src, folder)
        if os.path.isdir(d):
            for name in sorted(os.listdir(d)):
                if name.endswith((".c", ".h", ".cc")):
                    yield folder, os.path.join(d, name)


def definitions(src):
    """Function name -> folders of the .c files defining it with external linkage."""
    where = {}
    for folder, path in sources(src):
        if not path.endswith((".c", ".cc")):
            continue
        lines = strip(open(path, encoding="utf-8").read()).split("\n")
        for k, line in enumerate(lines):
            m = DEF_RE.match(line)
            if not m or line.startswith(("typedef", "extern", "#")):
                continue
            rest = "\n".join(lines[k:k + 12])  # a definition's body follows its parameter list
            if re.match(r"[^;{]*\)\s*\{", rest[rest.index("("):], re.S):
                where.setdefault(m.group(1), set()).add(folder)
    return where


def homes(src):
    """The folder of each .c file by its base name (selfcal/X.h belongs with X.c)."""
    return {os.path.splitext(os.path.basename(p))[0]: f for f, p in sources(src)
            if p.endswith((".c", ".cc"))}


def crossings(src):
    where = definitions(src)
    home = homes(src)
    found = []
    for folder, path in sources(src):
        allowed = RULES.get(folder)
        if allowed is None:
            continue
        text = open(path, encoding="utf-8").read()
        rel = os.path.relpath(path, src)
        for inc in INCLUDE_RE.findall(text):
            parts = os.path.normpath(os.path.join(folder, inc)).split(os.sep)
            if inc.startswith("selfcal/"):  # a public header: where its .c lives
                owner = home.get(os.path.splitext(os.path.basename(inc))[0])
                if owner and owner not in allowed:
                    found.append(f"{rel}: includes {inc} (its {owner}/ is above {folder}/)")
                continue
            if parts[0] not in allowed:
                found.append(f"{rel}: includes {inc} ({parts[0]}/ is above {folder}/)")
        code = strip(text)
        for name in sorted(set(CALL_RE.findall(code)) - KEYWORDS):
            folders = where.get(name, set())
            if folders and not folders & allowed:
                found.append(f"{rel}: calls {name} ({'/, '.join(sorted(folders))}/ is above "
                             f"{folder}/)")
    return found


def main(argv):
    self_test = argv[1:2] == ["--self-test"]
    src = argv[2] if self_test else argv[1]
    found = crossings(src)
    for line in found:
        print(line)
    if found:
        return 1
    print(f"no crossing: {', '.join(f'{k}/ uses {sorted(v)}' for k, v in RULES.items())}")
    if self_test:  # a call up from io/ and two includes of grid/ must be found in a copy
        with tempfile.TemporaryDirectory() as tmp:
            copy = os.path.join(tmp, "src")
            shutil.copytree(src, copy)
            grid_fn = next(n for n, f in definitions(copy).items() if f == {"grid"})
            with open(os.path.join(copy, "io", "zz_crossing.c"), "w") as f:
                f.write('#include "../grid/grid_lsq_internal.h"\n'
                        '#include "selfcal/grid_calibrate.h"\n'
                        f"void zz_crossing(void) {{ {grid_fn}(); }}\n")
            got = crossings(copy)
            if len(got) != 3:
                print(f"self-test: the crossings put in were not all found: {got}")
                return 1
            print(f"self-test: found {got}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
