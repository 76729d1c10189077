#!/usr/bin/env python3
"""Firmware exports (klipper, marlin, reprap) through the command line, checked by applying each
firmware's own formula to the values the file gives it:

  Klipper  klippy/extras/skew_correction.py: xy_factor = calc_skew_factor(AC, BD, AD) from
           `SET_SKEW XY=AC,BD,AD`; moves go to (x - y * xy_factor, y);
  Marlin   M852 I: planner skew(): (x - y * I, y);
  RRF      M556 S X: tanXY = X / S; Move::AxisTransform: (x + tanXY * y, y);
  scale    M92 steps/mm (Marlin, RRF) or rotation_distance (Klipper): the motor travel per
           commanded mm is new/old steps (old/new rotation_distance).

The firmware's correction (motor target - target) is compared with the map G (position mode: the
motors must go to t + G(t)) at the nodes and cell middles; the residual, after removing the
translation, rotation and magnification a self-calibrated map does not define, must be the part of
the map that is not first order (computed here by an independent least-squares fit), and must
equal what the exporter reports. Bad input: a map beyond the firmwares' limits, options that do
not apply: exit 2, one stderr line, no file.

usage: test_firmware.py SELFCAL_CLI WORKDIR"""
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from exportlib import Export  # noqa: E402

cli, work = sys.argv[1], sys.argv[2]
E = Export(cli, work)
check, run = E.check, E.run


def write_map(name, n, pitch, O, R, F_um=0.0, gauge=(0.3, -0.2, 1e-5, 2e-5)):
    """n x n map centred on (5, -3) mm: G = first order (O, R) + gauge terms + F (um)."""
    tx, ty, th, mg = gauge
    c = (n - 1) / 2
    x0, y0 = 5.0, -3.0
    nodes = {}
    path = os.path.join(work, name)
    with open(path, "w") as f:
        f.write("i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n")
        for i in range(n):
            for j in range(n):
                u, v = (j - c) * pitch, (i - c) * pitch       # from the grid centre, mm
                x, y = x0 + u, y0 + v
                gx = 1e3 * (O * v + R * u + tx * 1e-3 - th * v + mg * u)
                gy = 1e3 * (O * u - R * v + ty * 1e-3 + th * u + mg * v)
                gx += F_um * math.sin(0.7 * u) * math.cos(0.3 * v)
                gy += F_um * math.cos(0.5 * u + 0.2 * v)
                f.write(f"{i},{j},{x:.6f},{y:.6f},{gx:.6f},{gy:.6f},,\n")
                nodes[(i, j)] = (x, y, round(gx, 6), round(gy, 6))
    return path, nodes, n


def g_at(nodes, n, pitch, x, y):
    """Bilinear G of the map as written, held at its edges beyond it (selfcald's clamping)."""
    x0, y0 = nodes[(0, 0)][0], nodes[(0, 0)][1]
    u = min(max((x - x0) / pitch, 0.0), n - 1.0)
    v = min(max((y - y0) / pitch, 0.0), n - 1.0)
    j, i = min(int(u), n - 2), min(int(v), n - 2)
    fu, fv = u - j, v - i
    out = []
    for q in (2, 3):
        out.append((1 - fv) * ((1 - fu) * nodes[(i, j)][q] + fu * nodes[(i, j + 1)][q])
                   + fv * ((1 - fu) * nodes[(i + 1, j)][q] + fu * nodes[(i + 1, j + 1)][q]))
    return out


def samples(nodes, n, pitch):
    x0, y0 = nodes[(0, 0)][0], nodes[(0, 0)][1]
    for a in range(2 * n - 1):
        for b in range(2 * n - 1):
            yield x0 + b * pitch / 2, y0 + a * pitch / 2


def remove_fit(pts, terms):
    """Least squares of the 2-D residuals pts [(x, y, rx, ry)] on the given basis terms
    (functions (x, y) -> (bx, by)); returns the rms and max of what remains (normal equations,
    Gauss-Jordan: a handful of unknowns)."""
    m = len(terms)
    A = [[0.0] * (m + 1) for _ in range(m)]
    for x, y, rx, ry in pts:
        b = [t(x, y) for t in terms]
        for p in range(m):
            for q in range(m):
                A[p][q] += b[p][0] * b[q][0] + b[p][1] * b[q][1]
            A[p][m] += b[p][0] * rx + b[p][1] * ry
    for p in range(m):
        piv = max(range(p, m), key=lambda r: abs(A[r][p]))
        A[p], A[piv] = A[piv], A[p]
        for r in range(m):
            if r != p:
                f = A[r][p] / A[p][p]
                A[r] = [A[r][k] - f * A[p][k] for k in range(m + 1)]
    coef = [A[p][m] / A[p][p] for p in range(m)]
    ss, mx = 0.0, 0.0
    for x, y, rx, ry in pts:
        b = [t(x, y) for t in terms]
        dx = rx - sum(c * bb[0] for c, bb in zip(coef, b))
        dy = ry - sum(c * bb[1] for c, bb in zip(coef, b))
        ss += dx * dx + dy * dy
        mx = max(mx, abs(dx), abs(dy))
    return math.sqrt(ss / (2 * len(pts))), mx


def gauge_terms(xc, yc):
    return [lambda x, y: (1.0, 0.0), lambda x, y: (0.0, 1.0),
            lambda x, y: (-(y - yc), x - xc), lambda x, y: (x - xc, y - yc)]


def first_order_terms(xc, yc):
    return gauge_terms(xc, yc) + [lambda x, y: (y - yc, x - xc), lambda x, y: (x - xc, -(y - yc))]


def klipper_calc_skew_factor(ac, bd, ad):
    # klippy/extras/skew_correction.py, calc_skew_factor
    side = math.sqrt(2 * ac * ac + 2 * bd * bd - 4 * ad * ad) / 2.
    return math.tan(math.pi / 2 - math.acos((ac * ac - side * side - ad * ad) / (2 * side * ad)))


def firmware_transform(fmt, text, present):
    """(shift of x per unit y, kx, ky) from the exported text, by each firmware's rules."""
    if fmt == "klipper":
        m = re.search(r"^SET_SKEW XY=([-0-9.]+),([-0-9.]+),([-0-9.]+)\s*$", text, re.M)
        check(m is not None, f"klipper: SET_SKEW line in\n{text}")
        # Klipper restarts with no skew: the saved profile must be loaded after homing
        check("SKEW_PROFILE LOAD=selfcal" in text, f"klipper: no SKEW_PROFILE LOAD in\n{text}")
        f = klipper_calc_skew_factor(*map(float, m.groups()))
        shift = -f
        if present:
            rx = float(re.search(r"\[stepper_x\] rotation_distance: ([0-9.]+)", text).group(1))
            ry = float(re.search(r"\[stepper_y\] rotation_distance: ([0-9.]+)", text).group(1))
            return shift, present[0] / rx, present[1] / ry
        m = re.search(r"multiply the rotation_distance of X by ([0-9.]+) and of Y by ([0-9.]+)",
                      text)
        return shift, 1 / float(m.group(1)), 1 / float(m.group(2))
    if fmt == "marlin":
        check(re.search(r"^G21\b", text, re.M) is not None, "marlin: G21 before M852")
        m = re.search(r"^M852 I([-0-9.]+)\s*$", text, re.M)
        check(m is not None, f"marlin: M852 line in\n{text}")
        shift = -float(m.group(1))
    else:
        m = re.search(r"^M556 S([0-9.]+) X([-0-9.]+)\s*$", text, re.M)
        check(m is not None, f"reprap: M556 line in\n{text}")
        shift = float(m.group(2)) / float(m.group(1))
    if present:
        m = re.search(r"^M92 X([0-9.]+) Y([0-9.]+)\s*$", text, re.M)
        check(m is not None, f"{fmt}: M92 line")
        return shift, float(m.group(1)) / present[0], float(m.group(2)) / present[1]
    m = re.search(r"multiply the steps/mm \(M92\) of X by ([0-9.]+) and of Y by ([0-9.]+)", text)
    return shift, float(m.group(1)), float(m.group(2))


def residual(nodes, n, pitch, shift, kx, ky, at_target=False):
    """The map where the firmware moves, G(t + c(t)), minus its correction c(t) (the error the
    stage is left with, up to sign); at_target: G(t) - c(t), what earlier versions printed."""
    pts = []
    for x, y in samples(nodes, n, pitch):
        cx = (kx * (x + shift * y) - x) * 1e3   # the firmware's correction, um
        cy = (ky * y - y) * 1e3
        if at_target:
            gx, gy = g_at(nodes, n, pitch, x, y)
        else:
            gx, gy = g_at(nodes, n, pitch, x + 1e-3 * cx, y + 1e-3 * cy)
        pts.append((x, y, gx - cx, gy - cy))
    return pts


# name, nodes, pitch mm, O, R, non-linear part um; "printer": a 200 mm bed with a 1 mrad skew
# (2 O), where the map differs between the target and where the firmware moves.
cases = [("pure", 11, 5.0, 5e-5, -3e-5, 0.0), ("with_F", 9, 6.0, -4e-5, 6e-5, 0.4),
         ("printer", 11, 20.0, 5e-4, 1e-5, 0.02)]
for name, n, pitch, O, R, F in cases:
    mp, nodes, n = write_map(f"{name}.csv", n, pitch, O, R, F)
    xc, yc = 5.0, -3.0
    # The map's own non-first-order part (independent least squares): what no skew/scale can fix.
    raw = [(x, y, *g_at(nodes, n, pitch, x, y)) for x, y in samples(nodes, n, pitch)]
    expect_rms, _ = remove_fit(raw, first_order_terms(xc, yc))
    before_rms, _ = remove_fit(raw, gauge_terms(xc, yc))
    # O and R of the map as written (least squares over the nodes, Petro eqs. 4-5); for the pure
    # map they are the ones it was made with.
    su = {k: 0.0 for k in ("xgx", "ygx", "xgy", "ygy", "xx", "yy")}
    for (x, y, gx, gy) in nodes.values():
        u, v = x - xc, y - yc
        su["xgx"] += u * gx
        su["ygx"] += v * gx
        su["xgy"] += u * gy
        su["ygy"] += v * gy
        su["xx"] += u * u
        su["yy"] += v * v
    mO = 0.5e-3 * (su["ygx"] / su["yy"] + su["xgy"] / su["xx"])
    mR = 0.5e-3 * (su["xgx"] / su["xx"] - su["ygy"] / su["yy"])
    if F == 0:
        check(abs(mO - O) < 1e-10 and abs(mR - R) < 1e-10, f"{name}: O, R of the map {mO}, {mR}")
    O, R = mO, mR
    for fmt in ("klipper", "marlin", "reprap"):
        for present in (None, (80.0, 80.0) if fmt != "klipper" else (40.0, 32.0)):
            out = os.path.join(work, f"{name}_{fmt}{'_abs' if present else ''}.txt")
            args = ["--format", fmt, "--map", mp, "-o", out]
            if present:
                args += ["--steps-per-mm" if fmt != "klipper" else "--rotation-distance",
                         f"{present[0]},{present[1]}"]
            rc, so, se = run(*args)
            check(rc == 0, f"{name} {fmt}: exit {rc}: {se}")
            if rc != 0:
                continue
            text = open(out).read()
            shift, kx, ky = firmware_transform(fmt, text, present)
            # The firmware's skew is 2 O of x per y, its scale 1 + R / 1 - R (first order).
            check(abs(shift - 2 * O) < 1e-8, f"{name} {fmt}: x shift per y {shift}, want {2 * O}")
            check(abs(kx - 1 - R) < 1e-8 and abs(ky - 1 + R) < 1e-8,
                  f"{name} {fmt}: scale {kx}, {ky}, want {1 + R}, {1 - R}")
            rms, mx = remove_fit(residual(nodes, n, pitch, shift, kx, ky), gauge_terms(xc, yc))
            at_t, _ = remove_fit(residual(nodes, n, pitch, shift, kx, ky, True), gauge_terms(xc, yc))
            if name != "printer":
                # small maps: the moved position changes nothing that shows
                check(abs(rms - expect_rms) <= 2e-4,
                      f"{name} {fmt}: residual rms {rms:.6f} um, the map's non-first-order part "
                      f"{expect_rms:.6f} um")
            else:
                print(f"{name} {fmt}{' (present values)' if present else ''}: residual where the "
                      f"firmware moves rms {rms:.4f} um, max {mx:.4f} um; at the target rms "
                      f"{at_t:.4f} um")
                check(abs(rms - at_t) > 0.1 * at_t,
                      f"{name} {fmt}: the moved position must matter here ({rms} vs {at_t})")
            check(rms < (0.01 if F == 0 else 0.6) * before_rms,
                  f"{name} {fmt}: the correction must remove the first order: {rms} vs {before_rms}")
            # The opposite sign must not pass: it doubles the first order instead.
            bad, _ = remove_fit(residual(nodes, n, pitch, -shift, 2 - kx, 2 - ky),
                                gauge_terms(xc, yc))
            check(bad > 1.5 * before_rms, f"{name} {fmt}: the wrong sign would not show ({bad})")
            m = re.search(r"residual .* rms ([0-9.]+) um, max ([0-9.]+) um", so)
            check(m is not None, f"{name} {fmt}: report line in {so!r}")
            if m:
                # The exporter samples 4 x 4 per cell, this test 2 x 2: same field, close rms.
                check(abs(float(m.group(1)) - rms) <= 0.15 * rms + 2e-4,
                      f"{name} {fmt}: reported rms {m.group(1)} vs {rms:.6f}")
            mo = re.search(r"O = ([-0-9.e]+), R = ([-0-9.e]+)", so)
            check(mo is not None and abs(float(mo.group(1)) - O) < 1e-9
                  and abs(float(mo.group(2)) - R) < 1e-9, f"{name} {fmt}: O, R reported: {so}")
    print(f"{name}: map beyond first order {expect_rms:.4f} um rms (before correction "
          f"{before_rms:.4f} um); firmware residuals agree")

# Beyond the firmwares' limits: a 'map' with 2 O > 1 (an axis at more than 45 degrees).
mp, _, _ = write_map("absurd.csv", 5, 1.0, 0.6, 0.0)
for fmt in ("klipper", "marlin", "reprap"):
    out = os.path.join(work, f"absurd_{fmt}.txt")
    if os.path.exists(out):
        os.remove(out)
    rc, so, se = run("--format", fmt, "--map", mp, "-o", out)
    check(rc == 2 and len(se.strip().splitlines()) == 1 and "first order" in se
          and not os.path.exists(out), f"absurd map {fmt}: exit {rc}, {se!r}")
# Options that do not apply: exit 2, one line.
mp = os.path.join(work, "pure.csv")
for args in (["--format", "marlin", "--negate"], ["--format", "klipper", "--axis", "x"],
             ["--format", "reprap", "--rotation-distance", "40,40"],
             ["--format", "klipper", "--steps-per-mm", "80,80"],
             ["--format", "marlin", "--steps-per-mm", "80"],
             ["--format", "marlin", "--steps-per-mm", "-80,80"]):
    rc, so, se = run(*args, "--map", mp, "-o", os.path.join(work, "never.txt"))
    check(rc == 2 and len(se.strip().splitlines()) == 1, f"{args}: exit {rc}, {se!r}")
check(not os.path.exists(os.path.join(work, "never.txt")), "no file for refused options")
rc, so, se = run("--format", "klipper", "--map", os.path.join(work, "missing.csv"), "-o",
                 os.path.join(work, "never.txt"))
check(rc == 2 and "missing.csv" in se, f"missing map: {rc} {se!r}")

E.finish("firmware exports")
