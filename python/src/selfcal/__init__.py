"""selfcal: self-calibration of precision XY stages, from Python.

Everything here calls libselfcal, the C library behind the ``selfcal`` command line (the
extension module ``selfcal._native`` links the shared library shipped next to it): the same
estimators, the same file readers, the same error messages. Units are in the names: ``_mm``
millimetres, ``_um`` micrometres, ``_urad`` microradians.

Bad input raises :class:`selfcal.Error` (a ``ValueError``) whose message is the library's one
line, ``FILE:LINE: reason``, exactly as the command line prints it after ``selfcal:``.
"""
from __future__ import annotations

import numpy as _np

from . import _native
from ._native import Error

__all__ = [
    "Error", "version",
    "ProfileMeasurement", "ProfileResult", "read_profile", "calibrate_profile", "simulate_profile",
    "Table",
]
__version__ = _native.version()

_MODES = {"measure": 0, "position": 1}


def version() -> str:
    """The libselfcal version this package is built on (the command line's ``--version``)."""
    return _native.version()


def _mode_code(mode: str) -> int:
    try:
        return _MODES[mode]
    except (KeyError, TypeError):
        raise Error(f"mode must be 'measure' or 'position', not {mode!r}") from None


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

    def apply(self, x_mm, y_mm, mode: str = "measure", z_mm=None):
        """Correct positions (mm) as selfcald does (SPEC §4), vectorised in C.

        ``mode="measure"``: the inputs are indicated positions p; returns p − G(p) − profile
        offsets. ``mode="position"``: the inputs are targets; returns target + G(target) +
        profile offsets (pre-compensation). G is bilinear on the table's grid, clamped at its
        edges. Inputs of any shape (broadcast together); returns ``(x_mm, y_mm, status)`` of that
        shape (and ``z_mm`` as a fourth array when given). status: bit 0 table loaded, bit 1
        outside the grid (clamped), bit 2 input not finite (returned unchanged).
        """
        code = _mode_code(mode)
        arrays = [x_mm, y_mm] + ([z_mm] if z_mm is not None else [])
        b = _np.broadcast_arrays(*[_np.asarray(a, dtype=_np.float64) for a in arrays])
        shape = b[0].shape
        flat = [_np.ascontiguousarray(a).reshape(-1) for a in b]
        z = flat[2] if z_mm is not None else _np.zeros_like(flat[0])
        xo, yo, zo, st = self._t.apply(flat[0], flat[1], z, code)
        out = (xo.reshape(shape), yo.reshape(shape))
        if z_mm is not None:
            out += (zo.reshape(shape),)
        return out + (st.reshape(shape),)

    def __repr__(self) -> str:
        return (f"selfcal.Table({self.path!r}: {self.nx} x {self.ny} nodes, pitch "
                f"{self.px_mm:g} x {self.py_mm:g} mm, {len(self.profiles)} profile(s))")


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
    if method not in _PROFILE_METHODS:
        raise Error(f"method must be 'dft' or 'lsq', not {method!r}")
    if mc_trials and mc_trials < 2:
        raise Error("mc_trials must be 0 or at least 2")
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
