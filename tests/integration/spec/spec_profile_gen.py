"""Independent simulation of selfcal-profile v1 input from SPEC §2's model equations."""
import math
import random


def simulate(n, s_mm, d1, d2, seed, noise_disp=0.0, noise_ang=0.0):
    """f, e_y (um), and scans {k: [(n, m1_um, m2_um, m3_urad)]} per SPEC §2 (Ding eqs. 1-3)."""
    rng = random.Random(seed)
    ph = [rng.uniform(0, 6.28) for _ in range(8)]
    f = [0.3 * math.sin(2 * math.pi * 1.3 * k / n + ph[0]) + 0.05 * math.sin(2 * math.pi * 7.1 * k / n + ph[1])
         + 0.01 * rng.gauss(0, 1) + 2e-3 * k for k in range(n)]
    ey = [0.2 * math.cos(2 * math.pi * 0.7 * k / n + ph[2]) + 0.02 * rng.gauss(0, 1) + 1e-3 * k for k in range(n)]
    ep = [3.0 * math.sin(2 * math.pi * 1.1 * k / n + ph[3]) + 0.5 * rng.gauss(0, 1) for k in range(n)]  # urad
    u1, u2, u3, b0 = 0.11, -0.07, 2.5, 0.4  # um, um, urad, um
    scans = {}
    for k, d in ((1, d1), (2, d2)):
        D = d * s_mm
        rows = []
        for i in range(n - d):
            m1 = f[i] + ey[i] + u1 + b0 + rng.gauss(0, 1) * noise_disp
            # D[mm] * e_p[urad] is in nm: /1000 for um
            m2 = f[i + d] + ey[i] + D * ep[i] / 1000.0 + u2 + b0 + rng.gauss(0, 1) * noise_disp
            m3 = ep[i] + u3 + rng.gauss(0, 1) * noise_ang
            rows.append((i, m1, m2, m3))
        scans[k] = rows
    return f, ey, scans


def profile_lines(n, s_mm, d1, d2, scans, extra=(), shuffle_seed=None):
    lines = [(k, r) for k in (1, 2) for r in scans[k]]
    if shuffle_seed is not None:
        random.Random(shuffle_seed).shuffle(lines)
    out = ["# selfcal-profile v1", "# N = %d" % n, "# s_mm = %r" % float(s_mm), "# scan 1: d=%d" % d1, "# scan 2: d=%d" % d2]
    out += list(extra)
    out.append("scan,n,m1_um,m2_um,m3_urad")
    out += ["%d,%d,%.15g,%.15g,%.15g" % (k, i, m1, m2, m3) for k, (i, m1, m2, m3) in lines]
    return out


def write_profile(path, n, s_mm, d1, d2, scans, extra=(), shuffle_seed=None):
    with open(path, "w") as fh:
        fh.write("\n".join(profile_lines(n, s_mm, d1, d2, scans, extra, shuffle_seed)) + "\n")


def simulate_profile_lines(n, s_mm, d1, d2, seed):
    f, ey, scans = simulate(n, s_mm, d1, d2, seed)
    return profile_lines(n, s_mm, d1, d2, scans)
