"""Kalman filter + Rauch-Tung-Striebel smoother: an independent reference for MME.

For a linear assumed model and a fixed ``W``, MME is the maximum a posteriori
estimate of a linear Gaussian state-space model (process noise
``d_k ~ N(0, (h_k W)^-1)`` held over each interval, flat prior on ``x_0``),
so it must equal this smoother, written from scratch with the exact
discretisation (matrix exponentials) and a diffuse prior; its marginal
likelihood must equal the filter's prediction-error decomposition. Shared by
``tests/differentiation/test_transcription.py`` and ``test_weight.py``.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

__all__ = ["kalman_rts"]


def _discretise(A, B, h):
    """Exact ZOH discretisation: Phi = e^{Ah}, Gamma = int_0^h e^{As} ds B."""
    n, q = B.shape
    M = np.zeros((n + q, n + q))
    M[:n, :n] = A
    M[:n, n:] = B
    E = expm(M * h)
    return E[:n, :n], E[:n, n:]


def kalman_rts(A, B, C, R, W, y, t, p0=1e8, prior=None):
    """Kalman filter + RTS smoother for x' = A x + B d, y = C x + v.

    ``d`` is constant on each interval with covariance ``(h W)^-1``, which is
    the ZOH reading of the MME cost; the prior on ``x_0`` is ``N(0, p0 I)``,
    except for the states ``prior = (states, P)`` names, whose prior is the
    proper ``N(0, P)`` (an error model's stationary ``d_0``).
    Missing measurements (NaN) are skipped. (``p0 = 1e10`` would lose about
    six digits to cancellation in the covariance update; ``1e8`` is diffuse
    enough that its pull on the estimate is below 1e-7.) Returns the
    smoothed states, the smoothed model errors on the intervals, and
    ``-2 log p(y)`` (prediction error decomposition).
    """
    N, n = len(t), A.shape[0]
    Winv = np.linalg.inv(W)
    xf = np.zeros((N, n))
    Pf = np.zeros((N, n, n))
    xp = np.zeros((N, n))
    Pp = np.zeros((N, n, n))
    Phis, Gams = [], []
    x, P = np.zeros(n), p0 * np.eye(n)
    n_diffuse = n
    if prior is not None:
        idx = np.asarray(prior[0], dtype=int)
        P[np.ix_(idx, idx)] = prior[1]
        n_diffuse = n - idx.size
    n2ll = 0.0
    for k in range(N):
        if k > 0:
            h = t[k] - t[k - 1]
            Phi, Gam = _discretise(A, B, h)
            Phis.append(Phi)
            Gams.append(Gam)
            x = Phi @ x
            P = Phi @ P @ Phi.T + Gam @ (Winv / h) @ Gam.T
        xp[k], Pp[k] = x, P
        ok = ~np.isnan(y[k])
        if ok.any():
            Ck, Rk = C[ok], R[np.ix_(ok, ok)]
            e = y[k, ok] - Ck @ x
            S = Ck @ P @ Ck.T + Rk
            K = P @ Ck.T @ np.linalg.inv(S)
            x = x + K @ e
            P = (np.eye(n) - K @ Ck) @ P
            P = 0.5 * (P + P.T)
            n2ll += np.linalg.slogdet(S)[1] + e @ np.linalg.solve(S, e)
            n2ll += ok.sum() * np.log(2 * np.pi)
        xf[k], Pf[k] = x, P
    xs = xf.copy()
    ds = np.zeros((N - 1, B.shape[1]))
    for k in range(N - 2, -1, -1):
        Gk = Pf[k] @ Phis[k].T @ np.linalg.inv(Pp[k + 1])
        xs[k] = xf[k] + Gk @ (xs[k + 1] - xp[k + 1])
        h = t[k + 1] - t[k]
        # E[d_k | y]: d_k is independent of y_0..y_k, so it is updated only
        # through x_{k+1}: Cov(d_k, x_{k+1}) = (hW)^-1 Gamma^T.
        ds[k] = (
            (Winv / h) @ Gams[k].T @ np.linalg.solve(Pp[k + 1], xs[k + 1] - xp[k + 1])
        )
    # remove the diffuse prior's normalisation: a flat prior has density 1,
    # the N(0, p0 I) prior (2 pi p0)^{-n/2}
    n2ll -= n_diffuse * np.log(2 * np.pi * p0)
    return xs, ds, n2ll
