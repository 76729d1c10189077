#!/usr/bin/env python3
"""Straightness profiles as Aerotech Automation1 1-D axis calibration tables
(`selfcal export --format aerotech-a1 --profile AXIS:DIR:P.csv`, the file OUT-1d), applied by the
rule written again from Aerotech's help page "Axis Calibration" (not from the exporter):

- a 1-D table corrects an output axis from the position of one reference axis, axis indices
  one-based in the file;
- at a reference position of the table its value, between two of them linear interpolation,
  beyond them "the nearest end point of the table";
- tables add up; a file holds tables of one kind (so the profiles' 1-D tables are not in the
  map's 2-D file).

File form (the exporter's stated assumption, read here as written): `:START RefAxis OutputAxis
SAMPLEDIST=.. POSUNIT=.. CORUNIT=.. [NEGCOR]`, `:START OFFSET=..`, one correction per line, `:END`;
the table index is (position + OFFSET) / SAMPLEDIST, as for the 2-D table.

The profile is a real one (a DABAM mirror through `simulate profile` and `profile --method lsq`),
placed with @OFFSET_MM as x:y and as y:x; selfcald's profile is `lut build` + `lut dump` (linear,
clamped, SPEC §4). Exported beside the demo's map (25 x 25 at 1 mm) and a stitched rectangular
stage (41 x 31 at 2 mm, with --offset and other axis indices). On a simulated machine whose
output axis stands e(s) short of its command (e: the profile as selfcald applies it, s: the
reference axis' position), the controller commands t + c(s): the error left is the 0.1 nm unit
with the default sign, twice the uncorrected error with --negate. Bad input: exit 2, one line,
no file.

usage: test_a1_profile.py SELFCAL_CLI WORKDIR DABAM_DAT"""
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from exportlib import Export, interp_clamped, parse_lut_dump, precision_maps  # noqa: E402

cli, work, dabam = sys.argv[1], sys.argv[2], sys.argv[3]
E = Export(cli, work)
check, run, path, selfcal = E.check, E.run, E.path, E.selfcal
UNIT = 0.5e-4   # half the 0.1 nm unit of the written corrections, um
LUT_Q = 0.5e-4  # lut dump's 0.1 nm


def read_a1_1d(name):
    """[(ref axis, output axis, positions mm, corrections um)] of an Automation1 1-D file."""
    units = {"PRIMARY": 1.0, "PRIMARY/1000": 1e-3}
    lines = [ln.strip() for ln in open(path(name), encoding="utf-8")]
    lines = [ln for ln in lines if ln and not ln.startswith(";")]
    tables, k = [], 0
    while k < len(lines):
        head = lines[k].split()
        check(head[0] == ":START" and len(head) >= 3, f"{name}: a :START line, not {lines[k]!r}")
        ref, out = int(head[1]), int(head[2])
        kw = dict(w.split("=") for w in head[3:] if "=" in w)
        flags = [w for w in head[3:] if "=" not in w]
        k += 1
        if lines[k].startswith(":START "):  # the second :START line: OFFSET (and flags)
            kw.update(dict(w.split("=") for w in lines[k].split()[1:] if "=" in w))
            flags += [w for w in lines[k].split()[1:] if "=" not in w]
            k += 1
        vals = []
        while lines[k] != ":END":
            vals.append(float(lines[k]))
            k += 1
        k += 1
        pos_mm, cor_um = units[kw["POSUNIT"]], units[kw["CORUNIT"]] * 1e3
        if "NEGCOR" in flags:
            cor_um = -cor_um
        step = float(kw["SAMPLEDIST"]) * pos_mm
        first = -float(kw.get("OFFSET", "0")) * pos_mm   # index = (position + OFFSET) / step
        xs = [first + i * step for i in range(len(vals))]
        tables.append((ref, out, xs, [v * cor_um for v in vals]))
    return tables


def selfcald_profiles(map_csv, profs, name):
    """selfcald's profiles (lut build + lut dump): [(axis, dir, positions, errors)]."""
    args = ["lut", "build", "--map", map_csv]
    for p in profs:
        args += ["--profile", p]
    selfcal(*args, "-o", path(name + ".lut"))
    _, profiles = parse_lut_dump(selfcal("lut", "dump", path(name + ".lut")), check)
    check(len(profiles) == len(profs), f"{name}: {len(profiles)} profiles in the table")
    return [(a, d, [r[1] for r in rows], [r[2] for r in rows]) for a, d, rows in profiles]


def assess(tables, prof, ref_nr, out_nr, shift):
    """The output axis on the machine: commanded t + c(s) (the 1-D tables of that output axis
    with that reference axis, summed), it stands e(s) short. Returns residual and error left."""
    _, _, px, pe = prof
    mine = [t for t in tables if t[0] == ref_nr and t[1] == out_nr]
    check(len(mine) == 1, f"one table of axis {out_nr} from axis {ref_nr} ({len(mine)})")
    if not mine:
        return None
    _, _, xs, vs = mine[0]
    lo, hi = px[0] - 20.0, px[-1] + 20.0   # beyond both ends: the nearest end points
    res, left, raw = [], [], []
    # a dense sampling, the profile's points and the table's (where the largest errors of a
    # resampled table lie), all in selfcald's (map) coordinates
    grid = [lo + (hi - lo) * q / 6000 for q in range(6001)] + list(px) + [x - shift for x in xs]
    for s in grid:
        e = interp_clamped(px, pe, s)
        c = interp_clamped(xs, vs, s + shift)  # the controller's (machine) coordinates
        res.append(c - e)
        left.append(c - e)     # true - command: the stage stands e short of t + c
        raw.append(-e)
    rms = lambda v: math.sqrt(sum(a * a for a in v) / len(v))  # noqa: E731
    return {"max": max(abs(r) for r in res), "rms": rms(res), "left_rms": rms(left),
            "raw_rms": rms(raw), "n": len(xs), "first": xs[0]}


def printed(out):
    m = re.search(r"residual \(controller table - profile\) over (\d+) samples: rms ([0-9.]+) "
                  r"um, max ([0-9.]+) um", out)
    return (float(m.group(2)), float(m.group(3))) if m else None


# A real profile, and the two maps.
selfcal("simulate", "profile", "--profile", dabam, "--out", path("PIN.csv"), "--truth",
        path("PT.csv"), "--ey-um", "2", "--seed", "4")
selfcal("profile", "--method", "lsq", path("PIN.csv"), "--out", path("P.csv"))
precision_maps(E)
PROFS = [f"x:y:{path('P.csv')}@-160", f"y:x:{path('P.csv')}@-150"]

cases = {  # name: (map, axis indices x, y, --offset)
    "demo": (path("demo.csv"), (1, 2), (0.0, 0.0)),
    "stitched": (path("stitch.csv"), (3, 5), (100.0, -50.0)),
}
for cname, (csv, nr, offset) in cases.items():
    sd = selfcald_profiles(csv, PROFS, cname)
    check([(p[0], p[1]) for p in sd] == [("x", "y"), ("y", "x")], f"{cname}: selfcald's profiles")
    check(len(sd[0][2]) > 100 and max(abs(e) for e in sd[0][3]) > 1.0,
          f"{cname}: a real profile ({len(sd[0][2])} points)")
    got = {}
    for negate in (False, True):
        out_name = f"{cname}{'-neg' if negate else ''}.cal"
        one_d = out_name.replace(".cal", "-1d.cal")
        args = ["--format", "aerotech-a1", "--map", csv, "-o", path(out_name),
                "--axis-numbers", f"{nr[0]},{nr[1]}", "--offset", f"{offset[0]},{offset[1]}"]
        for p in PROFS:
            args += ["--profile", p]
        rc, out, err = run(*(args + (["--negate"] if negate else [])))
        check(rc == 0 and err == "", f"aerotech-a1 1-D {cname}: {rc} {err}")
        check(os.path.exists(path(out_name)) and os.path.exists(path(one_d)),
              f"{cname}: the 2-D file and the 1-D file OUT-1d")
        if rc != 0:
            continue
        check(":START2D" not in open(path(one_d)).read() and
              ":START " not in open(path(out_name)).read(),
              f"{cname}: the 1-D tables in their own file, not in the 2-D one")
        tables = read_a1_1d(one_d)
        check(len(tables) == 2, f"{one_d}: two 1-D tables ({len(tables)})")
        a = {}
        for prof in sd:
            ai, di = "xy".index(prof[0]), "xy".index(prof[1])
            a[prof[:2]] = assess(tables, prof, nr[ai], nr[di], offset[ai])
        if None in a.values():
            continue
        worst = max(v["max"] for v in a.values())
        left = math.sqrt(sum(v["left_rms"] ** 2 for v in a.values()) / 2)
        raw = math.sqrt(sum(v["raw_rms"] ** 2 for v in a.values()) / 2)
        got[negate] = (left, raw)
        pr = printed(out)
        print(f"aerotech-a1 1-D {cname}{' --negate' if negate else ''}: residual against "
              f"selfcald's profiles max {worst:.6f} um; printed {pr}; error left rms {left:.6f} "
              f"um, uncorrected rms {raw:.4f} um")
        check("1-D table(s): y from x (axis %d from axis %d), x from y (axis %d from axis %d)"
              % (nr[1], nr[0], nr[0], nr[1]) in out and "unit 0.0001 um" in out
              and "nearest end point beyond" in out, f"1-D summary line: {out}")
        for key, v in a.items():   # the profile's own points, shifted by --offset
            prof = next(p for p in sd if p[:2] == key)
            check(v["n"] == len(prof[2]) and abs(v["first"] - (prof[2][0] + offset["xy".index(key[0])])) < 1e-6,
                  f"{cname} {key}: the profile's own points ({v['n']}, from {v['first']})")
        if not negate:
            check(worst <= UNIT + LUT_Q + 1e-9,
                  f"{cname}: residual {worst} within the 0.1 nm unit and the lut's")
            check(pr is not None and abs(pr[1] - worst) <= 1e-4 + LUT_Q,
                  f"{cname}: printed residual {pr} agrees with {worst}")
    if len(got) == 2:
        ratio = got[True][0] / got[True][1]
        check(abs(ratio - 2.0) < 0.01, f"{cname}: the wrong sign doubles the error ({ratio})")
        check(got[False][0] < 1e-3 * got[False][1],
              f"{cname}: the right sign removes it ({got[False][0]})")

# A coarser table (--profile-interval): the printed residual is the rule's, resampling included.
rc, out, err = run("--format", "aerotech-a1", "--map", path("demo.csv"), "-o", path("coarse.cal"),
                   "--profile", PROFS[0], "--profile-interval", "2.5")
check(rc == 0, f"--profile-interval 2.5: {rc} {err}")
if rc == 0:
    sd = selfcald_profiles(path("demo.csv"), PROFS[:1], "coarse")
    tables = read_a1_1d("coarse-1d.cal")
    a = assess(tables, sd[0], 1, 2, 0.0)
    pr = printed(out)
    check(a is not None and abs(tables[0][2][1] - tables[0][2][0] - 2.5) < 1e-9,
          "coarse: SAMPLEDIST 2.5 mm")
    check(a is not None and pr is not None and abs(pr[1] - a["max"]) <= 1e-4 + LUT_Q,
          f"coarse: printed {pr} agrees with the rule's {a and a['max']}")
    check(a is not None and a["max"] > 10 * UNIT, f"coarse: resampling shows ({a and a['max']})")
    print(f"aerotech-a1 1-D at 2.5 mm: residual max {a and a['max']:.4f} um, printed {pr}")

# The open point, the :START line's axis order: --a1-1d-order out,ref writes the output axis
# first; read with that order, the tables are the same ones and the rule's residual is the same.
base = ["--format", "aerotech-a1", "--map", path("stitch.csv"), "--axis-numbers", "3,5",
        "--offset", "100,-50", "--profile", PROFS[0], "--profile", PROFS[1]]
rc1, out1, err1 = run(*base, "-o", path("ord-ro.cal"))
rc2, out2, err2 = run(*base, "-o", path("ord-or.cal"), "--a1-1d-order", "out,ref")
check(rc1 == 0 and rc2 == 0, f"--a1-1d-order: {rc1} {err1} {rc2} {err2}")
if rc1 == 0 and rc2 == 0:
    t_ro, t_or = read_a1_1d("ord-ro-1d.cal"), read_a1_1d("ord-or-1d.cal")
    check([(t[0], t[1]) for t in t_ro] == [(3, 5), (5, 3)],
          f"default order: reference axis first ({[(t[0], t[1]) for t in t_ro]})")
    check([(t[1], t[0]) for t in t_or] == [(t[0], t[1]) for t in t_ro]
          and [t[2:] for t in t_or] == [t[2:] for t in t_ro],
          "out,ref: the same tables with the two axis numbers swapped on :START")
    check("--a1-1d-order out,ref" in open(path("ord-or-1d.cal")).read(),
          "out,ref: the file says which order it wrote")
    sd = selfcald_profiles(path("stitch.csv"), PROFS, "order")
    swapped = [(t[1], t[0], t[2], t[3]) for t in t_or]  # read as written: output axis first
    for prof in sd:
        ai, di = "xy".index(prof[0]), "xy".index(prof[1])
        nr, off = (3, 5), (100.0, -50.0)
        r_ro = assess(t_ro, prof, nr[ai], nr[di], off[ai])
        r_or = assess(swapped, prof, nr[ai], nr[di], off[ai])
        check(r_ro is not None and r_or is not None and r_ro["max"] == r_or["max"],
              f"out,ref {prof[:2]}: the same residual read in its order")
for extra, what in ((["--a1-1d-order", "out,ref"], "--a1-1d-order without --profile"),
                    (["--profile", PROFS[0], "--a1-1d-order", "sideways"], "a bad --a1-1d-order")):
    rc, out, err = run("--format", "aerotech-a1", "--map", path("demo.csv"), "-o",
                       path("bad.cal"), *extra)
    check(rc == 2 and len(err.strip().splitlines()) == 1 and not os.path.exists(path("bad.cal")),
          f"{what}: exit 2, one line, no file ({rc} {err!r})")
rc, out, err = run("--format", "linuxcnc", "--map", path("demo.csv"), "-o", path("bad.cal"),
                   "--a1-1d-order", "out,ref")
check(rc == 2 and "--a1-1d-order applies to --format aerotech-a1" in err,
      f"--a1-1d-order with linuxcnc: exit 2 ({rc} {err!r})")

# Bad input: exit 2, one line, neither file.
bad_cases = (
    (["--profile", f"x:y:{path('P.csv')}@5000"], "a profile beside the map"),
    (["--profile", PROFS[0], "--profile-interval", "0.001"], "more points than a 1-D table"),
    (["--profile", PROFS[0], "--travel", "-200,200"], "--travel (beckhoff only)"),
    (["--profile", f"x:x:{path('P.csv')}"], "DIR = AXIS"),
    (["--profile", f"x:y:{path('missing.csv')}"], "a missing profile"),
)
for extra, what in bad_cases:
    for f in ("bad.cal", "bad-1d.cal"):
        if os.path.exists(path(f)):
            os.remove(path(f))
    rc, out, err = run("--format", "aerotech-a1", "--map", path("demo.csv"), "-o", path("bad.cal"),
                       *extra)
    check(rc == 2 and len(err.strip().splitlines()) == 1 and not os.path.exists(path("bad.cal"))
          and not os.path.exists(path("bad-1d.cal")),
          f"{what}: exit 2, one line, no file ({rc} {err!r})")

E.finish("export_a1_profile")
