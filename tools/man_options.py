#!/usr/bin/env python3
"""selfcal(1)'s option lists made from the commands' option tables (`selfcal --options CMD`,
tools/selfcal/cli_opts.h), so that the man page, the table and --help cannot drift.

  man_options.py SELFCAL MAN.in           rewrite the generated lists in MAN.in
  man_options.py --check SELFCAL MAN.in   exit 1 unless MAN.in holds exactly the lists the
                                          tables make, each command's --help names exactly
                                          the options of its table, and its option list
                                          (cli_opts_help) is the table's, row by row

A row's first name is the one shown (in --help and here); the others are aliases the command
also accepts ("-o|--out"). A list sits at the end of its command's `.SS "selfcal CMD ..."` section between the lines
`.\\" OPTIONS CMD (generated ...)` and `.\\" END OPTIONS`; a command without a table has none."""
import re
import subprocess
import sys

COMMANDS = ["grid", "plan", "profile", "profile-plan", "lut build", "export", "import grid",
            "import profile", "simulate exports", "simulate grid", "simulate profile", "plot map",
            "plot profile", "plot xy", "report grid", "report profile", "verify"]
BEGIN = '.\\" OPTIONS %s (generated from its option table by tools/man_options.py: do not edit)'
END = '.\\" END OPTIONS'
OPT = re.compile(r"(?<![\w-])--[a-z][a-z0-9]*(?:-[a-z0-9]+)*")


def table(selfcal, cmd):
    """The rows of cmd's table (name, value, kind, range, default, help), or None."""
    p = subprocess.run([selfcal, "--options"] + cmd.split(), capture_output=True, text=True,
                       timeout=60)
    if p.returncode == 2:
        return None
    if p.returncode != 0:
        sys.exit("%s --options %s: status %d" % (selfcal, cmd, p.returncode))
    return [line.split("\t") for line in p.stdout.splitlines()]


def roff(s):
    return s.replace("\\", "\\e").replace("-", "\\-")


def block(cmd, rows):
    out = [BEGIN % cmd, ".PP", "Options (the command's option table):"]
    for name, value, kind, rng, default, text in rows:
        names = "\\fB%s\\fR" % roff(name.split("|")[0])  # the name; an alias is not shown
        out += [".TP", names + (" \\fI%s\\fR" % roff(value) if value else "")]
        facts = []
        if kind in ("integer", "number") or (rng and kind != "choice" and "|" not in rng):
            facts.append("%s %s" % ("a whole number in" if kind == "integer" else "in", rng))
        elif rng:
            facts.append("one of " + rng.replace("|", ", "))
        if default:
            facts.append("default: " + default)
        out.append(roff(text + (" (%s)" % "; ".join(facts) if facts else "") + "."))
    return out + [END]


def rewrite(lines, cmd, rows):
    """lines with cmd's generated list replaced (or added at the end of its section)."""
    begin = BEGIN % cmd
    if begin in lines:
        a = lines.index(begin)
        b = lines.index(END, a)
        return lines[:a] + (block(cmd, rows) if rows else []) + lines[b + 1:]
    if not rows:
        return lines
    head = [k for k, l in enumerate(lines)
            if re.match(r'^\.SS "selfcal %s(?= |")' % re.escape(roff(cmd)), l)]
    if not head:
        sys.exit("no section `selfcal %s` in the man page" % cmd)
    end = next((k for k in range(head[0] + 1, len(lines)) if lines[k].startswith((".SS", ".SH"))),
               len(lines))
    return lines[:end] + block(cmd, rows) + lines[end:]


def own_opts(text, cmd):
    """The options a --help text names, leaving out those it cites of another command (`from grid
    --artifact`, `selfcal plan --design`)."""
    others = sorted((c for c in COMMANDS + ["lut dump", "lut info"] if c != cmd), key=len,
                    reverse=True)
    groups = "".join("(?<!%s )" % g for g in ("import", "simulate", "report", "plot", "lut"))
    cite = re.compile(r"(?<![\w-])%s(?:%s)\s+--[a-z][a-z0-9-]*"
                      % (groups, "|".join(map(re.escape, others))))
    return set(OPT.findall(cite.sub(" ", text))) - {"--help"}


def help_problems(selfcal, cmd, rows):
    p = subprocess.run([selfcal] + cmd.split() + ["--help"], capture_output=True, text=True,
                       timeout=60)
    in_help = own_opts(p.stdout, cmd)
    # the names --help's text can be searched for (OPT: lower case, as help_vs_man reads them)
    in_table = {n for n in (r[0].split("|")[0] for r in rows) if OPT.fullmatch(n)}
    return (["selfcal %s --help: %s (in its option table) is missing" % (cmd, o)
             for o in sorted(in_table - in_help)] +
            ["selfcal %s: %s (in --help) is not in its option table" % (cmd, o)
             for o in sorted(in_help - in_table)] + list_problems(p.stdout, cmd, rows))


def list_problems(text, cmd, rows):
    """--help's option list ("Options:", a row's name and value, then its help, up to a blank
    line) is the table's: the same names in the same order, each with the table's help."""
    m = re.search(r"^Options:\n(.*?)(?:\n\n|\Z)", text, re.M | re.S)
    if not m:
        return ["selfcal %s --help: no option list (Options:)" % cmd]
    items = re.split(r"\n(?=  -)", "\n" + m.group(1))[1:]
    names = [i.split()[0] for i in items]
    want = [r[0].split("|")[0] for r in rows]
    if names != want:
        return ["selfcal %s --help: its option list names %s, its table %s" % (cmd, names, want)]
    out = []
    for item, (name, value, _, _, default, help_) in zip(items, rows):
        flat = " ".join(item.split())
        head = " ".join([name.split("|")[0]] + ([value] if value else []))
        if not flat.startswith(head) or " ".join(help_.split()) not in flat or \
                (default and "default: " + " ".join(default.split()) not in flat):
            out.append("selfcal %s --help: the list's %r is not the table's %s" % (cmd, flat, head))
    return out


def main(argv):
    check = argv[:1] == ["--check"]
    if check:
        argv = argv[1:]
    if len(argv) != 2:
        sys.exit(__doc__)
    selfcal, path = argv
    text = open(path, encoding="utf-8").read()
    lines = text.split("\n")
    problems = []
    for cmd in COMMANDS:
        rows = table(selfcal, cmd)
        lines = rewrite(lines, cmd, rows)
        if rows is not None and check:
            problems += help_problems(selfcal, cmd, rows)
    new = "\n".join(lines)
    if not check:
        if new != text:
            open(path, "w", encoding="utf-8").write(new)
        return 0
    if new != text:
        old = text.split("\n")
        diff = [l for l in lines if l not in old][:5] + ["-" + l for l in old if l not in lines][:5]
        problems.append("%s: the option lists are not those of the tables (run "
                        "tools/man_options.py SELFCAL %s); e.g.\n  %s" % (path, path, "\n  ".join(diff)))
    for p in problems:
        print("FAIL:", p)
    if not problems:
        print("ok: the option lists of %s are the tables', and --help names the tables' options"
              % path)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
