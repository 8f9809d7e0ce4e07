"""Argument checks of :class:`FloatingFStepwise` (run by ``fit`` before any work).

Each error names the argument to fix.
"""

from __future__ import annotations

import numbers

import numpy as np

from ..core.validation import check_positive_number, check_probability

__all__ = ["check_data", "check_params"]

AUTOCORRELATION = ("newey-west", None)


def _check_thresholds(opt) -> dict:
    """The classic thresholds (f_enter/f_remove, alpha_enter/alpha_remove)."""
    f_enter = f_remove = alpha_enter = alpha_remove = None
    if opt.f_enter is not None:
        f_enter = check_positive_number(opt.f_enter, "f_enter")
    if opt.f_remove is not None:
        f_remove = check_positive_number(opt.f_remove, "f_remove")
        if f_enter is None:
            raise ValueError(
                "f_remove requires f_enter (fixed thresholds replace the default "
                "family-wise rule only when f_enter is given)"
            )
        if f_remove > f_enter:
            raise ValueError(
                f"f_remove ({f_remove}) must not exceed f_enter ({f_enter}): "
                "a function could enter and leave forever"
            )
    elif f_enter is not None:
        f_remove = f_enter
    if opt.alpha_enter is not None:
        if f_enter is not None:
            raise ValueError(
                "give f_enter or alpha_enter, not both (a fixed F threshold or a "
                "per-test significance level)"
            )
        alpha_enter = check_probability(opt.alpha_enter, "alpha_enter")
        if opt.alpha_remove is None:
            alpha_remove = max(alpha_enter, 0.10)
        else:
            alpha_remove = check_probability(opt.alpha_remove, "alpha_remove")
            if alpha_remove < alpha_enter:
                raise ValueError(
                    f"alpha_remove ({alpha_remove}) must be >= alpha_enter "
                    f"({alpha_enter}): a function could enter and leave forever"
                )
    elif opt.alpha_remove is not None:
        raise ValueError(
            "alpha_remove requires alpha_enter (significance levels replace "
            "f_enter/f_remove only when alpha_enter is given)"
        )
    return dict(
        f_enter=f_enter,
        f_remove=f_remove,
        alpha_enter=alpha_enter,
        alpha_remove=alpha_remove,
    )


def check_params(opt) -> dict:
    """Validated parameters of a :class:`FloatingFStepwise` as a dict."""
    params = _check_thresholds(opt)
    params["alpha"] = check_probability(opt.alpha, "alpha")
    if opt.autocorrelation not in AUTOCORRELATION:
        raise ValueError(
            f"autocorrelation must be 'newey-west' or None, got {opt.autocorrelation!r}"
        )
    if not (isinstance(opt.floating, (bool, np.bool_)) or opt.floating == "auto"):
        raise TypeError(
            f"floating must be True or False (or 'auto'), got {opt.floating!r}"
        )
    if not isinstance(opt.drop_insignificant_constant, (bool, np.bool_)):
        raise TypeError(
            "drop_insignificant_constant must be True or False, got "
            f"{opt.drop_insignificant_constant!r}"
        )
    params["float_ratio"] = check_positive_number(
        opt.float_ratio, "float_ratio", minimum=1.0, strict=False
    )
    for name, minimum in (("max_iter", 1), ("max_report", 0)):
        value = getattr(opt, name)
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            raise TypeError(f"{name} must be an integer, got {value!r}")
        if value < minimum:
            raise ValueError(f"{name} must be >= {minimum}, got {value}")
    tolerance = check_positive_number(opt.tolerance, "tolerance")
    if tolerance >= 1:
        raise ValueError(f"tolerance must be < 1, got {tolerance}")
    params["tolerance"] = tolerance
    return params


def check_data(x, y, sample_weight):
    """``x`` (float view), ``y`` (2-D copy) and the weights, checked before any work."""
    try:
        x = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"x must be a numeric array: {exc}") from None
    if x.ndim != 2:
        raise ValueError(f"x must be 2-D (n_samples, n_features), got shape {x.shape}")
    if x.shape[1] == 0:
        raise ValueError("x has no columns (the library is empty)")
    try:
        y = np.array(y, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"y must be a numeric array: {exc}") from None
    if y.ndim == 1:
        y = y.reshape(-1, 1)
    if y.ndim != 2:
        raise ValueError(f"y must be 1-D or 2-D, got shape {y.shape}")
    if y.shape[0] != x.shape[0]:
        raise ValueError(
            f"y has {y.shape[0]} rows but x has {x.shape[0]}: they must "
            "have one row per sample"
        )
    bad = ~np.isfinite(y)
    if np.any(bad):
        row, col = np.argwhere(bad)[0]
        kind = "NaN" if np.isnan(y[row, col]) else "inf"
        raise ValueError(
            f"y (the target) contains {kind} (first at row {row}, column "
            f"{col}); remove those samples first (e.g. the NaN end points "
            "of FiniteDifference(drop_endpoints=True))"
        )
    n = x.shape[0]
    if sample_weight is None:
        w = np.ones(n)
    else:
        try:
            w = np.asarray(sample_weight, dtype=float)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"sample_weight must be numeric: {exc}") from None
        if w.ndim == 0:
            w = np.full(n, float(w))
        if w.ndim != 1 or w.shape[0] != n:
            raise ValueError(
                f"sample_weight must have one entry per sample ({n}), got "
                f"shape {w.shape}"
            )
        if not np.all(np.isfinite(w)):
            raise ValueError("sample_weight contains NaN or inf")
        if np.any(w < 0):
            raise ValueError(
                f"sample_weight must be non-negative, got {w.min()} "
                f"(at index {int(np.argmin(w))})"
            )
    n_eff = float(w.sum())
    if n_eff < 2:
        raise ValueError(
            f"need at least 2 observations (sum of sample_weight), got {n_eff:g}"
        )
    return x, y, w
