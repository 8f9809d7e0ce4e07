"""The incremental QR state of one target, from which partial F-ratios follow.

:class:`IncrementalQR` keeps an orthonormal basis of the model's columns and
the projections of the library and of the target on it. Every candidate's
partial F-ratio of entry (eq. 19) and every model function's partial F-ratio
(eq. 20) then follows without a refit; adding or removing a function updates
the state in place.
"""

from __future__ import annotations

import numpy as np

from ._numeric import EPS
from .least_squares_state import EXACT_FIT_RTOL, LeastSquaresState
from .robust import (
    classic_joint_f,
    lag1_autocorrelation,
    robust_candidate_f,
    robust_in_model_f,
    robust_joint_f,
)
from .screening import Screen, xt

__all__ = ["IncrementalQR", "initial_residual"]


def initial_residual(sw, yw):
    """``(q0, z0, e)`` of the constant-only model of the weighted target ``yw``.

    ``q0 = sw / ||sw||``, ``z0 = q0^T yw`` and the residual ``e = yw - q0 z0``,
    projected twice. ``sw * e`` is the vector whose product with the library
    gives the first step's ``X^T e`` (which the screen's pass can compute:
    :func:`~.screening.screen_columns`'s ``products``).
    """
    q0 = sw / float(np.linalg.norm(sw))
    z0 = q0 @ yw
    e = yw - q0 * z0
    e -= q0 * (q0 @ e)
    return q0, z0, e


class IncrementalQR(LeastSquaresState):
    """Incremental least-squares state of one target during selection.

    With ``X`` the weighted library (rows scaled by ``sqrt(w)``) and ``S`` the
    model, it holds ``Q`` (orthonormal basis of the weighted constant and the
    model columns), the triangular ``T`` with ``[sqrt(w), X_S] = Q T``,
    ``z = Q^T y``, the residual ``e = y - Q z`` and ``C = Q^T X`` (``k+1`` rows,
    one per basis vector). The residual of candidate ``j`` against the model,
    ``r_j = x_j - Q C[:, j]``, is never formed: the partial F of entry (eq. 19)
    needs only ``||r_j||^2 = ||x_j - mean||^2 - sum_{i>0} C[i, j]^2`` and
    ``r_j^T e = x_j^T e`` (``e`` is orthogonal to ``Q``); both are kept up to
    date. Adding a column costs one product ``X^T q`` (``O(n p)``, read
    only); removing one rotates the small factor (``T`` minus a column, made
    triangular again by an orthogonal ``G``; ``Q G``, ``G^T C``: ``O(n k^2 +
    k^2 p)``) and the dropped direction ``u`` gives ``e += u (u^T y)``,
    ``X^T e += (u^T X) (u^T y)`` and ``||r||^2 += (u^T X)^2``.
    Where subtracting squares would lose accuracy (a candidate nearly in the
    span of the model), ``r_j`` is recomputed explicitly (Gram-Schmidt twice).

    ``X`` here is the library with each column multiplied by ``scale`` (see
    :func:`~.screening.screen_columns`), applied on the fly; ``yw`` is the weighted
    target already scaled to unit magnitude, and ``y_unit`` the factor that
    converts its coefficients back to the units of the data. ``xt_e``,
    optional: ``x^T (sw e)`` of the constant-only model's residual ``e``
    (:func:`initial_residual`) for the unscaled library, zero where not
    eligible, if the screen computed it; otherwise a product with the
    library computes it.
    """

    def __init__(
        self, x, sw, yw, screen: Screen, n_eff, tolerance, y_unit=1.0, xt_e=None
    ):
        self.x = x
        self.sw = sw
        self.yw = yw
        self._start(screen, n_eff, tolerance, y_unit)  # support: Q's columns 1..k
        self.un2 = screen.un2
        n, p = x.shape
        cap = 8
        self.Q = np.zeros((n, cap), order="F")
        self.C = np.zeros((cap, p))
        norm_sw = float(np.linalg.norm(sw))
        self.Q[:, 0], z0, self.e = initial_residual(sw, yw)
        self.C[0] = np.where(self.eligible, screen.mean * norm_sw, 0.0)
        self.T = np.array([[norm_sw]])
        self.z = np.array([z0])
        self.floor2 = (EXACT_FIT_RTOL * float(np.linalg.norm(yw))) ** 2
        self.sst = self.sse()  # centred total sum of squares
        self.nr2 = self.cn2.copy()
        if xt_e is None:
            self._exact_g()
        else:
            # X^T (sw e) of the unscaled library, zero where not eligible,
            # from the screen's pass (the same product _exact_g makes)
            self.g = xt_e * self.scale
            self.g_sse = self.sse()

    def sse(self) -> float:
        return float(self.e @ self.e)

    def _exact_g(self):
        """``g = X^T e`` by a product with the library (resets rounding drift)."""
        self.g = xt(self.x, self.sw * self.e, self.eligible) * self.scale
        self.g[self.in_model] = 0.0
        self.g_sse = self.sse()

    def _grow(self):
        cap = self.Q.shape[1]
        if self.k + 1 < cap:
            return
        Q = np.zeros((self.Q.shape[0], 2 * cap), order="F")
        Q[:, :cap] = self.Q
        C = np.zeros((2 * cap, self.C.shape[1]))
        C[:cap] = self.C
        self.Q, self.C = Q, C

    def residualised(self, cols) -> np.ndarray:
        """Columns ``cols`` (weighted, scaled) minus their projection on the model.

        Explicit (``O(n k)`` per column, Gram-Schmidt twice): for the few
        columns whose robust statistics are needed.
        """
        k1 = self.k + 1
        Qk = self.Q[:, :k1]
        r = self.x[:, cols] * self.sw[:, None] * self.scale[cols]
        r = r - Qk @ (Qk.T @ r)
        r -= Qk @ (Qk.T @ r)
        return r

    def _refresh(self, cols):
        """Recompute ``r_j`` for ``cols`` explicitly; refresh their statistics."""
        k1 = self.k + 1
        Qk = self.Q[:, :k1]
        Xj = self.x[:, cols] * self.sw[:, None] * self.scale[cols]
        A = Qk.T @ Xj
        Rj = Xj - Qk @ A
        A2 = Qk.T @ Rj
        Rj -= Qk @ A2
        self.C[:k1, cols] = A + A2
        self.nr2[cols] = np.einsum("ij,ij->j", Rj, Rj)
        self.g[cols] = Rj.T @ self.e

    def add(self, j: int) -> None:
        self._grow()
        k1 = self.k + 1
        Qk = self.Q[:, :k1]
        xj = self.x[:, j] * (self.sw * self.scale[j])
        # Gram-Schmidt twice: orthogonal to working precision even when the
        # column is nearly in the span of the model.
        a = Qk.T @ xj
        r = xj - Qk @ a
        a2 = Qk.T @ r
        r -= Qk @ a2
        a += a2
        rho = float(np.linalg.norm(r))
        q = r / rho
        T = np.zeros((k1 + 1, k1 + 1))
        T[:k1, :k1] = self.T
        T[:k1, k1] = a
        T[k1, k1] = rho
        self.T = T
        zq = float(q @ self.e)
        self.z = np.append(self.z, zq)
        self.e -= q * zq
        self.Q[:, k1] = q
        # the one O(n p) product
        cq = xt(self.x, self.sw * q, self.eligible) * self.scale
        self.C[k1] = cq
        self.support.append(j)
        self.in_model[j] = True
        old = self.nr2
        self.nr2 = old - cq**2
        self.g = self.g - cq * zq
        self.nr2[self.in_model] = 0.0
        self.g[self.in_model] = 0.0
        if self.sse() < 1e-4 * self.g_sse:
            self._exact_g()  # e shrank a lot: refresh the products
        # Subtracting squares loses accuracy when most of ||r_j|| goes away:
        # the error estimate eps * (old + 2 sqrt(old * ||x_j||^2)) / new.
        with np.errstate(divide="ignore", invalid="ignore"):
            err = EPS * (old + 2 * np.sqrt(old * self.un2)) / self.nr2
        redo = np.flatnonzero(
            self.eligible & ~self.in_model & ((self.nr2 <= 0) | ~(err < 1e-8))
        )
        if redo.size:
            self._refresh(redo)

    def remove(self, j: int) -> None:
        k1 = self.k + 1
        i = self.support.index(j) + 1  # column of T (0 is the constant)
        Tdel = np.delete(self.T, i, axis=1)  # (k+1, k): Hessenberg from i on
        G, Tnew = np.linalg.qr(Tdel, mode="complete")
        Qr = self.Q[:, :k1] @ G
        Cr = G.T @ self.C[:k1]
        zr = G.T @ self.z
        u, cu, a = Qr[:, -1], Cr[-1], float(zr[-1])  # the dropped direction
        self.Q[:, : k1 - 1] = Qr[:, :-1]
        self.Q[:, k1 - 1] = 0.0
        self.C[: k1 - 1] = Cr[:-1]
        self.C[k1 - 1] = 0.0
        self.T = Tnew[:-1]
        self.z = zr[:-1]
        self.support.remove(j)
        self.in_model[j] = False
        self.e = self.e + u * a
        self.g = self.g + cu * a
        self.nr2 = self.nr2 + cu**2
        self.nr2[self.in_model] = 0.0
        self.g[self.in_model] = 0.0

    # Statistics the rules ask the state for (a GramState computes them from
    # the library's moments instead).
    def residual_lag1(self) -> float:
        return lag1_autocorrelation(self.e)

    def robust_in_model_f(self, lags: int) -> np.ndarray:
        return robust_in_model_f(self, lags)

    def robust_candidate_f(self, lags: int, classic_f: np.ndarray) -> np.ndarray:
        return robust_candidate_f(self, lags, classic_f)

    def joint_f(self, cols, lags=None) -> float:
        """F-ratio of adding all of ``cols`` together (``lags``: Newey-West)."""
        r = self.residualised(cols)
        if lags is not None:
            return robust_joint_f(r, self.e, lags, self.k + 1)
        dof = self.n_eff - self.k - len(cols) - 1
        return classic_joint_f(r, self.e, self.sse(), self.floor2, dof)
