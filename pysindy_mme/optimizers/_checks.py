"""Argument checks of :class:`FloatingFStepwise` (run by ``fit`` before any work).

Each error names the argument to fix. A bad parameter value, of any kind
(out of range, or of the wrong type), raises :class:`InvalidParameterError`,
which is a ``ValueError`` (pysindy's and scikit-learn's convention) and, for
code that expects one for a wrong type, a ``TypeError``; scikit-learn's own
``InvalidParameterError`` is built the same way.

Data are checked as pysindy's ``BaseOptimizer.fit`` checks them: rows whose
library values or whose targets are all NaN are dropped (the end points of
``FiniteDifference(drop_endpoints=True)``), with their sample weights; complex
and sparse input are rejected (the library is read as a dense real array).
"""

from __future__ import annotations

import numpy as np

from ..core.constraints import Boolean, Integer, Interval, Options, check_parameters

__all__ = ["InvalidParameterError", "check_data", "check_params"]

# Defaults of FloatingFStepwise that _check_no_ignored compares against.
DEFAULT_ALPHA = 0.01
DEFAULT_FLOAT_RATIO = 10.0


class InvalidParameterError(ValueError, TypeError):
    """A parameter or argument of :class:`FloatingFStepwise` has a bad value.

    A ``ValueError`` (what pysindy's optimizers and scikit-learn raise for a bad
    parameter) that is also a ``TypeError``, so that a wrong type is caught
    either way.
    """


_POSITIVE = Interval(0.0, None, closed="neither")
_LEVEL = Interval(0.0, 1.0, closed="neither")

# What each parameter of FloatingFStepwise may be: one check, one message
# (core.constraints). initial_guess is not listed: its one check, with the
# reason, is in _check_no_ignored.
PARAMETER_CONSTRAINTS = {
    "f_enter": [None, _POSITIVE],
    "f_remove": [None, _POSITIVE],
    "alpha_enter": [None, _LEVEL],
    "alpha_remove": [None, _LEVEL],
    "floating": [Boolean(), Options("auto")],
    "float_ratio": [Interval(1.0, None, closed="left")],
    "alpha": [_LEVEL],
    "autocorrelation": [Options("newey-west"), None],
    "time_ordered": [Boolean(), Options("auto")],
    "errors_in_variables": [Options("auto", False)],
    "max_iter": [Integer(1)],
    "drop_insignificant_constant": [Boolean()],
    "fit_intercept": [Boolean()],
    "tolerance": [_LEVEL],
    "max_report": [Integer(0)],
    "normalize_columns": [Boolean()],
    "copy_X": [Boolean()],
    "unbias": [Boolean()],
}


def _float_or_none(value):
    return None if value is None else float(value)


def _check_thresholds(opt) -> dict:
    """The rules between the classic thresholds (each alone is in the table)."""
    f_enter, f_remove = _float_or_none(opt.f_enter), _float_or_none(opt.f_remove)
    alpha_enter = _float_or_none(opt.alpha_enter)
    alpha_remove = _float_or_none(opt.alpha_remove)
    if f_remove is not None:
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
    if alpha_enter is not None:
        if f_enter is not None:
            raise ValueError(
                "give f_enter or alpha_enter, not both (a fixed F threshold or a "
                "per-test significance level)"
            )
        if alpha_remove is None:
            alpha_remove = max(alpha_enter, 0.10)
        elif alpha_remove < alpha_enter:
            raise ValueError(
                f"alpha_remove ({alpha_remove}) must be >= alpha_enter "
                f"({alpha_enter}): a function could enter and leave forever"
            )
    elif alpha_remove is not None:
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
    """Validated parameters of a :class:`FloatingFStepwise` as a dict.

    Raises :class:`InvalidParameterError` (a ``ValueError``) naming the
    parameter.
    """
    try:
        return _check_params(opt)
    except InvalidParameterError:
        raise
    except (TypeError, ValueError) as exc:
        raise InvalidParameterError(str(exc)) from None


def _check_params(opt) -> dict:
    check_parameters(opt, PARAMETER_CONSTRAINTS)
    params = _check_thresholds(opt)
    params["alpha"] = float(opt.alpha)
    params["float_ratio"] = float(opt.float_ratio)
    params["tolerance"] = float(opt.tolerance)
    params["errors_in_variables"] = opt.errors_in_variables
    _check_no_ignored(opt, params)
    return params


def _check_no_ignored(opt, params) -> None:
    """A parameter that the chosen rule would not read is an error, not ignored.

    The rule is one documented set of parameters (see FloatingFStepwise's
    Notes): ``alpha`` belongs to the default rule, ``float_ratio`` to Phase
    II. Only values other than the default are refused, since the default
    cannot be told apart from "not given".
    """
    classic = params["f_enter"] is not None or params["alpha_enter"] is not None
    if classic and params["alpha"] != DEFAULT_ALPHA:
        raise ValueError(
            f"alpha={params['alpha']} is the default rule's family-wise level, "
            "but f_enter or alpha_enter selects the classic rule, which has "
            "none: give alpha, or f_enter / alpha_enter, not both"
        )
    if Boolean().accepts(opt.floating) and not opt.floating:
        if params["float_ratio"] != DEFAULT_FLOAT_RATIO:
            raise ValueError(
                f"float_ratio={params['float_ratio']} sets Phase II's threshold, "
                "but floating=False never runs Phase II"
            )
    if opt.initial_guess is not None:
        raise ValueError(
            "initial_guess is not supported: stepwise selection always starts "
            "from the constant-only model (leave initial_guess=None)"
        )


def _dense_real(value, name: str) -> np.ndarray:
    """``value`` as a float array; sparse and complex input rejected."""
    if value is None:
        raise InvalidParameterError(
            "FloatingFStepwise requires y to be passed, but the target y is None"
            if name == "y"
            else f"{name} is None"
        )
    if hasattr(value, "toarray") or hasattr(value, "tocsr"):
        raise InvalidParameterError(
            f"{name} is a sparse matrix: sparse input is not supported "
            f"(FloatingFStepwise reads a dense library; pass {name}.toarray())"
        )
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise InvalidParameterError(f"{name} must be a numeric array: {exc}") from None
    if np.iscomplexobj(arr) or (
        arr.dtype == object and any(isinstance(v, complex) for v in arr.flat)
    ):
        raise InvalidParameterError(
            f"Complex data not supported: {name} has complex values (their "
            "imaginary parts would be dropped); pass the real and imaginary parts "
            "as separate columns"
        )
    try:
        return np.asarray(arr, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidParameterError(f"{name} must be a numeric array: {exc}") from None


def check_data(x, y, sample_weight):
    """``x`` (float view), ``y`` (2-D), the weights and the rows kept.

    Rows where every library value or every target is NaN are dropped, as
    pysindy's ``BaseOptimizer.fit`` drops them (``pysindy.utils.
    drop_nan_samples``), and their weights with them. Returns ``(x, y, w,
    kept)`` where ``kept`` is None when no row was dropped, else the indices
    of the rows kept.
    """
    x = _dense_real(x, "x")
    if x.ndim != 2:
        raise InvalidParameterError(
            f"x must be 2-D (n_samples, n_features), got shape {x.shape}"
        )
    if x.shape[1] == 0:
        raise InvalidParameterError(
            f"x has no columns: 0 feature(s) (shape={x.shape}) while a minimum "
            "of 1 is required (the library is empty)"
        )
    y = _dense_real(y, "y")
    if y.ndim == 1:
        y = y.reshape(-1, 1)
    if y.ndim != 2:
        raise InvalidParameterError(f"y must be 1-D or 2-D, got shape {y.shape}")
    if y.shape[0] != x.shape[0]:
        raise InvalidParameterError(
            f"y has {y.shape[0]} rows but x has {x.shape[0]}: they must "
            "have one row per sample"
        )
    n = x.shape[0]
    if sample_weight is None:
        w = np.ones(n)
    else:
        w = _dense_real(sample_weight, "sample_weight")
        if w.ndim == 0:
            w = np.full(n, float(w))
        if w.ndim != 1 or w.shape[0] != n:
            raise InvalidParameterError(
                f"sample_weight must have one entry per sample ({n}), got "
                f"shape {w.shape}"
            )
        if not np.all(np.isfinite(w)):
            raise InvalidParameterError("sample_weight contains NaN or inf")
        if np.any(w < 0):
            raise InvalidParameterError(
                f"sample_weight must be non-negative, got {w.min()} "
                f"(at index {int(np.argmin(w))})"
            )
    # pysindy's BaseOptimizer.fit: drop the samples where x or y is all NaN.
    kept = None
    if n and y.shape[1]:
        # A row is all NaN only if its first value is: the whole check reads
        # only those rows (a wide library is not copied into a mask).
        x_nan = np.zeros(n, dtype=bool)
        maybe = np.flatnonzero(np.isnan(x[:, 0]))
        x_nan[maybe] = np.all(np.isnan(x[maybe]), axis=1)
        good = ~x_nan & ~np.all(np.isnan(y), axis=1)
        if not np.all(good):
            kept = np.flatnonzero(good)
            x, y, w = x[kept], y[kept], w[kept]
    bad = ~np.isfinite(y)
    if np.any(bad):
        row, col = np.argwhere(bad)[0]
        kind = "NaN" if np.isnan(y[row, col]) else "inf"
        where = int(row if kept is None else kept[row])
        raise InvalidParameterError(
            f"y (the target) contains {kind} (first at row {where}, column "
            f"{col}); rows whose targets are all NaN are dropped (as pysindy "
            "drops them), but a row with some finite targets cannot be used"
        )
    n_eff = float(w.sum())
    if x.shape[0] and n_eff == 0:
        raise InvalidParameterError(
            "sample_weight is zero for every sample: no observation to fit"
        )
    if n_eff < 2:
        raise InvalidParameterError(
            f"need at least 2 observations (sum of sample_weight), got {n_eff:g}: "
            f"{x.shape[0]} sample(s) were given (n_samples = {x.shape[0]})"
        )
    return x, y, w, kept
