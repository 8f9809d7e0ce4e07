"""Input checks shared by every public entry point.

Each function raises ``ValueError`` (bad value) or ``TypeError`` (bad kind)
whose message starts with the argument's name, so that a user reading the
error knows which argument to fix. They never modify their input: they return
a new (or read-only viewed) float array.
"""

from __future__ import annotations

import numbers

import numpy as np

__all__ = [
    "as_float_array",
    "check_finite",
    "check_positive_number",
    "check_time",
    "check_indices",
    "check_probability",
]


def as_float_array(value, name: str, ndim: int | tuple = (1, 2), allow_nan=False):
    """Convert to a float ndarray (a copy), checking dimensions and finiteness."""
    if value is None:
        raise TypeError(f"{name} is required, got None")
    try:
        arr = np.array(value, dtype=float, copy=True)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a numeric array: {exc}") from None
    dims = (ndim,) if isinstance(ndim, int) else tuple(ndim)
    if arr.ndim not in dims:
        raise ValueError(
            f"{name} must have {' or '.join(map(str, dims))} dimension(s), "
            f"got shape {arr.shape}"
        )
    if arr.size == 0:
        raise ValueError(f"{name} is empty (shape {arr.shape})")
    check_finite(arr, name, allow_nan=allow_nan)
    return arr


def check_finite(arr, name: str, allow_nan: bool = False) -> None:
    """Raise if ``arr`` holds inf (or NaN, unless ``allow_nan``)."""
    arr = np.asarray(arr)
    if np.any(np.isinf(arr)):
        idx = np.argwhere(np.isinf(arr))[0].tolist()
        raise ValueError(f"{name} contains inf (first at index {idx})")
    if not allow_nan and np.any(np.isnan(arr)):
        idx = np.argwhere(np.isnan(arr))[0].tolist()
        raise ValueError(f"{name} contains NaN (first at index {idx})")


def check_positive_number(value, name: str, *, minimum: float = 0.0, strict=True):
    """A finite real number ``> minimum`` (or ``>=`` if not strict)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    value = float(value)
    bad = value <= minimum if strict else value < minimum
    if not np.isfinite(value) or bad:
        relation = ">" if strict else ">="
        raise ValueError(f"{name} must be finite and {relation} {minimum}, got {value}")
    return value


def check_probability(value, name: str):
    """A number strictly between 0 and 1 (a significance level)."""
    value = check_positive_number(value, name)
    if value >= 1.0:
        raise ValueError(f"{name} must lie strictly between 0 and 1, got {value}")
    return value


def check_time(t, n_samples: int, name: str = "t") -> np.ndarray:
    """Sample times: a step (float) or an increasing array of length n_samples."""
    if np.ndim(t) == 0:
        dt = check_positive_number(t, name)
        return np.arange(n_samples) * dt
    t = as_float_array(t, name, ndim=1)
    if t.size != n_samples:
        raise ValueError(
            f"{name} has {t.size} entries but the data have {n_samples} samples"
        )
    if n_samples > 1 and not np.all(np.diff(t) > 0):
        k = int(np.argmax(~(np.diff(t) > 0)))
        raise ValueError(
            f"{name} must be strictly increasing; t[{k}] = {t[k]} is followed by "
            f"t[{k + 1}] = {t[k + 1]}"
        )
    return t


def check_indices(indices, upper: int, name: str) -> np.ndarray:
    """Distinct integer indices in ``[0, upper)``, returned sorted as given."""
    arr = np.atleast_1d(np.asarray(indices))
    if arr.size == 0:
        raise ValueError(f"{name} must name at least one index")
    if not np.issubdtype(arr.dtype, np.integer):
        if np.issubdtype(arr.dtype, np.floating) and np.all(arr == np.round(arr)):
            arr = arr.astype(int)
        else:
            raise TypeError(f"{name} must hold integer indices, got {indices!r}")
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a flat list of indices, got {indices!r}")
    if np.any(arr < 0) or np.any(arr >= upper):
        raise ValueError(
            f"{name} = {arr.tolist()} is out of range: indices must lie in "
            f"[0, {upper - 1}]"
        )
    if np.unique(arr).size != arr.size:
        raise ValueError(f"{name} = {arr.tolist()} repeats an index")
    return arr.astype(int)
