#!/usr/bin/env python3
"""SPEC §3 conformance (black box): exit statuses 0/2/1, one stderr line naming file and line,
no output file (nor temporary file) left behind on bad input.

usage: spec_errors.py SELFCAL TMPDIR
"""
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from spec_common import *  # noqa
from spec_profile_gen import simulate_profile_lines  # noqa

SELFCAL, BASE = sys.argv[1], sys.argv[2]


def good_grid_lines(n=5):
    t = synthesize_grid(n, 1.0, (0.0, 0.0), YE(n), 3)
    return t["lines"]


def write_lines(path, text_lines):
    with open(path, "w") as fh:
        fh.write("\n".join(text_lines) + "\n")


def grid_text(n=5, views=None, lines=None):
    views = views or YE(n)
    lines = good_grid_lines(n) if lines is None else lines
    hdr = ["# selfcal-grid v1", "# N = %d" % n, "# pitch_mm = 1.0", "# origin_mm = 0.0,0.0"]
    hdr += [v.header(k) for k, v in enumerate(views)]
    hdr.append("view,i,j,x_mm,y_mm")
    return hdr + ["%d,%d,%d,%.15f,%.15f" % l for l in lines]


def expect_bad(label, argv, in_path, line, outdir, want_rc=2):
    before = set(os.listdir(outdir))
    rc, out, err = run(argv)
    after = set(os.listdir(outdir))
    check(rc == want_rc, "%s: exit %d, SPEC: %d (stderr %r)" % (label, rc, want_rc, err.strip()))
    errl = [l for l in err.splitlines() if l.strip()]
    check(len(errl) == 1, "%s: %d stderr lines, SPEC: one (%r)" % (label, len(errl), err))
    if errl and in_path is not None:
        base = os.path.basename(in_path)
        check(base in errl[0], "%s: stderr does not name the file %s: %r" % (label, base, errl[0]))
        if line is not None:
            check(re.search(r"(:%d\b|line %d\b)" % (line, line), errl[0]) is not None,
                  "%s: stderr does not name line %d: %r" % (label, line, errl[0]))
    print("  %-40s rc=%d  %s" % (label, rc, errl[0] if errl else ""))
    check(after == before, "%s: files left behind: %r" % (label, sorted(after - before)))
    return errl[0] if errl else ""


def grid_cases():
    d = tmpdir(BASE, "errgrid")
    outdir = tmpdir(BASE, "errgrid_out")
    G, A, S = (os.path.join(outdir, f) for f in ("G.csv", "A.csv", "S.json"))
    base_argv = lambda m, p: [SELFCAL, "grid", "--method", m, p, "--map", G, "--artifact", A, "--summary", S]
    txt = grid_text()
    hdr_len = txt.index("view,i,j,x_mm,y_mm") + 1  # lines before the first data row

    # 1. non-numeric field in data line 12 (1-based file line)
    t = list(txt)
    L = hdr_len + 4
    f = t[L - 1].split(",")
    f[3] = "12.x"
    t[L - 1] = ",".join(f)
    p = os.path.join(d, "nonnum.csv")
    write_lines(p, t)
    for m in ("ye", "lsq"):
        expect_bad("grid %s non-numeric x_mm" % m, base_argv(m, p), p, L, outdir)
    # 2. duplicate mark: repeat data line L at the end
    t = list(txt) + [txt[hdr_len + 2]]
    p = os.path.join(d, "dup.csv")
    write_lines(p, t)
    expect_bad("grid duplicate mark", base_argv("ye", p), p, len(t), outdir)
    # 3. mark off the grid: view 2 (shift +1) measuring column N-1
    t = list(txt) + ["2,0,4,2.0,-2.0"]
    p = os.path.join(d, "offgrid.csv")
    write_lines(p, t)
    expect_bad("grid mark off the stage grid", base_argv("lsq", p), p, len(t), outdir)
    # 4. N even
    t = [l.replace("# N = 5", "# N = 6") for l in txt]
    p = os.path.join(d, "neven.csv")
    write_lines(p, t)
    expect_bad("grid N even", base_argv("lsq", p), p, 2, outdir)
    # 5. a view in the data not declared in the header
    t = list(txt) + ["7,0,0,-2.0,-2.0"]
    p = os.path.join(d, "undeclared.csv")
    write_lines(p, t)
    expect_bad("grid undeclared view", base_argv("ye", p), p, len(t), outdir)
    # 6. a view the method needs is missing from the data (Ye without view 2)
    t = [l for l in txt if not l.startswith("2,")]
    p = os.path.join(d, "missing.csv")
    write_lines(p, t)
    expect_bad("grid ye: view 2 absent", base_argv("ye", p), p, None, outdir)
    # 7. double shift with N < 7 (SPEC sets no bound; at N = 5 the -3 shift leaves the method's
    # chains too short, so the method refuses it as bad input; N = 7 is solved: spec_grid)
    t = grid_text(5, PETRO(5), synthesize_grid(5, 1.0, (0.0, 0.0), PETRO(5), 5)["lines"])
    p = os.path.join(d, "ds5.csv")
    write_lines(p, t)
    expect_bad("grid double-shift N=5", base_argv("double-shift", p), p, None, outdir)
    # 8. wrong magic
    t = ["# selfcal-grid v2"] + txt[1:]
    p = os.path.join(d, "magic.csv")
    write_lines(p, t)
    expect_bad("grid wrong format line", base_argv("lsq", p), p, 1, outdir)
    # 9. bad rot
    t = [l.replace("rot=90", "rot=45") for l in txt]
    p = os.path.join(d, "rot45.csv")
    write_lines(p, t)
    expect_bad("grid rot=45", base_argv("lsq", p), p, 6, outdir)
    # 10. not identifiable for lsq: {0, 90} only
    t = grid_text(5, [View(0), View(90)], [l for l in good_grid_lines() if l[0] != 2])
    p = os.path.join(d, "unident.csv")
    write_lines(p, t)
    expect_bad("grid lsq unidentifiable plan", base_argv("lsq", p), p, None, outdir)
    # 10b. headers that contradict the data
    t = list(txt) + ["0,7,0,0.0,0.0"]
    p = os.path.join(d, "i7.csv")
    write_lines(p, t)
    expect_bad("grid mark index beyond N", base_argv("lsq", p), p, len(t), outdir)
    t = [l.replace("# pitch_mm = 1.0", "# pitch_mm = 2.0") for l in txt]
    p = os.path.join(d, "pitch.csv")
    write_lines(p, t)
    expect_bad("grid header pitch contradicts data", base_argv("ye", p), p, None, outdir)
    full = [View(0), View(90), View(0, 2, 0), View(0, -3, 0)]
    t9 = synthesize_grid(9, 1.0, (0.0, 0.0), full, 2)["lines"]
    sel = [l for l in t9 if l[0] != 3 or l[1] == 4 or l[2] in (4, 5)]
    extra = [l for l in t9 if l[:3] == (3, 0, 6)]
    t = grid_text(9, PETRO(9), sel + extra)
    p = os.path.join(d, "rowscols.csv")
    write_lines(p, t)
    expect_bad("grid mark outside view 3's rows=/cols=", base_argv("lsq", p), p, len(t), outdir)
    # 11. plan: non-numeric N
    p = os.path.join(d, "plan_bad.csv")
    write_lines(p, ["# selfcal-grid v1", "# N = five", "# pitch_mm = 1.0", "# view 0: rot=0 shift=0,0"])
    expect_bad("plan N non-numeric", [SELFCAL, "plan", p], p, 2, outdir)
    # 12. output into a directory that does not exist: not bad input -> 1 (SPEC: 1 on other failures)
    good = os.path.join(d, "good.csv")
    write_lines(good, txt)
    rc, out, err = run([SELFCAL, "grid", "--method", "ye", good, "--map", os.path.join(outdir, "nodir", "G.csv")])
    check(rc == 1, "grid output in a missing directory: exit %d, SPEC: 1 on other failures (%r)" % (rc, err.strip()))
    check(os.listdir(outdir) == [], "grid: leftovers %r" % os.listdir(outdir))
    # success path: 0 and the files
    rc, out, err = run(base_argv("ye", good))
    check(rc == 0 and os.path.exists(G) and os.path.exists(A) and os.path.exists(S),
          "grid good input: exit %d, outputs present" % rc)
    check(sorted(os.listdir(outdir)) == ["A.csv", "G.csv", "S.json"], "grid: extra files %r" % os.listdir(outdir))
    # a failing run must not destroy nor alter an existing output
    before = open(G).read()
    p = os.path.join(d, "nonnum.csv")
    rc, out, err = run(base_argv("ye", p))
    check(rc == 2 and open(G).read() == before, "grid bad input over existing G.csv: rc %d, file changed: %s"
          % (rc, open(G).read() != before))
    check(sorted(os.listdir(outdir)) == ["A.csv", "G.csv", "S.json"], "grid: leftovers %r" % os.listdir(outdir))


def profile_cases():
    d = tmpdir(BASE, "errprof")
    outdir = tmpdir(BASE, "errprof_out")
    P = os.path.join(outdir, "P.csv")
    txt = simulate_profile_lines(110, 1.0, 10, 11, 3)
    hdr_len = txt.index("scan,n,m1_um,m2_um,m3_urad") + 1

    def case(label, lines, line, methods=("dft", "lsq")):
        p = os.path.join(d, label.replace(" ", "_") + ".csv")
        write_lines(p, lines)
        for m in methods:
            expect_bad("profile %s %s" % (m, label), [SELFCAL, "profile", "--method", m, p, "--out", P], p, line, outdir)

    t = list(txt)
    L = hdr_len + 7
    f = t[L - 1].split(",")
    f[2] = "nan"
    t[L - 1] = ",".join(f)
    case("nan field", t, L)
    t = list(txt)
    f = t[L - 1].split(",")
    f[4] = "1.5e"
    t[L - 1] = ",".join(f)
    case("junk field", t, L)
    # gap in n: remove one scan-1 sample. SPEC §2a: the DFT refuses it naming --method lsq,
    # least squares solves around it
    t = [l for i, l in enumerate(txt) if i != hdr_len + 20]
    case("gap in n", t, None, methods=("dft",))
    p = os.path.join(d, "gap_in_n.csv")
    rc, out, err = run([SELFCAL, "profile", "--method", "dft", p, "--out", P])
    check(rc == 2 and "--method lsq" in err, "profile dft gap: the message names --method lsq: %r" % err)
    rc, out, err = run([SELFCAL, "profile", "--method", "lsq", p, "--out", P])
    check(rc == 0 and os.path.exists(P), "profile lsq gap: solved around it: rc %d %r" % (rc, err))
    os.remove(P)
    # duplicate
    t = list(txt) + [txt[hdr_len + 3]]
    case("duplicate sample", t, len(t))
    # scan 2 missing
    t = [l for l in txt if not l.startswith("2,")]
    case("scan 2 missing", t, None)
    # d1, d2 not coprime
    t2 = simulate_profile_lines(120, 1.0, 4, 6, 3)
    case("d not coprime", t2, None)
    # DFT: N not p*d1*d2 (least squares solves it; DFT must refuse)
    t3 = simulate_profile_lines(97, 1.0, 3, 7, 3)
    case("N not multiple of d1 d2", t3, None, methods=("dft",))
    p = os.path.join(d, "ok97.csv")
    rc, out, err = run([SELFCAL, "profile", "--method", "lsq", p.replace("ok97", "N_not_multiple_of_d1_d2"), "--out", P])
    check(rc == 0, "profile lsq N=97 d=3/7: exit %d %s" % (rc, err.strip()))
    os.path.exists(P) and os.unlink(P)
    # N too small for least squares, n beyond N - d, header N contradicting the data
    case("N too small", simulate_profile_lines(15, 1.0, 10, 11, 3), None)
    t = list(txt) + ["1,100,0.1,0.1,0.1"]
    case("n beyond N-d1-1", t, len(t))
    t = [l.replace("# N = 110", "# N = 111") for l in txt]
    case("header N contradicts data", t, None)
    # wrong sigma header value
    t = list(txt)
    t.insert(hdr_len - 1, "# sigma_disp_um = abc")
    case("sigma header junk", t, hdr_len)


def lut_cases():
    d = tmpdir(BASE, "errlut")
    outdir = tmpdir(BASE, "errlut_out")
    T = os.path.join(outdir, "t.lut")
    mp = os.path.join(d, "G.csv")
    rows = ["i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um"]
    for i in range(3):
        for j in range(3):
            rows.append("%d,%d,%d,%d,%.6f,%.6f,," % (i, j, j - 1, i - 1, 0.1 * i + 0.2 * j, -0.3 * i))
    bad = list(rows)
    bad[5] = bad[5].replace(",,", ",x,")
    bad[5] = ",".join(bad[5].split(",")[:4] + ["zz"] + bad[5].split(",")[5:])
    write_lines(mp, bad)
    expect_bad("lut build non-numeric gx", [SELFCAL, "lut", "build", "--map", mp, "-o", T], mp, 6, outdir)
    good = os.path.join(d, "Ggood.csv")
    write_lines(good, rows)
    badp = os.path.join(d, "P.csv")
    write_lines(badp, ["n,x_mm,f_um,uf_um,ey_um", "0,0,0,0,0.1", "1,1,0,0,abc", "2,2,0,0,"])
    expect_bad("lut build non-numeric ey_um", [SELFCAL, "lut", "build", "--map", good, "--profile", "x:y:" + badp, "-o", T],
               badp, 3, outdir)
    rc, out, err = run([SELFCAL, "lut", "build", "--map", good, "--profile", "q:y:" + badp, "-o", T])
    check(rc == 2, "lut build bad AXIS 'q': exit %d" % rc)
    check(not os.listdir(outdir), "lut: leftovers %r" % os.listdir(outdir))
    # a corrupt table: dump must refuse with exit 2
    rc, out, err = run([SELFCAL, "lut", "build", "--map", good, "-o", T])
    if check(rc == 0, "lut build good: exit %d %s" % (rc, err.strip())):
        data = bytearray(open(T, "rb").read())
        data[len(data) // 2] ^= 0x10
        cp = os.path.join(d, "corrupt.lut")
        open(cp, "wb").write(bytes(data))
        rc, out, err = run([SELFCAL, "lut", "dump", cp])
        check(rc == 2, "lut dump of a corrupt table: exit %d, SPEC: 2 (bad input)" % rc)
        check(len([l for l in err.splitlines() if l.strip()]) == 1 and "corrupt.lut" in err,
              "lut dump corrupt: one stderr line naming the file: %r" % err)


grid_cases()
profile_cases()
lut_cases()
finish("spec_errors")
