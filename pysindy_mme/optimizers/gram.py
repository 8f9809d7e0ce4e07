"""The selection state of one target from the library's moments (tall libraries).

:class:`GramState` answers everything the selection machine and the rules
ask of :class:`~.incremental_qr.IncrementalQR` (partial F-ratios of entry
and in the model, classic and Newey-West robust, the joint test, the
residual's lag-1 autocorrelation, coefficients) from
:class:`~.moments.LibraryMoments`, without reading the data: each step costs
``O(m^3 + m^4)`` for ``m`` columns of the library, whatever the number of
rows. Same statistics, same formulas, so the same decisions (up to
rounding; ``tests/optimizers/test_gram.py``).

Coordinates: a vector ``U a`` of the data (``U`` has orthonormal columns
for the library and the target; see :mod:`.moments`) is represented by
``a``. With ``R_t`` the target's triangular factor
(:meth:`~.moments.LibraryMoments.target_factor`) and a model ``S`` (the
constant and the support), the QR factorisation ``R_t[:, S] = G [T; 0]`` splits these
coordinates into the model's span (``G[:, :k+1]``) and its orthogonal
complement (``G[:, k+1:]``); a column's or the target's complement
coordinates are its residual against the model.
"""

from __future__ import annotations

import numpy as np

from ._numeric import safe_ratio, scaled_target
from .incremental_qr import IncrementalQR, initial_residual
from .least_squares_state import EXACT_FIT_RTOL, RefactoredState
from .moments import LibraryMoments, pair_vectors
from .robust import ROBUST_CANDIDATES, classic_joint_f, small_sample_factor
from .screening import Screen

__all__ = ["GramState", "first_step_vectors", "rows_of_factor", "selection_state"]


def selection_state(moments, target, x, sw, yw, screen, n_eff, tolerance, y_scale):
    """The selection state of one target: from ``moments`` if there are any
    (the library's, or its errors-in-variables corrected moments).

    ``yw``: the weighted target in its power-of-two units (``y_scale``).
    ``screen.products``, if computed, holds row ``target`` of ``X^T (sw e)``
    for the first step (see :func:`~.incremental_qr.initial_residual`).
    """
    make = getattr(moments, "make_state", None)
    if make is not None:
        # corrected moments (errors in variables); a target whose noise is
        # the library's own (make_state: None) is selected on the rows as given
        state = make(yw, screen, n_eff, tolerance, 1.0 / y_scale)
        if state is not None:
            return state
    elif moments is not None and moments.usable[target]:
        return GramState(moments, target, screen, n_eff, tolerance, 1.0 / y_scale)
    xt_e = None if screen.products is None else screen.products[target]
    return IncrementalQR(
        x, sw, yw, screen, n_eff, tolerance, y_unit=1.0 / y_scale, xt_e=xt_e
    )


def rows_of_factor(R, n_eff):
    """``(rows, sqrt(w), w)``: the rows of the triangular factor ``R`` of
    ``[sqrt(w), X, y]`` (constant first) turned by a Householder reflection so
    that the constant's column is constant, and equal weights summing to
    ``n_eff``: a few rows whose weighted cross-products are ``R^T R``
    (:meth:`GramState.pseudo_rows`)."""
    m = R.shape[0]
    a = R[:, 0]
    t = np.full(m, a[0] / np.sqrt(m))
    v = a - t
    vv = float(v @ v)
    rows = R if vv == 0 else R - np.outer(v, (2.0 / vv) * (v @ R))
    w = np.full(m, n_eff / m)
    return rows, np.sqrt(w), w


def first_step_vectors(sw, y) -> np.ndarray:
    """``sw * e`` of each target (column of ``y``): ``X^T`` of it is the first
    step's ``X^T e`` (``e`` of the constant-only model, the target in its
    power-of-two units as the selection scales it)."""
    return np.array(
        [sw * initial_residual(sw, scaled_target(t)[1] * sw)[2] for t in y.T]
    ).reshape(-1, sw.size)


class GramState(RefactoredState):
    """Least-squares state of one target during selection, from moments.

    Parameters
    ----------
    moments : LibraryMoments
    target : int
        Which target (column of ``Y`` in the moments).
    screen : Screen
    n_eff : float
        Sum of the frequency weights.
    tolerance : float
        Collinearity tolerance (as :class:`~.incremental_qr.IncrementalQR`).
    y_unit : float
        Converts the scaled target's coefficients back to data units.
    """

    def __init__(
        self,
        moments: LibraryMoments,
        target: int,
        screen: Screen,
        n_eff,
        tolerance,
        y_unit=1.0,
    ):
        self.moments = moments
        self.y_col = moments.target_column(target)
        self.Rt = moments.target_factor(target)
        self._start(screen, n_eff, tolerance, y_unit)
        ry = self.Rt[:, -1]
        self.floor2 = (EXACT_FIT_RTOL * float(np.linalg.norm(ry))) ** 2
        self._update()
        self.sst = self.sse()

    # ------------------------------------------------------------- the model
    def _factor(self, support):
        """``(G, T, z, ey, xp)`` of the model ``support`` (``O(m^3)``).

        ``R[:, S] = G [T; 0]``; ``z`` the target's coordinates in the model's
        span, ``ey`` its residual and ``xp`` every eligible column's residual
        against the model, in complement coordinates.
        """
        rt = self.Rt
        cols = [0] + [int(self.moments.position[j]) for j in support]
        k1 = len(cols)
        G, Ts = np.linalg.qr(rt[:, cols], mode="complete")
        wy = G.T @ rt[:, -1]
        xp = G[:, k1:].T @ rt[:, 1:-1]
        return G, Ts[:k1], wy[:k1], wy[k1:], xp

    def _update(self):
        """Refactor the model: statistics of every candidate."""
        mo = self.moments
        self.G, self.T, self.z, self.ey, self.xp = self._factor(self.support)
        nr2 = np.zeros(self.in_model.size)
        g = np.zeros(self.in_model.size)
        nr2[mo.columns] = np.einsum("ij,ij->j", self.xp, self.xp)
        g[mo.columns] = self.xp.T @ self.ey
        nr2[self.in_model] = 0.0
        g[self.in_model] = 0.0
        self.nr2, self.g = nr2, g

    def _embed(self, local: np.ndarray) -> np.ndarray:
        """``U``-coordinates of vectors in the target's coordinates (``Rt``'s)."""
        out = np.zeros((self.moments.R.shape[0],) + local.shape[1:])
        out[: local.shape[0] - 1] = local[:-1]
        out[self.y_col] = local[-1]
        return out

    def _full(self, complement: np.ndarray) -> np.ndarray:
        """``U``-coordinates of vectors given in complement coordinates."""
        return self._embed(self.G[:, self.k + 1 :] @ complement)

    # ------------------------------------------------------ classic statistics
    def sse(self) -> float:
        return float(self.ey @ self.ey)

    # ------------------------------------------------------- robust statistics
    def _long_run_variance(self, a, b) -> np.ndarray:
        """Bartlett long-run variance of each score ``(U a_i) * (U b_i)``."""
        v = pair_vectors(a, b)
        var = np.einsum("ic,ij,jc->c", v, self.moments.bartlett, v)
        return np.maximum(var, 0.0)

    def _check_lags(self, lags: int) -> None:
        if lags != self.moments.lags:  # pragma: no cover - set up together
            raise ValueError(
                f"the moments hold {self.moments.lags} Newey-West lags, not {lags}"
            )

    def residual_lag1(self) -> float:
        """Lag-1 autocorrelation of the residual (``sum e_t e_t+1 / sum e_t^2``)."""
        return self._lag1(self._full(self.ey))

    def _lag1(self, e) -> float:
        if self.moments.n_rows < 2:
            return 0.0
        den = float(e @ self.moments.lag0 @ e)
        return float(e @ self.moments.lag1 @ e) / den if den > 0 else 0.0

    def robust_in_model_f(self, lags: int) -> np.ndarray:
        """Newey-West partial F-ratios of ``[constant, support...]``.

        As :func:`~.robust.robust_in_model_f`: the coefficient ``b_i`` is
        ``c_i^T y`` with ``c_i = Q T^-T e_i``; its variance is the long-run
        variance of ``c_i * e``.
        """
        self._check_lags(lags)
        k1 = self.k + 1
        tinv = self._tinv()
        beta = tinv @ self.z
        c = self._embed(self.G[:, :k1] @ tinv.T)
        var = self._long_run_variance(c, self._full(self.ey)[:, None])
        var *= small_sample_factor(self.moments.n_rows, k1)
        return safe_ratio(beta**2, var)

    def robust_candidate_f(self, lags: int, classic_f: np.ndarray) -> np.ndarray:
        """Newey-West partial F-ratios of entry of the strongest candidates.

        As :func:`~.robust.robust_candidate_f`: the ``ROBUST_CANDIDATES``
        candidates with the largest classic F-ratio, each with the residual
        of the enlarged model in its score; ``-inf`` elsewhere.
        """
        self._check_lags(lags)
        out = np.full(classic_f.shape, -np.inf)
        idx = np.flatnonzero(classic_f > -np.inf)
        if idx.size == 0:
            return out
        idx = idx[np.argsort(-classic_f[idx], kind="stable")][:ROBUST_CANDIDATES]
        xp = self.xp[:, self.moments.position[idx] - 1]
        nr2 = np.einsum("ij,ij->j", xp, xp)
        g = xp.T @ self.ey
        b = safe_ratio(g, nr2)
        r = self._full(xp)
        var = self._long_run_variance(r, self._full(self.ey)[:, None] - r * b)
        var *= small_sample_factor(self.moments.n_rows, self.k + 2)
        out[idx] = safe_ratio(g**2, var)
        return out

    def joint_f(self, cols, lags=None) -> float:
        """F-ratio of adding all of ``cols`` together (``lags``: Newey-West).

        As :func:`~.robust.robust_joint_f` (robust) or
        :func:`~.robust.classic_joint_f`.
        """
        cols = np.asarray(cols, dtype=int)
        xp = self.xp[:, self.moments.position[cols] - 1]
        q = cols.size
        if lags is None:
            dof = self.n_eff - self.k - q - 1
            return classic_joint_f(xp, self.ey, self.sse(), self.floor2, dof)
        self._check_lags(lags)
        b, *_ = np.linalg.lstsq(xp, self.ey, rcond=None)
        r = self._full(xp)
        cov_v = pair_vectors(r, self._full(self.ey - xp @ b)[:, None])
        cov = cov_v.T @ self.moments.bartlett @ cov_v
        cov *= small_sample_factor(self.moments.n_rows, self.k + 1 + q)
        g = xp.T @ self.ey
        w = np.linalg.lstsq(cov, g, rcond=None)[0]
        return float(g @ w) / q

    # ------------------------------------------------------- the final table
    def pseudo_rows(self, cols):
        """A few weighted rows with the inner products of the data's.

        Returns ``(x, y, w)``: columns ``cols`` of the library (in their
        power-of-two units) and the scaled target on the rows of ``R_t`` (one
        per column of the library, plus one), of equal
        weight, whose weighted cross-products (constant included) are those
        of all the data's rows, and ``sum(w) = n_eff``. Least squares, ANOVA
        tables and partial F-ratios of entry (:func:`~.anova.fit_anova`)
        read nothing else, so they are computed on these rows. (A Householder
        reflection maps the constant's column of ``R``, ``||sqrt(w)|| e_1``,
        to a constant vector.)
        """
        rows, sw, w = rows_of_factor(self.Rt, self.n_eff)
        pos = self.moments.position[np.asarray(cols, dtype=int)]
        return rows[:, pos] / sw[:, None], rows[:, -1] / sw, w

    def table_statistics(self, support, candidates, lags: int) -> dict:
        """Robust statistics of the model ``support`` (in that order).

        The values of :func:`~.robust.robust_table_statistics` (same keys),
        from the moments.
        """
        self._check_lags(lags)
        n = self.moments.n_rows
        G, T, z, ey, xp = self._factor(support)
        k1 = T.shape[0]
        tinv = self._tinv(T)
        beta = tinv @ z
        e = self._embed(G[:, k1:] @ ey)
        c = self._embed(G[:, :k1] @ tinv.T)
        var = self._long_run_variance(c, e[:, None]) * small_sample_factor(n, k1)
        out = np.zeros(len(candidates))
        if len(candidates):
            rp = xp[:, self.moments.position[np.asarray(candidates, dtype=int)] - 1]
            g = rp.T @ ey
            b = safe_ratio(g, np.einsum("ij,ij->j", rp, rp))
            r = self._embed(G[:, k1:] @ rp)
            v = self._long_run_variance(r, e[:, None] - r * b)
            out = safe_ratio(g**2, v * small_sample_factor(n, k1 + 1))
        ee = float(ey @ ey)
        lrv = max(float(e @ self.moments.bartlett_linear @ e), 0.0)
        return dict(
            in_model=np.atleast_1d(safe_ratio(beta**2, var)),
            out=np.atleast_1d(out),
            lag1=self._lag1(e),
            effective_n=float(n * ee / lrv) if lrv > 0 else float(n),
        )
