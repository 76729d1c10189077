"""Argument checks shared by the public functions: every value is checked where it comes in, and a
bad one is named in the message (the argument, the key, the index), never left to an internal
conversion's message. Types: :class:`ArgumentTypeError` (a TypeError); values:
:class:`InputError` (a ValueError)."""
import math
import operator
import os
from collections.abc import Collection, Iterable, Mapping, Sized
from typing import Any

import numpy as np
import numpy.typing as npt

from ._errors import ArgumentTypeError, InputError


def _kind(value: object) -> str:
    t = type(value).__name__
    return f"{t} {value!r}" if isinstance(value, (str, bytes)) else t


def keys(d: object, known: Collection[str], what: str, required: Collection[str] = ()) -> Mapping[str, Any]:
    """d as a mapping whose keys are all among known (and include required)."""
    if not isinstance(d, Mapping):
        raise ArgumentTypeError(f"{what} must be a dict with keys {', '.join(known)}, "
                                f"not {_kind(d)}")
    unknown = [k for k in d if k not in known]
    if unknown:
        raise InputError(f"{what}: unknown key{'s' if len(unknown) > 1 else ''} "
                         f"{', '.join(repr(k) for k in unknown)}; the known keys are "
                         f"{', '.join(known)}")
    missing = [k for k in required if k not in d]
    if missing:
        raise InputError(f"{what}: missing key{'s' if len(missing) > 1 else ''} "
                         f"{', '.join(missing)}")
    return d


def kwargs(given: Mapping[str, Any], known: Collection[str], what: str) -> None:
    """Keyword arguments all among known: ArgumentTypeError (as Python's own) naming the others."""
    unknown = [k for k in given if k not in known]
    if unknown:
        raise ArgumentTypeError(f"{what}: unknown keyword argument"
                                f"{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; the "
                                f"known ones are {', '.join(known)}")


def real(value: object, name: str, *, low: float = -math.inf, high: float = math.inf,
         low_open: bool = False, finite: bool = True) -> float:
    """A real number (int, float or numpy scalar; not text, bool or complex) within the limits."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer,
                                                                     np.floating)):
        hint = ""
        if isinstance(value, str):
            try:
                hint = f" (write {float(value)!r}, without quotes)"
            except ValueError:
                pass
        raise ArgumentTypeError(f"{name} must be a number, not {_kind(value)}{hint}")
    v = float(value)
    if math.isnan(v) or (finite and math.isinf(v)):
        raise InputError(f"{name} must be a finite number, not {v!r}")
    if v < low or (low_open and v == low) or v > high:
        lo = "" if low == -math.inf else f"{'>' if low_open else '>='} {low:g}"
        hi = "" if high == math.inf else f"<= {high:g}"
        raise InputError(f"{name} must be {' and '.join(x for x in (lo, hi) if x)}, not {v!r}")
    return v


def opt_real(value: object, name: str, **limits: Any) -> "float | None":
    """None, or real(value, ...)."""
    return None if value is None else real(value, name, **limits)


def integer(value: object, name: str, low: int = -(2**63), high: int = 2**63 - 1) -> int:
    """A whole number (int or numpy integer; not bool, text or a float) within [low, high]."""
    if isinstance(value, (bool, np.bool_)):
        raise ArgumentTypeError(f"{name} must be a whole number, not {_kind(value)}")
    try:
        v = operator.index(value)  # type: ignore[arg-type]
    except TypeError:
        raise ArgumentTypeError(f"{name} must be a whole number, not {_kind(value)}") from None
    if not low <= v <= high:
        raise InputError(f"{name} must lie within {low} .. {high}, not {v}")
    return v


def two(value: object) -> "tuple[object, object] | None":
    """The two items of a tuple, list or array of two (not text or a dict), else None."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Sized) \
            or not isinstance(value, Iterable) or len(value) != 2:
        return None
    a, b = list(value)
    return a, b


def pair(value: object, name: str, whole: bool = False) -> "tuple[Any, Any]":
    """Two numbers (a tuple, list or array of two)."""
    items = two(value)
    if items is None:
        raise ArgumentTypeError(f"{name} must be a pair of numbers, not {_kind(value)}")
    a, b = items
    if whole:
        return integer(a, f"{name}[0]"), integer(b, f"{name}[1]")
    return real(a, f"{name}[0]"), real(b, f"{name}[1]")


def choice(value: object, name: str, allowed: Collection[str]) -> str:
    """One of the allowed strings."""
    if not isinstance(value, str) or value not in allowed:
        raise InputError(f"{name} must be {', '.join(repr(a) for a in allowed)}, not {value!r}")
    return value


def flag(value: object, name: str) -> bool:
    """True or False (numpy's too)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ArgumentTypeError(f"{name} must be True or False, not {_kind(value)}")
    return bool(value)


def array(value: object, name: str, shape: "tuple[int, ...] | None" = None,
          ndim: "int | None" = None, nan_ok: bool = True) -> "npt.NDArray[np.float64]":
    """Real numbers as a float64 array: not text, None, objects or complex numbers; of the shape
    given; no infinity, and NaN only where nan_ok."""
    try:
        a = np.asarray(value)
    except (ValueError, TypeError) as e:  # ragged nested lists
        raise InputError(f"{name} must be an array of numbers ({e})") from None
    if a.dtype.kind not in "iuf":
        raise ArgumentTypeError(f"{name} must hold real numbers, not numpy dtype {a.dtype} "
                                f"(kind {a.dtype.kind!r})")
    a = a.astype(np.float64, copy=False)
    if ndim is not None and a.ndim != ndim:
        raise InputError(f"{name} must have {ndim} dimension(s), not shape {a.shape}")
    if shape is not None and a.shape != shape:
        raise InputError(f"{name} must have the shape {shape}, not {a.shape}")
    if np.isinf(a).any():
        idx = tuple(int(i) for i in np.argwhere(np.isinf(a))[0])
        raise InputError(f"{name}{list(idx)} is infinite"
                         + (" (NaN: not measured)" if nan_ok else ""))
    if not nan_ok and np.isnan(a).any():
        idx = tuple(int(i) for i in np.argwhere(np.isnan(a))[0])
        raise InputError(f"{name}{list(idx)} is NaN")
    return a


def path_like(value: object) -> bool:
    """A file path (str, bytes or os.PathLike)."""
    return isinstance(value, (str, bytes, os.PathLike))


def fspath(value: object, name: str) -> "str | bytes":
    """A file path as str or bytes; ArgumentTypeError naming the argument otherwise."""
    if not isinstance(value, (str, bytes, os.PathLike)):
        raise ArgumentTypeError(f"{name} must be a file path (str or os.PathLike), not "
                                f"{_kind(value)}")
    p: "str | bytes" = os.fspath(value)
    return p
