#!/usr/bin/env python3
"""--help and the man pages agree: every option a command's --help prints is in that command's
section of selfcal(1) (or in selfcald(8)), and every option a section documents is in --help;
the synopses of docs/formats.md section 3 name only options their command's --help has.
usage: help_vs_man.py SELFCAL SELFCALD MANDIR   (MANDIR: docs/man, formats.md beside it)"""
import os
import re
import subprocess
import sys

selfcal, selfcald, mandir = sys.argv[1:4]
COMMANDS = ["grid", "plan", "profile", "profile-plan", "lut build", "lut dump", "lut info", "export",
            "import grid", "import profile", "simulate exports", "simulate grid", "simulate profile",
            "plot map", "plot profile", "plot xy", "report grid", "report profile", "verify"]
OPT = re.compile(r"(?<![\w-])--[a-z][a-z0-9]*(?:-[a-z0-9]+)*")


def help_opts(argv, cmd=None):
    p = subprocess.run(argv + ["--help"], capture_output=True, text=True, timeout=60)
    if p.returncode != 0:
        sys.exit("FAIL: %s --help: status %d" % (" ".join(argv), p.returncode))
    text = p.stdout + p.stderr
    return text, own_opts(text, cmd)


def own_opts(text, cmd):
    """The options a text names, leaving out those it cites of another command (`from grid
    --artifact`, `selfcal plan --design`)."""
    if cmd:
        others = sorted((c for c in COMMANDS if c != cmd), key=len, reverse=True)
        groups = "".join("(?<!%s )" % g for g in ("import", "simulate", "report", "plot", "lut"))
        cite = re.compile(r"(?<![\w-])%s(?:%s)\s+--[a-z][a-z0-9-]*"
                          % (groups, "|".join(map(re.escape, others))))
        text = cite.sub(" ", text)
    return set(OPT.findall(text)) - {"--help"}


def roff_text(s):
    s = s.replace("\\-", "-").replace("\\(dq", '"')
    return re.sub(r"\\f[BIRP]", "", s)


def sections(path):
    """selfcal(1)'s `.SS "selfcal CMD ..."` sections: command -> its text."""
    out, cur = {}, None
    for line in open(path, encoding="utf-8"):
        t = roff_text(line.rstrip("\n"))
        m = re.match(r'^\.SS "selfcal (.*)"', t)
        if m:
            words = m.group(1).split()
            name = " ".join(words[:2]) if " ".join(words[:2]) in COMMANDS else words[0]
            cur = name
            out[cur] = t + "\n"
        elif t.startswith(".SH"):
            cur = None
        elif cur:
            out[cur] += t + "\n"
    return out


problems = []
man = sections(mandir + "/selfcal.1.in")
for cmd in COMMANDS:
    text, opts = help_opts([selfcal] + cmd.split(), cmd)
    # `lut dump --help` must not print another command's usage
    if not re.search(r"usage: selfcal %s\b" % re.escape(cmd), text):
        problems.append("selfcal %s --help: its usage line does not name `selfcal %s`" % (cmd, cmd))
    if cmd not in man:
        problems.append("selfcal(1): no section for `selfcal %s`" % cmd)
        continue
    documented = own_opts(man[cmd], cmd)
    for o in sorted(opts - documented):
        problems.append("selfcal(1), section `%s`: %s (in --help) is missing" % (cmd, o))
    for o in sorted(documented - opts):
        problems.append("selfcal %s --help: %s (in selfcal(1)) is missing" % (cmd, o))
for s in man:
    if s not in COMMANDS:
        problems.append("selfcal(1): section `%s` is not a command this test knows" % s)

text, opts = help_opts([selfcald])
documented = set(OPT.findall(roff_text(open(mandir + "/selfcald.8.in", encoding="utf-8").read())))
documented -= {"--help"}
for o in sorted(opts - documented):
    problems.append("selfcald(8): %s (in selfcald --help) is missing" % o)
for o in sorted(documented - opts):
    problems.append("selfcald --help: %s (in selfcald(8)) is missing" % o)

# docs/formats.md §3's synopses: every option a synopsis shows exists in that command's --help
formats = os.path.join(os.path.dirname(os.path.abspath(mandir)), "formats.md")
sec = re.search(r"^## 3\. .*?(?=^## 4\.)", open(formats, encoding="utf-8").read(), re.M | re.S)
if not sec:
    problems.append("formats.md: no section 3")
checked = 0
for syn in re.findall(r"^\| `([^`]*)`", sec.group(0) if sec else "", re.M):
    words = syn.split()
    if words[0] == "selfcald":
        cmd, argv = "selfcald", [selfcald]
    else:
        two = " ".join(words[1:3])
        cmd = two if two in COMMANDS else words[1]
        if cmd not in COMMANDS:
            continue  # `simulate grid|profile ...`
        argv = [selfcal] + cmd.split()
    _, opts = help_opts(argv)
    checked += 1
    for o in sorted(set(OPT.findall(syn)) - opts):
        problems.append("formats.md §3, `%s`: %s is not in its --help" % (cmd, o))
if checked < 5:
    problems.append("formats.md §3: only %d synopses found" % checked)

for p in problems:
    print("FAIL:", p)
if problems:
    sys.exit(1)
print("ok: %d commands and selfcald: --help and the man pages name the same options" % len(COMMANDS))
