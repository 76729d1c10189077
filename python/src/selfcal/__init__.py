"""selfcal: self-calibration of precision XY stages, from Python.

Everything here calls libselfcal, the C library behind the ``selfcal`` command line (the
extension module ``selfcal._native`` has the library linked in): the same
estimators, the same file readers, the same error messages. Units are in the names: ``_mm``
millimetres, ``_um`` micrometres, ``_urad`` microradians, ``_ppm`` parts per million.

Bad input raises :class:`selfcal.Error` (a ``ValueError``) whose message is the library's one
line, ``FILE:LINE: reason``, exactly as the command line prints it after ``selfcal:``.
"""
from __future__ import annotations

import numpy as _np

from . import _native
from ._native import Error

__all__ = [
    "Error", "version",
    "GridPlan", "GridMeasurement", "GridResult", "PlanAnalysis", "read_grid", "plan",
    "calibrate_grid", "simulate_grid",
    "ProfileMeasurement", "ProfileResult", "read_profile", "calibrate_profile", "simulate_profile",
    "Table", "build_table",
    "VerifyResult", "verify",
]
__version__ = _native.version()

_MODES = {"measure": 0, "position": 1, "measure-exact": 2}


def version() -> str:
    """The libselfcal version this package is built on (the command line's ``--version``)."""
    return _native.version()


def _mode_code(mode: str) -> int:
    try:
        return _MODES[mode]
    except (KeyError, TypeError):
        raise Error(f"mode must be 'measure', 'position' or 'measure-exact', not {mode!r}") from None


class Table:
    """A correction table (``selfcal lut build`` output), loaded and validated by the same
    correction core as ``selfcald``.

    ``Table(path)`` reads the file; a missing, corrupt or oversized table raises
    :class:`selfcal.Error`.
    """

    def __init__(self, path):
        self._t = _native.Table(path)
        self.path = path
        info = self._t.info()
        #: nodes along x and y
        self.nx: int = info["nx"]
        self.ny: int = info["ny"]
        #: position of node (i=0, j=0) in mm
        self.x0_mm: float = info["x0_mm"]
        self.y0_mm: float = info["y0_mm"]
        #: node spacing along x and y in mm
        self.px_mm: float = info["px_mm"]
        self.py_mm: float = info["py_mm"]
        #: the straightness profiles: dicts with axis, dir, n, start_mm, step_mm
        self.profiles: list = info["profiles"]

    def apply(self, x_mm, y_mm, mode: str = "measure", z_mm=None, out=None):
        """Correct positions (mm) as selfcald does (SPEC §4), vectorised in C.

        ``mode="measure"``: the inputs are indicated positions p; returns p − G(p) − profile
        offsets. ``mode="position"``: the inputs are targets; returns target + G(target) +
        profile offsets (pre-compensation). ``mode="measure-exact"``: the inputs are indicated
        positions p; returns the q with q + G(q) + offsets = p, the exact inverse of position mode
        (three fixed-point steps; measure mode is the first, off by G·∇G). G is bilinear on the table's grid, clamped at its
        edges. Inputs of any shape (broadcast together); returns ``(x_mm, y_mm, status)`` of that
        shape (and ``z_mm`` as a third array, before status, when given). status: bit 0 table
        loaded, bit 1 outside the grid (clamped), bit 2 input not finite (returned unchanged).

        ``out``: optional arrays to fill instead of new ones (the same tuple layout; float64 and
        uint32, C-contiguous, of the broadcast shape) — a caller correcting stream after stream
        reuses them and pays no allocation.
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
                raise Error(f"{name}: not real numbers (numpy dtype kind {kind!r})")
            conv.append(_np.asarray(a, dtype=_np.float64))
        try:
            b = _np.broadcast_arrays(*conv)
        except ValueError:
            raise Error("the positions' shapes %s do not broadcast together"
                        % ", ".join(str(c.shape) for c in conv)) from None
        shape = b[0].shape
        flat = [_np.ascontiguousarray(a).reshape(-1) for a in b]
        n_out = 4 if z_mm is not None else 3
        if out is None:
            out = tuple(_np.empty(shape, dtype=_np.float64) for _ in range(n_out - 1)) + (
                _np.empty(shape, dtype=_np.uint32),)
        elif len(out) != n_out:
            raise Error(f"out must hold {n_out} arrays")
        for k, o in enumerate(out):
            want = _np.uint32 if k == n_out - 1 else _np.float64
            if not isinstance(o, _np.ndarray) or o.shape != shape or not o.flags.c_contiguous \
                    or o.dtype != want or not o.flags.writeable:
                raise Error(f"out arrays must be writeable C-contiguous numpy arrays of shape "
                            f"{shape}: float64, the status uint32")
        flat_out = [o.reshape(-1) for o in out]  # views: the arrays are C-contiguous
        z = flat[2] if z_mm is not None else None
        zo = flat_out[2] if z_mm is not None else None
        self._t.apply(flat[0], flat[1], z, code, flat_out[0], flat_out[1], zo, flat_out[-1])
        return out

    def __repr__(self) -> str:
        return (f"selfcal.Table({self.path!r}: {self.nx} x {self.ny} nodes, pitch "
                f"{self.px_mm:g} x {self.py_mm:g} mm, {len(self.profiles)} profile(s))")


# ---- grid plates (SPEC §1, §5) ----

_GRID_METHODS = {"ye": 0, "double-shift": 1, "lsq": 2}


class GridPlan:
    """A view plan: N x N plate marks at ``pitch_mm``, the stage grid (``stage = (NX, NY)``,
    default the plate's N x N) centred at ``origin_mm``, and the views: dicts with ``rot``
    (0, 90, 180, 270, counter-clockwise), ``shift`` (sx, sy) in pitches, optional ``rows`` and
    ``cols`` (the plate rows/columns a partial view measures) and ``sigma_um`` (the stated
    standard uncertainty of each coordinate of the view's measurements) and ``temp_C`` (the
    plate's temperature during the view, on every view or none). The plate's scale and
    temperature (SPEC §11): ``plate_scale_ppm=(E, U)``, ``plate_cte_ppm_per_K=(A, U)``,
    ``temp_u_K`` (default 0.05), as the file's header lines."""

    def __init__(self, n, pitch_mm, views, origin_mm=(0.0, 0.0), stage=None,
                 plate_scale_ppm=None, plate_cte_ppm_per_K=None, temp_u_K=0.05):
        self.n, self.pitch_mm = int(n), float(pitch_mm)
        self.origin_mm = (float(origin_mm[0]), float(origin_mm[1]))
        self.stage = (int(stage[0]), int(stage[1])) if stage is not None else (self.n, self.n)
        self.views = [dict(rot=int(v["rot"]), shift=tuple(int(a) for a in v.get("shift", (0, 0))),
                           rows=v.get("rows"), cols=v.get("cols"), sigma_um=v.get("sigma_um"),
                           temp_C=v.get("temp_C"))
                      for v in views]
        pair = lambda t: None if t is None else (float(t[0]), float(t[1]))  # noqa: E731
        self.plate_scale_ppm = pair(plate_scale_ppm)
        self.plate_cte_ppm_per_K = pair(plate_cte_ppm_per_K)
        self.temp_u_K = float(temp_u_K)
        _native.grid_plan(self._as_dict())  # checked by the library now, not at first use

    @classmethod
    def _from_dict(cls, d):
        return cls(d["n"], d["pitch_mm"], d["views"], d["origin_mm"], d["stage"],
                   d.get("plate_scale_ppm"), d.get("plate_cte_ppm_per_K"), d.get("temp_u_K", 0.05))

    def _as_dict(self):
        return dict(n=self.n, pitch_mm=self.pitch_mm, origin_mm=self.origin_mm, stage=self.stage,
                    views=self.views, plate_scale_ppm=self.plate_scale_ppm,
                    plate_cte_ppm_per_K=self.plate_cte_ppm_per_K, temp_u_K=self.temp_u_K)

    @classmethod
    def standard(cls, name: str, n: int, pitch_mm: float = 1.0, origin_mm=(0.0, 0.0),
                 stage=None):
        """A standard plan: ``"ye"`` ({rot 0}, {rot 90}, {shift +1,0}), ``"double-shift"``
        (Petrò: {rot 0}, {rot 90}, {shift +2,0}, {shift -3,0: row c, columns c, c+1}) or
        ``"stitch"`` (a stage ``stage = (NX, NY)`` larger than the plate, covered by shifted
        placements plus a rotated and a +1 view)."""
        nx, ny = stage if stage is not None else (n, n)
        try:
            d = _native.grid_standard_plan(name, int(n), float(pitch_mm), float(origin_mm[0]),
                                           float(origin_mm[1]), int(nx), int(ny))
        except (OverflowError, TypeError) as e:
            raise Error(f"GridPlan.standard: {e}") from None
        return cls._from_dict(d)

    @property
    def n_views(self) -> int:
        return len(self.views)

    def __repr__(self):
        return (f"selfcal.GridPlan(N={self.n}, pitch_mm={self.pitch_mm:g}, stage={self.stage}, "
                f"{self.n_views} views)")


class GridMeasurement:
    """Measured mark positions of a plan, in memory (a ``selfcal-grid v1`` file's content).

    ``x_mm``, ``y_mm``: arrays of shape (views, N, N), the measured stage position of mark (i, j)
    (i = plate row, j = plate column) in each view, NaN where not measured. Optional arrays of
    the same shape: ``ux_um``, ``uy_um`` (standard uncertainty of each coordinate) and ``t_s``
    (time of each measurement, for drift)."""

    def __init__(self, plan: GridPlan, x_mm, y_mm, ux_um=None, uy_um=None, t_s=None):
        self.plan = plan
        self.x_mm = _np.asarray(x_mm, dtype=_np.float64)
        self.y_mm = _np.asarray(y_mm, dtype=_np.float64)
        self.ux_um = None if ux_um is None else _np.asarray(ux_um, dtype=_np.float64)
        self.uy_um = None if uy_um is None else _np.asarray(uy_um, dtype=_np.float64)
        self.t_s = None if t_s is None else _np.asarray(t_s, dtype=_np.float64)

    @classmethod
    def _from_dict(cls, d):
        return cls(GridPlan._from_dict(d["plan"]), d["x_mm"], d["y_mm"], d["ux_um"], d["uy_um"],
                   d["t_s"])

    def _as_dict(self):
        if (self.ux_um is None) != (self.uy_um is None):
            raise Error("give both ux_um and uy_um, or neither")
        return dict(plan=self.plan._as_dict(), x_mm=self.x_mm, y_mm=self.y_mm, ux_um=self.ux_um,
                    uy_um=self.uy_um, t_s=self.t_s)

    def write(self, path):
        """Write as a ``selfcal-grid v1`` file (atomically: complete or absent)."""
        _native.grid_write(path, self._as_dict())

    def __repr__(self):
        return f"selfcal.GridMeasurement({self.plan!r}, {int(_np.isfinite(self.x_mm).sum())} marks measured)"


def read_grid(path) -> GridMeasurement:
    """Read a ``selfcal-grid v1`` data file strictly (bad input raises :class:`Error`)."""
    return GridMeasurement._from_dict(_native.grid_read(path))


def _grid_source(source):
    if isinstance(source, GridMeasurement):
        return source._as_dict()
    if isinstance(source, GridPlan):
        return source._as_dict()
    return source


class PlanAnalysis:
    """What ``selfcal plan`` says of a plan: ``identifiable`` (does it determine G?), ``free``
    (degrees of freedom beyond the gauge left free), ``sigma_c_ratio_rms`` and
    ``sigma_c_ratio_max`` (predicted std(G)/σ_r, RMS over nodes and worst node; inf when not
    identifiable; the plan's geometry, with equal weights), ``sigma_c_rms_um`` and
    ``sigma_c_max_um`` (std(G) in µm with the uncertainties the views or data state; NaN when
    they state none), ``sigma_ratio_gx``/``sigma_ratio_gy`` (per node, shape (NY, NX)), counts, and
    ``residual_dof`` (the residuals' degrees of freedom; -1 when not identifiable), and
    Baarda's internal reliability of an identifying plan (NaN otherwise): ``n_testable``,
    ``n_untestable`` coordinate equations, ``redundancy_min``, ``redundancy_mean`` and the
    minimal detectable blunders ``mdb_ratio_max``, ``mdb_ratio_mean_r`` (in σ, 80 % power, the
    default outlier test), as ``selfcal plan`` prints them."""

    def __init__(self, d):
        for k, v in d.items():
            setattr(self, k, v)
        self.identifiable = bool(self.identifiable)
        self.plan = GridPlan._from_dict(d["plan"])

    def __repr__(self):
        return (f"selfcal.PlanAnalysis(identifiable={self.identifiable}, free={self.free}, "
                f"sigma_c_ratio_rms={self.sigma_c_ratio_rms:.4g}, "
                f"sigma_c_ratio_max={self.sigma_c_ratio_max:.4g})")


def plan(source) -> PlanAnalysis:
    """Analyse a plan before measuring, as ``selfcal plan``: ``source`` is a plan or data file
    path, a :class:`GridPlan` (what its views would measure) or a :class:`GridMeasurement` (what
    was measured)."""
    return PlanAnalysis(_native.grid_plan(_grid_source(source)))


class GridResult:
    """A grid calibration. Arrays indexed [i, j] as the map file: ``gx_um``, ``gy_um`` (stage
    error G, shape (NY, NX)), ``ugx_um``, ``ugy_um`` (standard uncertainties, k = 1; NaN for the
    closed forms), ``x_mm``, ``y_mm`` (node positions), ``ax_um``, ``ay_um`` (plate error, (N, N),
    NaN for an unmeasured mark). Scalars: ``O_urad`` (non-orthogonality, µrad), ``R_ppm`` (scale,
    ppm = µm/m), with ``uO_urad``, ``uR_ppm`` (the dimensionless ``O``, ``R``, ``uO``, ``uR``
    are kept through version 0.3, then dropped), per-view
    misalignments ``tx_um``, ``ty_um``, ``theta_urad`` (with ``utx_um`` ...),
    ``residual_rms_um``, ``sigma_r_est_um``, ``sigma_r_used_um``, ``dof``, ``variance_factor``,
    ``chi2_pass``. Least squares also gives the residuals ``rx_um``, ``ry_um``, the standardized
    residuals ``tx``, ``ty`` and ``outlier`` flags, shape (views, N, N), the outlier test
    (``outlier_alpha``, ``outlier_alpha_each``, each coordinate's ``outlier_alpha_coord``, the
    critical value ``outlier_crit`` of |t|, ``n_outlier_tests``), with ``view_noise="estimate"``
    each view's estimated noise ``view_sigma_um`` with its uncertainty ``view_sigma_u_um``, and
    ``view_noise_factor`` (on its stated
    uncertainties; NaN if it stated none), ``view_noise_estimated``, and on request
    ``covariance_um2``. ``warnings``: the lines ``selfcal grid`` prints as warnings.

    The plate's scale and temperature (SPEC §11): ``magnification_ppm`` and
    ``u_magnification_ppm`` (NaN when the file gives no ``plate_scale_ppm``: ``scale_included``
    is then False and G carries no magnification), and ``budget``, a dict with the views' scales
    (``view_scale_ppm``; with ``view_scale="free"`` also ``view_scale_free_ppm`` and their
    ``u_view_scale_free_ppm``), the noise part of u(G) (``ugx_noise_um``, ``ugy_noise_um``) and the
    budget table at the worst ``node``: ``rows`` (source, unit, u, sensitivity_um_per_unit,
    contribution_um, dof), ``u_c_um``, ``nu_eff``, ``k`` (``k_from``: "2" or
    "welch-satterthwaite") and ``U_um``. ``ugx_um``, ``ugy_um`` are then the combined
    uncertainties. ``monte_carlo`` (with ``monte_carlo=M``): a dict with per node ``ugx_um``,
    ``ugy_um``, their ``ratio_x``, ``ratio_y`` to the budget's, the 95 % coverage intervals
    ``gx_lo_um`` ... ``gy_hi_um``, and ``ratio_min``, ``ratio_max``, ``ratio_mean``,
    ``seconds``, ``threads``; else None."""

    def __init__(self, d, method):
        self.method = method
        for k, v in d.items():
            setattr(self, k, v)
        # None where no χ² test ran (no stated noise, or each view's noise estimated): the
        # command line's "n/a"
        tested = self.variance_factor == self.variance_factor and not self.view_noise_estimated
        self.chi2_pass = bool(self.chi2_pass) if tested else None
        self.weighted = bool(self.weighted)
        self.outlier_alpha_each = bool(self.outlier_alpha_each)
        self.view_noise_estimated = bool(self.view_noise_estimated)
        self.scale_included = bool(self.budget["scale_included"])
        self.magnification_ppm = self.budget["magnification_ppm"]
        self.u_magnification_ppm = self.budget["u_magnification_ppm"]

    def expanded(self, k: float = 2.0):
        """The expanded uncertainties (k·u(Gx), k·u(Gy)), GUM coverage factor k (default 2)."""
        return k * self.ugx_um, k * self.ugy_um

    def __repr__(self):
        ny, nx = self.gx_um.shape
        return f"selfcal.GridResult({self.method}, stage {nx} x {ny}, sigma_r_est_um={self.sigma_r_est_um:.4g})"


def calibrate_grid(source, method: str = "lsq", sigma_r_um=None, drift: bool = False,
                   reject_outliers: bool = False, covariance: bool = False,
                   outlier_alpha=None, outlier_alpha_each=None,
                   view_noise: str = "stated", view_scale: str = "model",
                   monte_carlo=None, seed: int = 1, progress=None, max_memory=None) -> GridResult:
    """Separate the stage error G from the plate error A, as ``selfcal grid``.

    ``source``: a ``selfcal-grid v1`` file path or a :class:`GridMeasurement`. ``method``:
    ``"lsq"`` (any identifying plan, weights, uncertainties, residuals and Baarda's outlier
    test), ``"ye"`` or ``"double-shift"`` (the closed forms). ``sigma_r_um``: the measurement
    noise if known (µm, data without stated uncertainties), else estimated from the residuals.
    ``drift``: per-view linear drift (needs ``t_s``). ``reject_outliers``: remove the worst
    flagged measurement and solve again until none is flagged. ``covariance``: the full
    covariance of G (small stages). ``outlier_alpha``: the outlier test's significance for the
    whole data set (default 0.05, as ``--outlier-alpha``); ``outlier_alpha_each`` instead: for
    each coordinate on its own (Baarda's α0, e.g. 0.001, as ``--outlier-alpha-each``).
    ``view_noise="estimate"``: each view's noise estimated from its residuals (variance
    components, as ``--view-noise estimate``): ``result.view_sigma_um`` per view.
    ``view_scale="free"``: each view's scale relative to the others an unknown (``--view-scale
    free``). ``monte_carlo=M``: the Monte Carlo check of the budget with ``seed`` (``--monte-carlo
    M --seed S``; least squares). Warnings (outliers, the χ² test, significant view scales) are
    in ``result.warnings`` and issued with :mod:`warnings` too.
    ``progress``: a callable ``progress(phase, work_done, work_total, peak_bytes)`` called as a
    least-squares solve goes (phases ``"assemble"``, ``"analyse"``, ``"factor"``, ``"selected
    inverse"``, ``"solve"``, ``"residuals"``; work in multiply-adds of the factor and the selected
    inverse, 0 until the analysis has counted it; the peak memory estimated so far in bytes); an
    exception it raises is raised after the solve. ``max_memory``: bytes a solve may use
    (default: the machine's available memory); a plan estimated to need more raises
    ``MemoryError`` before it is assembled or factored.
    """
    if progress is not None and not callable(progress):
        raise TypeError("progress must be callable")
    if max_memory is not None and not max_memory > 0:
        raise Error("max_memory must be a positive number of bytes")
    if not isinstance(method, str) or method not in _GRID_METHODS:
        raise Error(f"method must be 'ye', 'double-shift' or 'lsq', not {method!r}")
    if sigma_r_um is not None and not sigma_r_um > 0:
        raise Error("sigma_r_um must be positive")
    if outlier_alpha is not None and outlier_alpha_each is not None:
        raise Error("outlier_alpha and outlier_alpha_each exclude each other")
    if view_noise not in ("stated", "estimate"):
        raise Error(f"view_noise must be 'stated' or 'estimate', not {view_noise!r}")
    if view_scale not in ("model", "free"):
        raise Error(f"view_scale must be 'model' or 'free', not {view_scale!r}")
    if monte_carlo is not None and not (isinstance(monte_carlo, int) and 2 <= monte_carlo <= 10**7):
        raise Error("monte_carlo must be a number of trials of 2 to 1e7")
    if not isinstance(seed, int) or not 0 <= seed < 2**64:
        raise Error("seed must be a whole number of 0 to 2^64 - 1")
    if (view_scale == "free" or monte_carlo) and method != "lsq":
        raise Error("view_scale='free' and monte_carlo need method 'lsq'")
    alpha = outlier_alpha if outlier_alpha_each is None else outlier_alpha_each
    if alpha is not None and not 0 < alpha < 1:
        raise Error("the outlier test's significance must lie between 0 and 1")
    d = _native.grid_calibrate(_grid_source(source), _GRID_METHODS[method],
                               float(sigma_r_um or 0.0), bool(drift), bool(reject_outliers),
                               bool(covariance), float(alpha or 0.0),
                               outlier_alpha_each is not None, view_noise == "estimate",
                               view_scale == "free", int(monte_carlo or 0), int(seed),
                               progress, float(max_memory or 0.0))
    r = GridResult(d, method)
    if r.warnings:
        import warnings as _w
        for msg in r.warnings:
            _w.warn(msg, stacklevel=2)
    return r


def simulate_grid(plan="double-shift", n: int = 25, pitch_mm: float = 1.0, stage=None,
                  sigma_r_um: float = 0.01, sigma_g_um: float = 1.0, seed: int = 1, **params):
    """Simulate a plate measured in a plan, as ``selfcal simulate grid`` (Petrò §5).

    ``plan``: a :class:`GridPlan` or a standard plan's name (``"ye"``, ``"double-shift"``,
    ``"stitch"`` with ``stage=(NX, NY)``). Other parameters by name: ``rho``, ``O_urad``,
    ``R_ppm`` (or the dimensionless ``O``, ``R``, kept through version 0.3),
    ``sigma_a_um``, ``sigma_t_um``, ``sigma_theta_urad``, ``dt_s``, ``drift_vx_um_s``,
    ``drift_vy_um_s``. Returns ``(measurement, truth)``: a :class:`GridMeasurement` and a dict
    with ``gx_um``, ``gy_um`` (NY, NX), ``ax_um``, ``ay_um`` (N, N), ``O_urad``, ``R_ppm`` (and
    ``O``, ``R``) and the views' misalignments, all in the SPEC gauge.
    """
    for k in ("O", "R"):  # the keys with their unit: µrad and ppm
        unit = k + ("_urad" if k == "O" else "_ppm")
        if unit in params:
            if k in params:
                raise TypeError(f"give {unit} or {k}, not both")
            params[k] = float(params.pop(unit)) * 1e-6
    allowed = {"rho", "O", "R", "sigma_a_um", "sigma_t_um", "sigma_theta_urad", "dt_s",
               "drift_vx_um_s", "drift_vy_um_s"}
    bad = set(params) - allowed
    if bad:
        raise TypeError(f"unknown simulation parameter(s): {', '.join(sorted(bad))}")
    if isinstance(plan, str):
        plan = GridPlan.standard(plan, n, pitch_mm, stage=stage)
    p = dict(sigma_r_um=float(sigma_r_um), sigma_g_um=float(sigma_g_um), seed=int(seed),
             **{k: float(v) for k, v in params.items()})
    meas, truth = _native.grid_simulate(plan._as_dict(), p)
    return GridMeasurement._from_dict(meas), truth


# ---- straightness profiles (SPEC §2) ----

_PROFILE_METHODS = {"dft": 0, "lsq": 1}


def _nan_pad(v, n):
    out = _np.full(n, _np.nan)
    out[: len(v)] = v
    return out


class ProfileMeasurement:
    """A two-scan straightness measurement (``selfcal-profile v1``), in memory.

    Attributes: ``n`` points, sampling interval ``s_mm``, sensor spacings ``d1``, ``d2`` (in
    samples); per scan k = 0, 1 the arrays ``m1_um[k]``, ``m2_um[k]`` (displacement sensors, µm)
    and ``m3_urad[k]`` (angle sensor, µrad), each of ``n - d_k`` values; the sensors' noise
    ``sigma_disp_um`` and ``sigma_angle_urad`` (None when not stated).
    """

    def __init__(self, n, s_mm, d1, d2, m1_um, m2_um, m3_urad, sigma_disp_um=None,
                 sigma_angle_urad=None):
        self.n, self.s_mm, self.d1, self.d2 = int(n), float(s_mm), int(d1), int(d2)
        self.m1_um = tuple(_np.asarray(a, dtype=_np.float64) for a in m1_um)
        self.m2_um = tuple(_np.asarray(a, dtype=_np.float64) for a in m2_um)
        self.m3_urad = tuple(_np.asarray(a, dtype=_np.float64) for a in m3_urad)
        self.sigma_disp_um = sigma_disp_um
        self.sigma_angle_urad = sigma_angle_urad

    @classmethod
    def _from_dict(cls, d):
        return cls(d["n"], d["s_mm"], d["d1"], d["d2"], d["m1_um"], d["m2_um"], d["m3_urad"],
                   d["sigma_disp_um"], d["sigma_angle_urad"])

    def _as_dict(self):
        return dict(n=self.n, s_mm=self.s_mm, d1=self.d1, d2=self.d2, m1_um=self.m1_um,
                    m2_um=self.m2_um, m3_urad=self.m3_urad, sigma_disp_um=self.sigma_disp_um,
                    sigma_angle_urad=self.sigma_angle_urad)

    def write(self, path):
        """Write as a ``selfcal-profile v1`` file (atomically: complete or absent)."""
        _native.profile_write(path, self._as_dict())

    def __repr__(self):
        return f"selfcal.ProfileMeasurement(N={self.n}, s_mm={self.s_mm:g}, d={self.d1}/{self.d2})"


def read_profile(path) -> ProfileMeasurement:
    """Read a ``selfcal-profile v1`` file strictly (bad input raises :class:`Error`)."""
    return ProfileMeasurement._from_dict(_native.profile_read(path))


class ProfileResult:
    """A reconstructed straightness profile.

    Arrays of N values: ``x_mm`` (position), ``f_um`` (the profile relative to its least-squares
    line), ``uf_um`` (its standard uncertainty, k = 1; NaN when no noise is known or estimable),
    ``ey_um`` (the stage's straightness motion error from scan 1; NaN for n >= N - d1).
    Scalars: ``noise_known`` (given vs estimated from the residuals), ``sigma_y1_um``,
    ``sigma_y2_um`` (the noise of the combined differences used), ``dof``, ``wrss`` (weighted
    residual sum of squares), ``residual_ratio`` (sqrt(wrss/dof) against a given noise; NaN when
    estimated).
    """

    def __init__(self, d, method):
        self.method = method
        for k, v in d.items():
            setattr(self, k, v)
        self.noise_known = bool(self.noise_known)
        self.have_uf = bool(self.have_uf)

    def expanded_uf_um(self, k: float = 2.0):
        """The expanded uncertainty k·u(f) (GUM; k = 2 by default)."""
        return k * self.uf_um

    def __repr__(self):
        return f"selfcal.ProfileResult({self.method}, N={self.n}, d={self.d1}/{self.d2})"


def calibrate_profile(source, method: str = "lsq", sigma_disp_um=None, sigma_angle_urad=None,
                      mc_trials: int = 0, seed: int = 1) -> ProfileResult:
    """Reconstruct a straightness profile by the two-set two-point method, as ``selfcal profile``.

    ``source``: a ``selfcal-profile v1`` file path or a :class:`ProfileMeasurement`.
    ``method``: ``"lsq"`` (least squares, any coprime d1, d2 with N >= d1 + d2) or ``"dft"``.
    The noise given here (µm per displacement sensor, µrad for the angle sensor) wins over the
    file's header lines; with neither it is estimated from the residuals. ``mc_trials`` >= 2:
    Monte Carlo uncertainties instead of the analytic ones.
    """
    if not isinstance(method, str) or method not in _PROFILE_METHODS:
        raise Error(f"method must be 'dft' or 'lsq', not {method!r}")
    src = source._as_dict() if isinstance(source, ProfileMeasurement) else source
    d = _native.profile_calibrate(src, _PROFILE_METHODS[method], sigma_disp_um, sigma_angle_urad,
                                  int(mc_trials), int(seed))
    return ProfileResult(d, method)


def simulate_profile(n: int = 330, s_mm: float = 1.0, d1: int = 10, d2: int = 11,
                     sigma_disp_um: float = 0.01, sigma_angle_urad: float = 1.0,
                     f_um=None, amp_um: float = 1.0, harmonics: int = 40, dabam=None,
                     seed: int = 1, write_sigma: bool = True, **instrument):
    """Simulate a two-scan measurement of a profile, as ``selfcal simulate profile``.

    The profile is ``f_um`` (N values, µm) if given, else the DABAM file ``dabam`` (a ``.dat``
    with its ``.txt`` beside it), else a random smooth profile of RMS ``amp_um`` (same seed, same
    profile as the command line). Other instrument parameters (``ey_amp_um``, ``ep_amp_urad``,
    ``u1_um``, ``u2_um``, ``u3_urad``, ``b0_um``) may be given by name.
    Returns ``(measurement, truth)``: a :class:`ProfileMeasurement` and a dict with ``f_um`` and
    ``ey_um`` (N values; e_y relative to its least-squares line, NaN for n >= N - d1).
    """
    allowed = {"ey_amp_um", "ep_amp_urad", "u1_um", "u2_um", "u3_urad", "b0_um"}
    bad = set(instrument) - allowed
    if bad:
        raise TypeError(f"unknown instrument parameter(s): {', '.join(sorted(bad))}")
    params = dict(n=int(n), s_mm=float(s_mm), d1=int(d1), d2=int(d2),
                  sigma_disp_um=float(sigma_disp_um), sigma_angle_urad=float(sigma_angle_urad),
                  seed=int(seed), write_sigma=int(bool(write_sigma)),
                  **{k: float(v) for k, v in instrument.items()})
    meas, f, ey = _native.profile_simulate(params, f_um, float(amp_um), int(harmonics), dabam)
    m = ProfileMeasurement._from_dict(meas)
    return m, {"x_mm": _np.arange(m.n) * m.s_mm, "f_um": f, "ey_um": _nan_pad(ey, m.n)}


_AXES = {"x": 0, "y": 1, "z": 2}


def build_table(path, gx_um, gy_um, x0_mm: float, y0_mm: float, px_mm: float, py_mm: float = None,
                profiles=(), method: str = "", sigma_um: float = -1.0, created_unix_s: int = None):
    """Write a correction table from arrays, as ``selfcal lut build`` does from files.

    ``gx_um``, ``gy_um``: the stage error at the nodes, shape (NY, NX), indexed [i, j] (i along
    y); node (0, 0) at (``x0_mm``, ``y0_mm``), pitches ``px_mm`` and ``py_mm`` (default: px).
    ``profiles``: straightness errors, each a dict with ``axis`` and ``dir`` (``"x"``, ``"y"`` or
    ``"z"``: the error of coordinate dir as a function of axis), ``start_mm``, ``step_mm`` and
    ``err_um`` (values at start + k·step). ``method`` and ``sigma_um`` go into the table's
    provenance; ``created_unix_s`` defaults to SOURCE_DATE_EPOCH or now. Written atomically;
    returns the :class:`Table` loaded from it. A GridResult's map goes in as
    ``build_table(p, r.gx_um, r.gy_um, r.x_mm[0, 0], r.y_mm[0, 0], pitch)``.
    """
    import os
    import time
    if created_unix_s is None:
        created_unix_s = int(os.environ.get("SOURCE_DATE_EPOCH", time.time()))
    prof = []
    for p in profiles:
        try:
            prof.append((_AXES[p["axis"].lower()], _AXES[p["dir"].lower()], float(p["start_mm"]),
                         float(p["step_mm"]), _np.asarray(p["err_um"], dtype=_np.float64)))
        except (KeyError, AttributeError, TypeError, ValueError) as e:
            raise Error(f"a profile needs axis and dir among 'x', 'y', 'z', and start_mm, step_mm, "
                        f"err_um ({e!r})") from None
    _native.lut_build(path, gx_um, gy_um, float(x0_mm), float(y0_mm), float(px_mm),
                      float(py_mm if py_mm is not None else px_mm), prof, str(method),
                      float(sigma_um), int(created_unix_s))
    return Table(path)


# ---- verification of a compensated machine (selfcal verify) ----

_RULES = {"simple": 0, "guarded": 1}


class VerifyResult:
    """A verification of a compensated machine, as ``selfcal verify`` prints it: ``verdict``
    (``"pass"``, ``"fail"``, ``"inconclusive"``), ``decision_rule``, ``tolerance_um``,
    ``marks``, ``before_rms_um``, ``before_max_um``, ``after_rms_um``, ``after_max_um``,
    ``after_max_at_mm`` (x, y), the expanded uncertainty ``U_um`` (k = 2) of a residual and its
    parts: ``sigma_um`` (the re-measurement's noise; ``sigma_source``: ``"given"``,
    ``"stated"``, ``"residuals"``), ``u_plate_um``, ``quant_um`` (the table's quantization bound),
    ``u_um``, ``k``; ``U_given``; ``n_unmeasured``, ``n_unseen``. ``exit_status`` is the command
    line's: 0 pass, 3 fail, 4 inconclusive."""

    def __init__(self, d):
        for k, v in d.items():
            setattr(self, k, v)

    @property
    def exit_status(self) -> int:
        return {"pass": 0, "fail": 3, "inconclusive": 4}[self.verdict]

    def __repr__(self):
        return (f"VerifyResult(verdict={self.verdict!r}, decision_rule={self.decision_rule!r}, "
                f"after_max_um={self.after_max_um:.4g}, U_um={self.U_um:.4g}, "
                f"tolerance_um={self.tolerance_um:g})")


def verify(measurement, table, artifact, tolerance_um: float, decision_rule: str = "simple",
           u_verify_um=None, sigma_r_um=None, u_plate_um=None, raw: bool = False) -> VerifyResult:
    """Check a compensated machine, as ``selfcal verify`` (the same library function).

    ``measurement``: the plate measured again with the table loaded (a ``selfcal-grid v1`` file;
    ``raw=True``: uncompensated readings), ``table``: the table file, ``artifact``: the plate
    error of the calibration (``selfcal grid --artifact``). ``decision_rule``: ``"simple"``
    (pass if max |r| <= T) or ``"guarded"`` (ISO 14253-1: pass if max |r| + U <= T, fail if
    max |r| - U > T, else inconclusive). U = 2·sqrt(sigma² + u_plate² + u_q²) from
    ``sigma_r_um`` (else the file's stated noise, else the residuals'), ``u_plate_um`` (else
    sigma) and the table's quantization, or ``u_verify_um`` given.
    """
    import os
    if decision_rule not in _RULES:
        raise ValueError(f"decision_rule must be 'simple' or 'guarded', got {decision_rule!r}")

    def num(v, name):
        if v is None:
            return float("nan")
        v = float(v)
        if not v >= 0 or v > 1e6:
            raise ValueError(f"{name} must be a number >= 0 (um), got {v!r}")
        return v
    t = float(tolerance_um)
    if not 0 < t <= 1e6:
        raise ValueError(f"tolerance_um must be a positive number, got {tolerance_um!r}")
    return VerifyResult(_native.verify(os.fspath(measurement), os.fspath(table),
                                       os.fspath(artifact), t, _RULES[decision_rule],
                                       num(u_verify_um, "u_verify_um"), num(sigma_r_um, "sigma_r_um"),
                                       num(u_plate_um, "u_plate_um"), bool(raw)))
