"""Partial F-ratios that stay valid when the residuals are autocorrelated.

The classic partial F-ratio (eqs. 19, 20) divides a function's contribution
by the residual variance as if the residuals were independent. Derivatives
from smoothed finite differences, and MME's smooth estimate of the model
error, have errors that are correlated from one sample to the next and
systematic (smoothing bias); the classic F-ratio then counts each correlated
sample as new evidence and false functions pass any fixed threshold.

The robust (Newey-West) partial F-ratio of a function is its Wald statistic
``b**2 / Var(b)``, with ``Var(b)`` estimated from the products of the
function's residualised column ``r`` and the regression residual ``e`` and
their autocovariances up to ``lags`` (Bartlett weights, which keep the
estimate non-negative). For independent, equal-variance residuals it equals
the classic F-ratio (up to ``O(1/n)``); when the residuals are correlated or
heteroscedastic it is smaller in proportion. It is referred to the
chi-squared distribution with one degree of freedom.

Rows are taken in the order given: consecutive rows are neighbours in time.
Rows from several trajectories stacked one after the other (what pysindy
passes) add a few spurious products at the joins, which do not matter for
records longer than a few dozen samples. Rows in arbitrary order (bootstrap
samples inside ``EnsembleOptimizer``, shuffled rows, the windows of a weak
library) have no usable time neighbours, and the dependence between them
cannot be estimated: :func:`rows_look_time_ordered` tells such rows apart,
and the default rule then uses the ordinary test
(``FloatingFStepwise(time_ordered=...)``).

Sample weights: the state works with rows multiplied by ``sqrt(w)``, so a row
of weight ``w`` contributes the score ``w r e``; its variance is that of one
observation scaled by ``w**2``. Multiplying every weight by a constant
therefore changes no robust F-ratio.

Size (measured, ``tests/optimizers/test_default_rule.py``): with the
Bonferroni level 0.01 of the default rule, pure noise admits a column in
2.5% of fits (white noise, 500 rows, 30 columns; the estimated variance makes
the statistic's tail a little heavier than F's) and in 3.5% with AR(0.5)
errors and columns, where classic F-ratios admit one in 14.5%. With
lag-1 autocorrelation near 0.9 a few lags no longer capture the correlation;
that regime is left to the paper's rule (``floating="auto"``).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from ._numeric import safe_ratio

__all__ = [
    "BartlettWindows",
    "classic_joint_f",
    "lag1_autocorrelation",
    "long_run_covariance",
    "long_run_variance",
    "newey_west_lags",
    "robust_candidate_f",
    "robust_joint_f",
    "robust_in_model_f",
    "robust_table_statistics",
    "rows_look_time_ordered",
    "small_sample_factor",
]

# Robust F-ratios are computed for this many candidates, those with the
# largest classic F-ratios (O(n * k) work each); the rest cannot enter in
# that step. Twenty keeps wide libraries as fast as before.
ROBUST_CANDIDATES = 20


def newey_west_lags(n: float) -> int:
    """Newey and West's (1994) bandwidth: ``floor(4 (n / 100)**(2/9))``.

    5 lags for 400 samples, 7 for 2,000, 9 for 10,000.
    """
    return int(np.floor(4.0 * (max(float(n), 1.0) / 100.0) ** (2.0 / 9.0)))


# Window sums are formed from cumulative sums over blocks of this many rows:
# their rounding error is about eps * WINDOW_ROWS * max |u|.
WINDOW_ROWS = 4096


class BartlettWindows:
    """Sums of ``lags + 1`` consecutive rows, fed one block of rows at a time.

    The Bartlett kernel is the autocorrelation of a box: with ``u`` padded by
    zeros and ``B_s = u[s - lags] + ... + u[s]`` for every ``s`` whose window
    meets the data,

        ``sum_s B_s B_s^T = (lags + 1) sum_{|k| <= lags} (1 - |k| / (lags + 1))
        sum_t u[t] u[t + k]^T``,

    so a Newey-West long-run covariance is one Gram matrix of window sums,
    ``O(n m^2)``, instead of one product per lag, ``O(n m^2 lags)``. Each block
    of window sums comes from a cumulative sum over that block only (plus the
    ``lags`` rows before it), so rounding does not grow with the record.
    """

    def __init__(self, lags: int, width: int):
        self.lags = int(lags)
        self.carry = np.zeros((self.lags, width))  # the last ``lags`` rows seen

    def feed(self, block: np.ndarray) -> np.ndarray:
        """Window sums ending at each row of ``block`` (``block.shape`` rows)."""
        b, lags = block.shape[0], self.lags
        # Cumulative sums run down columns: column-major is several times
        # faster than row-major here.
        cs = np.empty((lags + b + 1, block.shape[1]), order="F")
        cs[0] = 0.0
        cs[1 : lags + 1] = self.carry
        cs[lags + 1 :] = block
        if lags:
            self.carry = cs[-lags:].copy() if b >= lags else cs[b + 1 :].copy()
        np.cumsum(cs[1:], axis=0, out=cs[1:])
        return cs[lags + 1 :] - cs[:b]

    def tail(self) -> np.ndarray:
        """Window sums ending past the last row (``lags`` rows of them)."""
        # The window ending i rows after the last holds carry[i - 1:].
        return np.cumsum(self.carry[::-1], axis=0)[::-1]


def long_run_covariance(u: np.ndarray, lags: int) -> np.ndarray:
    """Bartlett-weighted sum of the lagged cross-products of the columns of ``u``.

    ``sum_{|k| <= lags} (1 - |k| / (lags + 1)) sum_t u[t] u[t + k]^T``
    (not centred: under the null hypothesis the scores have mean zero),
    computed from window sums (:class:`BartlettWindows`), in row blocks.
    """
    u = np.asarray(u, dtype=float)
    n, m = u.shape
    windows = BartlettWindows(lags, m)
    out = np.zeros((m, m))
    if windows.lags == 0:
        return u.T @ u
    for start in range(0, n, WINDOW_ROWS):
        b = windows.feed(u[start : start + WINDOW_ROWS])
        out += b.T @ b
    b = windows.tail()
    out += b.T @ b
    return out / (windows.lags + 1.0)


def long_run_variance(u: np.ndarray, lags: int) -> np.ndarray:
    """The diagonal of :func:`long_run_covariance`: one value per column of ``u``."""
    u = np.asarray(u, dtype=float)
    if u.ndim == 1:
        return long_run_variance(u[:, None], lags)[0]
    n, m = u.shape
    windows = BartlettWindows(lags, m)
    out = np.zeros(m)
    if windows.lags == 0:
        return np.einsum("ij,ij->j", u, u)
    for start in range(0, n, WINDOW_ROWS):
        b = windows.feed(u[start : start + WINDOW_ROWS])
        out += np.einsum("ij,ij->j", b, b)
    b = windows.tail()
    out += np.einsum("ij,ij->j", b, b)
    # Bartlett weights make the estimate non-negative in exact arithmetic
    # (it is a sum of squares here, so in rounding too).
    return out / (windows.lags + 1.0)


def lag1_autocorrelation(e: np.ndarray) -> float:
    """``sum e[t] e[t+1] / sum e[t]**2`` of a residual (0 when it is zero)."""
    e = np.asarray(e, dtype=float)
    if e.size < 2:
        return 0.0
    den = float(e @ e)
    return float(e[:-1] @ e[1:]) / den if den > 0 else 0.0


# Rows are taken to be in time order unless the median lag-1 autocorrelation
# of the library columns is below this: near 1 for the samples of a
# trajectory, within a few 1/sqrt(n) of 0 in a random order.
TIME_ORDER_LAG1 = 0.3
# ... and shorter records are taken as given (too few rows to tell).
TIME_ORDER_MIN_ROWS = 20
# The decision reads at most this many columns (evenly spread).
TIME_ORDER_MAX_COLUMNS = 200


def rows_look_time_ordered(x, eligible) -> bool:
    """Whether the rows of the library ``x`` look like samples in time order.

    The median, over the ``eligible`` columns (finite, not constant), of the
    lag-1 autocorrelation in row order: samples of a trajectory give values
    near 1 (each column is a smooth function of time), rows in a random
    order (shuffled, bootstrapped, the random window centres of a weak
    library) values near 0. Rows are taken as time-ordered unless it is
    below ``TIME_ORDER_LAG1``; records of fewer than
    ``TIME_ORDER_MIN_ROWS`` rows or without an eligible column are taken as
    given (True).
    """
    cols = np.flatnonzero(np.asarray(eligible, dtype=bool))
    n = x.shape[0]
    if n < TIME_ORDER_MIN_ROWS or cols.size == 0:
        return True
    if cols.size > TIME_ORDER_MAX_COLUMNS:
        cols = cols[np.linspace(0, cols.size - 1, TIME_ORDER_MAX_COLUMNS).astype(int)]
    values = []
    # one gather of the columns read (a strided read per column is slow on a
    # wide array, and a streamed design makes them block by block)
    sub = np.asarray(x[:, cols], dtype=float)
    for c in sub.T:
        top = float(np.max(np.abs(c)))
        if not top > 0:
            continue
        c = c / top  # no overflow in the squares
        c = c - c.mean()
        values.append(lag1_autocorrelation(c))
    if not values:
        return True
    return bool(np.median(values) >= TIME_ORDER_LAG1)


def small_sample_factor(n: int, n_params: int) -> float:
    """``n / (n - p)``: the HC1 factor, so that white residuals give the classic F."""
    return n / max(n - n_params, 1)


def robust_in_model_f(state, lags: int) -> np.ndarray:
    """Robust partial F-ratios of ``[constant, support...]`` of an IncrementalQR.

    With ``[sqrt(w), X_S] = Q T``, the coefficient ``b_i`` is ``c_i^T y`` with
    ``c_i = Q T^{-T} e_i``; its robust variance is the long-run variance of
    ``c_i * e``.
    """
    k1 = state.k + 1
    tinv = scipy.linalg.solve_triangular(state.T, np.eye(k1))
    beta = tinv @ state.z
    c = state.Q[:, :k1] @ tinv.T
    var = long_run_variance(c * state.e[:, None], lags)
    var *= small_sample_factor(state.e.size, k1)
    return safe_ratio(beta**2, var)


def robust_joint_f(r: np.ndarray, e: np.ndarray, lags: int, n_model: int) -> float:
    """Newey-West Wald statistic, divided by ``q``, for adding all ``q``
    residualised columns ``r`` (n, q) to a model that leaves residual ``e``.

    With ``g = r^T e`` and ``S`` the long-run covariance of the scores
    ``r_t u_t`` (``u`` the residual of the enlarged model), the Wald
    statistic is ``g^T S^-1 g``; divided by ``q`` it is an F-ratio, equal to
    the classic joint F for white, homoscedastic residuals (HC1 factor).
    """
    q = r.shape[1]
    b, *_ = np.linalg.lstsq(r, e, rcond=None)
    cov = long_run_covariance(r * (e - r @ b)[:, None], lags)
    cov *= small_sample_factor(e.size, n_model + q)
    g = r.T @ e
    w = np.linalg.lstsq(cov, g, rcond=None)[0]
    return float(g @ w) / q


def classic_joint_f(r, e, sse: float, floor2: float, dof: float) -> float:
    """Classic F-ratio of adding all columns of ``r`` (residualised) to a model.

    ``e`` is the model's residual and ``sse`` its sum of squares; the
    columns' fitted reduction over ``q`` against the rest over ``dof``
    (``inf`` when the rest is at rounding level, below ``floor2``). Only inner
    products are read, so ``r`` and ``e`` may be given in any orthonormal
    coordinates.
    """
    q = r.shape[1]
    sol, *_ = np.linalg.lstsq(r, e, rcond=None)
    fitted = r @ sol
    reduction = min(float(fitted @ fitted), sse)
    rest = max(sse - reduction, 0.0)
    return np.inf if rest <= floor2 else (reduction / q) / (rest / dof)


def robust_candidate_f(state, lags: int, classic_f: np.ndarray) -> np.ndarray:
    """Robust partial F-ratios of entry of the strongest candidates.

    The ``ROBUST_CANDIDATES`` eligible candidates with the largest classic
    F-ratio of entry get their robust F-ratio; every other entry is ``-inf``
    (not assessed). For candidate ``j`` with residualised column ``r`` (its
    part orthogonal to the model) the statistic is ``(r^T e)**2 / V`` with
    ``V`` the long-run variance of ``r * (e - b r)``: the residual of the
    enlarged model, so that the function's own contribution does not inflate
    its variance.
    """
    out = np.full(classic_f.shape, -np.inf)
    idx = np.flatnonzero(classic_f > -np.inf)
    if idx.size == 0:
        return out
    idx = idx[np.argsort(-classic_f[idx], kind="stable")][:ROBUST_CANDIDATES]
    r = state.residualised(idx)
    nr2 = np.einsum("ij,ij->j", r, r)
    g = r.T @ state.e
    b = safe_ratio(g, nr2)
    var = long_run_variance(r * (state.e[:, None] - r * b), lags)
    var *= small_sample_factor(state.e.size, state.k + 2)
    out[idx] = safe_ratio(g**2, var)
    return out


def robust_table_statistics(design, yw, candidates, lags: int) -> dict:
    """Robust statistics of a fitted model, computed from scratch (for the table).

    Parameters
    ----------
    design : ndarray (n, p)
        Weighted design ``[sqrt(w), sqrt(w) X_S]`` (constant first).
    yw : ndarray (n,)
        Weighted target.
    candidates : ndarray (n, c)
        Weighted columns not in the model (finite), whose robust F-ratios of
        entry are wanted.
    lags : int
        Newey-West bandwidth.

    Returns
    -------
    dict
        ``in_model`` (robust partial F of each design column, constant first),
        ``out`` (robust F of entry of each candidate), ``lag1`` (residual's
        lag-1 autocorrelation) and ``effective_n`` (rows / (long-run variance
        of the residual / its variance): the number of independent
        observations the residual is worth).
    """
    n, p = design.shape
    q, r = np.linalg.qr(design)
    beta = scipy.linalg.solve_triangular(r, q.T @ yw)
    e = yw - design @ beta
    rinv = scipy.linalg.solve_triangular(r, np.eye(p))
    c = q @ rinv.T
    var = long_run_variance(c * e[:, None], lags) * small_sample_factor(n, p)
    in_model = safe_ratio(beta**2, var)
    out = np.zeros(candidates.shape[1])
    if candidates.shape[1]:
        rc = candidates - q @ (q.T @ candidates)
        rc -= q @ (q.T @ rc)
        g = rc.T @ e
        b = safe_ratio(g, np.einsum("ij,ij->j", rc, rc))
        v = long_run_variance(rc * (e[:, None] - rc * b), lags)
        out = safe_ratio(g**2, v * small_sample_factor(n, p + 1))
    ee = float(e @ e)
    lrv = float(long_run_variance(e, lags))
    return dict(
        in_model=np.atleast_1d(in_model),
        out=np.atleast_1d(out),
        lag1=lag1_autocorrelation(e),
        effective_n=float(n * ee / lrv) if lrv > 0 else float(n),
    )
