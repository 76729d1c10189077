"""Calibrate a simulated XY stage from Python, as a user would in Jupyter.

Simulate a 25 x 25 plate measured in Petrò's four views, check the plan, separate the stage
error G from the plate error A by least squares, compare with the truth, build a correction
table from the arrays, correct positions through it, and draw the map with matplotlib when it
is installed.

    pip install ./python            # from the project root
    python examples/python/calibrate_stage.py [--plot G.png]
"""
import argparse
import os
import sys
import tempfile

import numpy as np

import selfcal

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--plot", help="save the arrow map to this image file (needs matplotlib)")
ap.add_argument("--n", type=int, default=25, help="marks per plate side (odd, >= 9)")
args = ap.parse_args()

# 1. a simulated stage and plate, measured in Petrò's double-shift plan (sigma_r = 10 nm)
meas, truth = selfcal.simulate_grid("double-shift", n=args.n, pitch_mm=1.0, sigma_r_um=0.01, seed=1)
print(meas)

# 2. does the plan identify G, and how precisely? (before touching a real plate)
a = selfcal.plan(meas.plan)
print(f"identifiable: {a.identifiable}, predicted std(G)/sigma_r: RMS {a.sigma_c_ratio_rms:.3f}, "
      f"worst {a.sigma_c_ratio_max:.3f}")

# 3. least squares: G with every node's uncertainty, the noise estimated from the residuals
r = selfcal.calibrate_grid(meas, method="lsq")
err = np.hypot(r.gx_um - truth["gx_um"], r.gy_um - truth["gy_um"])
print(f"sigma_r estimated {r.sigma_r_est_um * 1e3:.2f} nm; O = {r.O:.3g} +- {r.uO:.2g}, "
      f"R = {r.R:.3g} +- {r.uR:.2g}")
# the error is a 2-D vector: compare its RMS with the RMS of the vector's predicted standard
# deviation, sqrt(u(gx)^2 + u(gy)^2), not with one component's u
print(f"|G - truth|: RMS {np.sqrt(np.mean(err ** 2)) * 1e3:.2f} nm, max {err.max() * 1e3:.2f} nm; "
      f"predicted (k = 1) RMS {np.sqrt(np.mean(r.ugx_um ** 2 + r.ugy_um ** 2)) * 1e3:.2f} nm")

# 4. a correction table from the arrays, and positions corrected through it (as selfcald does)
with tempfile.TemporaryDirectory() as d:
    table = selfcal.build_table(os.path.join(d, "stage.lut"), r.gx_um, r.gy_um, r.x_mm[0, 0],
                                r.y_mm[0, 0], meas.plan.pitch_mm, method="lsq")
    x, y = np.meshgrid(np.linspace(-10, 10, 5), np.linspace(-10, 10, 5))
    xc, yc, status = table.apply(x, y, mode="measure")
    print(f"{table}: corrected a 5 x 5 raster, largest shift {np.max(np.hypot(xc - x, yc - y)) * 1e3:.2f} µm")

# 5. the arrow map
if args.plot:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit("matplotlib is not installed: pip install matplotlib")
    fig, ax = plt.subplots(figsize=(6, 6))
    q = ax.quiver(r.x_mm, r.y_mm, r.gx_um, r.gy_um, np.hypot(r.gx_um, r.gy_um), angles="xy")
    ax.quiverkey(q, 0.85, 1.02, 1.0, "1 µm", labelpos="E")
    ax.set(xlabel="x (mm)", ylabel="y (mm)", title="stage error G (least squares)", aspect="equal")
    fig.savefig(args.plot, dpi=120)
    print(f"wrote {args.plot}")
