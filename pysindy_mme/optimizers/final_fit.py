"""The final fit of one target: coefficients and ANOVA table on the support.

After selection, the chosen model is described from scratch by a direct QR
least-squares fit (:func:`~.anova.fit_anova`), independent of the incremental
computations; the constant is then kept or dropped. For a tall, narrow
library (:class:`~.gram.GramState`) the same fit runs on ``m`` weighted
rows with the data's cross-products (:meth:`~.gram.GramState.pseudo_rows`),
and the robust statistics come from the library's moments.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ._numeric import one_blas_thread
from .anova import f_pvalue, fit_anova, lstsq_refined
from .incremental_qr import IncrementalQR
from .partial import settle_constant
from .robust import robust_table_statistics
from .screening import Screen

__all__ = ["final_fit"]


def final_fit(state, x, y, w, screen, *, joint=None, **kwargs):
    """:func:`_final_fit` with BLAS on one thread.

    Its products and factorisations are small (``n x k``): two threads cost
    more in synchronisation than they save (a QR factorisation of 10,000 x
    21 took 0.1 s instead of 0.003 s on a loaded 2-core machine).

    ``joint``: the original ``(x, y, partial_out columns)`` of a target
    selected on projected rows; the fit then keeps the constant and
    :func:`~.partial.settle_constant` settles it in the joint model.
    """
    with one_blas_thread():
        if joint is None:
            return _final_fit(state, x, y, w, screen, **kwargs)
        drop, fit_intercept = kwargs["drop_constant"], kwargs["fit_intercept"]
        kwargs.update(drop_constant=False, fit_intercept=True)
        fitted = _final_fit(state, x, y, w, screen, **kwargs)
        return settle_constant(
            *joint,
            w=w,
            fitted=fitted,
            screen=screen,
            rule=kwargs["rule"],
            drop=drop,
            fit_intercept=fit_intercept,
        )


def _final_fit(
    state: IncrementalQR,
    x,
    y,
    w,
    screen: Screen,
    *,
    tolerance: float,
    max_report: int,
    rule,
    drop_constant: bool,
    fit_intercept: bool = True,
):
    """Coefficients on the support (accurate QR solve) and the ANOVA table.

    ``y`` is the target scaled like the state's (``state.y_unit`` converts
    back). The fit runs on the support and reported columns only, each
    multiplied by its power-of-two ``screen.scale``; the table and the
    coefficients are then converted to the units of the data (exactly).
    With a robust ``rule`` (:class:`~.rules.FamilywiseRule`) the table also
    holds the robust statistics, and the constant is kept or dropped by its
    robust partial F-ratio.

    Without a constant column in the library and with ``fit_intercept``
    False, the coefficients are always refit through the origin (pysindy's
    convention: ``coef_`` is the whole model).

    Returns ``(row, intercept, table, dropped, significant_lost)``, the last
    True where a significant constant was left out that way.
    """
    support = np.sort(np.asarray(state.support, dtype=int))
    top = []
    if max_report > 0:
        f_cand = state.candidate_f()
        order = np.argsort(-f_cand, kind="stable")
        order = order[np.isfinite(f_cand[order])][:max_report]
        top = [int(i) for i in order]
    k = support.size
    cols = np.concatenate([support, np.asarray(top, dtype=int)])
    if hasattr(state, "pseudo_rows"):  # a state from moments
        xs, y, w = state.pseudo_rows(cols)
    else:
        xs = x[:, cols] * screen.scale[cols]
    table = fit_anova(
        xs,
        y,
        np.arange(k),
        intercept=True,
        sample_weight=w,
        candidates=np.arange(k, cols.size),
        tolerance=tolerance,
    )
    col_unit = screen.scale[support]
    y_unit = np.float64(state.y_unit)

    def units(value, *factors):
        # Exact power-of-two conversions back to data units; a coefficient
        # beyond the double range in these units is inf (and sums of squares
        # of data near 1e+-154 inf or 0), as they must be: the selection
        # itself ran on the scaled target.
        with np.errstate(over="ignore", under="ignore"):
            for factor in factors:
                value = value * factor
            return value

    def squared_units(value):
        return float(units(value, y_unit, y_unit))

    if rule.robust:
        table = _with_robust_statistics(table, state, cols, xs, y, w, rule)
    table = replace(
        table,
        n_candidates=rule.family_size(k),
        features=tuple(int(j) for j in support),
        out_features=tuple(top),
        coefficients=units(table.coefficients, col_unit, y_unit),
        std_errors=units(table.std_errors, col_unit, y_unit),
        intercept=float(units(table.intercept, y_unit)),
        intercept_std_error=float(units(table.intercept_std_error, y_unit)),
        ss_regression=squared_units(table.ss_regression),
        ss_residual=squared_units(table.ss_residual),
        ss_total=squared_units(table.ss_total),
        ms_regression=squared_units(table.ms_regression),
        ms_residual=squared_units(table.ms_residual),
    )
    row = np.zeros(x.shape[1])
    sw = np.sqrt(w)
    xw = xs[:, :k] * sw[:, None]
    origin = lstsq_refined(xw, y * sw) if k else np.zeros(0)
    if state.exact_fit():
        # Noise-free target: the constant's t**2 is a ratio of rounding
        # errors. It is needed only if the fit without it is not exact.
        resid = y * sw - xw @ origin
        insignificant = float(resid @ resid) <= state.floor2
    else:
        f_constant = (
            table.intercept_robust_partial_f
            if rule.robust
            else table.intercept_partial_f
        )
        insignificant = not f_constant >= rule.constant_threshold(k)
    forced = screen.carrier is None and not fit_intercept
    dropped = bool(forced or (drop_constant and insignificant))
    significant_lost = bool(forced and not insignificant)
    if dropped:
        icpt = 0.0
        row[support] = units(origin, col_unit, y_unit)
    else:
        icpt = table.intercept
        row[support] = table.coefficients
        if screen.carrier is not None:
            row[screen.carrier] = icpt / screen.carrier_value
            icpt = 0.0
    return row, icpt, table, dropped, significant_lost


def _with_robust_statistics(table, state, cols, xs, y, w, rule):
    """``table`` with the robust (Newey-West) statistics filled in.

    ``cols``: the library columns of ``xs`` (the support, then the reported
    candidates).
    """
    k = len(table.features)
    assessed = np.isfinite(table.out_partial_f)
    if hasattr(state, "table_statistics"):
        stats = state.table_statistics(cols[:k], cols[k:][assessed], rule.lags)
    else:
        sw = np.sqrt(w)
        design = np.column_stack([sw, xs[:, :k] * sw[:, None]])
        cand = xs[:, k:][:, assessed] * sw[:, None]
        stats = robust_table_statistics(design, y * sw, cand, rule.lags)
    out_f = np.full(table.out_partial_f.shape, np.nan)
    out_f[assessed] = stats["out"]
    dof = table.dof_residual
    return replace(
        table,
        robust=True,
        hac_lags=rule.lags,
        robust_partial_f=stats["in_model"][1:],
        robust_p_values=np.atleast_1d(f_pvalue(stats["in_model"][1:], 1, dof)),
        intercept_robust_partial_f=float(stats["in_model"][0]),
        out_robust_partial_f=out_f,
        out_robust_p_values=np.atleast_1d(f_pvalue(out_f, 1, dof - 1)),
        lag1_autocorrelation=stats["lag1"],
        effective_n=stats["effective_n"],
    )
