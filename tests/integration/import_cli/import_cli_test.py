#!/usr/bin/env python3
"""CLI tests of `selfcal import grid|profile` and `selfcal simulate exports` (SPEC §10).

Usage: import_cli_test.py CLI TMPDIR CASE
The exports are written here, in Python, from the selfcal-grid / selfcal-profile files of
`selfcal simulate` (the truth), so the importer is checked against an independent writer; every
assertion compares with that truth, never with stored outputs of selfcal.
"""
import csv
import math
import os
import random
import shlex
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import clitest  # noqa: E402  (the shared preamble: tests/integration/clitest.py)
from clitest import fail, fresh_dir, run  # noqa: E402

CLI, TMP, CASE = clitest.setup("import_cli_")


def read_grid(path):
    """A selfcal-grid v1 file: (header lines, {(view, i, j): (x_mm, y_mm)})."""
    head, rows = [], {}
    with open(path) as f:
        for line in f:
            line = line.rstrip("\n")
            if line.startswith("#"):
                head.append(line)
            elif line and line != "view,i,j,x_mm,y_mm":
                v, i, j, x, y = line.split(",")[:5]
                rows[(int(v), int(i), int(j))] = (float(x), float(y))
    return head, rows


def read_map(path):
    with open(path, newline="") as f:
        return {(int(r["i"]), int(r["j"])): (float(r["gx_um"]), float(r["gy_um"]))
                for r in csv.DictReader(f)}


def views_of(head):
    """[(view index, 'rot=.. shift=.. [rows= cols=]')] from the header lines."""
    out = []
    for h in head:
        if h.startswith("# view "):
            k, rest = h[len("# view "):].split(":", 1)
            out.append((int(k), rest.strip()))
    return out


def fmt(v, dec):
    s = "%.12f" % v
    return s.replace(".", ",") if dec == "," else s


def write_export(path, pts, delim=";", dec=",", scale=1000.0, names=("Nr", "X", "Y", "Z"),
                 rng=None):
    """One view's export: a header line, then the points (x_mm, y_mm) in random order."""
    pts = list(pts)
    if rng:
        rng.shuffle(pts)
    with open(path, "w") as f:
        f.write(delim.join(names) + "\n")
        for n, (x, y) in enumerate(pts):
            f.write(delim.join([str(n + 1), fmt(x * scale, dec), fmt(y * scale, dec),
                                fmt(0.0, dec)]) + "\n")


def simulate(d, plan="double-shift", n=25, extra=()):
    run("simulate", "grid", "--plan", plan, "--n", n, "--pitch-mm", 1, "--sigma-r-um", 0,
        "--seed", 7, "--out", os.path.join(d, "truth_in.csv"),
        "--truth-map", os.path.join(d, "G_true.csv"), *extra)
    return read_grid(os.path.join(d, "truth_in.csv"))


def import_args(views, files, n=25, units="um"):
    a = ["import", "grid", "--n", n, "--pitch-mm", 1, "--units", units, "--x-col", "X",
         "--y-col", "Y"]
    for (k, spec), f in zip(views, files):
        a += ["--view", spec, f]
    return a


def same_grid(got, want, tol_mm, what):
    """The imported marks are exactly want's (grid file rows {(view, i, j): (x_mm, y_mm)}), each
    within tol_mm of its position."""
    if set(got) != set(want):
        fail("%s: imported marks differ: extra %s, missing %s"
             % (what, sorted(set(got) - set(want))[:5], sorted(set(want) - set(got))[:5]))
    worst = max(max(abs(got[k][0] - want[k][0]), abs(got[k][1] - want[k][1])) for k in want)
    if worst > tol_mm:
        fail("%s: imported positions differ by %g mm" % (what, worst))


def check_bad(args, d, out, want):
    """Exit 2, one stderr line naming FILE:LINE (want: substring), no output file."""
    p = run(*args, "-o", out, expect=2)
    lines = p.stderr.strip().splitlines()
    if len(lines) != 1 or want not in lines[0] or not lines[0].startswith("selfcal: "):
        fail("want one stderr line with %r, got %r" % (want, p.stderr))
    if os.path.exists(out) or [f for f in os.listdir(d) if f.startswith(".")]:
        fail("bad input left an output file: %s" % os.listdir(d))


# ------------------------------------------------------------------------------------------
def case_recover(missing_views=(0, 1, 2, 3), name="recover"):
    """The acceptance test: exports (shuffled, µm, ';' and decimal commas, one mark missing,
    one stray point) from a noise-free simulated truth -> import -> lsq -> G to <= 1e-9 µm.
    The damaged mark (3, 4) is missing from every view (its plate error is then unknown) or, in
    recover_one_view, from view 1 only."""
    d = fresh_dir(name)
    head, rows = simulate(d)
    views = views_of(head)
    missing = (3, 4)
    rng = random.Random(11)
    files = []
    for k, _ in views:
        pts = [xy for (v, i, j), xy in sorted(rows.items())
               if v == k and not ((i, j) == missing and v in missing_views)]
        if k == 2:  # a speck of dust: half a pitch off a mark diagonally
            x, y = pts[len(pts) // 3]
            pts.append((x + 0.5, y - 0.5))
        files.append(os.path.join(d, "view%d.csv" % k))
        write_export(files[-1], pts, rng=rng)
    out = os.path.join(d, "imported.csv")
    p = run(*import_args(views, files), "-o", out)
    if "view2.csv:" not in p.stderr or "left out" not in p.stderr:
        fail("the stray point is not reported: %s" % p.stderr)
    if "no point for mark (3,4)" not in p.stderr:
        fail("the missing mark is not reported: %s" % p.stderr)
    ihead, irows = read_grid(out)
    want = {k: v for k, v in rows.items() if not (k[1:] == missing and k[0] in missing_views)}
    same_grid(irows, want, 1e-12, name)
    if [h for h in ihead if h.startswith("# view")] != [h for h in head if h.startswith("# view")]:
        fail("view lines differ: %s vs %s" % (ihead, head))
    run("grid", "--method", "lsq", out, "--map", os.path.join(d, "G.csv"), "--artifact",
        os.path.join(d, "A.csv"))
    t, e = read_map(os.path.join(d, "G_true.csv")), read_map(os.path.join(d, "G.csv"))
    err = max(max(abs(e[k][0] - t[k][0]), abs(e[k][1] - t[k][1])) for k in t)
    print("G recovered from imported exports: max |error| = %.3g um (missing mark in views %s)"
          % (err, missing_views))
    if not err <= 1e-9:
        fail("G error %g um > 1e-9 um" % err)
    if len(missing_views) == len(views):
        with open(os.path.join(d, "A.csv")) as f:
            r = [row for row in csv.DictReader(f) if (row["i"], row["j"]) == ("3", "4")]
        if not os.path.exists(os.path.join(d, "A.csv")) or r[0]["ax_um"] != "":
            fail("the plate error of the damaged mark should be empty: %s" % r)


def case_formats():
    """Tab + decimal point in mm, ',' + '.', quoted names in another case, extra columns, CRLF."""
    d = fresh_dir("formats")
    head, rows = simulate(d, plan="ye", n=9)
    views = views_of(head)
    rng = random.Random(3)
    styles = [("\t", ".", 1.0, "mm"), (",", ".", 1000.0, "um"), (";", ",", 1.0, "mm")]
    for delim, dec, scale, units in styles:
        files = []
        for k, _ in views:
            pts = [xy for (v, i, j), xy in rows.items() if v == k]
            files.append(os.path.join(d, "v%d_%d.csv" % (k, styles.index((delim, dec, scale, units)))))
            write_export(files[-1], pts, delim, dec, scale, ('"Point"', '"x"', "Y", "Z [mm]"), rng)
            if delim == ",":  # Windows line ends
                data = open(files[-1]).read().replace("\n", "\r\n")
                open(files[-1], "w", newline="").write(data)
        out = os.path.join(d, "out.csv")
        a = import_args(views, files, n=9, units=units)
        a[a.index("X")] = "x"
        run(*a, "-o", out)
        _, irows = read_grid(out)
        same_grid(irows, rows, 1e-9, "style %r" % delim)
    # a machine's preamble before the header line (program, date, operator, a blank line): the
    # same grid as without it
    pre = "Program: plate_9x9\nDate%s2026-11-27%sOperator: A. B.\n\n" % (";", ";")
    files2 = []
    for f in files:
        files2.append(f.replace(".csv", "_pre.csv"))
        open(files2[-1], "w").write(pre + open(f).read())
    out2 = os.path.join(d, "out_pre.csv")
    run(*[files2[files.index(x)] if x in files else x for x in a], "-o", out2)
    if read_grid(out2)[1] != irows:
        fail("a preamble changed the import")
    # a misspelt column in a file with a preamble: the error names the header line (4)
    bad = [x if x != "x" else "xx" for x in a]
    p = run(*[files2[files.index(x)] if x in files else x for x in bad], "-o", out2 + "2",
            expect=2)
    if ":4: no column named 'xx'" not in p.stderr or os.path.exists(out2 + "2"):
        fail("misspelt column after a preamble: %r" % p.stderr)
    # what machines write around the rows: a units line under the header, the header again at a
    # page break, a spreadsheet's empty line, a failed feature, a summary row whose mean lies on
    # the centre mark (so the centre is left out of that view first), a text footer: the same
    # grid, each kind named on stderr; a row after a footer-like line is still an error
    f0 = files[0]  # the ';' + ',' style, in mm
    lines = open(f0).read().splitlines()
    hdr, body = lines[0], [l for l in lines[1:] if l]
    cx = "%s;0;0;0" % "Mean"
    noisy = [hdr, ";".join(["", "MM", "MM", "MM"])] + body[:20] + [hdr] + body[20:40] + [";;;", "17a;;;"] + \
        body[40:] + [cx, "*** End of report ***", "Operator: A. B."]
    f_noisy = f0.replace(".csv", "_noisy.csv")
    open(f_noisy, "w").write("\n".join(noisy) + "\n")
    out3 = os.path.join(d, "out_noisy.csv")
    p = run(*[f_noisy if x == f0 else x for x in a], "-o", out3)
    if read_grid(out3)[1] != irows:
        fail("the lines around the rows changed the import")
    for want in (":2: a line of units under the header; skipped", ":23: the header line again (1 time",
                 ":45: 1 row without any value", "1 summary row (Mean", "2 lines after the last row are no row (a footer)"):
        if want not in p.stderr:
            fail("noisy export: stderr lacks %r: %s" % (want, p.stderr))
    # columns aligned by blanks under a preamble (as some machines print their tables)
    lines = open(f0).read().splitlines()
    blank = ["GEOPAK  Protocol  plate 9x9", "", "Element      X            Y            Z   "] + \
        ["CIR-%-6s %18s %18s %8s" % tuple(f.replace(",", ".") for f in l.split(";")) for l in lines[1:] if l]
    f_blank = f0.replace(".csv", "_blank.txt")
    open(f_blank, "w").write("\n".join(blank) + "\n")
    out5 = os.path.join(d, "out_blank.csv")
    run(*[f_blank if x == f0 else x for x in a], "-o", out5)
    if read_grid(out5)[1] != irows:
        fail("a blank-aligned table read differently")
    # a point 0.11 mm from the centre mark (which this view's file otherwise lacks), where the
    # others lie within a few um of theirs: left out and named, the centre mark absent
    f1 = files[1]
    lines = open(f1).read().splitlines()
    def at_centre(l):
        f = l.split(";")
        return len(f) > 2 and abs(float(f[1].replace(",", "."))) < 0.2 and abs(float(f[2].replace(",", "."))) < 0.2
    far = [lines[0]] + [l for l in lines[1:] if l and not at_centre(l)] + ["99;0,1;0,05;0"]
    f_far = f1.replace(".csv", "_far.csv")
    open(f_far, "w").write("\n".join(far) + "\n")
    out4 = os.path.join(d, "out_far.csv")
    p = run(*[f_far if x == f1 else x for x in a], "-o", out4)
    if "_far.csv:%d: point (0.100000, 0.050000) mm is more than 20 times as far" % len(far) not in p.stderr \
            or "view 1: no point for mark (4,4); absent" not in p.stderr:
        fail("a point far beyond the others: %s" % p.stderr)
    noisy_bad = noisy[:30] + ["*** page 2 ***"] + noisy[30:]
    open(f_noisy, "w").write("\n".join(noisy_bad) + "\n")
    p = run(*[f_noisy if x == f0 else x for x in a], "-o", out3 + "2", expect=2)
    if "_noisy.csv:31: 1 fields, the header line (line 1) has 4" not in p.stderr:
        fail("a non-row between rows: %r" % p.stderr)


def case_placement():
    """A plate placed 0.15 mm off and turned 5 mrad, with four stray points: every point still
    goes to its own mark, strays are left out."""
    d = fresh_dir("placement")
    head, rows = simulate(d, plan="ye", n=25)
    views = views_of(head)
    rng = random.Random(5)
    th, tx, ty = 5e-3, 0.15, -0.12
    files = []
    for k, _ in views:
        pts = []
        for (v, i, j), (x, y) in rows.items():
            if v == k:
                pts.append((tx + math.cos(th) * x - math.sin(th) * y,
                            ty + math.sin(th) * x + math.cos(th) * y))
        for s in range(4):
            x, y = pts[s * 37]
            pts.append((x + 0.5, y + 0.45))
        files.append(os.path.join(d, "v%d.csv" % k))
        write_export(files[-1], pts, rng=rng)
    out = os.path.join(d, "out.csv")
    p = run(*import_args(views, files), "-o", out)
    if p.stderr.count("; left out\n") != 12:
        fail("want 12 stray points left out: %s" % p.stderr)
    _, irows = read_grid(out)
    if set(irows) != set(rows):
        fail("marks differ after a misplaced plate")
    for key, (x, y) in rows.items():
        ex = tx + math.cos(th) * x - math.sin(th) * y
        if abs(irows[key][0] - ex) > 1e-9:
            fail("mark %s got another point" % (key,))
    # the fitted rotation: 5 mrad plus the simulation's own misalignment (sigma 100 urad)
    import re
    th_fit = [float(t) for t in re.findall(r"theta (-?[0-9.]+) urad", p.stderr)]
    if len(th_fit) != 3 or any(abs(t - 5000) > 500 for t in th_fit):
        fail("fitted rotations %s, want 5000 +- 500 urad" % th_fit)


def case_stage():
    """--stage larger than the plate: marks land on stage nodes, off-stage marks are absent, the
    header carries the stage line."""
    d = fresh_dir("stage")
    n, nx, ny, P = 9, 13, 9, 1.0
    views = [(0, "rot=0 shift=0,0"), (1, "rot=90 shift=0,0"), (2, "rot=0 shift=4,0"),
             (3, "rot=0 shift=-5,1")]
    c, cx, cy = (n - 1) // 2, (nx - 1) // 2, (ny - 1) // 2
    rng = random.Random(9)
    files, want = [], {}
    for k, spec in views:
        rot = int(spec.split()[0][4:])
        sx, sy = map(int, spec.split()[1][6:].split(","))
        pts = []
        for i in range(n):
            for j in range(n):
                px, py = j - c, i - c
                qx, qy = {0: (px, py), 90: (-py, px)}[rot]
                jj, ii = qx + sx + cx, qy + sy + cy
                if 0 <= jj < nx and 0 <= ii < ny:
                    x, y = (jj - cx) * P + 1e-3 * rng.uniform(-3, 3), (ii - cy) * P
                    pts.append((x, y))
                    want[(k, i, j)] = (x, y)
        files.append(os.path.join(d, "v%d.csv" % k))
        write_export(files[-1], pts, rng=rng)
    out = os.path.join(d, "out.csv")
    run(*import_args(views, files, n=n), "--stage", "%d,%d" % (nx, ny), "-o", out)
    head, irows = read_grid(out)
    if "# stage = 13,9" not in head:
        fail("no stage line: %s" % head)
    if set(irows) != set(want):
        fail("stage: marks differ: %s" % sorted(set(irows) ^ set(want))[:6])
    if sum(1 for k in want if k[0] == 3) != 8 * 6:
        fail("stage: view 3 should keep 6 columns of 8 rows")


def case_bad_input():
    d = fresh_dir("bad")
    head, rows = simulate(d, plan="ye", n=9)
    views = views_of(head)
    files = []
    for k, _ in views:
        files.append(os.path.join(d, "v%d.csv" % k))
        write_export(files[-1], [xy for (v, i, j), xy in sorted(rows.items()) if v == k])
    out = os.path.join(d, "out.csv")
    good = import_args(views, files, n=9)
    # no such column (the header line is line 1)
    a = list(good)
    a[a.index("Y")] = "Ypos"
    check_bad(a, d, out, "v0.csv:1: no column named 'Ypos'")
    # wrong units: every point is 1000x too far: the share test refuses the view
    a = list(good)
    a[a.index("um")] = "mm"
    check_bad(a, d, out, "v0.csv:1: only 1 of the 81 points lie within 0.25 mm of a mark of view rot=0 shift=0,0")
    # two points on one mark: a line repeated 3 µm off
    lines = open(files[1]).read().splitlines()
    f, x, y, z = lines[5].split(";")
    lines.append(";".join([f, x.replace(",", ",000003")[:len(x) + 6], y, z]))
    bad = os.path.join(d, "dup.csv")
    open(bad, "w").write("\n".join(lines) + "\n")
    a = import_args(views, [files[0], bad, files[2]], n=9)
    check_bad(a, d, out, "dup.csv:%d: this point and the point on line 6 both fall on mark"
              % len(lines))
    # mixed decimal marks
    lines = open(files[2]).read().splitlines()
    lines[7] = lines[7].replace(",", ".")
    bad = os.path.join(d, "mixed.csv")
    open(bad, "w").write("\n".join(lines) + "\n")
    a = import_args(views, [files[0], files[1], bad], n=9)
    check_bad(a, d, out, "mixed.csv:8: column 'X': decimal '.' here but ',' on line 2 (mixed decimal marks)")
    # decimal commas in a comma-separated file: the field count tells
    lines = [l.replace(";", ",") for l in open(files[0]).read().splitlines()]
    bad = os.path.join(d, "commas.csv")
    open(bad, "w").write("\n".join(lines) + "\n")
    a = import_args(views, [bad, files[1], files[2]], n=9)
    check_bad(a, d, out, "commas.csv:2: 7 fields, the header line (line 1) has 4")
    # ... unless the fields are quoted: "12,5" is then a number with a decimal comma
    quoted = [lines[0]] + [",".join('"%s"' % f for f in l.split(";"))
                           for l in open(files[0]).read().splitlines()[1:]]
    good_q = os.path.join(d, "quoted.csv")
    open(good_q, "w").write("\n".join(quoted) + "\n")
    run(*import_args(views, [good_q, files[1], files[2]], n=9), "-o", out)
    ref = os.path.join(d, "ref.csv")
    run(*import_args(views, files, n=9), "-o", ref)
    if read_grid(out) != read_grid(ref):
        fail("quoted decimal commas in a comma-separated file read differently")
    os.remove(out)
    # a quoted field with a decimal comma next to an unquoted one: the unquoted is still refused
    f3 = open(files[0]).read().splitlines()[2].split(";")
    mixed_q = quoted[:2] + ['"%s",%s,"%s","%s"' % tuple(f3)] + quoted[3:]
    open(good_q, "w").write("\n".join(mixed_q) + "\n")
    check_bad(import_args(views, [good_q, files[1], files[2]], n=9), d, out, "quoted.csv:3: ")
    # not a number, both marks in one number, empty file, missing file
    for name, text, want in [("nan.csv", "X;Y\n1;nan\n", "nan.csv:2: column 'Y': 'nan' is not a number"),
                             ("thou.csv", "X;Y\n1.000,5;2\n", "thou.csv:2: column 'X': '1.000,5' has both"),
                             ("empty.csv", "# nothing\n", "empty.csv:1: no header line"),
                             ("nodata.csv", "X;Y\n", "nodata.csv:1: no data lines")]:
        bad = os.path.join(d, name)
        open(bad, "w").write(text)
        a = import_args(views, [bad, files[1], files[2]], n=9)
        check_bad(a, d, out, want)
    check_bad(import_args(views, [os.path.join(d, "nope.csv"), files[1], files[2]], n=9), d, out,
              "nope.csv: cannot open")
    # usage errors: exit 2, one line
    for a in [["import", "grid", "--n", 8, "--pitch-mm", 1, "--view", "rot=0 shift=0,0", files[0]],
              ["import", "grid", "--n", 9, "--pitch-mm", 1, "--view", "rot=45 shift=0,0", files[0]],
              ["import", "grid", "--n", 9, "--pitch-mm", 1, "--tolerance-mm", 0.6, "--view",
               "rot=0 shift=0,0", files[0]],
              ["import", "grid", "--n", 9, "--pitch-mm", 1, "--view", "rot=0", files[0]],
              ["import", "grid", "--n", 9, "--pitch-mm", 1, "--view", "rot=0 shift=0,0"],
              ["import", "grid", "--n", 9, "--pitch-mm", 1, "--view", "rot=0 shift=0,0 rows=9", files[0]],
              ["import", "grid", "--n", 9, "--pitch-mm", 1, "--view", "rot=0 shift=30,0", files[0]]]:
        p = run(*a, "-o", out, expect=2)
        if len(p.stderr.strip().splitlines()) != 1 or os.path.exists(out):
            fail("usage error %s: %r" % (a, p.stderr))
    # a view's FILE forgotten: said so, not "unknown option 'out.csv'"
    p = run("import", "grid", "--n", 9, "--pitch-mm", 1, "--view", "rot=0 shift=0,0", "-o", out, expect=2)
    if "must be followed by its FILE, not by the option '-o'" not in p.stderr or os.path.exists(out):
        fail("forgotten view file: %r" % p.stderr)
    # an endless pipe (a header, then the same point forever) is refused at the row beyond the
    # most points a view takes, not read until memory runs out
    a = import_args(views, ["/dev/stdin", files[1], files[2]], n=9)
    with subprocess.Popen(["sh", "-c", "printf 'X;Y\\n'; exec yes '0,5;0,5'"],
                          stdout=subprocess.PIPE) as gen:
        p = subprocess.run([CLI] + [str(x) for x in a] + ["-o", out], stdin=gen.stdout,
                           capture_output=True, text=True, timeout=clitest._timeout)
        gen.kill()
    want = "/dev/stdin:%d: more than %d rows" % (4 * 513 * 513 + 2, 4 * 513 * 513)
    if p.returncode != 2 or want not in p.stderr or os.path.exists(out):
        fail("endless pipe: exit %d, %r (want %r)" % (p.returncode, p.stderr, want))
    run(*good, "-o", out)  # and the good files do import


def case_simulate_exports():
    """selfcal simulate exports writes what import reads back to the same measurements."""
    d = fresh_dir("simexports")
    head, rows = simulate(d)
    ex = os.path.join(d, "ex")
    p = run("simulate", "exports", os.path.join(d, "truth_in.csv"), "--dir", ex, "--missing",
            "3,4@1", "--missing", "0,0", "--stray", "2", "--seed", 3, "--displace", "5,6@0:0.4,-0.2")
    cmd = p.stdout.replace("\\\n", " ").split()
    if cmd[:3] != ["selfcal", "import", "grid"]:
        fail("simulate exports should print the import command: %r" % p.stdout)
    first = open(os.path.join(ex, "view0.csv")).readline().strip()
    if first != "Nr;X;Y;Z":
        fail("export header %r" % first)
    out = os.path.join(d, "imported.csv")
    args = shlex.split(p.stdout.replace("\\\n", " "))[1:]
    args[args.index("-o") + 1] = out
    p = run(*args)
    if "view2.csv:" not in p.stderr or "no point for mark (3,4)" not in p.stderr:
        fail("stray/missing not reported: %s" % p.stderr)
    _, irows = read_grid(out)
    want = {k: v for k, v in rows.items() if k[1:] != (0, 0) and k != (1, 3, 4)}
    x, y = want[(0, 5, 6)]
    want[(0, 5, 6)] = (x + 0.4e-3, y - 0.2e-3)
    same_grid(irows, want, 1e-12, "simulate exports + import")


def run_fd_limited(args, nofile=64):
    """selfcal ARGS with at most nofile open descriptors (ulimit -n)."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, nofile))
    return subprocess.run([CLI] + [str(a) for a in args], capture_output=True, text=True,
                          timeout=300, preexec_fn=limit)


def case_simulate_exports_many():
    """A plan of 1200 views (more than the 64 descriptors allowed here): simulate exports writes
    every view file under `ulimit -n 64`, import reads them back to the simulated measurements,
    and a failure at view 700 leaves no view file new or changed and no temporary file."""
    d = fresh_dir("simexports_many")
    nviews = 1200
    plan = os.path.join(d, "PLAN.csv")
    with open(plan, "w") as f:
        f.write("# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n# origin_mm = 0,0\n# stage = 9,9\n")
        f.write("# view 0: rot=90 shift=0,0\n# view 1: rot=0 shift=1,0\n")
        corners = ((-2, -2), (2, -2), (-2, 2), (2, 2))
        for v in range(2, nviews):
            f.write("# view %d: rot=0 shift=%d,%d\n" % ((v,) + corners[v % 4]))
    truth = os.path.join(d, "truth_in.csv")
    run("simulate", "grid", "--plan", plan, "--out", truth, "--truth-map",
        os.path.join(d, "G_true.csv"), "--sigma-r-um", 0, "--seed", 5)
    head, rows = read_grid(truth)
    ex = os.path.join(d, "ex")
    p = run_fd_limited(["simulate", "exports", truth, "--dir", ex, "--seed", 2])
    if p.returncode != 0:
        fail("simulate exports of %d views under ulimit -n 64: exit %d: %s"
             % (nviews, p.returncode, p.stderr))
    names = sorted(os.listdir(ex))
    if names != sorted("view%d.csv" % v for v in range(nviews)):
        fail("want view0..view%d.csv and nothing else, got %d entries (%s...)"
             % (nviews - 1, len(names), [n for n in names if "tmp" in n][:3]))
    for v in range(nviews):
        lines = open(os.path.join(ex, "view%d.csv" % v)).read().splitlines()
        if lines[0] != "Nr;X;Y;Z" or len(lines) != 26:
            fail("view%d.csv: a header and 25 points, got %d lines" % (v, len(lines)))
    args = shlex.split(p.stdout.replace("\\\n", " "))[1:]
    out = os.path.join(d, "imported.csv")
    args[args.index("-o") + 1] = out
    q = run_fd_limited(args)
    if q.returncode != 0:
        fail("import of %d views under ulimit -n 64: exit %d: %s"
             % (nviews, q.returncode, q.stderr[-500:]))
    _, irows = read_grid(out)
    same_grid(irows, rows, 1e-12, "simulate exports + import of %d views" % nviews)
    # all or none: view 700's name taken by a folder; the old view0.csv stays as it was
    ex2 = os.path.join(d, "ex2")
    os.makedirs(os.path.join(ex2, "view700.csv"))
    with open(os.path.join(ex2, "view0.csv"), "w") as f:
        f.write("old\n")
    p = run_fd_limited(["simulate", "exports", truth, "--dir", ex2])
    left = sorted(os.listdir(ex2))
    if p.returncode == 0 or len(p.stderr.strip().splitlines()) != 1 or "view700.csv" not in p.stderr:
        fail("a view that cannot be written: want one line naming it, got exit %d %r"
             % (p.returncode, p.stderr))
    if left != ["view0.csv", "view700.csv"] or open(os.path.join(ex2, "view0.csv")).read() != "old\n":
        fail("a failed export left files behind or changed one: %s" % left[:5])


def write_scan(path, rows, delim=";", dec=","):
    with open(path, "w") as f:
        f.write(delim.join(["pos [mm]", "A", "B", "phi"]) + "\n")
        for r in rows:
            f.write(delim.join(("%.17g" % v).replace(".", dec) for v in r) + "\n")


def read_profile(path):
    data = {}
    head = []
    for line in open(path):
        if line.startswith("#"):
            head.append(line.strip())
        elif line[0].isdigit():
            k, n, a, b, c = line.split(",")
            data[(int(k), int(n))] = (float(a), float(b), float(c))
    return head, data


def imported_as_simulated(path, data, what):
    """The imported file's header (N = 120, s = 0.5 mm, d = 6/7) and samples are the simulated
    file's; returns its samples."""
    head, got = read_profile(path)
    for h in ("# N = 120", "# s_mm = 0.5", "# scan 1: d=6", "# scan 2: d=7"):
        if h not in head:
            fail("%s: the header lacks %r: %s" % (what, h, head))
    if set(got) != set(data):
        fail("%s: the samples differ" % what)
    return got


def case_profile():
    """Sensor logs (reversed order, nm and mrad, ';' and decimal commas, an offset start) ->
    selfcal-profile v1 equal to the simulated file; then the checks: gaps, repeats, step,
    spacings, start, coverage."""
    d = fresh_dir("profile")
    src = os.path.join(d, "sim.csv")
    run("simulate", "profile", "--out", src, "--truth", os.path.join(d, "T.csv"), "--n", 120,
        "--s-mm", 0.5, "--d1", 6, "--d2", 7, "--noise-free")
    head, data = read_profile(src)
    s, start = 0.5, 100.25
    scans = {}
    for k, dk in ((1, 6), (2, 7)):
        rows = [(start + n * s, data[(k, n)][0] * 1e3, data[(k, n)][1] * 1e3, data[(k, n)][2] * 1e-3)
                for n in range(120 - dk)]
        scans[k] = rows
        write_scan(os.path.join(d, "s%d.csv" % k), rows[::-1])
    out = os.path.join(d, "out.csv")
    base = ["import", "profile", "--pos-col", "pos [mm]", "--m1-col", "a", "--m2-col", "b",
            "--m3-col", "PHI", "--disp-units", "nm", "--angle-units", "mrad"]
    files = [os.path.join(d, "s1.csv"), os.path.join(d, "s2.csv")]
    args = base + ["--spacing-mm", 3, files[0], "--spacing-mm", 3.5, files[1]]
    run(*args, "-o", out)
    odata = imported_as_simulated(out, data, "logs")
    worst = max(abs(a - b) for k in data for a, b in zip(odata[k], data[k]))
    if worst > 1e-12:
        fail("profile values differ by %g" % worst)
    run("profile", "--method", "lsq", out, "--out", os.path.join(d, "P.csv"))

    def bad(rows_by_scan, want, extra=(), spacings=(3, 3.5)):
        for k in (1, 2):
            write_scan(os.path.join(d, "b%d.csv" % k), rows_by_scan[k])
        a = base + list(extra) + ["--spacing-mm", spacings[0], os.path.join(d, "b1.csv"),
                                  "--spacing-mm", spacings[1], os.path.join(d, "b2.csv")]
        check_bad(a, d, os.path.join(d, "bad_out.csv"), want)

    # a gap (SPEC §2a) is passed on: the sample has no row, least squares solves around it
    gap = dict(scans)
    gap[2] = scans[2][:40] + scans[2][41:]
    for k in (1, 2):
        write_scan(os.path.join(d, "g%d.csv" % k), gap[k])
    gout = os.path.join(d, "gap_out.csv")
    run(*(base + ["--spacing-mm", 3, os.path.join(d, "g1.csv"), "--spacing-mm", 3.5,
                  os.path.join(d, "g2.csv")]), "-o", gout)
    ghead, gdata = read_profile(gout)
    if (2, 40) in gdata or (2, 39) not in gdata or (2, 41) not in gdata or len(gdata) != len(data) - 1:
        fail("import profile: the gap (scan 2, n = 40) is not passed on as a missing row")
    run("profile", "--method", "lsq", gout, "--out", os.path.join(d, "PG.csv"))
    # more than half of a scan missing: refused at the row after its largest gap
    gap[1] = scans[1][:2] + scans[1][80:]
    bad(gap, "b1.csv:4: scan 1: 36 of its 114 samples present (the largest gap: 78 samples")
    rep = dict(scans)
    rep[1] = scans[1][:10] + [scans[1][9]] + scans[1][10:]
    bad(rep, "b1.csv:12: position 104.750000 mm is sampled twice (also line 11)")
    step = dict(scans)
    r = list(scans[1][30])
    r[0] += 0.2
    step[1] = scans[1][:30] + [tuple(r)] + scans[1][31:]
    bad(step, "b1.csv:32: position 115.450000 mm is 0.400 steps off the sampling grid")
    # a sample half a step off the grid, inserted: named at its line (it skewed the step fitted
    # from the positions, which was then refused as "not a whole number of steps")
    half = dict(scans)
    r = list(scans[1][30])
    r[0] += 0.5 * s
    half[1] = scans[1][:31] + [tuple(r)] + scans[1][31:]
    bad(half, "b1.csv:33: position 115.500000 mm is 0.500 steps off the sampling grid")
    # a scan log whose units line was skipped but which is refused later: the error line alone
    # (the notes come only with a result)
    with open(os.path.join(d, "b1.csv"), "w") as f:
        f.write("pos [mm];A;B;phi\n;nm;nm;mrad\n")
        for q in range(len(scans[1])):
            rr = scans[1][q if q != 10 else 9]
            f.write(";".join(("%.17g" % v).replace(".", ",") for v in rr) + "\n")
    write_scan(os.path.join(d, "b2.csv"), scans[2])
    check_bad(base + ["--spacing-mm", 3, os.path.join(d, "b1.csv"), "--spacing-mm", 3.5,
                      os.path.join(d, "b2.csv")], d, os.path.join(d, "bad_out.csv"), "sampled twice")
    bad(scans, "the sensor spacing 3.2 mm is not a whole number of steps", spacings=(3, 3.2))
    late = dict(scans)
    late[2] = scans[2][1:] + [(scans[2][-1][0] + s,) + scans[2][-1][1:]]
    bad(late, "b2.csv:2: scan 2 starts at 100.750000 mm, scan 1 at 100.250000 mm")
    short = dict(scans)
    short[2] = scans[2][:-1]
    bad(short, "b2.csv:113: scan 2 covers 119 points")
    bad(scans, "the sensor spacings 3 and 3.54 mm are not whole multiples of one step",
        spacings=(3, 3.54))

    # a real scan's positions jitter (here up to 0.02 steps, the first sample 0.06 steps off
    # and one 0.08): the step is found from all of them and made exactly D1/d1, the grid's origin
    # is their median, so the default tolerance of 0.1 steps applies as documented
    rnd = __import__("random").Random(5)
    jit = {k: [(r[0] + s * (0.06 if (k, q) == (1, 0) else 0.08 if (k, q) == (1, 50) else
                            rnd.uniform(-0.02, 0.02)),) + r[1:] for q, r in enumerate(scans[k])]
           for k in (1, 2)}
    for k in (1, 2):
        write_scan(os.path.join(d, "j%d.csv" % k), jit[k])
    jout = os.path.join(d, "jit.csv")
    run(*(base + ["--spacing-mm", 3, os.path.join(d, "j1.csv"), "--spacing-mm", 3.5,
                  os.path.join(d, "j2.csv"), "-o", jout]))
    imported_as_simulated(jout, data, "jittered positions")


def case_weights():
    """--ux-col/--uy-col become ux_um,uy_um (converted to µm); sigma_um= passes to the view line;
    the least squares reads the result (SPEC §5)."""
    d = fresh_dir("weights")
    head, rows = simulate(d, plan="ye", n=9)
    views = views_of(head)
    files = []
    for k, _ in views:
        path = os.path.join(d, "v%d.csv" % k)
        with open(path, "w") as f:
            f.write("X;Y;uX;uY\n")
            for (v, i, j), (x, y) in sorted(rows.items()):
                if v == k:
                    f.write(";".join(fmt(t, ",") for t in (x, y, 0.001 * (1 + i), 0.002)) + "\n")
        files.append(path)
    out = os.path.join(d, "out.csv")
    views = [(0, views[0][1] + " sigma_um=0.05")] + views[1:]
    run(*import_args(views, files, n=9, units="mm"), "--ux-col", "ux", "--uy-col", "UY", "-o", out)
    lines = open(out).read().splitlines()
    if "# view 0: rot=0 shift=0,0 sigma_um=0.05" not in lines:
        fail("sigma_um not passed on: %s" % lines[:8])
    if "view,i,j,x_mm,y_mm,ux_um,uy_um" not in lines:
        fail("no uncertainty columns: %s" % lines[:9])
    for l in lines:
        if l[:1].isdigit():
            v, i, j, x, y, ux, uy = l.split(",")
            if abs(float(ux) - 1.0 * (1 + int(i))) > 1e-9 or abs(float(uy) - 2.0) > 1e-9:
                fail("uncertainties not in um: %s" % l)
    a = import_args(views, files, n=9, units="mm")
    p = run(*a, "--ux-col", "ux", "-o", out + "2", expect=2)
    if "--ux-col and --uy-col go together" not in p.stderr:
        fail(p.stderr)
    p = run("grid", "--method", "lsq", out, "--map", os.path.join(d, "G.csv"), "--summary",
            os.path.join(d, "S.json"))
    if '"variance_factor"' not in open(os.path.join(d, "S.json")).read():
        fail("with stated uncertainties the summary should report the variance factor")


def case_stitched():
    """A stage larger than the plate (SPEC §5): the plate stitched over a 25 x 19 stage in 8
    placements (selfcal simulate grid --plan stitch), exported with a damaged mark missing from
    every view and a stray point, imported with --stage, calibrated: G at all 475 nodes to
    <= 1e-9 µm."""
    d = fresh_dir("stitched")
    run("simulate", "grid", "--plan", "stitch", "--stage", "25,19", "--n", 13, "--pitch-mm", 1,
        "--sigma-r-um", 0, "--seed", 3, "--out", os.path.join(d, "truth_in.csv"),
        "--truth-map", os.path.join(d, "G_true.csv"))
    head, rows = read_grid(os.path.join(d, "truth_in.csv"))
    views = views_of(head)
    rng = random.Random(4)
    files = []
    for k, _ in views:
        pts = [xy for (v, i, j), xy in rows.items() if v == k and (i, j) != (6, 6)]
        if k == 1:
            pts.append((pts[0][0] - 0.5, pts[0][1] + 0.5))
        files.append(os.path.join(d, "view%d.csv" % k))
        write_export(files[-1], pts, rng=rng)
    out = os.path.join(d, "imported.csv")
    p = run(*import_args(views, files, n=13), "--stage", "25,19", "-o", out)
    if p.stderr.count("; left out\n") != 1:
        fail("want one stray point left out: %s" % p.stderr)
    ihead, irows = read_grid(out)
    if "# stage = 25,19" not in ihead or len(irows) != len(rows) - len(views):
        fail("stitched import: %s, %d rows of %d" % (ihead, len(irows), len(rows)))
    run("grid", "--method", "lsq", out, "--map", os.path.join(d, "G.csv"))
    t, e = read_map(os.path.join(d, "G_true.csv")), read_map(os.path.join(d, "G.csv"))
    if len(t) != 475 or set(t) != set(e):
        fail("stitched map: %d nodes" % len(e))
    err = max(max(abs(e[k][0] - t[k][0]), abs(e[k][1] - t[k][1])) for k in t)
    print("stitched: G at %d nodes recovered to %.3g um" % (len(t), err))
    if not err <= 1e-9:
        fail("stitched: G error %g um" % err)


def case_partial():
    """SPEC §10: marks without a point are absent, however many. Petrò's partial view 3 given
    as plain "rot=0 shift=-3,0" (its 22 of the 54 marks it could put on the stage), and a view
    of which more than half the marks are damaged: imported as measured, and the calibration
    from the partial import equals the truth (noise-free)."""
    d = fresh_dir("partial")
    head, rows = simulate(d, plan="double-shift", n=9)
    views = views_of(head)
    if "rows=" not in views[3][1]:
        fail("the simulated view 3 is not partial: %s" % views[3][1])
    plain = [(k, " ".join(w for w in spec.split() if w.startswith(("rot=", "shift="))))
             for k, spec in views]
    files = []
    for k, _ in views:
        files.append(os.path.join(d, "v%d.csv" % k))
        write_export(files[-1], [xy for (v, i, j), xy in sorted(rows.items()) if v == k])
    out = os.path.join(d, "out.csv")
    p = run(*import_args(plain, files, n=9), "-o", out)
    if "view 3 (rot=0 shift=-3,0): 22 of 54 marks" not in p.stderr:
        fail("view 3's report: %s" % p.stderr)
    _, irows = read_grid(out)
    same_grid(irows, rows, 1e-12, "partial view")
    for method in ("double-shift", "lsq"):
        run("grid", "--method", method, out, "--map", os.path.join(d, "G_%s.csv" % method))
        t, e = read_map(os.path.join(d, "G_true.csv")), read_map(os.path.join(d, "G_%s.csv" % method))
        err = max(max(abs(e[k][0] - t[k][0]), abs(e[k][1] - t[k][1])) for k in t)
        if not err <= 1e-9:
            fail("%s from the partial import: G error %g um" % (method, err))
    # view 3 measured whole (every mark it puts on the stage) but imported with rows=/cols= as
    # documented: the points on the marks they leave out are counted, not taken for strays
    # (the share test refused the view: "only 22 of the 54 points lie within ...")
    d2 = os.path.join(d, "whole3")
    os.makedirs(d2, exist_ok=True)
    plan = os.path.join(d2, "plan.csv")
    open(plan, "w").write("# selfcal-grid v1\n# N = 9\n# pitch_mm = 1\n" +
                          "".join("# view %d: %s\n" % (k, s) for k, s in plain))
    run("simulate", "grid", "--plan", plan, "--pitch-mm", 1, "--sigma-r-um", 0, "--seed", 7,
        "--out", os.path.join(d2, "in.csv"), "--truth-map", os.path.join(d2, "G.csv"))
    _, whole = read_grid(os.path.join(d2, "in.csv"))
    wfile = os.path.join(d2, "v3.csv")
    write_export(wfile, [xy for (v, i, j), xy in sorted(whole.items()) if v == 3])
    p = run(*import_args(views, files[:3] + [wfile], n=9), "-o", os.path.join(d2, "out.csv"))
    if "view 3: 32 points on marks its rows=/cols= leave out; left out" not in p.stderr or \
            "farther than" in p.stderr:
        fail("view 3 measured whole, imported with rows=/cols=: %s" % p.stderr)
    _, wi = read_grid(os.path.join(d2, "out.csv"))
    if sorted(k for k in wi if k[0] == 3) != sorted(k for k in rows if k[0] == 3):
        fail("view 3 measured whole: the imported marks are not those rows=/cols= select")
    # view 2 (shift 2,0) written in the plate's frame (the machine aligned on the plate): its
    # points sit two pitches left of where the view's marks are; they are numbered two marks off,
    # and the two columns beyond the view's first mark are left out on the lattice: warned about
    plate_frame = os.path.join(d, "v2_plate_frame.csv")
    write_export(plate_frame, [(x - 2.0, y) for (v, i, j), (x, y) in sorted(rows.items()) if v == 2])
    p = run(*import_args(views, files[:2] + [plate_frame] + files[3:], n=9), "-o", os.path.join(d, "pf.csv"))
    if "view 2: warning: 18 of the points left out lie on the mark lattice where this view has no mark" \
            not in p.stderr:
        fail("a view in the plate's frame: no warning: %s" % p.stderr)
    if "warning" in run(*import_args(views, files, n=9), "-o", os.path.join(d, "pf2.csv")).stderr:
        fail("the same views in the stage frame were warned about")
    # a damaged plate: view 2 (shift 2,0: 63 marks on the stage) keeps 2 in 5 of them
    v2 = [xy for (v, i, j), xy in sorted(rows.items()) if v == 2]
    kept = [xy for n, xy in enumerate(v2) if n % 5 < 2]
    write_export(files[2], kept)
    p = run(*import_args(plain, files, n=9), "-o", out)
    _, irows = read_grid(out)
    got = sum(1 for k in irows if k[0] == 2)
    if len(v2) != 63 or got != len(kept) or \
            "view 2 (rot=0 shift=2,0): %d of 63 marks" % len(kept) not in p.stderr:
        fail("damaged view 2: %d of %d marks imported; %s" % (got, len(kept), p.stderr))

# ------------------------------------------------------------------------------------------
# SPEC §10a: exports as measuring software writes them (docs/import.md's recipes)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import vendor_exports  # noqa: E402  (the layouts' writers, each citing its source)

DOC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "docs",
                   "import.md")


def recipe_options():
    """{recipe: [import options]} from docs/import.md: the ```sh block after each
    '<!-- recipe: NAME -->', without the plate, the views and -o (the test gives its own)."""
    out, lines = {}, open(DOC, encoding="utf-8").read().splitlines()
    for k, line in enumerate(lines):
        if not line.startswith("<!-- recipe: "):
            continue
        name = line[len("<!-- recipe: "):].split()[0]
        body, m = [], k + 2  # the line after the opening ```sh
        while not lines[m].startswith("```"):
            body.append(lines[m].rstrip("\\").strip())
            m += 1
        args = shlex.split(" ".join(body))[3:]  # selfcal import grid
        opts, a = [], 0
        while a < len(args):
            if args[a] in ("--n", "--pitch-mm", "-o"):
                a += 2
            elif args[a] == "--view":
                a += 3
            else:
                opts.append(args[a])
                a += 1
        out[name] = opts
    return out


def nominal_mm(spec, i, j, n, pitch=1.0):
    """The nominal stage position of mark (i, j) in the view 'rot=R shift=SX,SY' (SPEC §1)."""
    kv = dict(t.split("=") for t in spec.split())
    rot = int(kv["rot"])
    sx, sy = (int(v) for v in kv["shift"].split(","))
    c = (n - 1) / 2
    x, y = (j - c) * pitch, (i - c) * pitch
    for _ in range(rot // 90):
        x, y = -y, x
    return x + sx * pitch, y + sy * pitch


def vendor_setup(d, n=9):
    run("simulate", "grid", "--plan", "ye", "--n", n, "--pitch-mm", 1, "--sigma-r-um", 0.01,
        "--seed", 7, "--out", os.path.join(d, "truth_in.csv"),
        "--truth-map", os.path.join(d, "G_true.csv"))
    return read_grid(os.path.join(d, "truth_in.csv"))


def vendor_views(head, rows, n, dec, scale, rng, missing=None):
    """Per view: the points to export (id, x, y, nominal x, nominal y; rounded as written), and
    the direct data set of the same numbers {(view, i, j): (x, y)}."""
    per_view, direct = [], {}
    for k, spec in views_of(head):
        pts = []
        for (v, i, j), (x, y) in sorted(rows.items()):
            if v != k:
                continue
            nx, ny = nominal_mm(spec, i, j, n)
            if (k, i, j) == missing:
                pts.append([None, None, nx, ny])
                continue
            r = (vendor_exports.rounded(x, dec, scale), vendor_exports.rounded(y, dec, scale))
            pts.append([r[0], r[1], nx, ny])
            direct[(v, i, j)] = r
        rng.shuffle(pts)
        per_view.append([tuple(["C%d" % (q + 1)] + p) for q, p in enumerate(pts)])
    return per_view, direct


def write_direct(path, head, rows):
    with open(path, "w") as f:
        f.write("\n".join(h for h in head) + "\nview,i,j,x_mm,y_mm\n")
        for (v, i, j), (x, y) in sorted(rows.items()):
            f.write("%d,%d,%d,%.17g,%.17g\n" % (v, i, j, x, y))


def case_vendors():
    """Every recipe of docs/import.md: the layout written from the vendor's documentation,
    imported with the recipe's options, gives the direct solve's G to 1e-6 um, with no
    warning; a mark not measured (view 1) is absent where the layout can say so."""
    d = fresh_dir("vendors")
    n = 9
    head, rows = vendor_setup(d, n)
    recipes = recipe_options()
    if set(recipes) != set(vendor_exports.WRITERS):
        fail("recipes in docs/import.md %s, writers %s" % (sorted(recipes),
                                                           sorted(vendor_exports.WRITERS)))
    views = views_of(head)
    for name, (writer, dec, scale) in sorted(vendor_exports.WRITERS.items()):
        rng = random.Random(hash(name) & 0xffff)
        per_view, direct = vendor_views(head, rows, n, dec, scale, rng, missing=(1, 2, 3))
        files = []
        for k, pts in enumerate(per_view):
            files.append(os.path.join(d, "%s_view%d.csv" % (name, k)))
            writer(files[-1], pts, dec)
        out = os.path.join(d, "%s_in.csv" % name)
        args = ["import", "grid", "--n", n, "--pitch-mm", 1] + recipes[name]
        for (k, spec), f in zip(views, files):
            args += ["--view", spec, f]
        p = run(*args, "-o", out)
        if "warning" in p.stderr:
            fail("%s: a warning on a good export: %s" % (name, p.stderr))
        _, irows = read_grid(out)
        same_grid(irows, direct, 1e-12, name)
        dpath = os.path.join(d, "%s_direct.csv" % name)
        write_direct(dpath, head, direct)
        gi, gd = os.path.join(d, "%s_Gi.csv" % name), os.path.join(d, "%s_Gd.csv" % name)
        run("grid", "--method", "lsq", out, "--map", gi)
        run("grid", "--method", "lsq", dpath, "--map", gd)
        a, b = read_map(gi), read_map(gd)
        err = max(max(abs(a[k][0] - b[k][0]), abs(a[k][1] - b[k][1])) for k in b)
        print("%-14s %3d points imported, G vs the direct solve: max |diff| = %.3g um"
              % (name, len(irows), err))
        if not err <= 1e-6:
            fail("%s: G differs from the direct solve's by %g um" % (name, err))


def vendor_bad(d, name, text, opts, want, n=9, encoding="utf-8", expect=2, spec="rot=0 shift=0,0"):
    """A one-view import of text: exit expect, stderr holding want (exit 2: one line, no output)."""
    path = os.path.join(d, name)
    with open(path, "w", encoding=encoding, newline="") as f:
        f.write(text)
    out = os.path.join(d, "out.csv")
    args = ["import", "grid", "--n", n, "--pitch-mm", 1] + opts + ["--view", spec, path]
    if expect == 2:
        check_bad(args, d, out, want)
    else:
        p = run(*args, "-o", out, expect=expect)
        if want not in p.stderr:
            fail("%s: want %r in stderr, got %r" % (name, want, p.stderr))
        os.remove(out)


def case_vendor_messages():
    """Each bad case of issue 39 gives its own message (docs/import.md)."""
    d = fresh_dir("vendor_msg")
    n = 9
    head, rows = vendor_setup(d, n)
    per_view, _ = vendor_views(head, rows, n, 6, 1.0, random.Random(5))
    pts = per_view[0]
    buf = os.path.join(d, "pc.csv")
    vendor_exports.pcdmis_csv(buf, pts)
    pc = open(buf, newline="").read()
    # 1. one row per axis: X and Y in one column, and the defaults taking a row for the header
    vendor_bad(d, "pc1.csv", pc, ["--x-col", "MEAS", "--y-col", "MEAS"],
               "the column 'MEAS' is asked for twice (as the 1st and the 2nd quantity) (one row "
               "per axis, X and Y in one column? --id-col, --axis-col, --value-col)")
    vendor_bad(d, "pc2.csv", pc, [], "pc2.csv:6: no column named 'y' in this header line: this "
               "line is a data row, taken for the header because its value 'X' matches a "
               "column's name (one row per axis? --id-col, --axis-col, --value-col)")
    # ... and with the options it imports; a point with only its X row is left out, said so
    lines = pc.split("\r\n")
    y_row = [k for k, l in enumerate(lines) if '"Y"' in l][3]
    vendor_bad(d, "pc3.csv", "\r\n".join(lines[:y_row] + lines[y_row + 1:]),
               ["--id-col", "FEATURE", "--axis-col", "AXIS", "--value-col", "MEAS"],
               "pc3.csv:%d: 1 point with only some of its coordinates (a row of an axis "
               "missing; the first: '%s', no Y value); left out"
               % (y_row, lines[y_row].split(",")[0].strip('"')), expect=0)
    # an ID with a second X row: two views in one file (or a repeated feature name)
    vendor_bad(d, "pc4.csv", pc + lines[5] + "\r\n",
               ["--id-col", "FEATURE", "--axis-col", "AXIS", "--value-col", "MEAS"],
               "pc4.csv:%d: '%s(Bore)' has a second X row (the first is on or after line 6): one "
               "ID names one point (two views in one file? --where COL=VALUE picks one)"
               % (len(lines), pts[0][0]))
    # 2. header quirks: CALYPSO's trailing tab, GEOPAK's unlabelled tolerance bar: read, said so
    vendor_exports.calypso_chr(os.path.join(d, "chr.txt"), pts)
    vendor_bad(d, "chr2.txt", open(os.path.join(d, "chr.txt"), newline="").read(),
               ["--id-col", "featureid", "--axis-col", "type", "--value-col", "actual",
                "--axis-names", "X Value,Y Value"],
               "chr2.txt:1: the header line ends in 1 empty field (a trailing tab or delimiter); "
               "ignored", expect=0)
    tab = "Nr;X;Y;Z\r\n" + "".join("%d;%s;%s;0,0;---|-*--\r\n" % (
        q, ("%.6f" % p[1]).replace(".", ","), ("%.6f" % p[2]).replace(".", ","))
        for q, p in enumerate(pts))
    vendor_bad(d, "bar.csv", tab, ["--x-col", "X", "--y-col", "Y"],
               "bar.csv:2: %d rows have (the first) 5 fields where the header line (line 1) has "
               "4: the unlabelled fields at the end (no numbers) are ignored" % len(pts), expect=0)
    # 3. feature tables mix in the alignment: the origin point falls on the centre mark
    vendor_exports.calypso_fet(os.path.join(d, "fet.txt"), pts)
    fet = open(os.path.join(d, "fet.txt"), newline="").read()
    vendor_bad(d, "fet1.txt", fet, ["--x-col", "x", "--y-col", "y"], "both fall on mark (4,4)")
    vendor_bad(d, "fet2.txt", fet, ["--x-col", "x", "--y-col", "y", "--where", "type=Circle"],
               "fet2.txt:2: 3 rows left out by --where (the first here)", expect=0)
    vendor_bad(d, "fet3.txt", fet, ["--x-col", "x", "--y-col", "y", "--where", "kind=Circle"],
               "fet3.txt:1: no column named 'kind' (--where) in this header line")
    # 4. placeholders
    vis = "No.,X,Y\r\n" + "".join("%d,%.6f,%.6f\r\n" % (q, p[1], p[2]) for q, p in enumerate(pts))
    vis += "99,-----,-----\r\n"
    vendor_bad(d, "vis1.csv", vis, ["--x-col", "X", "--y-col", "Y"],
               "vis1.csv:%d: column 'X': '-----' is not a number (a placeholder for a mark not "
               "measured? --missing TOKEN)" % (len(pts) + 2))
    vendor_bad(d, "vis2.csv", vis, ["--x-col", "X", "--y-col", "Y", "--missing", "-----"],
               "vis2.csv:%d: 2 fields held a --missing placeholder (not measured)"
               % (len(pts) + 2), expect=0)
    # 5. no header line; items in columns
    nohead = "".join("%d;%s;%s\r\n" % (q, ("%.6f" % p[1]).replace(".", ","),
                                       ("%.6f" % p[2]).replace(".", ","))
                     for q, p in enumerate(pts))
    vendor_bad(d, "nohead1.csv", nohead, ["--x-col", "X", "--y-col", "Y"],
               "nohead1.csv:1: no column named 'X' in this header line (delimiter ';'): this "
               "line is a row of numbers (no header line? --no-header with the columns by "
               "number)")
    vendor_bad(d, "nohead2.csv", nohead, ["--no-header", "--x-col", "2", "--y-col", "3"],
               "view 0 (rot=0 shift=0,0): 81 of 81 marks", expect=0)
    big = [("P%d" % q, 0.001 * q, 0.0) for q in range(300)]
    wide = ";".join(["Merkmal"] + [b[0] for b in big]) + "\r\n" + \
        ";".join(["X"] + ["%.3f" % b[1] for b in big]) + "\r\n"
    vendor_bad(d, "wide.csv", wide, ["--x-col", "X", "--y-col", "Y"],
               "wide.csv:1: more than 256 columns (items in columns, one column per point? "
               "--transpose)")
    # 6. misleading errors no more: deviations, two views in one file, a cp1252 header
    dev = "Nr;dX;dY\r\n" + "".join("%d;%s;%s\r\n" % (
        q, ("%.6f" % ((p[1] - p[3]) * 1e3)).replace(".", ","),
        ("%.6f" % ((p[2] - p[4]) * 1e3)).replace(".", ",")) for q, p in enumerate(pts))
    vendor_bad(d, "dev.csv", dev, ["--x-col", "dX", "--y-col", "dY", "--units", "um"],
               "deviations rather than positions? (--deviations with the nominal columns)")
    two = "Nr;X;Y\r\n" + "".join("%d;%s;%s\r\n" % (q, ("%.6f" % p[1]).replace(".", ","),
                                                   ("%.6f" % p[2]).replace(".", ","))
                                 for q, p in enumerate(pts + per_view[1]))
    vendor_bad(d, "two.csv", two, ["--x-col", "X", "--y-col", "Y"],
               "two views in one file? (--where COL=VALUE reads one)")
    vendor_exports.excel_de(os.path.join(d, "de.csv"), pts)
    de = open(os.path.join(d, "de.csv"), encoding="cp1252", newline="").read()
    vendor_bad(d, "de1.csv", de, ["--x-col", "X-Ist [µm]", "--y-col", "Y-Ist [µm]", "--units",
                                  "um"],
               "de1.csv:1: no column named 'X-Ist [µm]' in this header line (delimiter ';') (this "
               "header line is not UTF-8 text: give the file's encoding, --encoding "
               "cp1252|latin-1|shift-jis)", encoding="cp1252")
    # nominal columns taken for measured ones: imports, with a warning
    vendor_bad(d, "de2.csv", de, ["--x-col", "X-Soll [µm]", "--y-col", "Y-Soll [µm]", "--units",
                                  "um", "--encoding", "cp1252"],
               "view 0: warning: every point lies within 1 nm of its nominal position: are these "
               "the nominal columns", encoding="cp1252", expect=0)
    # Stabw. is a summary label: the Mittelwert row above it is no point
    vendor_bad(d, "de3.csv", de, ["--x-col", "X-Ist [µm]", "--y-col", "Y-Ist [µm]", "--units",
                                  "um", "--encoding", "cp1252"],
               "4 summary rows (Mean, Max, ...: no measurement); skipped", encoding="cp1252",
               expect=0)
    # deviations with the nominal columns: the positions themselves
    devn = "Nr;X-Soll;Y-Soll;dX;dY\r\n" + "".join("%d;%.6f;%.6f;%.3f;%.3f\r\n" % (
        q, p[3], p[4], (p[1] - p[3]) * 1e3, (p[2] - p[4]) * 1e3) for q, p in enumerate(pts))
    devn = devn.replace(".", ",")
    vendor_bad(d, "devn.csv", devn, ["--x-col", "dX", "--y-col", "dY", "--units", "um",
                                     "--deviations", "--nominal-x-col", "X-Soll",
                                     "--nominal-y-col", "Y-Soll"],
               "view 0 (rot=0 shift=0,0): 81 of 81 marks", expect=0)
    # 7. the export's precision: 4 decimals in mm limit a 10 nm machine
    vendor_exports.pcdmis_csv(buf, pts, dec=4)
    vendor_bad(d, "pc5.csv", open(buf, newline="").read(),
               ["--id-col", "FEATURE", "--axis-col", "AXIS", "--value-col", "MEAS"],
               "view 0: warning: the positions have 4 decimals (steps of 0.1 um): rounding alone "
               "adds 0.0289 um of noise, more than a third of sigma_r = 0.01 um", expect=0)
    vendor_bad(d, "pc6.csv", open(buf, newline="").read(),
               ["--id-col", "FEATURE", "--axis-col", "AXIS", "--value-col", "MEAS"],
               "view 0 (rot=0 shift=0,0): 81 of 81", expect=0, spec="rot=0 shift=0,0 sigma_um=0.5")
    p = run("import", "grid", "--n", n, "--pitch-mm", 1, "--id-col", "FEATURE", "--axis-col",
            "AXIS", "--value-col", "MEAS", "--view", "rot=0 shift=0,0 sigma_um=0.5",
            os.path.join(d, "pc6.csv"), "-o", os.path.join(d, "out.csv"))
    if "warning" in p.stderr:
        fail("4 decimals warned about for a 0.5 um machine: %s" % p.stderr)
    os.remove(os.path.join(d, "out.csv"))
    # the options' own mistakes: exit 2, one line, no output
    out = os.path.join(d, "out.csv")
    f0 = os.path.join(d, "pc1.csv")
    for opts, want in (
            (["--id-col", "FEATURE", "--axis-col", "AXIS"], "needs --id-col, --axis-col and "
             "--value-col"),
            (["--id-col", "F", "--axis-col", "A", "--value-col", "M", "--axis-names", "X"],
             "--axis-names needs two names"),
            (["--axis-names", "X,Y"], "--axis-names goes with --id-col"),
            (["--where", "type"], "--where needs COL=VALUE"),
            (["--missing", ""], "--missing needs a token"),
            (["--encoding", "ebcdic"], "--encoding: utf-8, cp1252, latin-1 or shift-jis"),
            (["--deviations", "--nominal-x-col", "NX"], "--deviations needs --nominal-x-col and "
             "--nominal-y-col"),
            (["--nominal-x-col", "NX", "--nominal-y-col", "NY"], "go with --deviations"),
            (["--transpose", "--id-col", "F", "--axis-col", "A", "--value-col", "M"],
             "--transpose and one row per axis do not go together"),
            (["--transpose", "--where", "a=b"], "--where filters rows"),
            (["--id-col", "F", "--axis-col", "A", "--value-col", "M", "--deviations",
              "--nominal-x-col", "NX", "--nominal-y-col", "NY"], "name the same")):
        p = run("import", "grid", "--n", n, "--pitch-mm", 1, *opts, "--view", "rot=0 shift=0,0",
                f0, "-o", out, expect=2)
        if len(p.stderr.strip().splitlines()) != 1 or want not in p.stderr or \
                os.path.exists(out):
            fail("usage error %s: want %r, got %r" % (opts, want, p.stderr))
    # an endless pipe of rows that give no point (filtered, other axes, unlabelled) is refused
    # after a million in a row, not read forever
    out = os.path.join(d, "out.csv")
    for gen, opts in (("printf 'T;X;Y\\n'; exec yes 'L;0;0'", ["--where", "T=C"]),
                      ("printf 'ID;AXIS;V\\n'; exec yes 'C1;Z;0'",
                       ["--id-col", "ID", "--axis-col", "AXIS", "--value-col", "V"]),
                      ("printf 'X;1\\nY;1\\n'; exec yes 'Z;0'", ["--transpose"])):
        a = ["import", "grid", "--n", n, "--pitch-mm", 1, "--x-col", "X", "--y-col", "Y"] + opts
        a += ["--view", "rot=0 shift=0,0", "/dev/stdin", "-o", out]
        with subprocess.Popen(["sh", "-c", gen], stdout=subprocess.PIPE) as g:
            p = subprocess.run([CLI] + [str(x) for x in a], stdin=g.stdout, capture_output=True,
                               text=True, timeout=clitest._timeout)
            g.kill()
        if p.returncode != 2 or "/dev/stdin:100000" not in p.stderr or \
                "an endless input?" not in p.stderr or os.path.exists(out):
            fail("endless pipe %s: exit %d, %r" % (opts, p.returncode, p.stderr))


def g17(v):
    return ("%.17g" % v).replace(".", ",")


def case_profile_layouts():
    """import profile with the layout options (SPEC §10a where they apply): logs with no header
    line (columns by number) and logs with one row per channel (ID = sample, AXIS = channel,
    other channels and a filtered run mixed in) import to the same file as the plain logs."""
    d = fresh_dir("profile_layouts")
    src = os.path.join(d, "sim.csv")
    run("simulate", "profile", "--out", src, "--truth", os.path.join(d, "T.csv"), "--n", 60,
        "--s-mm", 0.5, "--d1", 4, "--d2", 5, "--noise-free")
    head, data = read_profile(src)
    plain, nohead, longf = [], [], []
    for k, dk in ((1, 4), (2, 5)):
        rows = [(10 + n * 0.5, data[(k, n)][0], data[(k, n)][1], data[(k, n)][2])
                for n in range(60 - dk)]
        for name, lst in (("plain", plain), ("nohead", nohead), ("long", longf)):
            lst.append(os.path.join(d, "%s%d.csv" % (name, k)))
        write_scan(plain[-1], rows, delim=";", dec=",")
        with open(nohead[-1], "w") as f:
            f.write("".join("%d;%s\n" % (q, ";".join(g17(v) for v in r))
                            for q, r in enumerate(rows)))
        with open(longf[-1], "w") as f:
            f.write("Run;Sample;Channel;Value\n")
            for q, r in enumerate(rows):
                for ch, v in zip(("Pos", "A", "B", "Phi", "Temp"), list(r) + [20.0]):
                    f.write("1;%d;%s;%s\n" % (q, ch, g17(v)))
                    f.write("0;%d;%s;%s\n" % (q, ch, g17(v + 1)))  # a discarded run
    with open(plain[0]) as f:
        cols = f.readline().strip().split(";")
    outs = []
    for name, files, opts in (
            ("plain", plain, ["--pos-col", cols[0], "--m1-col", cols[1], "--m2-col", cols[2],
                              "--m3-col", cols[3]]),
            ("nohead", nohead, ["--no-header", "--pos-col", 2, "--m1-col", 3, "--m2-col", 4,
                                "--m3-col", 5]),
            ("long", longf, ["--id-col", "Sample", "--axis-col", "Channel", "--value-col", "Value",
                             "--axis-names", "Pos,A,B,Phi", "--where", "Run=1"])):
        outs.append(os.path.join(d, "%s_out.csv" % name))
        p = run("import", "profile", *opts, "--spacing-mm", 2, files[0], "--spacing-mm", 2.5,
                files[1], "-o", outs[-1])
        if name == "long" and ("rows left out by --where" not in p.stderr or
                               "of other axes" not in p.stderr):
            fail("the long logs' notes are missing: %s" % p.stderr)
    ref = open(outs[0]).read()
    for o in outs[1:]:
        if open(o).read() != ref:
            fail("%s differs from the plain logs' import" % o)


CASES = {"recover": case_recover,
         "vendors": case_vendors, "vendor_messages": case_vendor_messages,
         "profile_layouts": case_profile_layouts,
         "recover_one_view": lambda: case_recover((1,), "recover_one_view"), "formats": case_formats, "placement": case_placement,
         "stage": case_stage, "bad_input": case_bad_input,
         "simulate_exports": case_simulate_exports, "profile": case_profile,
         "simulate_exports_many": case_simulate_exports_many,
         "weights": case_weights, "stitched": case_stitched, "partial": case_partial}
CASES[CASE]()
print("ok")
