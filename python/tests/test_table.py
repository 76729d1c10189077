"""Table.apply: the correction core from numpy, checked against an independent bilinear
evaluation of `selfcal lut dump` (SPEC §4)."""
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import selfcal
from conftest import Cli

TableFixture = tuple[Path, tuple[Any, list[dict[str, Any]]]]


def parse_dump(text: str) -> "tuple[Any, list[dict[str, Any]]]":
    grid: "list[list[float]]" = []
    profiles: "list[dict[str, Any]]" = []
    cur: "dict[str, Any] | None" = None
    for line in text.splitlines():
        if line.startswith("# profile"):
            kv = dict(t.split("=") for t in line.split(":", 1)[1].split())
            cur = {"axis": kv["axis"], "dir": kv["dir"], "rows": []}
            profiles.append(cur)
        elif not line or line[0].isalpha():
            continue
        elif cur is None:
            grid.append([float(v) for v in line.split(",")])
        else:
            cur["rows"].append([float(v) for v in line.split(",")])
    return np.array(grid), profiles


def reference(grid: Any, profiles: "list[dict[str, Any]]", x: Any, y: Any, mode: str) -> "tuple[Any, Any, Any]":
    """Independent SPEC §4 evaluation: bilinear G clamped at the edges, profiles linear, clamped."""
    xs, ys = np.unique(grid[:, 2]), np.unique(grid[:, 3])
    nx, ny = len(xs), len(ys)
    gx = np.zeros((ny, nx))
    gy = np.zeros((ny, nx))
    for i, j, _, _, a, b in grid:
        gx[int(i), int(j)], gy[int(i), int(j)] = a, b

    def bil(g: Any, xq: Any, yq: Any) -> Any:
        u = np.clip((xq - xs[0]) / (xs[1] - xs[0]), 0, nx - 1)
        v = np.clip((yq - ys[0]) / (ys[1] - ys[0]), 0, ny - 1)
        j = np.minimum(u.astype(int), nx - 2)
        i = np.minimum(v.astype(int), ny - 2)
        fu, fv = u - j, v - i
        return ((g[i, j] * (1 - fu) + g[i, j + 1] * fu) * (1 - fv)
                + (g[i + 1, j] * (1 - fu) + g[i + 1, j + 1] * fu) * fv)

    corr = {"x": bil(gx, x, y) * 1e-3, "y": bil(gy, x, y) * 1e-3, "z": 0 * x}
    coord = {"x": x, "y": y, "z": 0 * x}
    for p in profiles:
        r = np.array(p["rows"])
        corr[p["dir"]] = corr[p["dir"]] + np.interp(coord[p["axis"]], r[:, 1], r[:, 2]) * 1e-3
    sign = -1 if mode == "measure" else 1
    outside = ((x < xs[0]) | (x > xs[-1]) | (y < ys[0]) | (y > ys[-1]))
    return x + sign * corr["x"], y + sign * corr["y"], outside


@pytest.fixture(scope="module")
def table(cli: Cli, tmp_path_factory: pytest.TempPathFactory) -> TableFixture:
    d = tmp_path_factory.mktemp("table")
    cli("simulate", "grid", "--plan", "double-shift", "--n", 11, "--pitch-mm", 2,
        "--sigma-r-um", 0.01, "--out", d / "in.csv", "--truth-map", d / "Gt.csv")
    cli("grid", "--method", "lsq", d / "in.csv", "--map", d / "G.csv")
    cli("simulate", "profile", "--n", 120, "--d1", 3, "--d2", 7, "--s-mm", 0.25,
        "--out", d / "s.csv", "--truth", d / "t.csv")
    cli("profile", "--method", "lsq", d / "s.csv", "--out", d / "P.csv", "--quiet")
    cli("lut", "build", "--map", d / "G.csv", "--profile", f"y:x:{d / 'P.csv'}", "-o", d / "T.lut")
    dump = cli("lut", "dump", d / "T.lut").stdout
    return d / "T.lut", parse_dump(dump)


@pytest.mark.parametrize("mode", ["measure", "position"])
def test_apply_matches_dump(table: TableFixture, mode: str) -> None:
    path, (grid, profiles) = table
    t = selfcal.Table(path)
    assert (t.nx, t.ny) == (11, 11) and len(t.profiles) == 1
    rng = np.random.default_rng(1)
    x = rng.uniform(-13, 13, size=(40, 25))
    y = rng.uniform(-13, 13, size=(40, 25))
    xo, yo, st = t.apply(x, y, mode=mode)
    assert xo.shape == x.shape and yo.shape == y.shape and st.shape == x.shape
    rx, ry, outside = reference(grid, profiles, x, y, mode)
    # the core rounds node values to float: a few 1e-10 mm at most for micrometre corrections
    assert np.max(np.abs(xo - rx)) < 1e-9 and np.max(np.abs(yo - ry)) < 1e-9
    assert np.array_equal((st & 2) != 0, outside)
    assert np.all(st & 1)


def test_broadcast_scalars_and_invalid(table: TableFixture) -> None:
    t = selfcal.Table(table[0])
    xo, yo, st = t.apply(0.5, [0.0, 1.0, np.nan])
    assert xo.shape == (3,)
    assert st[2] & 4 and np.isnan(yo[2]) and xo[2] == 0.5
    xo, yo, zo, st = t.apply(1.0, 2.0, z_mm=3.0)
    assert xo.shape == () and zo == 3.0


def test_position_then_measure_is_near_identity(table: TableFixture) -> None:
    t = selfcal.Table(table[0])
    x = np.linspace(-9, 9, 101)
    xp, yp, _ = t.apply(x, x[::-1], mode="position")
    xm, ym, _ = t.apply(xp, yp, mode="measure")
    # the round trip leaves only the change of the correction over the correction itself
    # (second order): a small fraction of the correction
    corr = max(np.max(np.abs(xp - x)), np.max(np.abs(yp - x[::-1])))
    assert corr > 1e-4
    assert np.max(np.abs(xm - x)) < 0.01 * corr and np.max(np.abs(ym - x[::-1])) < 0.01 * corr


def test_measure_exact_inverts_position(table: TableFixture) -> None:
    t = selfcal.Table(table[0])
    x = np.linspace(-9, 9, 101)
    xp, yp, _ = t.apply(x, x[::-1], mode="position")
    xe, ye, st = t.apply(xp, yp, mode="measure-exact")
    xm, ym, _ = t.apply(xp, yp, mode="measure")
    assert np.all(st & 1)
    # the exact inverse takes position mode back to its input (the float-rounded table aside);
    # measure mode's first order leaves G·grad G, far more
    exact = max(np.max(np.abs(xe - x)), np.max(np.abs(ye - x[::-1])))
    first = max(np.max(np.abs(xm - x)), np.max(np.abs(ym - x[::-1])))
    assert exact < 1e-9 and first > 100 * exact
    with pytest.raises(selfcal.Error, match="measure-exact"):
        t.apply(x, x, mode="exact")


def test_errors(tmp_path: Path) -> None:
    with pytest.raises(selfcal.Error, match="nope.lut"):
        selfcal.Table(tmp_path / "nope.lut")
    bad = tmp_path / "bad.lut"
    bad.write_bytes(b"not a table at all" * 10)
    with pytest.raises(selfcal.Error, match="not a valid table"):
        selfcal.Table(bad)


def test_mode_checked(table: TableFixture) -> None:
    t = selfcal.Table(table[0])
    with pytest.raises(selfcal.Error, match="mode"):
        t.apply(0, 0, mode="forward")


def test_bad_positions_raise_selfcal_error(table: TableFixture) -> None:
    """SPEC §8: errors raise selfcal.Error, also for arguments numpy would refuse."""
    t = selfcal.Table(table[0])
    with pytest.raises(selfcal.Error, match="do not broadcast"):
        t.apply(np.ones(3), np.ones(2))
    with pytest.raises(selfcal.Error, match="x_mm: not real numbers"):
        t.apply("a", "b")
    with pytest.raises(selfcal.Error, match="z_mm: not real numbers"):
        t.apply(1.0, 2.0, z_mm=[1.0, "c"])  # type: ignore[arg-type]
    # what numpy would quietly turn into numbers: None (NaN), complex (real part), numeric text
    bad: Any
    for bad in (None, [1.0, None], 1 + 2j, np.array([1.0, 2.0], complex), "1.5", [True, False]):
        with pytest.raises(selfcal.Error, match="x_mm: not real numbers"):
            t.apply(bad, 2.0)
        with pytest.raises(selfcal.Error, match="y_mm: not real numbers"):
            t.apply(2.0, bad)
    # integers are numbers
    assert t.apply(np.arange(3), 0)[2].shape == (3,)
    with pytest.raises(selfcal.Error, match="out must hold 3"):
        t.apply(1.0, 2.0, out=(np.empty(()),))
    x = np.zeros((3, 4))
    for bad in ((np.empty((3, 4), np.float32), np.empty((3, 4)), np.empty((3, 4), np.uint32)),
                (np.empty((3, 4)), np.empty((3, 4)), np.empty((3, 4), np.int64))):
        with pytest.raises(selfcal.Error, match="out arrays"):
            t.apply(x, x, out=bad)


def test_build_table_from_arrays_equals_cli(cli: Cli, tmp_path: Path) -> None:
    m, truth = selfcal.simulate_grid("double-shift", n=9, pitch_mm=2.0, sigma_r_um=0.01, seed=8)
    r = selfcal.calibrate_grid(m)
    prof = dict(axis="y", dir="x", start_mm=-8.0, step_mm=0.5, err_um=np.sin(np.arange(33) / 5.0))
    t = selfcal.build_table(tmp_path / "py.lut", r.gx_um, r.gy_um, r.x_mm[0, 0], r.y_mm[0, 0], 2.0,
                            profiles=[prof], method="lsq", created_unix_s=0)
    assert (t.nx, t.ny) == (9, 9) and t.profiles[0]["axis"] == "y" and t.profiles[0]["n"] == 33
    grid, profiles = parse_dump(cli("lut", "dump", tmp_path / "py.lut").stdout)
    i, j = grid[:, 0].astype(int), grid[:, 1].astype(int)
    assert np.max(np.abs(grid[:, 4] - r.gx_um[i, j])) < 1e-4  # int16 codes: <= 0.05 nm
    assert np.max(np.abs(grid[:, 2] - r.x_mm[i, j])) < 1e-9
    p = np.array(profiles[0]["rows"])
    assert np.max(np.abs(p[:, 2] - prof["err_um"])) < 1e-4
    with pytest.raises(selfcal.Error):
        selfcal.build_table(tmp_path / "bad.lut", r.gx_um, r.gy_um[:3], 0, 0, 1)
    assert not (tmp_path / "bad.lut").exists()


def test_out_arrays_are_filled_in_place(table: TableFixture) -> None:
    t = selfcal.Table(table[0])
    x = np.linspace(-5, 5, 12).reshape(3, 4)
    out = (np.empty((3, 4)), np.empty((3, 4)), np.empty((3, 4), dtype=np.uint32))
    r = t.apply(x, -x, out=out)
    assert all(a is b for a, b in zip(r, out))
    xo, yo, st = t.apply(x, -x)
    assert np.array_equal(out[0], xo) and np.array_equal(out[1], yo) and np.array_equal(out[2], st)
    with pytest.raises(ValueError):
        t.apply(x, -x, out=(np.empty((3, 4)), np.empty((3, 4)), np.empty((3, 4))))  # status dtype
    with pytest.raises(ValueError):
        t.apply(x, -x, out=(np.empty((4, 3)).T, np.empty((3, 4)), np.empty((3, 4), dtype=np.uint32)))
