"""Regressors every model of a target contains, projected out first.

``FloatingFStepwise.fit(..., partial_out=[N_0, N_1, ...])`` selects the
library functions of target ``t`` *given* the columns of ``N_t`` (always in
the model, never reported as terms). By the Frisch-Waugh-Lovell theorem, the
least-squares coefficients of library columns in a regression that also
holds ``N_t`` equal those of the regression of the residuals of the target
on the residuals of the columns, both taken against ``N_t``. The selection
therefore runs unchanged on the projected library and target.

What it is for: a grey-box model whose parameters the study will re-fit. Its
model error ``d(t)`` was estimated at the current parameters; a missing term
that a change of the parameters partly mimics (``-k h`` beside a missing
``-sqrt(h)``) must be judged on what the parameters *cannot* explain, or a
look-alike that bends the other way wins. The parameters' sensitivities
``df_t/dp`` along the trajectory are the columns to project out.

The constant: the selection always holds it (as without ``partial_out``), so
the columns are centred (weighted) before the projection, which is then the
projection on ``[1, N_t]`` together. The constant the user reads is that of
the joint regression with ``N_t`` as given (not centred: a sensitivity's mean
is part of what the parameter explains), settled after the selection by
:func:`settle_constant` on the original rows: its value, its partial F
(robust under a robust rule) and the decision to drop it are those of the
joint model ``y ~ 1 + N_t + X_S``. The selection's F-ratios use the sample's
degrees of freedom, not reduced by the ``rank(N_t)`` partialled columns (a
relative error of ``rank(N_t) / n`` in every F-ratio), which the summary says.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.linalg

from ._checks import InvalidParameterError, _dense_real
from .robust import robust_table_statistics

__all__ = [
    "check_partial_out",
    "project_out",
    "settle_constant",
    "target_groups",
]

#: a partialled column whose share of the others' span leaves less than this
#: relative norm adds nothing and is dropped (numerical rank)
RANK_RTOL = 1e-10


def check_partial_out(partial_out, n_rows: int, n_targets: int):
    """``partial_out`` as a list of ``(n_rows, k_t)`` float arrays, or None.

    One entry per target; an entry may be None (nothing projected out of that
    target). Raises a ValueError naming the entry that is wrong.
    """
    if partial_out is None:
        return None
    if isinstance(partial_out, np.ndarray) or not hasattr(partial_out, "__len__"):
        raise InvalidParameterError(
            "partial_out must be a list with one entry per target (an array "
            f"(n_samples, k) or None), got {type(partial_out).__name__}"
        )
    if len(partial_out) != n_targets:
        raise InvalidParameterError(
            f"partial_out has {len(partial_out)} entries but y has {n_targets} "
            "target(s): give one per target (None where nothing is projected out)"
        )
    out = []
    for t, entry in enumerate(partial_out):
        if entry is None:
            out.append(np.zeros((n_rows, 0)))
            continue
        arr = _dense_real(entry, f"partial_out[{t}]")
        if arr.ndim == 1:
            arr = arr.reshape(-1, 1)
        if arr.ndim != 2 or arr.shape[0] != n_rows:
            raise InvalidParameterError(
                f"partial_out[{t}] must have shape (n_samples, k) with "
                f"n_samples = {n_rows}, got {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise InvalidParameterError(f"partial_out[{t}] contains NaN or inf")
        if arr.shape[1] >= n_rows - 2:
            raise InvalidParameterError(
                f"partial_out[{t}] has {arr.shape[1]} columns for {n_rows} "
                "samples: it would leave no degrees of freedom"
            )
        out.append(arr)
    return out


def _basis(nuisance: np.ndarray, w: np.ndarray, centre: bool) -> np.ndarray:
    """An orthonormal basis (in the ``w``-weighted rows) of the columns,
    centred first if ``centre``."""
    if nuisance.shape[1] == 0:
        return np.zeros((nuisance.shape[0], 0))
    sw = np.sqrt(w)
    if centre:
        nuisance = nuisance - (w @ nuisance) / w.sum()
    a = nuisance * sw[:, None]
    norms = np.linalg.norm(a, axis=0)
    a = a[:, norms > 0]
    if a.shape[1] == 0:
        return np.zeros((nuisance.shape[0], 0))
    q, r, _ = scipy.linalg.qr(a, mode="economic", pivoting=True)
    diag = np.abs(np.diag(r))
    rank = int(np.sum(diag > RANK_RTOL * diag[0]))
    return q[:, :rank]


def project_out(x, y, nuisance, w, centre: bool = True):
    """``(x_p, y_p, rank)``: ``x`` and ``y`` minus their weighted projections
    on the ``nuisance`` columns.

    ``w`` are positive frequency weights. The projection is orthogonal in the
    weighted inner product. With ``centre`` (for a fit with an intercept, as
    FloatingFStepwise's selection always has) the columns are centred first:
    the weighted least squares of ``y_p`` on ``x_p`` with an intercept gives
    the library coefficients of that of ``y`` on ``x``, ``nuisance`` and a
    constant, and constant columns of ``x`` stay as they are. Without it
    (for a fit through the origin, pysindy's convention, with any constant
    in the library) the fit of ``y_p`` on ``x_p`` gives those of ``y`` on
    ``x`` and ``nuisance``. Non-finite library columns stay non-finite (the
    screen sets them aside).
    """
    q = _basis(nuisance, w, centre)
    if q.shape[1] == 0:
        return x, y, 0
    sw = np.sqrt(w)[:, None]
    with np.errstate(invalid="ignore", over="ignore"):
        x_p = x - (q @ (q.T @ (x * sw))) / sw
        y_p = y - (q @ (q.T @ (y * sw))) / sw
        if centre:
            # a constant column is orthogonal to the centred columns: kept
            # exact (rounding would make it a near-constant the screen sets
            # aside)
            constant = np.ptp(x, axis=0) == 0
            x_p[:, constant] = x[:, constant]
    return x_p, y_p, q.shape[1]


def target_groups(x, y, w, nuisance):
    """``(x, y, targets, rank)``: the targets selected together on one library.

    Without ``nuisance`` all targets share ``x`` (rank 0); with it each target
    gets its own projected library and target, and ``rank`` is the number of
    independent columns projected out.
    """
    if nuisance is None:
        yield x, y, list(range(y.shape[1])), 0
        return
    for t, n_t in enumerate(nuisance):
        x_p, y_p, rank = project_out(x, y[:, [t]], n_t, w)
        yield x_p, y_p, [t], rank


def settle_constant(x, y, nuisance, *, w, fitted, screen, rule, drop, fit_intercept):
    """The constant of a target selected with ``partial_out``, in the joint model.

    ``fitted`` is ``final_fit``'s ``(row, intercept, table, dropped,
    significant_lost)`` on the projected rows, with the constant kept;
    ``x``, ``y`` (1-D), ``w`` and ``nuisance`` are the original rows. The
    constant of ``y ~ 1 + nuisance + x[:, S]`` is tested by its partial F
    (robust under a robust rule) against the rule's constant threshold and
    dropped as ``final_fit`` drops it (``drop``; forced without a constant
    column and ``fit_intercept``), the library coefficients then refit
    without it. Returns the same five values, the table's intercept entries
    replaced by the joint model's.
    """
    row, _, table, _, _ = fitted
    row = row.copy()
    carrier = screen.carrier
    support = np.array([j for j in np.flatnonzero(row) if j != carrier], dtype=int)
    sw = np.sqrt(w)
    n_cols = nuisance.shape[1]
    design = np.column_stack([sw, nuisance * sw[:, None], x[:, support] * sw[:, None]])
    yw = y * sw
    beta, *_ = np.linalg.lstsq(design, yw, rcond=None)
    e = yw - design @ beta
    dof = float(w.sum()) - design.shape[1]
    s2 = float(e @ e) / dof
    inverse = np.linalg.pinv(design.T @ design)
    std_error = float(np.sqrt(s2 * inverse[0, 0]))
    partial_f = float(beta[0] ** 2 / (s2 * inverse[0, 0]))
    robust_f = np.nan
    if rule.robust:
        stats = robust_table_statistics(design, yw, np.zeros((len(yw), 0)), rule.lags)
        robust_f = float(stats["in_model"][0])
    f_constant = robust_f if rule.robust else partial_f
    insignificant = not f_constant >= rule.constant_threshold(support.size)
    forced = carrier is None and not fit_intercept
    dropped = bool(forced or (drop and insignificant))
    constant = joint_constant = float(beta[0])
    if dropped:
        beta, *_ = np.linalg.lstsq(design[:, 1:], yw, rcond=None)
        row[support] = beta[n_cols:]
        constant = 0.0
    else:
        row[support] = beta[1 + n_cols :]
    icpt = constant
    if carrier is not None:
        row[carrier] = constant / screen.carrier_value
        icpt = 0.0
    table = replace(
        table,
        intercept=joint_constant,
        intercept_std_error=std_error,
        intercept_partial_f=partial_f,
        intercept_robust_partial_f=robust_f,
    )
    return row, icpt, table, dropped, bool(forced and not insignificant)
