#!/usr/bin/env python3
"""SPEC §2 conformance (black box): selfcal profile on selfcal-profile v1 files written here from
the SPEC's model equations; output columns, f relative to its LS line, e_y, uncertainties.

usage: spec_profile.py SELFCAL TMPDIR {recover|sigma}
"""
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from spec_common import *  # noqa
from spec_profile_gen import simulate, write_profile  # noqa

SELFCAL, BASE, MODE = sys.argv[1], sys.argv[2], sys.argv[3]
OUT_COLS = ["n", "x_mm", "f_um", "uf_um", "ey_um"]


def read_out(path, label):
    comments, header, rows = read_csv(path)
    check(header == OUT_COLS, "%s: output header %r, SPEC says %r" % (label, header, OUT_COLS))
    return rows


def recover(method, n, s_mm, d1, d2, seed, shuffle=False):
    label = "profile %s N=%d d=%d/%d" % (method, n, d1, d2)
    d = tmpdir(BASE, "prof")
    f, ey, scans = simulate(n, s_mm, d1, d2, seed)
    inp, out = os.path.join(d, "in.csv"), os.path.join(d, "P.csv")
    write_profile(inp, n, s_mm, d1, d2, scans, shuffle_seed=seed if shuffle else None)
    rc, o, e = run([SELFCAL, "profile", "--method", method, inp, "--out", out])
    if not check(rc == 0, "%s: exit %d %s" % (label, rc, e.strip())):
        return
    rows = read_out(out, label)
    check(len(rows) == n, "%s: %d rows, want N=%d" % (label, len(rows), n))
    if len(rows) != n:
        return
    xs = [k * s_mm for k in range(n)]
    fref = ls_line_residual(xs, f)
    m = n - d1
    eyref = ls_line_residual(xs[:m], ey[:m])
    ef = eey = 0.0
    for k, r in enumerate(rows):
        if not check(int(r["n"]) == k and abs(float(r["x_mm"]) - k * s_mm) < 1e-9,
                     "%s: row %d has n=%s x_mm=%s (want x = n*s)" % (label, k, r["n"], r["x_mm"])):
            return
        ef = max(ef, abs(float(r["f_um"]) - fref[k]))
        if r["uf_um"] != "":
            check(float(r["uf_um"]) >= 0, "%s: negative uf" % label)
        if k >= m:
            check(r["ey_um"] == "", "%s: ey_um at n=%d >= N-d1 should be empty, got %r" % (label, k, r["ey_um"]))
        else:
            if r["ey_um"] == "":
                check(False, "%s: ey_um empty at n=%d < N-d1" % (label, k))
            else:
                eey = max(eey, abs(float(r["ey_um"]) - eyref[k]))
    check(ef <= 1e-8, "%s: max |f - truth (minus LS line)| = %g um" % (label, ef))
    check(eey <= 1e-8, "%s: max |ey - truth (minus LS line over scan 1)| = %g um" % (label, eey))
    print("%-36s f err %.2e um, ey err %.2e um" % (label, ef, eey))


def test_recover():
    recover("dft", 110, 1.0, 10, 11, 1)
    recover("lsq", 110, 1.0, 10, 11, 2, shuffle=True)
    recover("dft", 66, 0.5, 2, 3, 3, shuffle=True)
    recover("lsq", 97, 2.0, 3, 7, 4)  # N not a multiple of d1*d2: least squares only
    recover("dft", 110, 1.0, 11, 10, 5)  # scan 1 has the larger spacing: ey empty from N - 11
    recover("lsq", 110, 1.0, 11, 10, 6)


def test_simulate():
    """selfcal simulate profile writes a valid selfcal-profile v1 file (independent parser)."""
    d = tmpdir(BASE, "simprof")
    inp, tr = os.path.join(d, "in.csv"), os.path.join(d, "truth.csv")
    rc, o, e = run([SELFCAL, "simulate", "profile", "--n", "120", "--s-mm", "0.5", "--d1", "7", "--d2", "9",
                    "--out", inp, "--truth", tr])
    if not check(rc == 0, "simulate profile: exit %d %s" % (rc, e.strip())):
        return
    with open(inp) as fh:
        lines = [l.rstrip("\n") for l in fh]
    check(lines[0] == "# selfcal-profile v1", "simulate profile: first line %r" % lines[0])
    k = 1
    hdr = {}
    while lines[k].startswith("#"):
        m = re.match(r"^# (N|s_mm|sigma_disp_um|sigma_angle_urad) = (\S+)$", lines[k]) or re.match(r"^# scan ([12]): d=(\d+)$", lines[k])
        if check(m is not None, "simulate profile: header line %r not in SPEC form" % lines[k]):
            hdr[m.group(1)] = m.group(2)
        k += 1
    check(hdr.get("N") == "120" and float(hdr.get("s_mm", "nan")) == 0.5 and hdr.get("1") == "7" and hdr.get("2") == "9",
          "simulate profile: header %r" % hdr)
    check(lines[k] == "scan,n,m1_um,m2_um,m3_urad", "simulate profile: column header %r" % lines[k])
    seen = {1: set(), 2: set()}
    for l in lines[k + 1:]:
        f = l.split(",")
        check(len(f) == 5 and all(math.isfinite(float(v)) for v in f[2:]), "simulate profile: row %r" % l)
        seen[int(f[0])].add(int(f[1]))
    check(seen[1] == set(range(120 - 7)) and seen[2] == set(range(120 - 9)), "simulate profile: samples n = 0..N-d_k-1")
    _, header, rows = read_csv(tr)
    check(header == OUT_COLS, "simulate profile truth: header %r" % header)
    rc, o, e = run([SELFCAL, "profile", "--method", "lsq", inp, "--out", os.path.join(d, "P.csv")])
    check(rc == 0, "profile on simulated input: exit %d %s" % (rc, e.strip()))


def ls_uncertainty(n, s_mm, d1, d2, sd, sa):
    """Independent dense constrained LS covariance (SPEC weights 1/(2 sd^2 + (D_k sa)^2))."""
    m = n + 2  # f(0..n-1), c1, c2
    NTN = [[0.0] * m for _ in range(m)]
    for k, d in ((0, d1), (1, d2)):
        D = d * s_mm
        var = 2 * sd * sd + (D * sa / 1000.0) ** 2
        w = 1.0 / var
        for i in range(n - d):
            row = {i + d: 1.0, i: -1.0, n + k: 1.0}
            for a, va in row.items():
                for b, vb in row.items():
                    NTN[a][b] += w * va * vb
    # KKT with constraints sum f = 0, sum x f = 0
    K = [r + [0.0, 0.0] for r in NTN] + [[0.0] * (m + 2), [0.0] * (m + 2)]
    for i in range(n):
        K[m][i] = K[i][m] = 1.0
        K[m + 1][i] = K[i][m + 1] = i * s_mm
    inv = invert_dense(K)
    return [math.sqrt(max(0.0, inv[i][i])) for i in range(n)]


def test_sigma():
    n, s_mm, d1, d2 = 40, 1.0, 3, 5
    sd, sa = 0.01, 2.0
    d = tmpdir(BASE, "profsig")
    f, ey, scans = simulate(n, s_mm, d1, d2, 7, noise_disp=0.003, noise_ang=0.5)
    ref = ls_uncertainty(n, s_mm, d1, d2, sd, sa)
    # header sigma lines
    inp = os.path.join(d, "in.csv")
    write_profile(inp, n, s_mm, d1, d2, scans, extra=["# sigma_disp_um = %r" % sd, "# sigma_angle_urad = %r" % sa])
    out = os.path.join(d, "P.csv")
    rc, o, e = run([SELFCAL, "profile", "--method", "lsq", inp, "--out", out])
    if check(rc == 0, "profile sigma header: exit %d %s" % (rc, e.strip())):
        rows = read_out(out, "sigma header")
        u = [float(r["uf_um"]) for r in rows]
        err = max(abs(a - b) / b for a, b in zip(u, ref))
        check(err < 1e-6, "profile lsq uf with header sigmas vs independent dense covariance: rel err %g" % err)
        print("uf (header sigmas) vs independent covariance: max rel err %.2e; mid uf %.5f um" % (err, u[n // 2]))
    # command line wins over the header: double both sigmas -> uf doubles
    out2 = os.path.join(d, "P2.csv")
    rc, o, e = run([SELFCAL, "profile", "--method", "lsq", inp, "--out", out2,
                    "--sigma-disp-um", repr(2 * sd), "--sigma-angle-urad", repr(2 * sa)])
    if check(rc == 0, "profile sigma override: exit %d %s" % (rc, e.strip())):
        u2 = [float(r["uf_um"]) for r in read_out(out2, "sigma override")]
        err = max(abs(a - 2 * b) / (2 * b) for a, b in zip(u2, ref))
        check(err < 1e-6, "profile lsq uf with CLI sigmas (2x header) vs independent: rel err %g" % err)
    # changing only the angle noise changes the weights: compare with independent covariance
    out3 = os.path.join(d, "P3.csv")
    rc, o, e = run([SELFCAL, "profile", "--method", "lsq", inp, "--out", out3, "--sigma-angle-urad", "20"])
    if check(rc == 0, "profile sigma angle override: exit %d %s" % (rc, e.strip())):
        ref3 = ls_uncertainty(n, s_mm, d1, d2, sd, 20.0)
        u3 = [float(r["uf_um"]) for r in read_out(out3, "sigma angle override")]
        err = max(abs(a - b) / b for a, b in zip(u3, ref3))
        check(err < 1e-6, "profile lsq uf with header sd + CLI angle sigma: rel err %g" % err)
    # no sigma anywhere: estimated from the residuals (one sigma for y_1 and y_2, equal weights):
    # sigma^2 = RSS / (number of y - (N + 2) + 2); uf = sigma * sqrt(diag of the unit-weight covariance)
    inp4 = os.path.join(d, "in4.csv")
    write_profile(inp4, n, s_mm, d1, d2, scans)
    out4 = os.path.join(d, "P4.csv")
    rc, o, e = run([SELFCAL, "profile", "--method", "lsq", inp4, "--out", out4])
    if check(rc == 0, "profile no sigma: exit %d %s" % (rc, e.strip())):
        rows4 = read_out(out4, "sigma estimated")
        u4 = [r["uf_um"] for r in rows4]
        if check(all(x != "" and float(x) > 0 for x in u4), "profile: uf from estimated noise not all positive"):
            yk = {}
            for k, dk in ((1, d1), (2, d2)):
                yk[k] = [m2 - m1 - dk * s_mm * m3 / 1000.0 for (_, m1, m2, m3) in scans[k]]
            fhat = [float(r["f_um"]) for r in rows4]
            rss = 0.0
            for k, dk in ((1, d1), (2, d2)):
                diffs = [yk[k][i] - (fhat[i + dk] - fhat[i]) for i in range(n - dk)]
                ck = sum(diffs) / len(diffs)  # the LS zero-point c_k given f
                rss += sum((v - ck) ** 2 for v in diffs)
            dof = (n - d1) + (n - d2) - n
            sig = math.sqrt(rss / dof)
            # unit weights: ls_uncertainty with 2 sd^2 + (D sa)^2 = 1 for both scans
            ref4 = ls_uncertainty(n, s_mm, d1, d2, math.sqrt(0.5), 0.0)
            err = max(abs(float(a) / (sig * b) - 1) for a, b in zip(u4, ref4))
            check(err < 1e-6, "profile lsq uf with the noise estimated from residuals: rel err %g (sigma_y %.4g um)" % (err, sig))
            print("uf (estimated sigma_y = %.5f um) vs independent: max rel err %.2e" % (sig, err))


{"recover": test_recover, "sigma": test_sigma, "simulate": test_simulate}[MODE]()
finish("spec_profile " + MODE)
