"""Straightness profiles from Python: recovery against simulated truth, equality with the command
line on the same files, errors."""
from pathlib import Path

import numpy as np
import pytest

import selfcal
from conftest import Cli, read_csv


def line_removed(v: "np.typing.NDArray[np.float64]") -> "np.typing.NDArray[np.float64]":
    x = np.arange(len(v), dtype=float)
    a, b = np.polyfit(x, v, 1)
    out: "np.typing.NDArray[np.float64]" = v - (a * x + b)
    return out


@pytest.mark.parametrize("method", ["lsq", "dft"])
def test_noise_free_recovery(method: str) -> None:
    m, truth = selfcal.simulate_profile(n=330, d1=10, d2=11, sigma_disp_um=0, sigma_angle_urad=0,
                                        seed=7)
    r = selfcal.calibrate_profile(m, method=method, sigma_disp_um=0.01, sigma_angle_urad=1.0)
    assert r.f_um.shape == (330,)
    assert np.max(np.abs(r.f_um - line_removed(truth["f_um"]))) < 1e-9
    valid = ~np.isnan(truth["ey_um"])
    assert valid.sum() == 320
    assert np.array_equal(valid, ~np.isnan(r.ey_um))
    assert np.max(np.abs(r.ey_um[valid] - truth["ey_um"][valid])) < 1e-9
    # given noise: uncertainties follow it (Ding's set-up, ~12.7 nm in the middle)
    assert r.noise_known and r.have_uf
    assert 0.010 < r.uf_um[165] < 0.016
    assert np.allclose(r.expanded_uf_um(), 2 * r.uf_um)


def test_arbitrary_profile_in_memory() -> None:
    f = np.sin(np.linspace(0, 7, 200)) * 0.3
    m, truth = selfcal.simulate_profile(n=200, d1=3, d2=7, f_um=f, sigma_disp_um=0,
                                        sigma_angle_urad=0, write_sigma=False)
    assert m.sigma_disp_um is None
    assert np.array_equal(truth["f_um"], f)
    r = selfcal.calibrate_profile(m, method="lsq")
    assert np.max(np.abs(r.f_um - line_removed(f))) < 1e-9
    # noise-free data: the noise estimated from the residuals is (nearly) zero
    assert not r.noise_known and np.max(r.uf_um) < 1e-9


@pytest.mark.parametrize("method", ["lsq", "dft"])
def test_equals_cli(cli: Cli, tmp_path: Path, method: str) -> None:
    m, _ = selfcal.simulate_profile(n=330, d1=10, d2=11, seed=3)
    data = tmp_path / "scans.csv"
    m.write(data)
    back = selfcal.read_profile(data)
    for k in range(2):
        assert np.array_equal(back.m1_um[k], m.m1_um[k])
        assert np.array_equal(back.m3_urad[k], m.m3_urad[k])
    out = tmp_path / "P.csv"
    cli("profile", "--method", method, data, "--out", out, "--quiet")
    c = read_csv(out)
    r = selfcal.calibrate_profile(str(data), method=method)
    for col in ("f_um", "uf_um", "ey_um"):
        a, b = c[col], getattr(r, col)
        assert np.array_equal(np.isnan(a), np.isnan(b)), col
        ok = ~np.isnan(a)
        assert np.allclose(a[ok], b[ok], rtol=1e-12, atol=1e-13), col
    assert np.allclose(c["x_mm"], r.x_mm)


def test_simulation_equals_cli(cli: Cli, tmp_path: Path) -> None:
    data, truth = tmp_path / "s.csv", tmp_path / "t.csv"
    cli("simulate", "profile", "--n", 110, "--d1", 10, "--d2", 11, "--seed", 5, "--out", data,
        "--truth", truth)
    m, t = selfcal.simulate_profile(n=110, d1=10, d2=11, seed=5)
    c = selfcal.read_profile(data)
    for k in range(2):
        assert np.allclose(c.m1_um[k], m.m1_um[k], rtol=1e-15, atol=1e-15)
        assert np.allclose(c.m3_urad[k], m.m3_urad[k], rtol=1e-15, atol=1e-15)
    tt = read_csv(truth)
    assert np.allclose(tt["f_um"], t["f_um"], rtol=1e-14, atol=1e-15)


def test_bad_file_message_equals_cli(cli: Cli, tmp_path: Path) -> None:
    m, _ = selfcal.simulate_profile(n=60, d1=3, d2=7)
    bad = tmp_path / "bad.csv"
    m.write(bad)
    lines = bad.read_text().splitlines()
    k = next(i for i, l in enumerate(lines) if l.startswith("scan,")) + 5
    lines[k] = ",".join(lines[k].split(",")[:-1] + ["zz"])
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(selfcal.Error) as e:
        selfcal.calibrate_profile(str(bad))
    assert isinstance(e.value, ValueError)
    p = cli("profile", "--method", "lsq", bad, "--out", tmp_path / "P.csv", check=False)
    assert p.returncode == 2
    assert p.stderr.strip() == str(e.value)
    assert str(e.value).startswith(f"selfcal: {bad}:{k + 1}: ")
    assert not (tmp_path / "P.csv").exists()


def test_errors(tmp_path: Path) -> None:
    with pytest.raises(selfcal.Error, match="missing"):
        selfcal.read_profile("/nonexistent/missing.csv")
    m, _ = selfcal.simulate_profile(n=120, d1=4, d2=6)  # gcd 2: not solvable
    with pytest.raises(selfcal.Error, match="d1"):
        selfcal.calibrate_profile(m)
    with pytest.raises(selfcal.Error):
        selfcal.calibrate_profile(m, method="fourier")
    with pytest.raises(selfcal.Error):
        selfcal.simulate_profile(n=20, d1=30, d2=31)
    with pytest.raises(TypeError):
        selfcal.simulate_profile(wobble_um=3)
    # bad input raises selfcal.Error, as the command line refuses it (stop 27's audit)
    with pytest.raises(selfcal.Error, match=r"sigma_disp_um .*, got -1$"):
        selfcal.calibrate_profile(m, sigma_disp_um=-1)
    with pytest.raises(selfcal.Error, match="sigma_angle_urad"):
        selfcal.calibrate_profile(m, sigma_angle_urad=float("nan"))
    with pytest.raises(selfcal.Error, match="mc_trials"):
        selfcal.calibrate_profile(m, mc_trials=2**40)
    with pytest.raises(selfcal.Error, match=r"harmonics.*, got -1 and 1$"):
        selfcal.simulate_profile(harmonics=-1)
    with pytest.raises(selfcal.InputError, match=r"^n must lie within 2 \.\. 2147483647, not 4294967416$"):
        selfcal.calibrate_profile(selfcal.ProfileMeasurement(2**32 + 120, m.s_mm, m.d1, m.d2, m.m1_um,
                                                             m.m2_um, m.m3_urad))
    with pytest.raises(selfcal.Error):
        selfcal.calibrate_profile(5)  # type: ignore[arg-type]
    m2, _ = selfcal.simulate_profile(n=50, d1=3, d2=7)
    m2.m1_um[0][3] = np.inf
    with pytest.raises(selfcal.Error, match="not a finite measurement"):
        m2.write(tmp_path / "inf.csv")
    assert not (tmp_path / "inf.csv").exists()
    # NaN is a gap (SPEC §2a): written as an empty field, read back as NaN, solved around
    m2.m1_um[0][3] = np.nan
    m2.write(tmp_path / "nan.csv")
    back = selfcal.read_profile(tmp_path / "nan.csv")
    assert np.isnan(back.m1_um[0][3]) and np.isfinite(back.m2_um[0][3])
    r = selfcal.calibrate_profile(tmp_path / "nan.csv")
    assert np.all(np.isfinite(r.f_um))
    m3, _ = selfcal.simulate_profile(n=42, d1=3, d2=7)  # N = 2·3·7: the DFT's own condition
    m3.m3_urad[1][5] = np.nan
    m3.write(tmp_path / "gap42.csv")
    with pytest.raises(selfcal.Error, match="--method lsq"):
        selfcal.calibrate_profile(tmp_path / "gap42.csv", method="dft")
    m, _ = selfcal.simulate_profile(n=50, d1=3, d2=7)
    m.m1_um = (m.m1_um[0][:-1], m.m1_um[1])
    with pytest.raises(selfcal.Error, match="m1_um of scan 1 has 46 values, expected 47"):
        selfcal.calibrate_profile(m)
