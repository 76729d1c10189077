#!/usr/bin/env python3
"""The command line as a newcomer meets it (Python 3 standard library only).

usage: test_cli.py CASE SELFCAL SELFCALD|none WORK_DIR VERSION
  help          every level of the command tree answers --help (exit 0, a usage on stdout);
                `selfcal --help` lists --version and every subcommand (lut dump, lut info too);
                --version prints VERSION; usage errors are one stderr line, exit 2
  grid_summary  `selfcal grid` prints method, noise, residual RMS, O, R and the worst node, the same
                as its JSON summary and its map say; --quiet prints nothing
  lut_offset    `lut build --profile AXIS:DIR:P.csv@OFFSET_MM` places a profile on the machine
                axis (seen in `lut dump`); a profile beside the map gets a warning (exit 0); bad
                offsets are bad input
"""
import json
import math
import os
import re
import shutil
import subprocess
import sys

CASE, CLI, DAEMON, WORK, VERSION = sys.argv[1:6]
FAILS = []


def check(cond, what):
    if not cond:
        FAILS.append(what)
        print("FAIL:", what, file=sys.stderr)
    return cond


def run(*args, prog=None):
    p = subprocess.run([prog or CLI] + [str(a) for a in args], stdout=subprocess.PIPE,
                       stderr=subprocess.PIPE, text=True, timeout=120)
    return p.returncode, p.stdout, p.stderr


def must(*args):
    rc, out, err = run(*args)
    if rc != 0:
        print("setup failed: %s: %s" % (" ".join(map(str, args)), err), file=sys.stderr)
        sys.exit(1)
    return out, err


def path(name):
    return os.path.join(WORK, name)


def case_help():
    rc, top, err = run("--help")
    check(rc == 0 and top.startswith("usage:") and err == "", "selfcal --help: rc %d" % rc)
    check("--version" in top, "selfcal --help mentions --version")
    commands = sorted(set(re.findall(r"^  selfcal ([a-z][a-z-]*(?: [a-z]+)?)", top, re.M)))
    for want in ("grid", "plan", "profile", "profile-plan", "lut build", "lut dump", "lut info", "export",
                 "simulate grid", "simulate profile", "plot map", "plot profile"):
        check(want in commands, "selfcal --help lists '%s' (found %s)" % (want, commands))
    groups = sorted({c.split()[0] for c in commands if " " in c})
    for words in commands + groups:
        rc, out, err = run(*words.split(), "--help")
        check(rc == 0 and out.startswith("usage:") and err == "",
              "selfcal %s --help: rc %d, stdout %r, stderr %r" % (words, rc, out[:60], err[:200]))
        if words in groups:
            for sub in [c for c in commands if c.startswith(words + " ")]:
                check(sub in out, "selfcal %s --help lists '%s'" % (words, sub))
    rc, out, err = run("--version")
    check(rc == 0 and out == "selfcal %s\n" % VERSION, "selfcal --version: %r (want %s)" % (out, VERSION))
    if DAEMON != "none":
        rc, out, err = run("--help", prog=DAEMON)
        check(rc == 0 and out.startswith("usage:") and err == "", "selfcald --help: rc %d %r" % (rc, err))
        rc, out, err = run("--version", prog=DAEMON)
        check(rc == 0 and out == "selfcald %s\n" % VERSION, "selfcald --version: %r" % out)
    # usage problems: exit 2, one stderr line, nothing on stdout
    for args in ([], ["frobnicate"], ["simulate"], ["simulate", "nothing"], ["plot", "--bogus"],
                 ["grid", "--bogus"], ["lut"], ["lut", "bogus"]):
        rc, out, err = run(*args)
        check(rc == 2 and out == "" and len(err.splitlines()) == 1,
              "selfcal %s: rc %d, stdout %r, stderr %r (want 2, one line)" % (" ".join(args), rc, out, err))
    # an unknown option as the last word is said to be unknown (it was "needs a value")
    for args, prog in ((["grid", "--bogus"], None), (["lut", "build", "--bogus"], None),
                       (["--table", "x.lut", "--bogus"], DAEMON)):
        if prog == "none":
            continue
        rc, out, err = run(*args, prog=prog)
        check(rc == 2 and "unknown option" in err, "%s: rc %d, stderr %r" % (" ".join(args), rc, err))


def read_map(p):
    with open(p) as f:
        head = f.readline().strip().split(",")
        return [dict(zip(head, line.strip().split(","))) for line in f if line.strip()]


def case_grid_summary():
    for plan, method in (("double-shift", "lsq"), ("double-shift", "double-shift"), ("ye", "ye")):
        inp, gmap, summ = path("in_%s.csv" % plan), path("G_%s.csv" % method), path("S_%s.json" % method)
        must("simulate", "grid", "--plan", plan, "--n", 11, "--pitch-mm", 2, "--origin-mm", "10,-4",
             "--seed", 9, "--out", inp, "--truth-map", path("truth.csv"))
        out, err = must("grid", "--method", method, inp, "--map", gmap, "--summary", summ)
        kv = dict(re.findall(r"^(\w+): (.*)$", out, re.M))
        for key in ("method", "sigma_r_est_um", "residual_rms_um", "O", "R", "worst_node"):
            check(key in kv, "%s: summary line '%s:' (stdout %r)" % (method, key, out))
        if FAILS:
            return
        s = json.load(open(summ))
        check(kv["method"] == method, "%s: method line %r" % (method, kv["method"]))
        for key, js in (("O", "O"), ("R", "R"), ("residual_rms_um", "residual_rms_um")):
            got = float(kv[key].split()[0])
            check(math.isclose(got, float(s[js]), rel_tol=1e-5, abs_tol=1e-12),
                  "%s: %s printed %g, JSON %g" % (method, key, got, s[js]))
        rows = read_map(gmap)
        worst = max(rows, key=lambda r: math.hypot(float(r["gx_um"]), float(r["gy_um"])))
        m = re.match(r"(\d+),(\d+) at \(([-\d.e]+), ([-\d.e]+)\) mm: \|G\| = ([\d.e-]+) um", kv["worst_node"])
        if check(m is not None, "%s: worst_node line %r" % (method, kv["worst_node"])):
            check((int(m.group(1)), int(m.group(2))) == (int(worst["i"]), int(worst["j"])) and
                  abs(float(m.group(3)) - float(worst["x_mm"])) < 1e-9 and
                  abs(float(m.group(4)) - float(worst["y_mm"])) < 1e-9,
                  "%s: worst node %s, the map's largest |G| is at %s,%s (%s, %s)" %
                  (method, m.groups()[:4], worst["i"], worst["j"], worst["x_mm"], worst["y_mm"]))
            check(math.isclose(float(m.group(5)), math.hypot(float(worst["gx_um"]), float(worst["gy_um"])),
                               rel_tol=1e-5), "%s: |G| of the worst node" % method)
        if method == "lsq":
            check("u = " in kv["worst_node"], "lsq: the worst node's uncertainty is printed")
        rc, out, err = run("grid", "--method", method, inp, "--map", gmap, "--quiet")
        check(rc == 0 and out == "" and err == "", "%s --quiet: rc %d, stdout %r" % (method, rc, out))


def dump_profiles(table):
    out, _ = must("lut", "dump", table)
    profiles, cur = [], None
    for line in out.splitlines():
        if line.startswith("# profile"):
            cur = []
            profiles.append(cur)
        elif cur is not None and re.match(r"^\d+,", line):
            cur.append([float(v) for v in line.split(",")])
    return profiles


def case_lut_offset():
    must("simulate", "grid", "--plan", "ye", "--n", 25, "--seed", 3, "--out", path("g.csv"),
         "--truth-map", path("gt.csv"))
    must("grid", "--method", "ye", "--quiet", path("g.csv"), "--map", path("G.csv"))  # x, y = -12..12 mm
    must("simulate", "profile", "--n", 330, "--d1", 10, "--d2", 11, "--out", path("p.csv"), "--truth", path("pt.csv"))
    must("profile", "--method", "lsq", "--quiet", path("p.csv"), "--out", path("P.csv"))  # x_mm = 0..329
    # no offset: 0..329 mm against a map at -12..12 mm overlaps (0..12): no warning
    rc, out, err = run("lut", "build", "--map", path("G.csv"), "--profile", "x:y:" + path("P.csv"), "-o", path("T0.lut"))
    check(rc == 0 and err == "", "overlapping profile: rc %d, stderr %r" % (rc, err))
    p0 = dump_profiles(path("T0.lut"))[0]
    check(abs(p0[0][1] - 0.0) < 1e-9, "no offset: the profile starts at 0 mm (%g)" % p0[0][1])
    # an offset moves the profile: pos = x_mm + offset
    rc, out, err = run("lut", "build", "--map", path("G.csv"), "--profile", "y:x:" + path("P.csv") + "@-164.5",
                       "-o", path("T1.lut"))
    check(rc == 0 and err == "", "offset -164.5: rc %d, stderr %r" % (rc, err))
    p1 = dump_profiles(path("T1.lut"))[0]
    check(len(p1) == len(p0) and all(abs(a[1] - (b[1] - 164.5)) < 1e-6 and a[2] == b[2] for a, b in zip(p1, p0)),
          "offset -164.5 shifts every position and keeps every value")
    # beside the map: a warning on stderr, still exit 0 and a table
    for spec, label in (("@100", "after the map"), ("@-400", "before the map")):
        rc, out, err = run("lut", "build", "--map", path("G.csv"), "--profile", "x:y:" + path("P.csv") + spec,
                           "-o", path("T2.lut"))
        check(rc == 0 and re.search(r"warning: .*P\.csv.* do not overlap", err) and len(err.splitlines()) == 1
              and os.path.exists(path("T2.lut")), "%s: rc %d, stderr %r" % (label, rc, err))
        os.remove(path("T2.lut"))
    # bad offsets are bad input; nothing written
    for spec in ("@1e9", "@nan", "@inf"):
        rc, out, err = run("lut", "build", "--map", path("G.csv"), "--profile", "x:y:" + path("P.csv") + spec,
                           "-o", path("T3.lut"))
        check(rc == 2 and len(err.splitlines()) == 1 and not os.path.exists(path("T3.lut")),
              "offset %s: rc %d, stderr %r" % (spec, rc, err))


def case_bad_values():
    """Option values beyond what the outputs' readers accept, or that would be silently clamped
    or wrapped: exit 2, one stderr line, nothing written (exploratory testing, stop 27)."""
    must("simulate", "grid", "--plan", "ye", "--n", 7, "--out", path("in.csv"), "--truth-map", path("T.csv"))
    must("simulate", "profile", "--n", 200, "--d1", 5, "--d2", 7, "--out", path("p.csv"), "--truth", path("pt.csv"))
    with open(path("v0.csv"), "w") as f:
        f.write("X,Y\n0,0\n1,0\n")
    cases = [
        (["simulate", "grid", "--plan", "ye", "--n", 7, "--sigma-g-um", "1e200"], "at most 1e+06"),
        (["simulate", "grid", "--plan", "ye", "--n", 7, "--sigma-a-um", "1e308"], "at most 1e+06"),
        (["simulate", "grid", "--plan", "ye", "--n", 7, "--pitch-mm", "1e308"], "pitch"),
        (["simulate", "grid", "--plan", "ye", "--n", 7, "--O", "5"], "within +-0.1"),
        (["simulate", "grid", "--plan", "ye", "--n", 7, "--seed", "-1"], "--seed"),
        (["simulate", "profile", "--n", 200, "--d1", 5, "--d2", 7, "--seed", "99999999999999999999"], "--seed"),
        (["grid", "--method", "lsq", path("in.csv"), "--map", path("G.csv"), "--sigma-r-um", "1e308"],
         "--sigma-r-um"),
        (["export", "--format", "linuxcnc", "--axis", "x", "--map", path("T.csv"), "--at", "100",
          "-o", path("x.comp")], "outside the map"),
        (["import", "grid", "--n", 3, "--pitch-mm", 1, "--x-col", "X", "--y-col", "Y", "--tolerance-mm", 0,
          "--view", "rot=0 shift=0,0", path("v0.csv"), "-o", path("imp.csv")], "tolerance must be positive"),
        (["import", "grid", "--n", 3, "--pitch-mm", 0, "--x-col", "X", "--y-col", "Y",
          "--view", "rot=0 shift=0,0", path("v0.csv"), "-o", path("imp.csv")], "the pitch must be 1e-06 to 1e+06 mm"),
    ]
    # a plan that needs terabytes: refused before any work (it ran out of memory after minutes)
    rc, out, err = run("profile-plan", "--n", 100000000, "--s-mm", 1, "--sigma-disp-um", 0.01,
                       "--sigma-angle-urad", 1, "--d-max", 5000)
    check(rc == 2 and "needs about" in err and len(err.splitlines()) == 1, "profile-plan 4 TB: rc %d %r" % (rc, err))
    for args, needle in cases:
        if args[0] == "simulate":
            args = args + ["--out", path("s_out.csv")] + (["--truth-map", path("s_t.csv")] if args[1] == "grid"
                                                          else ["--truth", path("s_t.csv")])
        before = sorted(os.listdir(WORK))
        rc, out, err = run(*args)
        check(rc == 2 and len(err.splitlines()) == 1 and needle in err and sorted(os.listdir(WORK)) == before,
              "%s: rc %d, stderr %r (want 2 with %r, nothing written)" % (" ".join(map(str, args[:4])), rc, err,
                                                                          needle))


shutil.rmtree(WORK, ignore_errors=True)
os.makedirs(WORK)
{"help": case_help, "grid_summary": case_grid_summary, "lut_offset": case_lut_offset,
 "bad_values": case_bad_values}[CASE]()
if FAILS:
    print("%d check(s) failed" % len(FAILS), file=sys.stderr)
    sys.exit(1)
shutil.rmtree(WORK, ignore_errors=True)
print("ok:", CASE)
