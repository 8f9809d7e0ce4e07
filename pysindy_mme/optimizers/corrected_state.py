"""The selection state of one target on a noisy library's corrected moments.

See :mod:`.errors_in_variables` for the correction; this module keeps the
state the selection machine reads (:class:`CorrectedState`), with the
statistics of :class:`~.gram.GramState` computed from the corrected Gram
matrix and the robust ones from the corrected estimating equations.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from ._numeric import safe_ratio
from .gram import rows_of_factor
from .least_squares_state import EXACT_FIT_RTOL, RefactoredState
from .robust import (
    ROBUST_CANDIDATES,
    lag1_autocorrelation,
    long_run_covariance,
    long_run_variance,
    small_sample_factor,
)

__all__ = ["SUBSET_BUDGET", "CorrectedState"]

#: models of fewer terms searched at most for one that fits better
#: (:meth:`CorrectedState.dominating_support`): every model of up to 5 terms
#: of a degree-3 library of three states (16,664) at about 20 us each
SUBSET_BUDGET = 20_000


def _cholesky(gram) -> np.ndarray | None:
    """Upper Cholesky factor, or None where ``gram`` is not positive definite
    to working accuracy (scaled to unit diagonal first)."""
    d = np.sqrt(np.maximum(np.diag(gram), 0.0))
    if not np.all(d > 0):
        return None
    try:
        lower = np.linalg.cholesky(gram / np.outer(d, d))
    except np.linalg.LinAlgError:
        return None
    if not np.min(np.abs(np.diag(lower))) > 1e-7:
        return None
    return lower.T * d


class CorrectedState(RefactoredState):
    """Selection state of one target on the corrected moments of a noisy library.

    The same quantities as :class:`~.gram.GramState` (``T``, ``z``, and
    each candidate's ``nr2`` and ``g``), but from the corrected Gram matrix's
    entries on the model and one candidate at a time, never from a factor of
    the whole: the corrected matrix estimates the noise-free library's,
    which along an attractor is nearly singular, so sampling error can make
    it indefinite in directions no small model spans. A candidate whose
    corrected residual against the model is not positive (to the
    collinearity tolerance) is explained by the model within the noise and
    cannot enter. The robust statistics (and the residual's
    autocorrelation) come from the rows: the corrected estimating equations
    (module docstring).
    """

    def __init__(self, moments, yw, screen, n_eff, tolerance, y_unit):
        cm = self.cm = moments
        self.yw = yw
        self.b = cm.rows.T @ yw  # cross-products with the target (kept)
        self.yy = float(yw @ yw)
        self._start(screen, n_eff, tolerance, y_unit)
        self.floor2 = (EXACT_FIT_RTOL * np.sqrt(self.yy)) ** 2
        self._update()
        self.sst = self.sse()

    # ------------------------------------------------------------- the model
    def _local(self, support) -> list:
        """Columns of ``[1, X]`` (0: the constant) of ``support``."""
        return [0] + [int(self.cm.position[j]) for j in support]

    def _update(self):
        """Refactor the model and every candidate's statistics (``O(m k^2)``)."""
        cm, gram = self.cm, self.cm.gram
        cols = self._local(self.support)
        self.T = scipy.linalg.cholesky(gram[np.ix_(cols, cols)])
        self.z = scipy.linalg.solve_triangular(self.T, self.b[cols], trans="T")
        beta = scipy.linalg.solve_triangular(self.T, self.z)
        # every column's coordinates on the model: T^-T G[model, column]
        proj = scipy.linalg.solve_triangular(self.T, gram[cols], trans="T")
        nr2 = np.diag(gram) - np.einsum("ij,ij->j", proj, proj)
        g = self.b - gram[:, cols] @ beta
        full_nr2 = np.zeros(self.in_model.size)
        full_g = np.zeros(self.in_model.size)
        full_nr2[cm.columns] = nr2[1:]
        full_g[cm.columns] = g[1:]
        full_nr2[self.in_model] = 0.0
        full_g[self.in_model] = 0.0
        # not positive: within the noise of the model's span (cannot enter)
        self.nr2 = np.maximum(full_nr2, 0.0)
        self.g = np.where(full_nr2 > 0, full_g, 0.0)

    def sse(self) -> float:
        return max(self.yy - float(self.z @ self.z), 0.0)

    def sse_of(self, support) -> float:
        """Corrected residual sum of squares of the model ``support`` (inf
        where the corrected Gram matrix is not positive definite on it)."""
        cols = self._local(support)
        try:
            T = scipy.linalg.cholesky(self.cm.gram[np.ix_(cols, cols)])
        except np.linalg.LinAlgError:
            return np.inf
        z = scipy.linalg.solve_triangular(T, self.b[cols], trans="T")
        return self.yy - float(z @ z)

    def dominating_support(self, budget: int = SUBSET_BUDGET):
        """A model of fewer terms with a smaller corrected residual, or None.

        The smallest number of terms at which some model of the eligible
        columns fits better than the current one, and the best model of that
        size (the first in ``itertools.combinations`` order among equals).
        None also when that would mean more than ``budget`` models.
        """
        from itertools import combinations
        from math import comb

        k = self.k
        columns = [int(j) for j in self.cm.columns]
        if k < 2 or sum(comb(len(columns), m) for m in range(1, k)) > budget:
            return None
        current = self.sse()
        for m in range(1, k):
            subsets = np.array(list(combinations(columns, m)), dtype=int)
            sse = self._sse_of_many(subsets)
            best = int(np.argmin(sse))
            if sse[best] < current:
                return [int(j) for j in subsets[best]]
        return None

    def _sse_of_many(self, subsets) -> np.ndarray:
        """:meth:`sse_of` of each row of ``subsets`` (one batched factorisation)."""
        local = np.column_stack(
            [np.zeros(len(subsets), dtype=int), self.cm.position[subsets]]
        )
        A = self.cm.gram[local[:, :, None], local[:, None, :]]
        b = self.b[local]
        out = np.full(len(subsets), np.inf)
        # positive definite ones only: the corrected matrix need not be
        d = np.sqrt(np.einsum("cii->ci", A))
        scaled = A / (d[:, :, None] * d[:, None, :])
        ok = np.linalg.eigvalsh(scaled)[:, 0] > 1e-14
        if ok.any():
            L = np.linalg.cholesky(A[ok])
            z = np.linalg.solve(L, b[ok][..., None])[..., 0]
            out[ok] = self.yy - np.einsum("ci,ci->c", z, z)
        return out

    # ----------------------------------------------- the rows' estimating eqs
    def _lags(self) -> int:
        return int(self.cm.lags or 0)

    def _fit(self, cols):
        """``(beta, V, e)`` of the model on ``cols`` of ``[1, X]``: corrected
        coefficients, their Newey-West sandwich covariance (without the
        small-sample factor) and the residual series. Raises ``LinAlgError``
        where the corrected Gram matrix on ``cols`` is singular."""
        cm = self.cm
        A = cm.gram[np.ix_(cols, cols)]
        theta = cm.rows[:, cols]
        beta = np.linalg.solve(A, self.b[cols])
        e = self.yw - theta @ beta
        psi = theta * self.yw[:, None] - cm.outer_times(cols, beta)
        ainv = np.linalg.inv(A)
        omega = long_run_covariance(psi, self._lags())
        return beta, ainv @ omega @ ainv, e

    def _wald(self, cols, q: int) -> float:
        """Wald statistic over ``q`` of the last ``q`` of ``cols`` (HC1 factor)."""
        try:
            beta, V, _ = self._fit(cols)
        except np.linalg.LinAlgError:
            return -np.inf
        V = V[-q:, -q:] * small_sample_factor(self.cm.n_rows, len(cols))
        bq = beta[-q:]
        if q == 1:
            return float(safe_ratio(bq[0] ** 2, max(V[0, 0], 0.0)))
        return float(bq @ np.linalg.lstsq(V, bq, rcond=None)[0]) / q

    def _check_lags(self, lags: int) -> None:
        if lags != self._lags():  # pragma: no cover - set up together
            raise ValueError(f"the moments hold {self._lags()} lags, not {lags}")

    def residual_lag1(self) -> float:
        e = self.yw - self.cm.rows[:, self._local(self.support)] @ self.coef_scaled()
        return lag1_autocorrelation(e)

    def coef_scaled(self) -> np.ndarray:
        """Coefficients of ``[1, support...]`` in the scaled units."""
        return scipy.linalg.solve_triangular(self.T, self.z)

    def robust_in_model_f(self, lags: int) -> np.ndarray:
        self._check_lags(lags)
        return self._robust_in_model(self._local(self.support))[0]

    def _robust_in_model(self, cols):
        """``(robust partial F of each of cols, the residual series)``."""
        beta, V, e = self._fit(cols)
        var = np.diag(V) * small_sample_factor(self.cm.n_rows, len(cols))
        return safe_ratio(beta**2, np.maximum(var, 0.0)), e

    def robust_candidate_f(self, lags: int, classic_f: np.ndarray) -> np.ndarray:
        self._check_lags(lags)
        out = np.full(classic_f.shape, -np.inf)
        idx = np.flatnonzero(classic_f > -np.inf)
        idx = idx[np.argsort(-classic_f[idx], kind="stable")][:ROBUST_CANDIDATES]
        base = self._local(self.support)
        for j in idx:
            out[j] = self._wald(base + [int(self.cm.position[j])], 1)
        return out

    def joint_f(self, cols, lags=None) -> float:
        local = [int(self.cm.position[c]) for c in cols]
        base = self._local(self.support)
        q = len(local)
        if lags is not None:
            self._check_lags(lags)
            return self._wald(base + local, q)
        rest = self.sse_of(list(self.support) + [int(c) for c in cols])
        if rest == np.inf:
            return -np.inf
        reduction = self.sse() - rest
        dof = self.n_eff - self.k - q - 1
        if rest <= self.floor2:
            return np.inf
        return (reduction / q) / (rest / dof)

    # ------------------------------------------------------- the final table
    def pseudo_rows(self, cols):
        """A few weighted rows with the corrected inner products (as
        :meth:`~.gram.GramState.pseudo_rows`). Reported candidates that make
        the corrected matrix indefinite get the smallest eigenvalue the model
        alone has (their entry statistics only; the model's are exact)."""
        cm = self.cm
        local = [0] + [int(cm.position[j]) for j in cols]
        m = len(local)
        full = np.empty((m + 1, m + 1))
        full[:m, :m] = cm.gram[np.ix_(local, local)]
        full[:m, m] = full[m, :m] = self.b[local]
        full[m, m] = self.yy
        R = _cholesky(full)
        if R is None:
            d = np.sqrt(np.diag(full))
            corr = full / np.outer(d, d)
            w_, v_ = np.linalg.eigh(corr)
            k1 = self.k + 1
            floor = np.linalg.eigvalsh(corr[np.ix_(range(k1), range(k1))]).min()
            corr = (v_ * np.maximum(w_, floor * 1e-3)) @ v_.T
            R = np.linalg.cholesky(corr).T * d
        rows, sw, w = rows_of_factor(R, self.n_eff)
        return rows[:, 1:m] / sw[:, None], rows[:, m] / sw, w

    def table_statistics(self, support, candidates, lags: int) -> dict:
        """Robust statistics of the model ``support`` (as
        :meth:`~.gram.GramState.table_statistics`), from the estimating
        equations."""
        self._check_lags(lags)
        n = self.cm.n_rows
        cols = self._local(support)
        in_model, e = self._robust_in_model(cols)
        out = np.array(
            [self._wald(cols + [int(self.cm.position[j])], 1) for j in candidates]
        )
        ee = float(e @ e)
        lrv = float(long_run_variance(e, self._lags()))
        return dict(
            in_model=np.atleast_1d(in_model),
            out=np.atleast_1d(out) if len(candidates) else np.zeros(0),
            lag1=lag1_autocorrelation(e),
            effective_n=float(n * ee / lrv) if lrv > 0 else float(n),
        )
