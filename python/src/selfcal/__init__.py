"""selfcal: self-calibration of precision XY stages, from Python.

Everything here calls libselfcal, the C library behind the ``selfcal`` command line (the
extension module ``selfcal._native`` has the library linked in): the same
estimators, the same file readers, the same error messages. Units are in the names: ``_mm``
millimetres, ``_um`` micrometres, ``_urad`` microradians, ``_ppm`` parts per million.

Every argument is checked where it comes in, and an object when it is built. Errors are the
standard library's kinds, each also a :class:`selfcal.Error`: a missing file raises
:class:`FileNotFoundError` (:class:`MissingFileError`), a refused one :class:`PermissionError`
(:class:`FilePermissionError`), a folder :class:`IsADirectoryError` (:class:`DirectoryError`),
bad content or an unknown key :class:`ValueError` (:class:`InputError`), a wrong type
:class:`TypeError` (:class:`ArgumentTypeError`). The message is the library's one line,
``selfcal: FILE:LINE: reason``, as the command line prints it.
"""
import os as _os
import time as _time
import warnings as _warnings
from collections.abc import (Callable as _Callable, Iterable as _Iterable, Mapping as _Mapping,
                             Sequence as _Sequence)
from typing import TYPE_CHECKING as _TYPE_CHECKING, Any as _Any, Union as _Union

import numpy as _np
import numpy.typing as _npt

from . import _check
from . import _native
from ._errors import (ArgumentTypeError, DirectoryError, Error, FileError, FilePermissionError,
                      InputError, InternalError, MissingFileError, OutOfMemoryError,
                      UnsolvableError)

__all__ = [
    "Error", "InputError", "UnsolvableError", "ArgumentTypeError", "FileError",
    "MissingFileError", "FilePermissionError", "DirectoryError", "OutOfMemoryError",
    "InternalError", "version",
    "GridPlan", "GridMeasurement", "GridResult", "PlanAnalysis", "read_grid", "plan",
    "calibrate_grid", "simulate_grid",
    "ProfileMeasurement", "ProfileResult", "read_profile", "calibrate_profile", "simulate_profile",
    "Table", "build_table",
    "VerifyResult", "verify",
]
__version__ = _native.version()

#: a file path: str, bytes or os.PathLike
_PathLike = _Union[str, bytes, _os.PathLike[str], _os.PathLike[bytes]]
_F64 = _npt.NDArray[_np.float64]

_MODES = {"measure": 0, "position": 1, "measure-exact": 2}


def version() -> str:
    """The libselfcal version this package is built on.

    Returns
    -------
    str
        The version, as the command line's ``--version`` prints it (e.g. ``"0.4.0"``).
    """
    return _native.version()


def _mode_code(mode: object) -> int:
    return _MODES[_check.choice(mode, "mode", _MODES)]


class Table:
    """A correction table (``selfcal lut build`` output), loaded and validated by the same
    correction core as ``selfcald``.

    Parameters
    ----------
    path : str or os.PathLike
        The table file.

    Attributes
    ----------
    path : str or os.PathLike
        The file it was read from.
    nx, ny : int
        Nodes along x and y.
    x0_mm, y0_mm : float
        Position of node (i=0, j=0), mm.
    px_mm, py_mm : float
        Node spacing along x and y, mm.
    profiles : list of dict
        The straightness profiles: dicts with ``axis``, ``dir``, ``n``, ``start_mm``,
        ``step_mm``.

    Raises
    ------
    FileNotFoundError, PermissionError, IsADirectoryError
        The file cannot be read (:class:`MissingFileError` ...).
    ValueError
        A corrupt or oversized table (:class:`InputError`).
    """

    def __init__(self, path: _PathLike) -> None:
        self._t = _native.Table(_check.fspath(path, "path"))
        self.path = path
        info = self._t.info()
        self.nx: int = info["nx"]
        self.ny: int = info["ny"]
        self.x0_mm: float = info["x0_mm"]
        self.y0_mm: float = info["y0_mm"]
        self.px_mm: float = info["px_mm"]
        self.py_mm: float = info["py_mm"]
        self.profiles: "list[dict[str, _Any]]" = info["profiles"]

    def apply(self, x_mm: _npt.ArrayLike, y_mm: _npt.ArrayLike, mode: str = "measure",
              z_mm: "_npt.ArrayLike | None" = None,
              out: "tuple[_np.ndarray[_Any, _Any], ...] | None" = None
              ) -> "tuple[_np.ndarray[_Any, _Any], ...]":
        """Correct positions as selfcald does (SPEC §4), vectorised in C.

        Parameters
        ----------
        x_mm, y_mm : array_like of float
            Positions, mm; any shapes that broadcast together.
        mode : {"measure", "position", "measure-exact"}
            ``"measure"``: the inputs are indicated positions p; returns p − G(p) − profile
            offsets. ``"position"``: the inputs are targets; returns target + G(target) +
            profile offsets (pre-compensation). ``"measure-exact"``: returns the q with
            q + G(q) + offsets = p, the exact inverse of position mode (three fixed-point
            steps; measure mode is the first, off by G·∇G). G is bilinear on the table's grid,
            clamped at its edges.
        z_mm : array_like of float, optional
            A third coordinate, mm, corrected by the z profiles.
        out : tuple of numpy.ndarray, optional
            Arrays to fill instead of new ones (the same layout as the result; float64 and
            uint32, C-contiguous, of the broadcast shape): a caller correcting stream after
            stream reuses them and pays no allocation.

        Returns
        -------
        x_mm, y_mm[, z_mm] : numpy.ndarray of float64
            The corrected positions, mm, of the broadcast shape (z only when given).
        status : numpy.ndarray of uint32
            Bit 0 table loaded, bit 1 outside the grid (clamped), bit 2 input not finite
            (returned unchanged).

        Raises
        ------
        ValueError
            An unknown mode, shapes that do not broadcast, unusable ``out`` arrays.
        TypeError
            Positions that are not real numbers.
        """
        code = _mode_code(mode)
        arrays = [x_mm, y_mm] + ([z_mm] if z_mm is not None else [])
        names = ("x_mm", "y_mm", "z_mm")
        conv = []
        for name, a in zip(names, arrays):
            # real numbers only: numpy would take None as NaN, a complex number by dropping its
            # imaginary part, text by parsing it
            kind = _np.asarray(a).dtype.kind
            if kind not in "iuf":
                raise ArgumentTypeError(f"{name}: not real numbers (numpy dtype kind {kind!r})")
            conv.append(_np.asarray(a, dtype=_np.float64))
        try:
            b = _np.broadcast_arrays(*conv)
        except ValueError:
            raise InputError("the positions' shapes %s do not broadcast together"
                             % ", ".join(str(c.shape) for c in conv)) from None
        shape = b[0].shape
        flat = [_np.ascontiguousarray(a).reshape(-1) for a in b]
        n_out = 4 if z_mm is not None else 3
        if out is None:
            out = tuple(_np.empty(shape, dtype=_np.float64) for _ in range(n_out - 1)) + (
                _np.empty(shape, dtype=_np.uint32),)
        elif not isinstance(out, (tuple, list)) or len(out) != n_out:
            raise InputError(f"out must hold {n_out} arrays")
        for k, o in enumerate(out):
            want = _np.uint32 if k == n_out - 1 else _np.float64
            if not isinstance(o, _np.ndarray) or o.shape != shape or not o.flags.c_contiguous \
                    or o.dtype != want or not o.flags.writeable:
                raise InputError(f"out arrays must be writeable C-contiguous numpy arrays of "
                                 f"shape {shape}: float64, the status uint32")
        flat_out = [o.reshape(-1) for o in out]  # views: the arrays are C-contiguous
        z = flat[2] if z_mm is not None else None
        zo = flat_out[2] if z_mm is not None else None
        self._t.apply(flat[0], flat[1], z, code, flat_out[0], flat_out[1], zo, flat_out[-1])
        return tuple(out)

    def __repr__(self) -> str:
        return (f"selfcal.Table({self.path!r}: {self.nx} x {self.ny} nodes, pitch "
                f"{self.px_mm:g} x {self.py_mm:g} mm, {len(self.profiles)} profile(s))")


# ---- grid plates (SPEC §1, §5) ----

_GRID_METHODS = {"ye": 0, "double-shift": 1, "lsq": 2}
# sc_grid_options.solver and .node_sigma (selfcal/grid_lsq.h), as `grid --solver/--node-sigma`
_GRID_SOLVERS = {"auto": 0, "reduced": 1, "full": 2}
_NODE_SIGMA_ALL, _NODE_SIGMA_NONE, _NODE_SIGMA_SAMPLE = 0, 1, 2
_VIEW_KEYS = ("rot", "shift", "rows", "cols", "sigma_um", "temp_C")


def _index_list(v: object, name: str, n: int) -> "list[int] | None":
    if v is None:
        return None
    if isinstance(v, (str, bytes)) or not isinstance(v, _Iterable):
        raise ArgumentTypeError(f"{name} must be a list of plate indices, not {type(v).__name__}")
    return [_check.integer(i, f"{name}[{k}]", 0, n - 1) for k, i in enumerate(v)]


def _view(v: object, k: int, n: int) -> "dict[str, _Any]":
    what = f"views[{k}]"
    d = _check.keys(v, _VIEW_KEYS, what, required=("rot",))
    sigma = d.get("sigma_um")
    temp = d.get("temp_C")
    return dict(rot=_check.integer(d["rot"], f"{what}['rot']", -2**31, 2**31 - 1),
                shift=_check.pair(d.get("shift", (0, 0)), f"{what}['shift']", whole=True),
                rows=_index_list(d.get("rows"), f"{what}['rows']", n),
                cols=_index_list(d.get("cols"), f"{what}['cols']", n),
                sigma_um=None if sigma is None else _check.real(sigma, f"{what}['sigma_um']",
                                                                low=0, low_open=True),
                temp_C=None if temp is None else _check.real(temp, f"{what}['temp_C']"))


class GridPlan:
    """A view plan: which marks of an N x N plate each view measures, and where.

    Built from its arguments and checked at once, as the library checks a file's header (nothing
    is solved: no CHOLMOD is loaded).

    Parameters
    ----------
    n : int
        Marks per row and column of the plate (odd, 3 or more).
    pitch_mm : float
        The plate's mark spacing, mm (> 0).
    views : sequence of dict
        One dict per view, with the keys ``rot`` (0, 90, 180, 270: the plate's rotation,
        counter-clockwise, degrees), ``shift`` ((sx, sy) in pitches, default (0, 0)), and
        optionally ``rows``, ``cols`` (the plate rows and columns a partial view measures),
        ``sigma_um`` (the stated standard uncertainty of each coordinate, µm) and ``temp_C``
        (the plate's temperature during the view, °C: on every view or none). Any other key is
        refused, with the list of the known ones.
    origin_mm : (float, float), optional
        The stage position of the grid's centre, mm.
    stage : (int, int), optional
        The stage grid (NX, NY) in nodes; default the plate's N x N.
    plate_scale_ppm : (float, float), optional
        The plate's scale error E and its standard uncertainty U, ppm (SPEC §11).
    plate_cte_ppm_per_K : (float, float), optional
        The plate's expansion coefficient A and its uncertainty U, ppm/K.
    temp_u_K : float, optional
        Standard uncertainty of the temperatures, K (default 0.05).

    Attributes
    ----------
    n, pitch_mm, origin_mm, stage, views, plate_scale_ppm, plate_cte_ppm_per_K, temp_u_K
        The checked arguments (views as dicts with all six keys).

    Raises
    ------
    ValueError
        An inconsistent plan or a bad value, named (:class:`InputError`).
    TypeError
        An argument of the wrong type, named (:class:`ArgumentTypeError`).
    """

    def __init__(self, n: int, pitch_mm: float, views: "_Sequence[_Mapping[str, _Any]]",
                 origin_mm: "tuple[float, float]" = (0.0, 0.0),
                 stage: "tuple[int, int] | None" = None,
                 plate_scale_ppm: "tuple[float, float] | None" = None,
                 plate_cte_ppm_per_K: "tuple[float, float] | None" = None,
                 temp_u_K: float = 0.05) -> None:
        self.n = _check.integer(n, "n", 3, 2**31 - 1)
        self.pitch_mm = _check.real(pitch_mm, "pitch_mm", low=0, low_open=True)
        self.origin_mm: "tuple[float, float]" = _check.pair(origin_mm, "origin_mm")
        self.stage: "tuple[int, int]" = (_check.pair(stage, "stage", whole=True)
                                         if stage is not None else (self.n, self.n))
        if isinstance(views, (str, bytes, _Mapping)) or not isinstance(views, _Sequence):
            raise ArgumentTypeError(f"views must be a list of dicts, not {type(views).__name__}")
        self.views = [_view(v, k, self.n) for k, v in enumerate(views)]
        self.plate_scale_ppm: "tuple[float, float] | None" = (
            None if plate_scale_ppm is None else _check.pair(plate_scale_ppm, "plate_scale_ppm"))
        self.plate_cte_ppm_per_K: "tuple[float, float] | None" = (
            None if plate_cte_ppm_per_K is None
            else _check.pair(plate_cte_ppm_per_K, "plate_cte_ppm_per_K"))
        self.temp_u_K = _check.real(temp_u_K, "temp_u_K", low=0)
        _native.grid_check(self._as_dict())  # checked by the library now, nothing solved

    @classmethod
    def _from_dict(cls, d: "dict[str, _Any]") -> "GridPlan":
        return cls(d["n"], d["pitch_mm"], d["views"], d["origin_mm"], d["stage"],
                   d.get("plate_scale_ppm"), d.get("plate_cte_ppm_per_K"), d.get("temp_u_K", 0.05))

    def _as_dict(self) -> "dict[str, _Any]":
        return dict(n=self.n, pitch_mm=self.pitch_mm, origin_mm=self.origin_mm, stage=self.stage,
                    views=self.views, plate_scale_ppm=self.plate_scale_ppm,
                    plate_cte_ppm_per_K=self.plate_cte_ppm_per_K, temp_u_K=self.temp_u_K)

    @classmethod
    def standard(cls, name: str, n: int, pitch_mm: float = 1.0,
                 origin_mm: "tuple[float, float]" = (0.0, 0.0),
                 stage: "tuple[int, int] | None" = None) -> "GridPlan":
        """A standard plan.

        Parameters
        ----------
        name : {"ye", "double-shift", "stitch"}
            ``"ye"``: {rot 0}, {rot 90}, {shift +1,0}. ``"double-shift"`` (Petrò): {rot 0},
            {rot 90}, {shift +2,0}, {shift -3,0: row c, columns c, c+1}. ``"stitch"``: a stage
            larger than the plate, covered by shifted placements plus a rotated and a +1 view.
        n : int
            Marks per row and column of the plate.
        pitch_mm : float, optional
            Mark spacing, mm (default 1).
        origin_mm : (float, float), optional
            Stage position of the grid's centre, mm.
        stage : (int, int), optional
            The stage grid (NX, NY) in nodes (``"stitch"``); default N x N.

        Returns
        -------
        GridPlan
            The plan.
        """
        _check.choice(name, "name", ("ye", "double-shift", "stitch"))
        nn = _check.integer(n, "n", 3, 2**31 - 1)
        ox, oy = _check.pair(origin_mm, "origin_mm")
        nx, ny = _check.pair(stage, "stage", whole=True) if stage is not None else (nn, nn)
        for v, what in ((nx, "stage[0]"), (ny, "stage[1]")):
            _check.integer(v, what, 1, 2**31 - 1)
        d = _native.grid_standard_plan(name, nn, _check.real(pitch_mm, "pitch_mm", low=0,
                                                             low_open=True), ox, oy, nx, ny)
        return cls._from_dict(d)

    @property
    def n_views(self) -> int:
        """The number of views."""
        return len(self.views)

    def __repr__(self) -> str:
        return (f"selfcal.GridPlan(N={self.n}, pitch_mm={self.pitch_mm:g}, stage={self.stage}, "
                f"{self.n_views} views)")


class GridMeasurement:
    """Measured mark positions of a plan, in memory (a ``selfcal-grid v1`` file's content).

    Checked when built, as the file reader checks a file: shapes, real numbers, no infinity, x
    and y measured together, only marks the view places on a stage node, none more than half a
    pitch from its nominal position.

    Parameters
    ----------
    plan : GridPlan
        The plan the marks were measured in.
    x_mm, y_mm : array_like of float, shape (views, N, N)
        The measured stage position of mark (i, j) (i = plate row, j = plate column) in each
        view, mm; NaN where not measured.
    ux_um, uy_um : array_like of float, shape (views, N, N), optional
        Standard uncertainty of each coordinate, µm (both or neither).
    t_s : array_like of float, shape (views, N, N), optional
        Time of each measurement, s (for drift).

    Raises
    ------
    ValueError
        A wrong shape, an infinite value, a mark the view does not measure (:class:`InputError`).
    TypeError
        Not a GridPlan, or arrays of text or objects (:class:`ArgumentTypeError`).
    """

    plan: GridPlan
    x_mm: _F64
    y_mm: _F64
    ux_um: "_F64 | None"
    uy_um: "_F64 | None"
    t_s: "_F64 | None"

    def __init__(self, plan: GridPlan, x_mm: _npt.ArrayLike, y_mm: _npt.ArrayLike,
                 ux_um: "_npt.ArrayLike | None" = None, uy_um: "_npt.ArrayLike | None" = None,
                 t_s: "_npt.ArrayLike | None" = None) -> None:
        if not isinstance(plan, GridPlan):
            raise ArgumentTypeError(f"plan must be a selfcal.GridPlan, not {type(plan).__name__}")
        shape = (plan.n_views, plan.n, plan.n)
        self.plan = plan
        self.x_mm = _check.array(x_mm, "x_mm", shape)
        self.y_mm = _check.array(y_mm, "y_mm", shape)
        if (ux_um is None) != (uy_um is None):
            raise InputError("give both ux_um and uy_um, or neither")
        self.ux_um = None if ux_um is None else _check.array(ux_um, "ux_um", shape)
        self.uy_um = None if uy_um is None else _check.array(uy_um, "uy_um", shape)
        self.t_s = None if t_s is None else _check.array(t_s, "t_s", shape)
        _native.grid_check(self._as_dict())

    @classmethod
    def _from_dict(cls, d: "dict[str, _Any]") -> "GridMeasurement":
        # the library's own output: built without checking it again
        m = cls.__new__(cls)
        m.plan = GridPlan._from_dict(d["plan"])
        m.x_mm, m.y_mm, m.ux_um, m.uy_um, m.t_s = (d["x_mm"], d["y_mm"], d["ux_um"], d["uy_um"],
                                                   d["t_s"])
        return m

    def _as_dict(self) -> "dict[str, _Any]":
        if (self.ux_um is None) != (self.uy_um is None):
            raise InputError("give both ux_um and uy_um, or neither")
        return dict(plan=self.plan._as_dict(), x_mm=self.x_mm, y_mm=self.y_mm, ux_um=self.ux_um,
                    uy_um=self.uy_um, t_s=self.t_s)

    def write(self, path: _PathLike) -> None:
        """Write as a ``selfcal-grid v1`` file, atomically (complete or absent).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write.

        Raises
        ------
        FileNotFoundError, PermissionError, IsADirectoryError
            The file cannot be written there.
        """
        _native.grid_write(_check.fspath(path, "path"), self._as_dict())

    def __repr__(self) -> str:
        return (f"selfcal.GridMeasurement({self.plan!r}, "
                f"{int(_np.isfinite(self.x_mm).sum())} marks measured)")


def read_grid(path: _PathLike) -> GridMeasurement:
    """Read a ``selfcal-grid v1`` data file strictly, as the command line does.

    Parameters
    ----------
    path : str or os.PathLike
        The data file.

    Returns
    -------
    GridMeasurement
        Its plan and measured positions.

    Raises
    ------
    FileNotFoundError, PermissionError, IsADirectoryError
        The file cannot be read (``e.filename``, ``e.errno``).
    ValueError
        Bad content, with ``file:line: reason`` (:class:`InputError`).
    """
    return GridMeasurement._from_dict(_native.grid_read(_check.fspath(path, "path")))


def _grid_source(source: object) -> object:
    if isinstance(source, (GridMeasurement, GridPlan)):
        return source._as_dict()
    if _check.path_like(source):
        return _check.fspath(source, "source")
    raise ArgumentTypeError(f"source must be a file path, a selfcal.GridMeasurement or a "
                            f"selfcal.GridPlan, not {type(source).__name__}")


class PlanAnalysis:
    """What ``selfcal plan`` says of a plan, before measuring.

    Attributes
    ----------
    identifiable : bool
        Does the plan determine G?
    free : int
        Degrees of freedom beyond the gauge left free (0 when identifiable).
    sigma_c_ratio_rms, sigma_c_ratio_max : float
        Predicted std(G)/σ_r, RMS over the nodes and worst node (the plan's geometry, equal
        weights); inf when not identifiable.
    sigma_c_rms_um, sigma_c_max_um : float
        std(G), µm, with the uncertainties the views or data state; NaN when they state none.
    sigma_ratio_gx, sigma_ratio_gy : numpy.ndarray, shape (NY, NX)
        std(G)/σ_r per node.
    n_unknowns, n_equations, n_constraints, n_stage_unmeasured : int
        Counts.
    residual_dof : int
        The residuals' degrees of freedom; -1 when not identifiable.
    n_testable, n_untestable : int
        Coordinate equations Baarda's test can and cannot check.
    redundancy_min, redundancy_mean : float
        Redundancy numbers (NaN when not identifiable).
    mdb_ratio_max, mdb_ratio_mean_r : float
        Minimal detectable blunders, in σ (80 % power, the default outlier test).
    plan : GridPlan
        The plan analysed.
    """

    identifiable: bool
    free: int
    sigma_c_ratio_rms: float
    sigma_c_ratio_max: float
    sigma_c_rms_um: float
    sigma_c_max_um: float
    sigma_ratio_gx: _F64
    sigma_ratio_gy: _F64
    n_unknowns: int
    n_equations: int
    n_constraints: int
    n_stage_unmeasured: int
    residual_dof: int
    n_testable: int
    n_untestable: int
    redundancy_min: float
    redundancy_mean: float
    mdb_ratio_max: float
    mdb_ratio_mean_r: float
    plan: GridPlan

    def __init__(self, d: "dict[str, _Any]") -> None:
        for k, v in d.items():
            setattr(self, k, v)
        self.identifiable = bool(self.identifiable)
        self.plan = GridPlan._from_dict(d["plan"])

    def __repr__(self) -> str:
        return (f"selfcal.PlanAnalysis(identifiable={self.identifiable}, free={self.free}, "
                f"sigma_c_ratio_rms={self.sigma_c_ratio_rms:.4g}, "
                f"sigma_c_ratio_max={self.sigma_c_ratio_max:.4g})")


def plan(source: "_PathLike | GridPlan | GridMeasurement") -> PlanAnalysis:
    """Analyse a plan before measuring, as ``selfcal plan`` (least squares: loads CHOLMOD).

    Parameters
    ----------
    source : str, os.PathLike, GridPlan or GridMeasurement
        A plan or data file, a plan (what its views would measure) or a measurement (what was
        measured).

    Returns
    -------
    PlanAnalysis
        Identifiability, predicted uncertainties and reliability.
    """
    return PlanAnalysis(_native.grid_plan(_grid_source(source)))


class GridResult:
    """A grid calibration (what ``selfcal grid`` writes and prints).

    Arrays are indexed [i, j] as the map file (i along y).

    Attributes
    ----------
    method : str
        ``"lsq"``, ``"ye"`` or ``"double-shift"``.
    gx_um, gy_um : numpy.ndarray, shape (NY, NX)
        The stage error G at the nodes, µm.
    ugx_um, ugy_um : numpy.ndarray, shape (NY, NX)
        Their standard uncertainties (k = 1), µm; NaN for the closed forms. With a plate scale
        (SPEC §11) the combined uncertainties of the budget.
    x_mm, y_mm : numpy.ndarray, shape (NY, NX)
        The node positions, mm.
    ax_um, ay_um : numpy.ndarray, shape (N, N)
        The plate error, µm; NaN for an unmeasured mark.
    O_urad, R_ppm, uO_urad, uR_ppm : float
        Non-orthogonality (µrad) and scale (ppm = µm/m) with their uncertainties (the
        dimensionless ``O``, ``R``, ``uO``, ``uR`` are kept through version 0.3).
    tx_um, ty_um, theta_urad, utx_um, uty_um, utheta_urad : numpy.ndarray, shape (views,)
        The views' misalignments and their uncertainties.
    residual_rms_um, sigma_r_est_um, sigma_r_used_um : float
        Residual RMS, the noise estimated from the residuals and the one used, µm.
    dof : int
        The residuals' degrees of freedom.
    variance_factor : float
        The χ² test's variance factor (NaN where no test ran).
    chi2_pass : bool or None
        The χ² test's result; None where no test ran (no stated noise, or each view's noise
        estimated): the command line's "n/a".
    rx_um, ry_um, tx, ty : numpy.ndarray, shape (views, N, N)
        Least squares: the residuals (µm) and the standardized residuals.
    outlier : numpy.ndarray of bool, shape (views, N, N)
        Flagged by Baarda's test (``outlier_alpha``, ``outlier_alpha_each``,
        ``outlier_alpha_coord``, the critical value ``outlier_crit`` of |t|,
        ``n_outlier_tests``, ``n_flagged``, ``n_removed``).
    view_sigma_um, view_sigma_u_um, view_noise_factor : numpy.ndarray, shape (views,)
        With ``view_noise="estimate"``: each view's noise (µm), its uncertainty and the factor
        on its stated uncertainties (NaN if it stated none).
    covariance_um2 : numpy.ndarray or None
        On request: the full covariance of G, µm².
    magnification_ppm, u_magnification_ppm : float
        The plate scale's part (NaN when the data give no ``plate_scale_ppm``:
        ``scale_included`` is then False).
    budget : dict
        The uncertainty budget at the worst ``node``: ``view_scale_ppm`` (and with
        ``view_scale="free"`` ``view_scale_free_ppm``, ``u_view_scale_free_ppm``), the noise
        part ``ugx_noise_um``, ``ugy_noise_um``, ``rows`` (source, unit, u,
        sensitivity_um_per_unit, contribution_um, dof), ``u_c_um``, ``nu_eff``, ``k``
        (``k_from``: "2" or "welch-satterthwaite") and ``U_um``.
    monte_carlo : dict or None
        With ``monte_carlo=M``: per node ``ugx_um``, ``ugy_um``, their ``ratio_x``,
        ``ratio_y`` to the budget's, the 95 % intervals ``gx_lo_um`` ... ``gy_hi_um``, and
        ``ratio_min``, ``ratio_max``, ``ratio_mean``, ``seconds``, ``threads``.
    warnings : list of str
        The lines ``selfcal grid`` prints as warnings.
    """

    method: str
    gx_um: _F64
    gy_um: _F64
    ugx_um: _F64
    ugy_um: _F64
    x_mm: _F64
    y_mm: _F64
    ax_um: _F64
    ay_um: _F64
    O_urad: float
    R_ppm: float
    uO_urad: float
    uR_ppm: float
    O: float
    R: float
    uO: float
    uR: float
    tx_um: _F64
    ty_um: _F64
    theta_urad: _F64
    utx_um: _F64
    uty_um: _F64
    utheta_urad: _F64
    residual_rms_um: float
    sigma_r_est_um: float
    sigma_r_used_um: float
    n_measurements: int
    dof: int
    weighted: bool
    variance_factor: float
    chi2_lo: float
    chi2_hi: float
    chi2_pass: "bool | None"
    rx_um: _F64
    ry_um: _F64
    tx: _F64
    ty: _F64
    outlier: "_npt.NDArray[_np.bool_]"
    n_flagged: int
    n_removed: int
    covariance_um2: "_F64 | None"
    warnings: "list[str]"
    outlier_alpha: float
    outlier_alpha_each: bool
    outlier_alpha_coord: float
    outlier_crit: float
    n_outlier_tests: int
    view_noise_estimated: bool
    view_sigma_um: _F64
    view_noise_factor: _F64
    view_sigma_u_um: _F64
    scale_included: bool
    magnification_ppm: float
    u_magnification_ppm: float
    budget: "dict[str, _Any]"
    monte_carlo: "dict[str, _Any] | None"

    def __init__(self, d: "dict[str, _Any]", method: str) -> None:
        self.method = method
        for k, v in d.items():
            setattr(self, k, v)
        tested = self.variance_factor == self.variance_factor and not self.view_noise_estimated
        self.chi2_pass = bool(self.chi2_pass) if tested else None
        self.weighted = bool(self.weighted)
        self.outlier_alpha_each = bool(self.outlier_alpha_each)
        self.view_noise_estimated = bool(self.view_noise_estimated)
        self.scale_included = bool(self.budget["scale_included"])
        self.magnification_ppm = self.budget["magnification_ppm"]
        self.u_magnification_ppm = self.budget["u_magnification_ppm"]

    def expanded(self, k: float = 2.0) -> "tuple[_F64, _F64]":
        """The expanded uncertainties of G (GUM).

        Parameters
        ----------
        k : float, optional
            The coverage factor (default 2).

        Returns
        -------
        (numpy.ndarray, numpy.ndarray)
            k·u(Gx), k·u(Gy), µm, shape (NY, NX).
        """
        kk = _check.real(k, "k", low=0)
        return kk * self.ugx_um, kk * self.ugy_um

    def __repr__(self) -> str:
        ny, nx = self.gx_um.shape
        return (f"selfcal.GridResult({self.method}, stage {nx} x {ny}, "
                f"sigma_r_est_um={self.sigma_r_est_um:.4g})")


def _node_sigma(value: object) -> "tuple[int, int]":
    """``node_sigma`` of calibrate_grid as (mode, K): "all", "none", ("sample", K), "sample:K"."""
    known = "'all', 'none', ('sample', K) or 'sample:K'"
    if isinstance(value, str):
        if value == "all":
            return _NODE_SIGMA_ALL, 0
        if value == "none":
            return _NODE_SIGMA_NONE, 0
        if value.startswith("sample:"):
            try:
                k = int(value[7:], 10)
            except ValueError:
                raise InputError(f"node_sigma must be {known}, not {value!r}") from None
            return _NODE_SIGMA_SAMPLE, _check.integer(k, "node_sigma's K", 1, 10**6)
        raise InputError(f"node_sigma must be {known}, not {value!r}")
    if isinstance(value, tuple) and len(value) == 2 and value[0] == "sample":
        return _NODE_SIGMA_SAMPLE, _check.integer(value[1], "node_sigma's K", 1, 10**6)
    raise ArgumentTypeError(f"node_sigma must be {known}, not {type(value).__name__}")


def calibrate_grid(source: "_PathLike | GridMeasurement", method: str = "lsq",
                   sigma_r_um: "float | None" = None, drift: bool = False,
                   reject_outliers: bool = False, covariance: bool = False,
                   outlier_alpha: "float | None" = None,
                   outlier_alpha_each: "float | None" = None,
                   view_noise: str = "stated", view_scale: str = "model",
                   monte_carlo: "int | None" = None, seed: int = 1,
                   progress: "_Callable[[str, float, float, float], object] | None" = None,
                   max_memory: "float | None" = None, solver: str = "auto",
                   node_sigma: "str | tuple[str, int]" = "all") -> GridResult:
    """Separate the stage error G from the plate error A, as ``selfcal grid``.

    Parameters
    ----------
    source : str, os.PathLike or GridMeasurement
        A ``selfcal-grid v1`` file or a measurement in memory.
    method : {"lsq", "ye", "double-shift"}
        ``"lsq"``: least squares (any identifying plan, weights, uncertainties, residuals,
        Baarda's outlier test; loads CHOLMOD); ``"ye"``, ``"double-shift"``: the closed forms
        (no CHOLMOD).
    sigma_r_um : float, optional
        The measurement noise if known, µm (> 0; data without stated uncertainties); else
        estimated from the residuals.
    drift : bool
        Per-view linear drift (needs ``t_s``).
    reject_outliers : bool
        Remove the worst flagged measurement and solve again until none is flagged.
    covariance : bool
        The full covariance of G (small stages).
    outlier_alpha : float, optional
        The outlier test's significance for the whole data set (0 < α < 1, default 0.05, as
        ``--outlier-alpha``).
    outlier_alpha_each : float, optional
        Instead: for each coordinate on its own (Baarda's α0, e.g. 0.001).
    view_noise : {"stated", "estimate"}
        ``"estimate"``: each view's noise estimated from its residuals (variance components).
    view_scale : {"model", "free"}
        ``"free"``: each view's scale relative to the others an unknown (least squares).
    monte_carlo : int, optional
        Trials (2 .. 1e7) of the Monte Carlo check of the budget (least squares).
    seed : int
        The Monte Carlo seed (0 .. 2^64 - 1).
    progress : callable, optional
        ``progress(phase, work_done, work_total, peak_bytes)``, called as a least-squares solve
        goes (phases ``"assemble"``, ``"analyse"``, ``"factor"``, ``"selected inverse"``,
        ``"solve"``, ``"residuals"``; work in multiply-adds; the peak memory estimated so far,
        bytes); an exception it raises is raised after the solve.
    max_memory : float, optional
        Bytes a solve may use (default: the machine's available memory).
    solver : {"auto", "reduced", "full"}
        Which normal matrix the least squares factor, as ``--solver``: ``"reduced"`` (the plate
        error A eliminated: plate-sized stages, a few views), ``"full"`` (A kept as unknowns:
        stitched stages of hundreds of placements) or ``"auto"`` (full when a mark is measured
        in more than about 17 views on average). Both give the same results.
    node_sigma : {"all", "none"} or ("sample", K) or "sample:K"
        Which uncertainties of G the least squares compute, as ``--node-sigma``: ``"all"``
        every node's and every measurement's leverage (the outlier test needs them);
        ``"none"`` neither (``ugx_um``, ``ugy_um`` and the residuals' t NaN, no outlier test);
        ``("sample", K)`` or ``"sample:K"``: K nodes spread over the stage (1 <= K <= 10^6),
        the others NaN. Other than ``"all"`` it excludes ``reject_outliers``,
        ``view_noise="estimate"`` and ``monte_carlo``.

    Returns
    -------
    GridResult
        G, A, their uncertainties and the diagnostics. Warnings (outliers, the χ² test,
        significant view scales) are in ``result.warnings`` and issued with :mod:`warnings`.

    Raises
    ------
    FileNotFoundError, PermissionError, IsADirectoryError
        The file cannot be read.
    ValueError
        Bad content or arguments (:class:`InputError`); a plan that does not identify G
        (:class:`UnsolvableError`).
    TypeError
        An argument of the wrong type (:class:`ArgumentTypeError`).
    MemoryError
        A solve estimated to need more than ``max_memory`` (:class:`OutOfMemoryError`).
    """
    src = _grid_source(source)
    if progress is not None and not callable(progress):
        raise ArgumentTypeError("progress must be callable")
    mm = _check.opt_real(max_memory, "max_memory", low=0, low_open=True)
    _check.choice(method, "method", _GRID_METHODS)
    sr = _check.opt_real(sigma_r_um, "sigma_r_um", low=0, low_open=True)
    flags = [_check.flag(v, name) for v, name in ((drift, "drift"),
                                                  (reject_outliers, "reject_outliers"),
                                                  (covariance, "covariance"))]
    oa = _check.opt_real(outlier_alpha, "outlier_alpha", low=0, low_open=True, high=1)
    oe = _check.opt_real(outlier_alpha_each, "outlier_alpha_each", low=0, low_open=True, high=1)
    if oa is not None and oe is not None:
        raise InputError("outlier_alpha and outlier_alpha_each exclude each other")
    alpha = oa if oe is None else oe
    if alpha is not None and alpha >= 1:
        raise InputError("the outlier test's significance must lie between 0 and 1")
    _check.choice(view_noise, "view_noise", ("stated", "estimate"))
    _check.choice(view_scale, "view_scale", ("model", "free"))
    mc = None if monte_carlo is None else _check.integer(monte_carlo, "monte_carlo", 2, 10**7)
    sd = _check.integer(seed, "seed", 0, 2**64 - 1)
    if (view_scale == "free" or mc) and method != "lsq":
        raise InputError("view_scale='free' and monte_carlo need method 'lsq'")
    _check.choice(solver, "solver", tuple(_GRID_SOLVERS))
    ns_mode, ns_k = _node_sigma(node_sigma)
    if ns_mode != _NODE_SIGMA_ALL and (flags[1] or view_noise == "estimate" or mc):
        raise InputError("reject_outliers, view_noise='estimate' and monte_carlo need every "
                         "leverage: node_sigma='all'")
    d = _native.grid_calibrate(src, _GRID_METHODS[method], float(sr or 0.0), flags[0],
                               flags[1], flags[2], float(alpha or 0.0), oe is not None,
                               view_noise == "estimate", view_scale == "free", int(mc or 0), sd,
                               progress, float(mm or 0.0), _GRID_SOLVERS[solver], ns_mode,
                               ns_k)
    r = GridResult(d, method)
    for msg in r.warnings:
        _warnings.warn(msg, stacklevel=2)
    return r


_SIM_GRID_PARAMS = ("rho", "O_urad", "R_ppm", "O", "R", "sigma_a_um", "sigma_t_um",
                    "sigma_theta_urad", "dt_s", "drift_vx_um_s", "drift_vy_um_s")


def simulate_grid(plan: "str | GridPlan" = "double-shift", n: int = 25, pitch_mm: float = 1.0,
                  stage: "tuple[int, int] | None" = None, sigma_r_um: float = 0.01,
                  sigma_g_um: float = 1.0, seed: int = 1,
                  **params: float) -> "tuple[GridMeasurement, dict[str, _Any]]":
    """Simulate a plate measured in a plan, as ``selfcal simulate grid`` (Petrò §5).

    No least squares: works without CHOLMOD.

    Parameters
    ----------
    plan : str or GridPlan
        A plan, or a standard plan's name (``"ye"``, ``"double-shift"``, ``"stitch"`` with
        ``stage``).
    n : int
        Marks per row and column (standard plans).
    pitch_mm : float
        Mark spacing, mm (standard plans).
    stage : (int, int), optional
        The stage grid (NX, NY) of ``"stitch"``.
    sigma_r_um : float
        Measurement noise, µm (>= 0).
    sigma_g_um : float
        RMS of the random stage error, µm (>= 0).
    seed : int
        The random seed (same seed, same data as the command line).
    **params : float
        ``rho``, ``O_urad``, ``R_ppm`` (or the dimensionless ``O``, ``R``, kept through
        version 0.3), ``sigma_a_um``, ``sigma_t_um``, ``sigma_theta_urad``, ``dt_s``,
        ``drift_vx_um_s``, ``drift_vy_um_s``; any other name is refused (TypeError, with the
        list).

    Returns
    -------
    measurement : GridMeasurement
        The simulated measurement.
    truth : dict
        ``gx_um``, ``gy_um`` (NY, NX), ``ax_um``, ``ay_um`` (N, N), ``O_urad``, ``R_ppm`` (and
        ``O``, ``R``) and the views' misalignments, all in the SPEC gauge.
    """
    _check.kwargs(params, _SIM_GRID_PARAMS, "simulate_grid")
    p: "dict[str, _Any]" = {k: _check.real(v, k) for k, v in params.items()}
    for k in ("O", "R"):  # the keys with their unit: µrad and ppm
        unit = k + ("_urad" if k == "O" else "_ppm")
        if unit in p:
            if k in p:
                raise ArgumentTypeError(f"give {unit} or {k}, not both")
            p[k] = p.pop(unit) * 1e-6
    if isinstance(plan, str):
        plan = GridPlan.standard(plan, n, pitch_mm, stage=stage)
    elif not isinstance(plan, GridPlan):
        raise ArgumentTypeError(f"plan must be a selfcal.GridPlan or a standard plan's name, "
                                f"not {type(plan).__name__}")
    p.update(sigma_r_um=_check.real(sigma_r_um, "sigma_r_um", low=0),
             sigma_g_um=_check.real(sigma_g_um, "sigma_g_um", low=0),
             seed=_check.integer(seed, "seed", 0, 2**64 - 1))
    meas, truth = _native.grid_simulate(plan._as_dict(), p)
    return GridMeasurement._from_dict(meas), truth


# ---- straightness profiles (SPEC §2) ----

_PROFILE_METHODS = {"dft": 0, "lsq": 1}


def _nan_pad(v: _F64, n: int) -> _F64:
    out = _np.full(n, _np.nan)
    out[: len(v)] = v
    return out


def _scans(value: object, name: str, n: int, d: "tuple[int, int]") -> "tuple[_F64, _F64]":
    items = _check.two(value)
    if items is None:
        raise ArgumentTypeError(f"{name} must hold the two scans' arrays")
    a, b = items
    return (_check.array(a, f"{name}[0]", (n - d[0],)), _check.array(b, f"{name}[1]", (n - d[1],)))


class ProfileMeasurement:
    """A two-scan straightness measurement (``selfcal-profile v1``), in memory.

    Checked when built, as the file reader checks a file.

    Parameters
    ----------
    n : int
        Points of the profile.
    s_mm : float
        The sampling interval, mm (> 0).
    d1, d2 : int
        The sensor spacings of scans 1 and 2, in samples.
    m1_um, m2_um : pair of array_like of float
        Per scan k = 0, 1: the displacement sensors' readings, µm, ``n - d_k`` values each.
    m3_urad : pair of array_like of float
        Per scan: the angle sensor's readings, µrad, ``n - d_k`` values each.
    sigma_disp_um : float, optional
        The displacement sensors' noise, µm (>= 0; None: not stated).
    sigma_angle_urad : float, optional
        The angle sensor's noise, µrad (>= 0; None: not stated).

    Raises
    ------
    ValueError
        A wrong length, a value that is not finite, bad spacings (:class:`InputError`).
    TypeError
        Text where numbers are needed (:class:`ArgumentTypeError`).
    """

    n: int
    s_mm: float
    d1: int
    d2: int
    m1_um: "tuple[_F64, _F64]"
    m2_um: "tuple[_F64, _F64]"
    m3_urad: "tuple[_F64, _F64]"
    sigma_disp_um: "float | None"
    sigma_angle_urad: "float | None"

    def __init__(self, n: int, s_mm: float, d1: int, d2: int,
                 m1_um: "_Sequence[_npt.ArrayLike]", m2_um: "_Sequence[_npt.ArrayLike]",
                 m3_urad: "_Sequence[_npt.ArrayLike]", sigma_disp_um: "float | None" = None,
                 sigma_angle_urad: "float | None" = None) -> None:
        self.n = _check.integer(n, "n", 2, 2**31 - 1)
        self.s_mm = _check.real(s_mm, "s_mm", low=0, low_open=True)
        self.d1 = _check.integer(d1, "d1", 1, self.n - 1)
        self.d2 = _check.integer(d2, "d2", 1, self.n - 1)
        d = (self.d1, self.d2)
        self.m1_um = _scans(m1_um, "m1_um", self.n, d)
        self.m2_um = _scans(m2_um, "m2_um", self.n, d)
        self.m3_urad = _scans(m3_urad, "m3_urad", self.n, d)
        self.sigma_disp_um = _check.opt_real(sigma_disp_um, "sigma_disp_um", low=0)
        self.sigma_angle_urad = _check.opt_real(sigma_angle_urad, "sigma_angle_urad", low=0)
        _native.profile_check(self._as_dict())

    @classmethod
    def _from_dict(cls, d: "dict[str, _Any]") -> "ProfileMeasurement":
        m = cls.__new__(cls)  # the library's own output: not checked again
        m.n, m.s_mm, m.d1, m.d2 = d["n"], d["s_mm"], d["d1"], d["d2"]
        m.m1_um, m.m2_um, m.m3_urad = d["m1_um"], d["m2_um"], d["m3_urad"]
        m.sigma_disp_um, m.sigma_angle_urad = d["sigma_disp_um"], d["sigma_angle_urad"]
        return m

    def _as_dict(self) -> "dict[str, _Any]":
        return dict(n=self.n, s_mm=self.s_mm, d1=self.d1, d2=self.d2, m1_um=self.m1_um,
                    m2_um=self.m2_um, m3_urad=self.m3_urad, sigma_disp_um=self.sigma_disp_um,
                    sigma_angle_urad=self.sigma_angle_urad)

    def write(self, path: _PathLike) -> None:
        """Write as a ``selfcal-profile v1`` file, atomically (complete or absent).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write.
        """
        _native.profile_write(_check.fspath(path, "path"), self._as_dict())

    def __repr__(self) -> str:
        return f"selfcal.ProfileMeasurement(N={self.n}, s_mm={self.s_mm:g}, d={self.d1}/{self.d2})"


def read_profile(path: _PathLike) -> ProfileMeasurement:
    """Read a ``selfcal-profile v1`` file strictly, as the command line does.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    ProfileMeasurement
        The two scans.

    Raises
    ------
    FileNotFoundError, PermissionError, IsADirectoryError
        The file cannot be read.
    ValueError
        Bad content, with ``file:line: reason`` (:class:`InputError`).
    """
    return ProfileMeasurement._from_dict(_native.profile_read(_check.fspath(path, "path")))


class ProfileResult:
    """A reconstructed straightness profile.

    Attributes
    ----------
    method : str
        ``"lsq"`` or ``"dft"``.
    x_mm : numpy.ndarray, shape (N,)
        Positions, mm.
    f_um : numpy.ndarray, shape (N,)
        The profile relative to its least-squares line, µm.
    uf_um : numpy.ndarray, shape (N,)
        Its standard uncertainty (k = 1), µm; NaN when no noise is known or estimable.
    ey_um : numpy.ndarray, shape (N,)
        The stage's straightness motion error from scan 1, µm; NaN for n >= N - d1.
    noise_known : bool
        The noise was given (else estimated from the residuals).
    have_uf : bool
        ``uf_um`` holds uncertainties.
    sigma_disp_um, sigma_angle_urad : float
        The noise used, µm and µrad.
    sigma_y1_um, sigma_y2_um : float
        The noise of the combined differences used, µm.
    dof : int
        Degrees of freedom of the residuals.
    wrss : float
        Weighted residual sum of squares.
    residual_ratio : float
        sqrt(wrss/dof) against a given noise; NaN when estimated.
    n, d1, d2 : int
        Points and spacings.
    s_mm : float
        Sampling interval, mm.
    """

    method: str
    x_mm: _F64
    f_um: _F64
    uf_um: _F64
    ey_um: _F64
    noise_known: bool
    have_uf: bool
    sigma_disp_um: float
    sigma_angle_urad: float
    sigma_y1_um: float
    sigma_y2_um: float
    dof: int
    wrss: float
    residual_ratio: float
    n: int
    s_mm: float
    d1: int
    d2: int

    def __init__(self, d: "dict[str, _Any]", method: str) -> None:
        self.method = method
        for k, v in d.items():
            setattr(self, k, v)
        self.noise_known = bool(self.noise_known)
        self.have_uf = bool(self.have_uf)

    def expanded_uf_um(self, k: float = 2.0) -> _F64:
        """The expanded uncertainty k·u(f) (GUM).

        Parameters
        ----------
        k : float, optional
            The coverage factor (default 2).

        Returns
        -------
        numpy.ndarray
            k·u(f), µm, shape (N,).
        """
        return _check.real(k, "k", low=0) * self.uf_um

    def __repr__(self) -> str:
        return f"selfcal.ProfileResult({self.method}, N={self.n}, d={self.d1}/{self.d2})"


def calibrate_profile(source: "_PathLike | ProfileMeasurement", method: str = "lsq",
                      sigma_disp_um: "float | None" = None,
                      sigma_angle_urad: "float | None" = None,
                      mc_trials: int = 0, seed: int = 1) -> ProfileResult:
    """Reconstruct a straightness profile by the two-set two-point method, as ``selfcal profile``.

    Parameters
    ----------
    source : str, os.PathLike or ProfileMeasurement
        A ``selfcal-profile v1`` file or a measurement in memory.
    method : {"lsq", "dft"}
        Least squares (any coprime d1, d2 with N >= d1 + d2) or the DFT.
    sigma_disp_um : float, optional
        Noise of each displacement sensor, µm (>= 0); wins over the file's header line.
    sigma_angle_urad : float, optional
        Noise of the angle sensor, µrad (>= 0). With neither given nor stated, the noise is
        estimated from the residuals.
    mc_trials : int
        0: analytic uncertainties; 2 .. 1e8: Monte Carlo ones.
    seed : int
        The Monte Carlo seed.

    Returns
    -------
    ProfileResult
        The profile, its uncertainty and the motion error.

    Raises
    ------
    FileNotFoundError, PermissionError, IsADirectoryError
        The file cannot be read.
    ValueError
        Bad content or arguments (:class:`InputError`).
    """
    _check.choice(method, "method", _PROFILE_METHODS)
    if isinstance(source, ProfileMeasurement):
        src: object = source._as_dict()
    elif _check.path_like(source):
        src = _os.fspath(source)
    else:
        raise ArgumentTypeError(f"source must be a file path or a selfcal.ProfileMeasurement, "
                                f"not {type(source).__name__}")
    sd = _check.opt_real(sigma_disp_um, "sigma_disp_um")
    sa = _check.opt_real(sigma_angle_urad, "sigma_angle_urad")
    d = _native.profile_calibrate(src, _PROFILE_METHODS[method], sd, sa,
                                  _check.integer(mc_trials, "mc_trials"),
                                  _check.integer(seed, "seed", 0, 2**64 - 1))
    return ProfileResult(d, method)


_SIM_PROFILE_PARAMS = ("ey_amp_um", "ep_amp_urad", "u1_um", "u2_um", "u3_urad", "b0_um")


def simulate_profile(n: int = 330, s_mm: float = 1.0, d1: int = 10, d2: int = 11,
                     sigma_disp_um: float = 0.01, sigma_angle_urad: float = 1.0,
                     f_um: "_npt.ArrayLike | None" = None, amp_um: float = 1.0,
                     harmonics: int = 40, dabam: "_PathLike | None" = None,
                     seed: int = 1, write_sigma: bool = True,
                     **instrument: float) -> "tuple[ProfileMeasurement, dict[str, _F64]]":
    """Simulate a two-scan measurement of a profile, as ``selfcal simulate profile``.

    Parameters
    ----------
    n : int
        Points.
    s_mm : float
        Sampling interval, mm.
    d1, d2 : int
        Sensor spacings of the two scans, samples.
    sigma_disp_um, sigma_angle_urad : float
        Sensor noise, µm and µrad.
    f_um : array_like of float, optional
        The profile, N values, µm.
    amp_um : float
        Else the RMS of a random smooth profile, µm (same seed, same profile as the command
        line) ...
    harmonics : int
        ... of this many harmonics (1 .. 100000).
    dabam : str or os.PathLike, optional
        Or a DABAM ``.dat`` file (with its ``.txt`` beside it).
    seed : int
        The random seed.
    write_sigma : bool
        State the noise in the measurement.
    **instrument : float
        ``ey_amp_um``, ``ep_amp_urad``, ``u1_um``, ``u2_um``, ``u3_urad``, ``b0_um``; any other
        name is refused (TypeError, with the list).

    Returns
    -------
    measurement : ProfileMeasurement
        The simulated scans.
    truth : dict
        ``x_mm``, ``f_um`` and ``ey_um`` (N values; e_y relative to its least-squares line, NaN
        for n >= N - d1).
    """
    _check.kwargs(instrument, _SIM_PROFILE_PARAMS, "simulate_profile")
    nn = _check.integer(n, "n", 2, 100000000)
    params = dict(n=nn,
                  s_mm=_check.real(s_mm, "s_mm", low=0, low_open=True),
                  d1=_check.integer(d1, "d1", 1, 2**31 - 1),
                  d2=_check.integer(d2, "d2", 1, 2**31 - 1),
                  sigma_disp_um=_check.real(sigma_disp_um, "sigma_disp_um", low=0),
                  sigma_angle_urad=_check.real(sigma_angle_urad, "sigma_angle_urad", low=0),
                  seed=_check.integer(seed, "seed", 0, 2**64 - 1),
                  write_sigma=int(_check.flag(write_sigma, "write_sigma")),
                  **{k: _check.real(v, k) for k, v in instrument.items()})
    f = None if f_um is None else _check.array(f_um, "f_um", (nn,), nan_ok=False)
    path = None if dabam is None else _check.fspath(dabam, "dabam")
    meas, fv, ey = _native.profile_simulate(params, f, _check.real(amp_um, "amp_um"),
                                            _check.integer(harmonics, "harmonics", -2**31,
                                                           2**31 - 1), path)
    m = ProfileMeasurement._from_dict(meas)
    return m, {"x_mm": _np.arange(m.n) * m.s_mm, "f_um": fv, "ey_um": _nan_pad(ey, m.n)}


_AXES = {"x": 0, "y": 1, "z": 2}
_PROFILE_KEYS = ("axis", "dir", "start_mm", "step_mm", "err_um")


def build_table(path: _PathLike, gx_um: _npt.ArrayLike, gy_um: _npt.ArrayLike, x0_mm: float,
                y0_mm: float, px_mm: float, py_mm: "float | None" = None,
                profiles: "_Sequence[_Mapping[str, _Any]]" = (), method: str = "",
                sigma_um: float = -1.0, created_unix_s: "int | None" = None) -> Table:
    """Write a correction table from arrays, as ``selfcal lut build`` does from files.

    Parameters
    ----------
    path : str or os.PathLike
        The table file to write (atomically).
    gx_um, gy_um : array_like of float, shape (NY, NX)
        The stage error at the nodes, µm, indexed [i, j] (i along y).
    x0_mm, y0_mm : float
        Position of node (0, 0), mm.
    px_mm : float
        Node pitch along x, mm.
    py_mm : float, optional
        Node pitch along y, mm (default: ``px_mm``).
    profiles : sequence of dict
        Straightness errors, each with the keys ``axis`` and ``dir`` (``"x"``, ``"y"`` or
        ``"z"``: the error of coordinate dir as a function of axis), ``start_mm``, ``step_mm``
        and ``err_um`` (values at start + k·step, µm); any other key is refused.
    method : str
        Provenance: the method that made G.
    sigma_um : float
        Provenance: its uncertainty, µm (-1: not stated).
    created_unix_s : int, optional
        Creation time (default: SOURCE_DATE_EPOCH, else now).

    Returns
    -------
    Table
        The table loaded from the file written. A GridResult's map goes in as
        ``build_table(p, r.gx_um, r.gy_um, r.x_mm[0, 0], r.y_mm[0, 0], pitch)``.
    """
    if created_unix_s is None:
        created_unix_s = int(_os.environ.get("SOURCE_DATE_EPOCH", _time.time()))
    if isinstance(profiles, (str, bytes, _Mapping)) or not isinstance(profiles, _Sequence):
        raise ArgumentTypeError(f"profiles must be a list of dicts, not {type(profiles).__name__}")
    prof = []
    for k, p in enumerate(profiles):
        what = f"profiles[{k}]"
        _check.keys(p, _PROFILE_KEYS, what, required=_PROFILE_KEYS)
        axes = []
        for key in ("axis", "dir"):
            v = p[key]
            if not isinstance(v, str) or v.lower() not in _AXES:
                raise InputError(f"{what}['{key}'] must be 'x', 'y' or 'z', not {v!r}")
            axes.append(_AXES[v.lower()])
        prof.append((axes[0], axes[1], _check.real(p["start_mm"], f"{what}['start_mm']"),
                     _check.real(p["step_mm"], f"{what}['step_mm']"),
                     _check.array(p["err_um"], f"{what}['err_um']", ndim=1, nan_ok=False)))
    px = _check.real(px_mm, "px_mm")
    if not isinstance(method, str):
        raise ArgumentTypeError(f"method must be text, not {type(method).__name__}")
    _native.lut_build(_check.fspath(path, "path"), _check.array(gx_um, "gx_um", ndim=2),
                      _check.array(gy_um, "gy_um", ndim=2), _check.real(x0_mm, "x0_mm"),
                      _check.real(y0_mm, "y0_mm"), px,
                      px if py_mm is None else _check.real(py_mm, "py_mm"), prof, method,
                      _check.real(sigma_um, "sigma_um"),
                      _check.integer(created_unix_s, "created_unix_s"))
    return Table(path)


# ---- verification of a compensated machine (selfcal verify) ----

_RULES = {"simple": 0, "guarded": 1}


class VerifyResult:
    """A verification of a compensated machine, as ``selfcal verify`` prints it.

    Attributes
    ----------
    verdict : str
        ``"pass"``, ``"fail"`` or ``"inconclusive"``.
    decision_rule : str
        ``"simple"`` or ``"guarded"``.
    tolerance_um : float
        The tolerance T, µm.
    marks : int
        Marks compared.
    before_rms_um, before_max_um, after_rms_um, after_max_um : float
        The residual error before and after compensation, µm.
    after_max_at_mm : (float, float)
        Where the largest remains, mm.
    U_um : float
        The expanded uncertainty (k = 2) of a residual, µm.
    sigma_um : float
        The re-measurement's noise, µm (``sigma_source``: ``"given"``, ``"stated"``,
        ``"residuals"``).
    u_plate_um, quant_um, u_um, k : float
        The plate's part, the table's quantization bound, the combined standard uncertainty
        (µm) and the coverage factor.
    U_given : bool
        U was given (``u_verify_um``).
    n_unmeasured, n_unseen : int
        Marks not measured, and not in the calibration.
    """

    verdict: str
    decision_rule: str
    tolerance_um: float
    marks: int
    before_rms_um: float
    before_max_um: float
    after_rms_um: float
    after_max_um: float
    after_max_at_mm: "tuple[float, float]"
    U_um: float
    sigma_um: float
    sigma_source: str
    u_plate_um: float
    u_plate_given: bool
    quant_um: float
    u_um: float
    k: float
    U_given: bool
    n_unmeasured: int
    n_unseen: int

    def __init__(self, d: "dict[str, _Any]") -> None:
        for k, v in d.items():
            setattr(self, k, v)

    @property
    def exit_status(self) -> int:
        """The command line's exit status: 0 pass, 3 fail, 4 inconclusive."""
        return {"pass": 0, "fail": 3, "inconclusive": 4}[self.verdict]

    def __repr__(self) -> str:
        return (f"VerifyResult(verdict={self.verdict!r}, decision_rule={self.decision_rule!r}, "
                f"after_max_um={self.after_max_um:.4g}, U_um={self.U_um:.4g}, "
                f"tolerance_um={self.tolerance_um:g})")


def verify(measurement: _PathLike, table: _PathLike, artifact: _PathLike, tolerance_um: float,
           decision_rule: str = "simple", u_verify_um: "float | None" = None,
           sigma_r_um: "float | None" = None, u_plate_um: "float | None" = None,
           raw: bool = False) -> VerifyResult:
    """Check a compensated machine, as ``selfcal verify`` (the same library function).

    Parameters
    ----------
    measurement : str or os.PathLike
        The plate measured again with the table loaded (a ``selfcal-grid v1`` file).
    table : str or os.PathLike
        The table file.
    artifact : str or os.PathLike
        The plate error of the calibration (``selfcal grid --artifact``).
    tolerance_um : float
        The tolerance T, µm (> 0).
    decision_rule : {"simple", "guarded"}
        ``"simple"``: pass if max |r| <= T; ``"guarded"`` (ISO 14253-1): pass if
        max |r| + U <= T, fail if max |r| - U > T, else inconclusive.
    u_verify_um : float, optional
        U given, µm; else U = 2·sqrt(sigma² + u_plate² + u_q²) from ...
    sigma_r_um : float, optional
        ... the noise, µm (else the file's stated noise, else the residuals') ...
    u_plate_um : float, optional
        ... the plate's uncertainty, µm (else sigma) and the table's quantization.
    raw : bool
        The readings are uncompensated (the table is applied here).

    Returns
    -------
    VerifyResult
        The verdict and its figures.
    """
    rule = _check.choice(decision_rule, "decision_rule", _RULES)

    def num(v: object, name: str) -> float:
        x = _check.opt_real(v, name, low=0, high=1e6)
        return float("nan") if x is None else x
    t = _check.real(tolerance_um, "tolerance_um", low=0, low_open=True, high=1e6)
    return VerifyResult(_native.verify(_check.fspath(measurement, "measurement"),
                                       _check.fspath(table, "table"),
                                       _check.fspath(artifact, "artifact"), t, _RULES[rule],
                                       num(u_verify_um, "u_verify_um"),
                                       num(sigma_r_um, "sigma_r_um"),
                                       num(u_plate_um, "u_plate_um"), _check.flag(raw, "raw")))
