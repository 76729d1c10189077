"""The package as its users meet it: bad input refused where it comes in, with the standard
library's exceptions and a message naming what is wrong; CHOLMOD loaded only by least squares;
a clean namespace; numpydoc docstrings on every public name (issue 38)."""
import errno
import inspect
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

import selfcal


def _plan() -> selfcal.GridPlan:
    return selfcal.GridPlan.standard("ye", 5)


def _meas() -> selfcal.GridMeasurement:
    return selfcal.simulate_grid("ye", n=5, seed=2)[0]


def _prof() -> selfcal.ProfileMeasurement:
    return selfcal.simulate_profile(n=60, d1=3, d2=7)[0]


# The bad-input table of the README's Python section: what is called, the exception type (also a
# selfcal.Error, and the standard one named), and a pattern its message must match.
BAD_INPUT: "list[tuple[str, Callable[[], Any], type, str]]" = [
    ("view key typo", lambda: selfcal.GridPlan(5, 1.0, [dict(rot=0, shfit=(1, 0))]),
     ValueError, r"^views\[0\]: unknown key 'shfit'; the known keys are rot, shift, rows, cols, "
                 r"sigma_um, temp_C$"),
    ("view without rot", lambda: selfcal.GridPlan(5, 1.0, [dict(shift=(1, 0))]),
     ValueError, r"^views\[0\]: missing key rot$"),
    ("view not a dict", lambda: selfcal.GridPlan(5, 1.0, [(0, (1, 0))]),  # type: ignore[list-item]
     TypeError, r"^views\[0\] must be a dict with keys rot, shift"),
    ("shift of text", lambda: selfcal.GridPlan(5, 1.0, [dict(rot=0, shift="10")]),
     TypeError, r"^views\[0\]\['shift'\] must be a pair of numbers, not str '10'$"),
    ("pitch as text", lambda: selfcal.GridPlan(5, "1.0", [dict(rot=0)]),  # type: ignore[arg-type]
     TypeError, r"^pitch_mm must be a number, not str '1\.0' \(write 1\.0, without quotes\)$"),
    ("n a float", lambda: selfcal.GridPlan(5.5, 1.0, [dict(rot=0)]),  # type: ignore[arg-type]
     TypeError, r"^n must be a whole number, not float$"),
    ("n even (the library's check)", lambda: selfcal.GridPlan(8, 1.0, [dict(rot=0)]),
     ValueError, r"^selfcal: .*N"),
    ("negative view sigma", lambda: selfcal.GridPlan(5, 1.0, [dict(rot=0, sigma_um=-1)]),
     ValueError, r"^views\[0\]\['sigma_um'\] must be > 0, not -1\.0$"),
    ("sigma_r_um as text", lambda: selfcal.calibrate_grid(_meas(), sigma_r_um="0.01"),  # type: ignore[arg-type]
     TypeError, r"^sigma_r_um must be a number, not str '0\.01' \(write 0\.01, without quotes\)$"),
    ("sigma_r_um NaN", lambda: selfcal.calibrate_grid(_meas(), sigma_r_um=float("nan")),
     ValueError, r"^sigma_r_um must be a finite number, not nan$"),
    ("unknown method", lambda: selfcal.calibrate_grid(_meas(), method="fast"),
     ValueError, r"^method must be 'ye', 'double-shift', 'lsq', not 'fast'$"),
    ("drift not a bool", lambda: selfcal.calibrate_grid(_meas(), drift="yes"),  # type: ignore[arg-type]
     TypeError, r"^drift must be True or False, not str 'yes'$"),
    ("source of a wrong type", lambda: selfcal.calibrate_grid(5),  # type: ignore[arg-type]
     TypeError, r"^source must be a file path, a selfcal\.GridMeasurement or a selfcal\.GridPlan"),
    ("measurement of a wrong shape", lambda: selfcal.GridMeasurement(
        _plan(), np.zeros((2, 5, 5)), np.zeros((2, 5, 5))),
     ValueError, r"^x_mm must have the shape \(3, 5, 5\), not \(2, 5, 5\)$"),
    ("measurement of text", lambda: selfcal.GridMeasurement(
        _plan(), np.full((3, 5, 5), "1"), np.zeros((3, 5, 5))),
     TypeError, r"^x_mm must hold real numbers, not numpy dtype <U1"),
    ("measurement infinite", lambda: selfcal.GridMeasurement(
        _plan(), np.full((3, 5, 5), np.inf), np.zeros((3, 5, 5))),
     ValueError, r"^x_mm\[0, 0, 0\] is infinite \(NaN: not measured\)$"),
    ("mark far from its place", lambda: selfcal.GridMeasurement(
        _plan(), np.where(np.isfinite(_meas().x_mm), 100.0, np.nan), _meas().y_mm),
     ValueError, r"more than half a pitch from its nominal position$"),
    ("only ux_um", lambda: selfcal.GridMeasurement(
        _plan(), _meas().x_mm, _meas().y_mm, ux_um=np.ones((3, 5, 5))),
     ValueError, r"^give both ux_um and uy_um, or neither$"),
    ("plan not a GridPlan", lambda: selfcal.GridMeasurement(
        {"n": 5}, np.zeros((3, 5, 5)), np.zeros((3, 5, 5))),  # type: ignore[arg-type]
     TypeError, r"^plan must be a selfcal\.GridPlan, not dict$"),
    ("simulation parameter typo", lambda: selfcal.simulate_grid("ye", n=5, sigma_a=0.1),
     TypeError, r"^simulate_grid: unknown keyword argument sigma_a; the known ones are rho, "
                r"O_urad, R_ppm, O, R, sigma_a_um, sigma_t_um"),
    ("instrument parameter typo", lambda: selfcal.simulate_profile(u1=0.1),
     TypeError, r"^simulate_profile: unknown keyword argument u1; the known ones are ey_amp_um"),
    ("profile of a wrong length", lambda: selfcal.ProfileMeasurement(
        60, 1.0, 3, 7, (np.zeros(56), np.zeros(53)), _prof().m2_um, _prof().m3_urad),
     ValueError, r"^m1_um\[0\] must have the shape \(57,\), not \(56,\)$"),
    ("profile spacing of text", lambda: selfcal.ProfileMeasurement(
        60, 1.0, "3", 7, _prof().m1_um, _prof().m2_um, _prof().m3_urad),  # type: ignore[arg-type]
     TypeError, r"^d1 must be a whole number, not str '3'$"),
    ("profile noise as text", lambda: selfcal.calibrate_profile(_prof(), sigma_disp_um="0.01"),  # type: ignore[arg-type]
     TypeError, r"^sigma_disp_um must be a number, not str '0\.01'"),
    ("table profile key typo", lambda: selfcal.build_table(
        "t.lut", np.zeros((3, 3)), np.zeros((3, 3)), 0, 0, 1,
        profiles=[dict(axis="x", dir="y", start_mm=0, step=1, err_um=[0, 0])]),
     ValueError, r"^profiles\[0\]: unknown key 'step'; the known keys are axis, dir, start_mm, "
                 r"step_mm, err_um$"),
    ("table mode", lambda: selfcal.Table(_TABLE[0]).apply(0.0, 0.0, mode="exact"),
     ValueError, r"^mode must be 'measure', 'position', 'measure-exact', not 'exact'$"),
    ("verify rule", lambda: selfcal.verify("m", "t", "a", 1.0, decision_rule="strict"),
     ValueError, r"^decision_rule must be 'simple', 'guarded', not 'strict'$"),
    ("verify tolerance as text", lambda: selfcal.verify("m", "t", "a", "1"),  # type: ignore[arg-type]
     TypeError, r"^tolerance_um must be a number, not str '1'"),
]
_TABLE: "list[str]" = []


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    if not _TABLE:
        _TABLE.append(str(tmp_path / "t0.lut"))
        selfcal.build_table(_TABLE[0], np.zeros((3, 3)), np.zeros((3, 3)), 0.0, 0.0, 1.0)


@pytest.mark.parametrize("what,call,kind,pattern", BAD_INPUT, ids=[b[0] for b in BAD_INPUT])
def test_bad_input_table(what: str, call: Callable[[], Any], kind: type, pattern: str) -> None:
    with pytest.raises(selfcal.Error) as e:
        call()
    assert isinstance(e.value, kind), (what, type(e.value).__mro__)
    assert re.search(pattern, str(e.value)), (what, str(e.value))
    # never a bare internal message: every one says what it is about
    assert "object cannot be interpreted" not in str(e.value)


def test_file_errors(tmp_path: Path) -> None:
    missing = tmp_path / "missing.csv"
    for call in (selfcal.read_grid, selfcal.read_profile, selfcal.Table, selfcal.calibrate_grid,
                 selfcal.calibrate_profile):
        with pytest.raises(FileNotFoundError) as e:
            call(missing)
        assert isinstance(e.value, selfcal.MissingFileError)
        assert isinstance(e.value, selfcal.Error) and isinstance(e.value, OSError)
        assert not isinstance(e.value, ValueError)
        assert e.value.errno == errno.ENOENT and e.value.filename == str(missing)
        assert str(e.value) == f"selfcal: {missing}: cannot open: {os.strerror(errno.ENOENT)}"
    with pytest.raises(IsADirectoryError) as d:
        selfcal.read_grid(tmp_path)
    assert isinstance(d.value, selfcal.DirectoryError) and d.value.errno == errno.EISDIR
    assert str(d.value) == f"selfcal: {tmp_path}: is a directory, not a file"
    with pytest.raises(FileNotFoundError):
        selfcal.simulate_profile(dabam=tmp_path / "none.dat")
    # writing: a folder that does not exist, a folder in place of the file
    with pytest.raises(FileNotFoundError) as w:
        _meas().write(tmp_path / "no" / "x.csv")
    assert w.value.errno == errno.ENOENT and isinstance(w.value, selfcal.FileError)
    with pytest.raises(IsADirectoryError):
        _prof().write(tmp_path)
    with pytest.raises(FileNotFoundError):
        selfcal.verify(missing, missing, missing, 1.0)
    # content is a ValueError, not an OSError
    bad = tmp_path / "bad.csv"
    bad.write_text("# selfcal-grid v2\n")
    with pytest.raises(ValueError) as v:
        selfcal.read_grid(bad)
    assert isinstance(v.value, selfcal.InputError) and not isinstance(v.value, OSError)
    assert str(v.value).startswith(f"selfcal: {bad}:1: ")


def test_permission_error(tmp_path: Path) -> None:
    f = tmp_path / "locked.csv"
    _meas().write(f)
    f.chmod(0)
    code = ("import errno, sys, selfcal\n"
            "try:\n    selfcal.read_grid(sys.argv[1])\n"
            "except PermissionError as e:\n"
            "    assert isinstance(e, selfcal.FilePermissionError) and e.errno == errno.EACCES\n"
            "    assert e.filename == sys.argv[1] and 'Permission denied' in str(e)\n"
            "    print('ok')\n")
    cmd = [sys.executable, "-c", code, str(f)]
    if os.geteuid() == 0:  # root reads any file: run as nobody
        if not shutil.which("setpriv"):
            pytest.skip("root without setpriv: cannot drop privileges")
        os.chmod(tmp_path, 0o755)
        cmd = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", *cmd]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and p.stdout.strip() == "ok", p.stderr


def test_exception_hierarchy() -> None:
    pairs = {selfcal.InputError: ValueError, selfcal.UnsolvableError: ValueError,
             selfcal.ArgumentTypeError: TypeError, selfcal.FileError: OSError,
             selfcal.MissingFileError: FileNotFoundError,
             selfcal.FilePermissionError: PermissionError,
             selfcal.DirectoryError: IsADirectoryError, selfcal.OutOfMemoryError: MemoryError,
             selfcal.InternalError: RuntimeError}
    for cls, std in pairs.items():
        assert issubclass(cls, selfcal.Error) and issubclass(cls, std), cls
        e = cls(errno.ENOENT, "x", "f") if issubclass(cls, OSError) else cls("m")
        assert isinstance(e, std)
    assert not issubclass(selfcal.Error, ValueError) and not issubclass(selfcal.FileError, ValueError)
    # a plan that does not identify G: unsolvable (a ValueError)
    with pytest.raises(selfcal.UnsolvableError, match="do not identify G"):
        selfcal.calibrate_grid(selfcal.simulate_grid(
            selfcal.GridPlan(9, 1.0, [dict(rot=0), dict(rot=90)]))[0])


def test_keys_checked_everywhere() -> None:
    # a typo in any key is refused (it used to be ignored: shift (0, 0), a wrong calibration)
    with pytest.raises(ValueError, match="'shfit'"):
        selfcal.plan(selfcal.GridPlan(5, 1.0, [dict(rot=0), dict(rot=90), dict(rot=0, shfit=(1, 0))]))
    with pytest.raises(TypeError, match="got an unexpected keyword argument 'sigma_r'"):
        selfcal.calibrate_grid(_meas(), sigma_r=0.01)  # type: ignore[call-arg]
    # the right keys still work, numpy numbers included
    p = selfcal.GridPlan(np.int64(5), np.float64(1.0),  # type: ignore[arg-type]
                         [dict(rot=0), dict(rot=np.int32(90)), dict(rot=0, shift=(1, 0), sigma_um=0.01)])
    assert p.views[2]["shift"] == (1, 0) and p.views[2]["sigma_um"] == 0.01


def test_closed_forms_and_simulation_without_cholmod() -> None:
    # plans, measurements and simulations never load the solver (the closed forms try it for
    # their noise estimate, NaN without it)
    code = ("import selfcal\n"
            "p = selfcal.GridPlan(5, 1.0, [dict(rot=0), dict(rot=90), dict(rot=0, shift=(1, 0))])\n"
            "m, t = selfcal.simulate_grid(p, sigma_r_um=0.0, seed=4)\n"
            "m2, _ = selfcal.simulate_grid('double-shift', n=9)\n"
            "selfcal.GridMeasurement(m.plan, m.x_mm, m.y_mm)\n"
            "assert 'libcholmod' not in open('/proc/self/maps').read(), 'CHOLMOD loaded'\n"
            "r = selfcal.calibrate_grid(m, method='ye')\n"
            "assert abs(r.gx_um - t['gx_um']).max() < 1e-6\n"
            "selfcal.calibrate_grid(m2, method='double-shift')\n"
            "print('closed forms ok')\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and "closed forms ok" in p.stdout, p.stderr
    # and with the system's CHOLMOD hidden (a mount namespace: /dev/null bound over it)
    libs = [os.path.realpath(os.path.join(d, "libcholmod.so.3"))
            for d in ("/usr/lib/x86_64-linux-gnu", "/lib/x86_64-linux-gnu", "/usr/lib64")
            if os.path.exists(os.path.join(d, "libcholmod.so.3"))]
    if os.geteuid() != 0 or not shutil.which("unshare") or not libs:
        pytest.skip("hiding CHOLMOD needs root, unshare and a system libcholmod.so.3")
    hide = "; ".join(f"mount --bind /dev/null '{lib}'" for lib in sorted(set(libs)))
    lsq = ("import selfcal\n"
           "m, _ = selfcal.simulate_grid('ye', n=5)\n"
           "try:\n    selfcal.calibrate_grid(m, method='lsq')\n"
           "except selfcal.FileError as e:\n"
           "    assert isinstance(e, OSError) and 'CHOLMOD' in str(e), e\n"
           "    print('lsq refused:', type(e).__name__, e)\n")
    script = (f"set -e; {hide}; {sys.executable} -c \"$1\"; {sys.executable} -c \"$2\"")
    h = subprocess.run(["unshare", "-m", "--propagation", "private", "sh", "-c", script, "sh",
                        code, lsq], capture_output=True, text=True, timeout=120)
    assert h.returncode == 0, h.stderr
    assert "closed forms ok" in h.stdout and "lsq refused:" in h.stdout, h.stdout


def test_namespace_and_typing() -> None:
    assert not hasattr(selfcal, "annotations")  # no `from __future__ import annotations` leak
    public = {n for n in dir(selfcal) if not n.startswith("_")}
    assert public <= set(selfcal.__all__), public - set(selfcal.__all__)
    assert all(hasattr(selfcal, n) for n in selfcal.__all__)
    pkg = Path(selfcal.__file__).parent
    assert (pkg / "py.typed").is_file() and (pkg / "_native.pyi").is_file()


def _sections(doc: str) -> "set[str]":
    lines = doc.splitlines()
    return {lines[k].strip() for k in range(len(lines) - 1)
            if lines[k].strip() and re.fullmatch(r"-{3,}", lines[k + 1].strip())
            and len(lines[k + 1].strip()) == len(lines[k].strip())}


def test_numpydoc_docstrings() -> None:
    for name in selfcal.__all__:
        obj = getattr(selfcal, name)
        doc = inspect.getdoc(obj)
        assert doc and len(doc.splitlines()[0]) > 10, name
        secs = _sections(doc)
        if inspect.isfunction(obj):
            sig = inspect.signature(obj)
            if sig.parameters:
                assert "Parameters" in secs, (name, secs)
                for p in sig.parameters.values():  # every parameter described
                    key = "**" + p.name if p.kind is p.VAR_KEYWORD else p.name
                    assert re.search(rf"^{re.escape(key)}\b|, {re.escape(key)}\b", doc, re.M), (name, key)
            assert "Returns" in secs, (name, secs)
            assert sig.return_annotation is not inspect.Signature.empty, name
        elif inspect.isclass(obj) and not issubclass(obj, BaseException):
            assert secs & {"Parameters", "Attributes"}, (name, secs)
            for mname, m in vars(obj).items():
                if inspect.isfunction(m) and not mname.startswith("_"):
                    mdoc = inspect.getdoc(m) or ""
                    if len(inspect.signature(m).parameters) > 1:
                        assert "Parameters" in _sections(mdoc), (name, mname)
                    assert "Returns" in _sections(mdoc) or inspect.signature(m).return_annotation in (None, "None"), (name, mname)
        # help() shows it
        assert doc.splitlines()[0] in _help_text(obj), name


def _help_text(obj: object) -> str:
    import pydoc
    return pydoc.plain(pydoc.render_doc(obj))


def test_units_in_docstrings() -> None:
    # every number-bearing parameter named with a unit says the unit in its description
    units = {"_mm": "mm", "_um": "µm", "_urad": "µrad", "_ppm": "ppm"}
    for name in selfcal.__all__:
        obj = getattr(selfcal, name)
        if not inspect.isfunction(obj):
            continue
        doc = inspect.getdoc(obj) or ""
        for p in inspect.signature(obj).parameters:
            for suffix, unit in units.items():
                if p.endswith(suffix):
                    block = re.search(rf"^(?:.*\b)?{p}\b.*\n((?:    .*\n?)*)", doc, re.M)
                    assert block and unit in block.group(0), (name, p)
