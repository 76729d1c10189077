"""Grid self-calibration from Python: recovery against simulated truth, equality with the
command line on the same files, plans, errors."""
import json
import math
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import selfcal
from conftest import Cli, read_csv


@pytest.mark.parametrize("method", ["lsq", "double-shift", "ye"])
def test_noise_free_recovery(method: str) -> None:
    plan = "ye" if method == "ye" else "double-shift"
    m, truth = selfcal.simulate_grid(plan, n=11, sigma_r_um=0.0, seed=4)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # noise-free data flag nothing
        r = selfcal.calibrate_grid(m, method=method)
    assert r.gx_um.shape == (11, 11) and r.ax_um.shape == (11, 11)
    assert np.max(np.abs(r.gx_um - truth["gx_um"])) < 1e-9
    assert np.max(np.abs(r.gy_um - truth["gy_um"])) < 1e-9
    assert np.max(np.abs(r.ax_um - truth["ax_um"])) < 1e-9
    assert abs(r.O - truth["O"]) < 1e-12 and abs(r.R - truth["R"]) < 1e-12
    assert abs(r.O_urad - truth["O_urad"]) < 1e-6 and abs(r.R_ppm - truth["R_ppm"]) < 1e-6
    assert r.O_urad == pytest.approx(r.O * 1e6) and r.R_ppm == pytest.approx(r.R * 1e6)
    assert np.isnan(r.ugx_um).all() == (method != "lsq")


def test_first_order_terms_in_urad_and_ppm() -> None:
    m, truth = selfcal.simulate_grid("double-shift", n=9, sigma_r_um=0.0, seed=3, O_urad=12.0,
                                     R_ppm=-4.0)
    assert truth["O_urad"] == pytest.approx(12.0) and truth["R_ppm"] == pytest.approx(-4.0)
    assert truth["O"] == pytest.approx(12e-6)
    r = selfcal.calibrate_grid(m, method="lsq")
    assert r.O_urad == pytest.approx(12.0, abs=1e-6) and r.R_ppm == pytest.approx(-4.0, abs=1e-6)
    assert np.isfinite(r.uO_urad) and r.uO_urad == pytest.approx(r.uO * 1e6)
    with pytest.raises(TypeError):
        selfcal.simulate_grid("ye", n=5, O=1e-5, O_urad=10.0)


def test_stitched_stage_and_missing_mark_in_memory() -> None:
    m, truth = selfcal.simulate_grid("stitch", n=7, stage=(13, 11), sigma_r_um=0.0, seed=2)
    assert m.plan.stage == (13, 11)
    m.x_mm[:, 2, 3] = np.nan  # a damaged mark, in every view
    m.y_mm[:, 2, 3] = np.nan
    a = selfcal.plan(m)
    assert a.identifiable and a.free == 0 and a.sigma_ratio_gx.shape == (11, 13)
    r = selfcal.calibrate_grid(m)
    assert r.gx_um.shape == (11, 13)
    assert np.max(np.abs(r.gx_um - truth["gx_um"])) < 1e-9
    assert np.isnan(r.ax_um[2, 3]) and np.isfinite(r.ax_um[0, 0])
    # a damaged corner mark leaves the stage's corner node unmeasured: not identifiable
    m.x_mm[:, 1, 1] = m.y_mm[:, 1, 1] = np.nan
    b = selfcal.plan(m)
    assert not b.identifiable and b.free > 0


def test_hundreds_of_views(tmp_path: Path) -> None:
    """363 placements (no fixed cap on views): simulated, written, read, analysed, calibrated."""
    m, truth = selfcal.simulate_grid("stitch", n=3, stage=(21, 21), sigma_r_um=0.0, seed=4)
    assert len(m.plan.views) == 363 and m.x_mm.shape == (363, 3, 3)
    f = tmp_path / "many.csv"
    m.write(f)
    back = selfcal.read_grid(str(f))
    assert len(back.plan.views) == 363
    assert np.allclose(back.x_mm, m.x_mm, atol=1e-12, equal_nan=True)
    assert selfcal.plan(back).identifiable
    r = selfcal.calibrate_grid(back)
    assert np.max(np.abs(r.gx_um - truth["gx_um"])) < 1e-9
    assert len(r.tx_um) == 363
    assert np.max(np.abs(np.asarray(r.tx_um) - truth["tx_um"])) < 1e-9


def test_progress_and_memory() -> None:
    """The progress callback sees every phase; a memory limit below the estimate refuses."""
    m, _ = selfcal.simulate_grid("stitch", n=9, stage=(29, 29), seed=3)
    seen = []
    r = selfcal.calibrate_grid(m, progress=lambda ph, done, tot, peak: seen.append((ph, done, tot, peak)))
    phases = [p for p, *_ in seen]
    for want in ("assemble", "analyse", "factor", "selected inverse", "solve", "residuals"):
        assert want in phases
    assert phases.index("assemble") < phases.index("factor") < phases.index("solve")
    assert all(peak > 0 for p, d, t, peak in seen if p != "residuals")
    assert any(t > 0 and d == t for p, d, t, peak in seen)
    assert np.isfinite(r.gx_um).all()
    with pytest.raises(MemoryError, match="needs about"):
        selfcal.calibrate_grid(m, max_memory=65536)

    def boom(*a: object) -> None:
        raise KeyError("stop")
    with pytest.raises(KeyError):
        selfcal.calibrate_grid(m, progress=boom)


def test_plan_analysis_matches_cli(cli: Cli, tmp_path: Path) -> None:
    p = selfcal.GridPlan(9, 1.0, [dict(rot=0), dict(rot=90)])
    a = selfcal.plan(p)
    assert not a.identifiable and a.free == (81 - 5) // 2 and a.sigma_c_ratio_rms == np.inf
    m, _ = selfcal.simulate_grid("double-shift", n=13)
    f = tmp_path / "in.csv"
    m.write(f)
    out = cli("plan", f).stdout
    lines = dict(l.split(": ", 1) for l in out.splitlines() if ": " in l)
    b = selfcal.plan(str(f))
    assert lines["identifiable"] == "yes" and b.identifiable
    assert int(lines["free"]) == b.free == 0
    assert float(lines["sigma_c_ratio_rms"]) == pytest.approx(b.sigma_c_ratio_rms, rel=1e-5)
    assert float(lines["sigma_c_ratio_max"]) == pytest.approx(b.sigma_c_ratio_max, rel=1e-5)
    assert int(lines["testable_equations"]) == b.n_testable
    assert int(lines["untestable_equations"]) == b.n_untestable
    for key in ("redundancy_min", "redundancy_mean", "mdb_ratio_max", "mdb_ratio_mean_r"):
        assert float(lines[key]) == pytest.approx(getattr(b, key), rel=1e-5)
    assert np.isnan(a.redundancy_min) and a.n_testable == 0  # not identifiable: no figures
    assert np.isnan(b.sigma_c_rms_um) and "sigma_c_rms_um" not in lines  # nothing stated


def test_plan_with_stated_uncertainties(cli: Cli, tmp_path: Path) -> None:
    """Views stating sigma_um: the ratios stay the geometry's (equal weights), std(G) in µm is
    given apart, and equals ratio x sigma when every view states the same sigma."""
    text = ("# selfcal-grid v1\n# N = 9\n# pitch_mm = 1\n"
            "# view 0: rot=0 shift=0,0 sigma_um=%s\n# view 1: rot=90 shift=0,0 sigma_um=%s\n"
            "# view 2: rot=0 shift=1,0 sigma_um=%s\n")
    plain = tmp_path / "plain.csv"
    plain.write_text((text % (1, 1, 1)).replace(" sigma_um=1", ""))
    base = selfcal.plan(str(plain))
    for sig, name in (((0.01, 0.01, 0.01), "same.csv"), ((0.01, 0.01, 0.03), "mixed.csv")):
        f = tmp_path / name
        f.write_text(text % sig)
        a = selfcal.plan(str(f))
        lines = dict(l.split(": ", 1) for l in cli("plan", f).stdout.splitlines() if ": " in l)
        assert a.sigma_c_ratio_rms == pytest.approx(base.sigma_c_ratio_rms, rel=1e-12)
        assert float(lines["sigma_c_ratio_rms"]) == pytest.approx(base.sigma_c_ratio_rms, rel=1e-5)
        assert float(lines["sigma_c_rms_um"]) == pytest.approx(a.sigma_c_rms_um, rel=1e-5)
        assert float(lines["sigma_c_max_um"]) == pytest.approx(a.sigma_c_max_um, rel=1e-5)
        if sig[2] == sig[0]:
            assert a.sigma_c_rms_um == pytest.approx(0.01 * base.sigma_c_ratio_rms, rel=1e-9)
            assert a.sigma_c_max_um == pytest.approx(0.01 * base.sigma_c_ratio_max, rel=1e-9)
        else:  # a noisier view: worse than all at 0.01, better than all at 0.03
            assert 0.01 * base.sigma_c_ratio_rms < a.sigma_c_rms_um < 0.03 * base.sigma_c_ratio_rms


@pytest.mark.parametrize("method", ["lsq", "double-shift"])
def test_equals_cli(cli: Cli, tmp_path: Path, method: str) -> None:
    m, _ = selfcal.simulate_grid("double-shift", n=13, sigma_r_um=0.02, seed=9)
    f = tmp_path / "in.csv"
    m.write(f)
    back = selfcal.read_grid(f)
    ok = np.isfinite(m.x_mm)
    assert np.array_equal(ok, np.isfinite(back.x_mm))
    assert np.max(np.abs(back.x_mm[ok] - m.x_mm[ok])) < 1e-12
    cli("grid", "--method", method, f, "--map", tmp_path / "G.csv", "--artifact", tmp_path / "A.csv",
        "--quiet")
    g, a = read_csv(tmp_path / "G.csv"), read_csv(tmp_path / "A.csv")
    r = selfcal.calibrate_grid(str(f), method=method)
    i, j = g["i"].astype(int), g["j"].astype(int)
    for col in ("gx_um", "gy_um", "ugx_um", "ugy_um"):
        c, p = g[col], getattr(r, col)[i, j]
        assert np.array_equal(np.isnan(c), np.isnan(p)), col
        assert np.allclose(c[~np.isnan(c)], p[~np.isnan(p)], rtol=1e-9, atol=1e-12), col
    assert np.allclose(g["x_mm"], r.x_mm[i, j]) and np.allclose(g["y_mm"], r.y_mm[i, j])
    ia, ja = a["i"].astype(int), a["j"].astype(int)
    assert np.allclose(a["ax_um"], r.ax_um[ia, ja], rtol=1e-9, atol=1e-12)
    # the in-memory path gives the same numbers as the file path
    r2 = selfcal.calibrate_grid(m, method=method)
    assert np.allclose(r2.gx_um, r.gx_um, rtol=1e-9, atol=1e-11)


def test_weights_outliers_and_residuals(cli: Cli, tmp_path: Path) -> None:
    m, truth = selfcal.simulate_grid("double-shift", n=11, sigma_r_um=0.01, seed=3)
    m.x_mm[0, 3, 4] += 0.005  # a 5 µm blunder (500 sigma)
    with pytest.warns(UserWarning, match=r"view 0 mark \(3,4\) is an outlier"):
        r = selfcal.calibrate_grid(m)
    assert r.outlier[0, 3, 4] and r.n_flagged >= 1
    assert abs(r.tx[0, 3, 4]) > r.outlier_crit
    # the test it ran: 0.05 for the whole data set by default, Baarda's alpha0 on request
    assert r.outlier_alpha == 0.05 and not r.outlier_alpha_each
    nt = int(np.isfinite(r.tx).sum() + np.isfinite(r.ty).sum())
    assert r.n_outlier_tests == nt
    assert math.isclose(math.erfc(r.outlier_crit / math.sqrt(2)), 1 - 0.95 ** (1 / nt),
                        rel_tol=1e-9)
    with pytest.warns(UserWarning, match="alpha = 0.001 for each coordinate"):
        r_each = selfcal.calibrate_grid(m, outlier_alpha_each=0.001)
    assert r_each.outlier_alpha_each and abs(r_each.outlier_crit - 3.2905267314919) < 1e-9
    t_max = np.fmax(np.abs(np.nan_to_num(r_each.tx)), np.abs(np.nan_to_num(r_each.ty)))
    assert np.array_equal(r_each.outlier, t_max > r_each.outlier_crit)
    for bad in ({"outlier_alpha": 0}, {"outlier_alpha": 1.5}, {"outlier_alpha_each": -1},
                {"outlier_alpha": 0.1, "outlier_alpha_each": 0.1}, {"view_noise": "guess"},
                {"view_noise": "estimate", "sigma_r_um": 0.01}):
        with pytest.raises(selfcal.Error):
            selfcal.calibrate_grid(m, **bad)
    with pytest.warns(UserWarning, match="removed outlier view 0 mark"):
        rr = selfcal.calibrate_grid(m, reject_outliers=True)
    assert rr.n_removed >= 1
    assert np.max(np.abs(rr.gx_um - truth["gx_um"])) < 6 * np.max(rr.ugx_um)
    # the same flags as the command line's residual file
    f = tmp_path / "o.csv"
    m.write(f)
    cli("grid", "--method", "lsq", f, "--map", tmp_path / "G.csv", "--residuals",
        tmp_path / "R.csv", "--quiet")
    res = read_csv(tmp_path / "R.csv")
    flagged = {(int(v), int(i), int(j)) for v, i, j, o in
               zip(res["view"], res["i"], res["j"], res["outlier"]) if o == 1}
    assert flagged == {tuple(int(x) for x in k) for k in zip(*np.nonzero(r.outlier))}
    # stated weights: uncertainties follow them
    m2, _ = selfcal.simulate_grid("double-shift", n=11, sigma_r_um=0.01, seed=5)
    m2.ux_um = np.where(np.isfinite(m2.x_mm), 0.01, np.nan)
    m2.uy_um = m2.ux_um.copy()
    w = selfcal.calibrate_grid(m2)
    assert w.weighted and w.chi2_pass and 0.5 < w.variance_factor < 1.5


def test_covariance() -> None:
    m, _ = selfcal.simulate_grid("ye", n=5, sigma_r_um=0.01)
    r = selfcal.calibrate_grid(m, sigma_r_um=0.01, covariance=True)
    c = r.covariance_um2
    assert c is not None
    assert c.shape == (50, 50) and np.allclose(c, c.T)
    assert np.allclose(np.sqrt(np.diag(c))[0::2], r.ugx_um.reshape(-1), rtol=1e-6)


def test_errors(cli: Cli, tmp_path: Path) -> None:
    with pytest.raises(selfcal.Error, match="missing.csv"):
        selfcal.read_grid(tmp_path / "missing.csv")
    m, _ = selfcal.simulate_grid("ye", n=9)
    with pytest.raises(selfcal.Error, match="double-shift needs"):
        selfcal.calibrate_grid(m, method="double-shift")
    with pytest.raises(selfcal.Error):
        selfcal.GridPlan(8, 1.0, [dict(rot=0)])  # N even
    with pytest.raises(selfcal.Error, match="shape"):
        selfcal.calibrate_grid(selfcal.GridMeasurement(m.plan, m.x_mm[:2], m.y_mm[:2]))
    bad = tmp_path / "bad.csv"
    m.write(bad)
    lines = bad.read_text().splitlines()
    lines[-1] = lines[-1].rsplit(",", 1)[0] + ",abc"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(selfcal.Error) as e:
        selfcal.calibrate_grid(str(bad))
    p = cli("grid", "--method", "lsq", bad, "--map", tmp_path / "G.csv", check=False)
    assert p.returncode == 2 and p.stderr.strip() == str(e.value)
    assert str(e.value).startswith(f"selfcal: {bad}:{len(lines)}: ")
    with pytest.raises(selfcal.Error, match="do not identify G"):
        selfcal.calibrate_grid(selfcal.simulate_grid(selfcal.GridPlan(9, 1.0, [dict(rot=0), dict(rot=90)]))[0])
    # bad input in memory is refused as the file reader refuses it (stop 27's audit)
    x, y = m.x_mm.copy(), m.y_mm.copy()
    x[0, 3, 3] = y[0, 3, 3] = np.inf
    with pytest.raises(selfcal.Error, match="infinite"):
        selfcal.calibrate_grid(selfcal.GridMeasurement(m.plan, x, y))
    x, y = m.x_mm.copy(), m.y_mm.copy()
    j = int(np.argwhere(np.isnan(x[2]))[0][1]) if np.isnan(x[2]).any() else None
    if j is not None:  # view 2 (shift +1) leaves a column of the plate off the stage
        i = int(np.argwhere(np.isnan(x[2]))[0][0])
        x[2, i, j], y[2, i, j] = 123.0, -5.0
        with pytest.raises(selfcal.Error, match="does not place that mark"):
            selfcal.calibrate_grid(selfcal.GridMeasurement(m.plan, x, y))
    u = np.full(m.x_mm.shape, 0.01)
    u2 = u.copy()
    u2[0, 4, 4] = -0.01
    with pytest.raises(selfcal.Error, match="not positive"):
        selfcal.calibrate_grid(selfcal.GridMeasurement(m.plan, m.x_mm, m.y_mm, u2, u))
    bad_source: Any
    for bad_source in (5, {}):
        with pytest.raises(selfcal.Error):
            selfcal.plan(bad_source)
        with pytest.raises(selfcal.Error):
            selfcal.calibrate_grid(bad_source)
    with pytest.raises(selfcal.Error, match="method"):
        selfcal.calibrate_grid(m, method=[])  # type: ignore[arg-type]
    with pytest.raises(selfcal.Error):
        selfcal.GridPlan.standard("ye", 2**31)
    with pytest.raises(selfcal.Error):
        selfcal.GridPlan(9, 1.0, [dict(rot=2**32, shift=(0, 0))])
    with pytest.raises(selfcal.Error, match="pitch"):
        selfcal.plan(selfcal.GridPlan(9, 1e308, [dict(rot=0, shift=(0, 0)), dict(rot=90, shift=(0, 0)),
                                                 dict(rot=0, shift=(1, 0))]))
    # no χ² test without stated noise: None, as the command line's "n/a"
    assert selfcal.calibrate_grid(m).chi2_pass is None


def test_example_script_runs(tmp_path: Path) -> None:
    import os
    import subprocess
    import sys
    script = os.path.join(os.path.dirname(__file__), "..", "..", "examples", "python",
                          "calibrate_stage.py")
    p = subprocess.run([sys.executable, "-W", "ignore", script, "--n", "11"], capture_output=True,
                       text=True, timeout=300, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert "identifiable: True" in p.stdout and "corrected a 5 x 5 raster" in p.stdout


def test_view_noise_estimated(cli: Cli, tmp_path: Path) -> None:
    sig = [0.02 if v == 1 else 0.03 if v == 3 else 0.05 if v == 20 else 0.01 for v in range(22)]
    std = selfcal.GridPlan.standard("stitch", 15, 1.0, stage=(41, 31))
    plan = selfcal.GridPlan(15, 1.0, [dict(v, sigma_um=s) for v, s in zip(std.views, sig)],
                            stage=(41, 31))
    m, _ = selfcal.simulate_grid(plan, sigma_r_um=0.01, seed=5)
    f = tmp_path / "st.csv"
    m.write(f)
    text = f.read_text().splitlines(True)
    g = tmp_path / "unstated.csv"
    g.write_text("".join(re.sub(r" sigma_um=[0-9.e-]+", "", l) for l in text))
    r = selfcal.calibrate_grid(str(g), view_noise="estimate")
    assert r.view_noise_estimated and r.view_sigma_um.shape == (22,)
    assert np.all(np.abs(r.view_sigma_um / np.array(sig) - 1) < 0.25)
    assert np.all(np.isnan(r.view_noise_factor))
    assert np.all((r.view_sigma_u_um > 0.02 * r.view_sigma_um) &
                  (r.view_sigma_u_um < 0.15 * r.view_sigma_um))
    # the command line's summary gives the same estimates
    cli("grid", "--method", "lsq", g, "--map", tmp_path / "G.csv", "--summary",
        tmp_path / "S.json", "--view-noise", "estimate", "--quiet")
    s = json.loads((tmp_path / "S.json").read_text())
    assert np.allclose([v["sigma_um_est"] for v in s["views"]], r.view_sigma_um, rtol=1e-9)


def test_calibration_releases_the_gil(tmp_path: Path) -> None:
    """Other Python threads run while a grid is calibrated (and a file read): the solve and the
    readers run without the GIL. Measured as the longest pause of a thread that only counts time,
    against the calibration's own duration (held, the pause would be all of it)."""
    import threading
    import time
    m, _ = selfcal.simulate_grid("double-shift", n=101, sigma_r_um=0.01, seed=6)
    path = tmp_path / "big.csv"
    m.write(path)
    done = threading.Event()
    span = {}

    def work() -> None:
        t0 = time.perf_counter()
        selfcal.calibrate_grid(path)
        span["s"] = time.perf_counter() - t0
        done.set()

    th = threading.Thread(target=work)
    gaps, last = [], time.perf_counter()
    th.start()
    while not done.is_set():
        time.sleep(0.001)
        now = time.perf_counter()
        gaps.append(now - last)
        last = now
    th.join()
    assert span["s"] > 0.1, span  # long enough to tell a held GIL from a released one
    assert max(gaps) < 0.5 * span["s"], (max(gaps), span["s"])


def test_scale_and_budget_match_cli(cli: Cli, tmp_path: Path) -> None:
    """SPEC §11 through Python: a file with a certified plate scale, an expansion coefficient and
    per-view temperatures gives the command line's G, M, combined u, budget and Monte Carlo."""
    f = tmp_path / "in.csv"
    cli("simulate", "grid", "--plan", "double-shift", "--n", 15, "--out", f, "--truth-map",
        tmp_path / "T.csv", "--plate-scale-ppm", "2,0.1", "--plate-cte-ppm-per-k", "9,0.5",
        "--view-temp-c", "20.3,19.8,20.6,20.1", "--magnification-ppm", -6)
    r = selfcal.calibrate_grid(str(f), monte_carlo=200, seed=4)
    cli("grid", "--method", "lsq", f, "--map", tmp_path / "G.csv", "--summary",
        tmp_path / "S.json", "--monte-carlo", 200, "--seed", 4, "--quiet")
    g = read_csv(tmp_path / "G.csv")
    s = json.loads((tmp_path / "S.json").read_text())
    assert r.scale_included and s["scale_included"]
    assert abs(r.magnification_ppm + 6) < 0.2
    assert r.magnification_ppm == pytest.approx(s["magnification_ppm"], rel=1e-12)
    assert r.u_magnification_ppm == pytest.approx(s["u_magnification_ppm"], rel=1e-12)
    assert np.allclose(r.gx_um.ravel(), g["gx_um"], atol=1e-12)
    assert np.allclose(r.ugx_um.ravel(), g["ugx_um"], rtol=1e-9)
    b = r.budget
    assert b["k_from"] == "2" and b["k"] == 2
    assert [row["source"] for row in b["rows"]] == [row["source"] for row in s["budget"]["rows"]]
    assert b["U_um"] == pytest.approx(s["budget"]["U_um"], rel=1e-12)
    assert np.all(r.ugx_um >= b["ugx_noise_um"])  # the combined u holds the noise part
    mc = r.monte_carlo
    assert mc is not None
    assert mc["trials"] == 200 and mc["ratio_mean"] == pytest.approx(
        s["monte_carlo"]["ratio_mean"], rel=1e-12)
    assert 0.8 < mc["ratio_mean"] < 1.2 and mc["ugx_um"].shape == r.gx_um.shape
    # without the scale line: no magnification, and it says so
    t = tmp_path / "noE.csv"
    t.write_text("".join(l for l in f.read_text().splitlines(True)
                         if not l.startswith("# plate_scale_ppm")))
    r = selfcal.calibrate_grid(str(t), view_scale="free")
    assert not r.scale_included and math.isnan(r.magnification_ppm)
    assert r.budget["view_scale_free"] and r.budget["u_view_scale_free_ppm"].shape == (4,)
    # the scale lines survive read_grid and write; a GridMeasurement carries them to calibrate
    m = selfcal.read_grid(str(f))
    assert m.plan.plate_scale_ppm == (2.0, 0.1) and m.plan.plate_cte_ppm_per_K == (9.0, 0.5)
    assert [v["temp_C"] for v in m.plan.views] == [20.3, 19.8, 20.6, 20.1]
    m.write(tmp_path / "again.csv")
    assert selfcal.calibrate_grid(m).magnification_ppm == pytest.approx(s["magnification_ppm"],
                                                                        rel=1e-9)
    assert selfcal.read_grid(str(tmp_path / "again.csv")).plan.plate_scale_ppm == (2.0, 0.1)
    with pytest.raises(selfcal.Error, match="every view"):
        selfcal.GridPlan(5, 1.0, [dict(rot=0, temp_C=20.0), dict(rot=90)],
                         plate_cte_ppm_per_K=(8, 0.1))
    with pytest.raises(selfcal.Error, match="view_scale"):
        selfcal.calibrate_grid(str(t), view_scale="loose")
    with pytest.raises(selfcal.Error):
        selfcal.calibrate_grid(str(t), method="ye", monte_carlo=10)


def test_solver_and_node_sigma(cli: Cli, tmp_path: Path) -> None:
    """solver= and node_sigma= as `grid --solver/--node-sigma`: both matrices give the same
    results; none and sample:K leave the other nodes' σ NaN, as the command line writes them."""
    m, _ = selfcal.simulate_grid("stitch", n=7, stage=(19, 19), sigma_r_um=0.01, seed=8)
    red = selfcal.calibrate_grid(m, solver="reduced")
    full = selfcal.calibrate_grid(m, solver="full")
    for col in ("gx_um", "gy_um", "ugx_um", "ugy_um", "ax_um"):
        a, b = getattr(red, col), getattr(full, col)
        assert np.isfinite(a).all(), col
        assert np.allclose(a, b, rtol=1e-9, atol=1e-12), col
    none = selfcal.calibrate_grid(m, node_sigma="none")
    assert np.isnan(none.ugx_um).all() and np.isnan(none.ugy_um).all()
    assert np.allclose(none.gx_um, red.gx_um, rtol=1e-9, atol=1e-12)
    s1 = selfcal.calibrate_grid(m, node_sigma="sample:5", solver="full")
    s2 = selfcal.calibrate_grid(m, node_sigma=("sample", 5))
    ok = np.isfinite(s1.ugx_um)
    assert 1 <= ok.sum() < ok.size
    assert np.array_equal(ok, np.isfinite(s2.ugx_um))
    assert np.allclose(s1.ugx_um[ok], red.ugx_um[ok], rtol=1e-6)
    f = tmp_path / "st.csv"
    m.write(f)
    cli("grid", "--method", "lsq", f, "--map", tmp_path / "G.csv", "--node-sigma", "sample:5",
        "--solver", "full",
        "--quiet")
    g = read_csv(tmp_path / "G.csv")
    i, j = g["i"].astype(int), g["j"].astype(int)
    c, p = g["ugx_um"], s1.ugx_um[i, j]
    assert np.array_equal(np.isnan(c), np.isnan(p))
    assert np.allclose(c[~np.isnan(c)], p[~np.isnan(p)], rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError, match="'auto', 'reduced', 'full'"):
        selfcal.calibrate_grid(m, solver="fast")
    for bad in ("some", "sample:", "sample:x", "sample:0", ("sample", 0), ("sample", 10**7)):
        with pytest.raises(ValueError, match="node_sigma"):
            selfcal.calibrate_grid(m, node_sigma=bad)
    for wrong in (5, None, ("all", 3), ["sample", 5]):
        with pytest.raises(TypeError, match="node_sigma must be"):
            selfcal.calibrate_grid(m, node_sigma=wrong)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="node_sigma's K"):
        selfcal.calibrate_grid(m, node_sigma=("sample", 2.5))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="node_sigma='all'"):
        selfcal.calibrate_grid(m, node_sigma="none", reject_outliers=True)
    with pytest.raises(ValueError, match="node_sigma='all'"):
        selfcal.calibrate_grid(m, node_sigma="sample:3", view_noise="estimate")
