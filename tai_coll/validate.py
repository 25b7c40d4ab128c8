"""Argument checks shared by every public constructor and method.

Each check runs on the host before any kernel, and its error names the argument and what
was accepted, so a user sees `radius must be > 0` and not a Taichi trace.
"""

from __future__ import annotations

import functools
import numbers
import warnings

import numpy as np


def real(name: str, value, *, low=None, high=None, low_open=False, allow_none=False):
    """A finite real number, optionally inside [low, high] (or (low, high] with low_open)."""
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number; got {type(value).__name__}")
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"{name} must be finite; got {value}")
    if low is not None and (value <= low if low_open else value < low):
        raise ValueError(f"{name} must be {'>' if low_open else '>='} {low}; got {value}")
    if high is not None and value > high:
        raise ValueError(f"{name} must be <= {high}; got {value}")
    return value


def integer(name: str, value, *, low=None):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer; got {value!r}")
    if low is not None and value < low:
        raise ValueError(f"{name} must be >= {low}; got {value}")
    return int(value)


def vector3(name: str, value, *, allow_none=False, nonzero=False) -> np.ndarray | None:
    """A finite 3-vector as a float64 array."""
    if value is None and allow_none:
        return None
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a sequence of 3 numbers; got {value!r}") from None
    if arr.shape != (3,):
        raise ValueError(f"{name} must have 3 components; got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite; got {arr.tolist()}")
    if nonzero and np.linalg.norm(arr) < 1e-12:
        raise ValueError(f"{name} must be a non-zero vector; got {arr.tolist()}")
    return arr


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
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be an array of shape (N, 3); got {type(value).__name__}") from None
    if arr.ndim == 1 and arr.shape == (3,):
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3); got {arr.shape}")
    bad = ~np.all(np.isfinite(arr), axis=1)
    if bad.any():
        idx = np.flatnonzero(bad)
        raise ValueError(f"{name} must be finite; {idx.size} rows are NaN or inf "
                         f"(first: row {idx[0]} = {arr[idx[0]].tolist()})")
    return arr


def per_item(name: str, value, count: int, *, positive=True) -> np.ndarray:
    """A scalar or an (count,) array of finite numbers, > 0 when `positive`."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number or an array of shape ({count},)") from None
    if arr.ndim == 0:
        arr = np.full(count, float(arr))
    elif arr.shape != (count,):
        raise ValueError(f"{name} must be a scalar or have shape ({count},); got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    if positive and count and np.min(arr) <= 0:
        raise ValueError(f"{name} must be > 0; got minimum {np.min(arr)}")
    return arr


def rotation(name: str, value) -> np.ndarray:
    """A proper 3x3 rotation matrix (orthonormal, det +1); None means the identity."""
    if value is None:
        return np.eye(3)
    try:
        R = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a 3x3 rotation matrix") from None
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
                    warnings.warn(f"{function.__qualname__.split('.')[0]}: {old}= is now called {new}=; the old "
                                  "name will be removed in tai_coll 0.3", DeprecationWarning, stacklevel=2)
                    kwargs[new] = kwargs.pop(old)
            return function(*args, **kwargs)

        return call

    return wrap
