"""Argument checks shared by every public constructor and method.

Each check runs on the host before any kernel, and its error names the argument and what
was accepted, so a user sees `radius must be > 0` and not a Taichi trace. Floats that reach
kernels must also fit the precision Taichi runs in (`representable`, the one place that
rule lives).
"""

from __future__ import annotations

import functools
import numbers

import numpy as np

from . import notices, runtime


def storage_precision() -> str:
    """The float precision kernels store values in: the running runtime's, or before
    tc.init "f32", the default that first use starts (f32's range lies inside f64's, so a
    value accepted then fits either)."""
    info = runtime.info()
    return "f32" if info is None else info.precision


def representable(name: str, values, *, underflow=True):
    """The one range rule for floats that reach a kernel: refuse finite values beyond the
    largest number of the storage precision (stored as inf) and, with `underflow`, non-zero
    ones below its smallest normal number (the kernels flush those to 0: a mass of 1e-50 kg
    would become 0). Points and vectors pass underflow=False: a coordinate of 1e-40 stored
    as 0 is off by less than the precision resolves anyway, and velocities that decay frame
    after frame must not start failing when written back."""
    precision = storage_precision()
    limits = np.finfo(np.float64 if precision == "f64" else np.float32)
    arr = np.asarray(values, dtype=np.float64)
    magnitude = np.abs(arr)
    bad = magnitude > limits.max
    if underflow:
        bad |= (magnitude > 0) & (magnitude < limits.tiny)
    if not np.any(bad):
        return values
    first = int(np.flatnonzero(bad)[0])
    where = ""
    if arr.ndim == 1:
        where = f" (index {first})"
    elif arr.ndim == 2:
        where = f" (row {first // arr.shape[1]})"
    elif arr.ndim > 2:
        where = f" (at {tuple(int(i) for i in np.unravel_index(first, arr.shape))})"
    value, tiny, largest = float(arr.flat[first]), float(limits.tiny), float(limits.max)
    held = f"0, or magnitudes {tiny:.4g} to {largest:.4g}" if underflow else f"magnitudes up to {largest:.4g}"
    wider = precision == "f32" and abs(value) >= np.finfo(np.float64).tiny
    raise ValueError(f"{name} must be within the range {precision} holds ({held}); got {value:g}{where}, which "
                     f"would be stored as {'inf' if abs(value) > largest else '0'}"
                     + ("; tc.init(precision='f64') holds more" if wider else ""))


def _float_array(name: str, value, expected: str) -> np.ndarray:
    """`value` as a float64 array. Complex, boolean and text input is refused rather than
    cast: numpy would drop an imaginary part silently and read "1" as 1.0."""
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged nesting
        raise TypeError(f"{name} must be {expected}; got {type(value).__name__}") from None
    if arr.dtype.kind == "c":
        raise TypeError(f"{name} must be real numbers; got complex values")
    if arr.dtype.kind not in "iufO":
        what = {"b": "booleans", "U": "text", "S": "bytes"}.get(arr.dtype.kind, f"{arr.dtype} values")
        raise TypeError(f"{name} must be {expected} of real numbers; got {what}")
    try:
        return arr.astype(np.float64)
    except OverflowError:
        raise ValueError(f"{name} must be finite; got an integer too large for a float") from None
    except (TypeError, ValueError):  # objects that are not numbers (None, complex, ...)
        raise TypeError(f"{name} must be {expected}; got {type(value).__name__}") from None


def real(name: str, value, *, low=None, high=None, low_open=False, allow_none=False, stored=True):
    """A finite real number, optionally inside [low, high] (or (low, high] with low_open),
    that the storage precision holds (`representable`) unless `stored` is False (a value
    used on the host only)."""
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number; got {type(value).__name__}")
    try:
        value = float(value)
    except OverflowError:
        raise ValueError(f"{name} must be finite; got an integer too large for a float") from None
    if not np.isfinite(value):
        raise ValueError(f"{name} must be finite; got {value}")
    if low is not None and (value <= low if low_open else value < low):
        raise ValueError(f"{name} must be {'>' if low_open else '>='} {low}; got {value}")
    if high is not None and value > high:
        raise ValueError(f"{name} must be <= {high}; got {value}")
    return representable(name, value) if stored else value


def integer(name: str, value, *, low=None):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer; got {value!r}")
    if low is not None and value < low:
        raise ValueError(f"{name} must be >= {low}; got {value}")
    return int(value)


def vector3(name: str, value, *, allow_none=False, nonzero=False, stored=True) -> np.ndarray | None:
    """A finite 3-vector as a float64 array, within the storage precision's range unless
    `stored` is False (see `real`)."""
    if value is None and allow_none:
        return None
    arr = _float_array(name, value, "a sequence of 3 numbers")
    if arr.shape != (3,):
        raise ValueError(f"{name} must have 3 components; got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite; got {arr.tolist()}")
    if nonzero:
        with np.errstate(over="ignore"):
            norm = np.linalg.norm(arr)
        if not 1e-12 <= norm < np.inf:  # (a length that overflows would normalise to 0)
            raise ValueError(f"{name} must be a non-zero vector of finite length; got {arr.tolist()}")
    return representable(name, arr, underflow=False) if stored else arr


def box(name: str, value):
    """An axis-aligned box given as (lower corner, upper corner): two float64 3-vectors with
    upper > lower on every axis."""
    try:
        lo, hi = value
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair (lower corner, upper corner)") from None
    lo = vector3(f"{name} lower corner", lo)
    hi = vector3(f"{name} upper corner", hi)
    if np.any(hi <= lo):
        raise ValueError(f"{name} upper corner must exceed the lower one; got {lo.tolist()} and {hi.tolist()}")
    return lo, hi


def points(name: str, value, *, allow_none=False) -> np.ndarray | None:
    """An (N, 3) array of finite numbers (float64). A single point (3,) becomes (1, 3)."""
    if value is None and allow_none:
        return None
    arr = _float_array(name, value, "an array of shape (N, 3)")
    if arr.ndim == 1 and arr.shape == (3,):
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3); got {arr.shape}")
    bad = ~np.all(np.isfinite(arr), axis=1)
    if bad.any():
        idx = np.flatnonzero(bad)
        raise ValueError(f"{name} must be finite; {idx.size} rows are NaN or inf "
                         f"(first: row {idx[0]} = {arr[idx[0]].tolist()})")
    return representable(name, arr, underflow=False)


def per_item(name: str, value, count: int, *, positive=True) -> np.ndarray:
    """A scalar or an (count,) array of finite numbers, > 0 when `positive`, that the
    storage precision holds (`representable`)."""
    arr = _float_array(name, value, f"a number or an array of shape ({count},)")
    if arr.ndim == 0:
        arr = np.full(count, float(arr))
    elif arr.shape != (count,):
        raise ValueError(f"{name} must be a scalar or have shape ({count},); got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    if positive and count and np.min(arr) <= 0:
        raise ValueError(f"{name} must be > 0; got minimum {np.min(arr)}")
    return representable(name, arr)


def rotation(name: str, value) -> np.ndarray:
    """A proper 3x3 rotation matrix (orthonormal, det +1); None means the identity."""
    if value is None:
        return np.eye(3)
    # (no range rule: the entries of a rotation lie in [-1, 1], and one flushed to 0 leaves
    # it orthonormal to round-off)
    R = _float_array(name, value, "a 3x3 rotation matrix")
    if R.shape != (3, 3):
        raise ValueError(f"{name} must be a 3x3 rotation matrix; got shape {R.shape}")
    if not np.all(np.isfinite(R)):
        raise ValueError(f"{name} must be finite")
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise ValueError(f"{name} must be orthonormal with determinant +1 (a rotation)")
    return R


def renamed_arguments(**renames):
    """Decorator for a function whose keyword arguments were renamed (old="new"): the old
    name still works, with a DeprecationWarning, until the next minor version; giving both
    is a TypeError."""

    def wrap(function):
        @functools.wraps(function)
        def call(*args, **kwargs):
            for old, new in renames.items():
                if old in kwargs:
                    if new in kwargs:
                        raise TypeError(f"give {new}= only ({old}= is its old name)")
                    notices.warn(f"{function.__qualname__.split('.')[0]}: {old}= is now called {new}=; the old "
                                  "name will be removed in tai_coll 0.3", DeprecationWarning)
                    kwargs[new] = kwargs.pop(old)
            return function(*args, **kwargs)

        return call

    return wrap
