"""The weight ``W`` on the model error: the covariance constraint or ML.

``"auto"`` (the paper) chooses the scalar ``W`` at which the measurement-
minus-estimate covariance matches the noise covariance (eq. 3): the ratio
``trace(R^-1 S) / m`` increases with ``W``, so the search expands by decades
from a reference scale until the sign of ``ratio - 1`` changes, then finds
the root by Brent's method in ``log W``. ``"ml"`` maximises the restricted
marginal likelihood read off the KKT factorisation: it walks downhill by
decades until the minimum of ``-2 log p(y | W)`` is bracketed, then refines
it. Every solve is warm-started from the previous one.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq, minimize_scalar

__all__ = ["WSearch", "search_W", "reference_W", "covariance_ratio", "channel_ratios"]

# W is searched in [W_ref * 10**-DECADES, W_ref * 10**DECADES].
DECADES = 12.0
_STEP = np.log(10.0)


@dataclass
class WSearch:
    """Outcome of :func:`search_W`.

    Attributes
    ----------
    result : SmootherResult
        The solution at the chosen ``W``.
    W : float
    history : list of (W, criterion)
        Covariance ratio ("auto") or ``-2 log p(y|W)`` ("ml"), sorted by W.
    at_bound : bool
        The criterion could not be met inside the search range.
    n_iter : int
        Gauss-Newton iterations over the whole search.
    converged : bool
        Every solve of the search converged.
    """

    result: object
    W: float
    history: list = field(default_factory=list)
    at_bound: bool = False
    n_iter: int = 0
    converged: bool = True


def reference_W(smoother) -> float:
    """A scale for W: mean sample interval / (error states' unit)^2.

    Per interval the cost weighs ``h W d^2`` against ``r^2 / R``, so in the
    solver's units (:mod:`.units`: a residual of one unit is a one-sigma
    residual) ``h`` is the weight at which a model error of one unit per time
    unit costs as much as a one-sigma residual; in the user's units that is
    ``h / s_e^2``, ``s_e`` the error states' unit (their geometric mean). It
    does not grow with the record length, and it changes with the units of
    the error states exactly as the W that meets the criterion does, so the
    search (and its result) is the same in any units. (``h / R`` in the
    data's units was not: a model error in a state other than the measured
    one, in other units, put the answer outside the range.) The search range
    is ``10**+-12`` times this reference.
    """
    se = np.asarray(smoother.unit, dtype=float)[smoother.es]
    # R in the solver's units has a unit diagonal (each channel's unit is its sd)
    return float(np.mean(smoother.h)) / float(np.exp(2.0 * np.mean(np.log(se))))


def channel_ratios(res, smoother) -> np.ndarray:
    """``mean(r_j^2) / R_jj`` per measured channel (observed samples only)."""
    return np.nanmean(res.residuals**2, axis=0) / np.diag(smoother.R)


def covariance_ratio(res, smoother) -> float:
    """``trace(R^-1 S) / m`` with ``S`` the residual second-moment matrix."""
    r0 = np.where(smoother.mask, res.residuals, 0.0)
    if smoother.m == 1:
        S = np.array([[r0[:, 0] @ r0[:, 0] / max(smoother.n_obs, 1)]])
    else:
        mk = smoother.mask.astype(float)
        S = (r0.T @ r0) / np.maximum(mk.T @ mk, 1.0)
    return float(np.trace(np.linalg.solve(smoother.R, S)) / smoother.m)


class _Criterion:
    """``log W -> criterion``, memoised, with the last solution kept (warm start).

    Only the latest full solution is kept (a solution holds O(N) arrays).
    """

    def __init__(self, smoother, mode, solve, verbose):
        self.smoother, self.mode, self.solve, self.verbose = (
            smoother,
            mode,
            solve,
            verbose,
        )
        self.values = {}
        self.last = self.last_logw = None
        self.n_iter, self.converged = 0, True

    def run(self, logw):
        if self.last_logw != logw:
            q = self.smoother.q
            self.last = self.solve(np.exp(logw) * np.eye(q), self.last)
            self.last_logw = logw
            self.n_iter += self.last.n_iter
            self.converged &= bool(self.last.converged)
        return self.last

    def __call__(self, logw):
        if logw not in self.values:
            res = self.run(logw)
            if self.mode == "ml":
                self.values[logw] = res.neg2_log_likelihood
            else:
                self.values[logw] = covariance_ratio(res, self.smoother)
            if self.verbose:
                name = "-2 log p" if self.mode == "ml" else "ratio"
                print(f"MME: W = {np.exp(logw):.6g}, {name} = {self.values[logw]:.6g}")
        return self.values[logw]


def _constraint_root(crit, l0, lo, hi):
    """``log W`` where the covariance ratio is 1 (or the bound reached)."""

    def g(lw):
        return crit(lw) - 1.0

    a = b = l0
    ga = gb = g(a)
    direction = 1.0 if ga < 0 else -1.0
    # the ratio increases with W: expand until the sign changes
    while np.sign(ga) == np.sign(gb):
        nxt = float(np.clip(b + direction * _STEP, lo, hi))
        if nxt == b:
            warnings.warn(
                "W='auto': the covariance constraint cannot be met for W in "
                f"[{np.exp(lo):.3g}, {np.exp(hi):.3g}]: the covariance ratio "
                f"stays {'below' if gb < 0 else 'above'} 1 ({gb + 1:.4g} at "
                f"W = {np.exp(b):.3g}). "
                + (
                    "The assumed model alone fits the data to within the "
                    "noise, or noise_variance is too large."
                    if gb < 0
                    else "The data cannot be fitted to within the noise: "
                    "noise_variance is too small."
                ),
                UserWarning,
                stacklevel=5,
            )
            return b, True
        a, ga = b, gb
        b = nxt
        gb = g(b)
    return brentq(g, min(a, b), max(a, b), xtol=5e-3), False


def _likelihood_minimum(crit, l0, lo, hi):
    """``log W`` minimising ``-2 log p(y | W)`` (or the bound reached)."""
    left, mid, right = l0 - _STEP, l0, l0 + _STEP
    fl, fm, fr = crit(left), crit(mid), crit(right)
    # walk downhill until the minimum is bracketed
    while not (fm <= fl and fm <= fr):
        if fl < fr:
            right, fr, mid, fm = mid, fm, left, fl
            left = max(left - _STEP, lo)
            if left == mid:
                break
            fl = crit(left)
        else:
            left, fl, mid, fm = mid, fm, right, fr
            right = min(right + _STEP, hi)
            if right == mid:
                break
            fr = crit(right)
    else:
        opt = minimize_scalar(
            crit, bounds=(left, right), method="bounded", options={"xatol": 1e-2}
        )
        return (float(opt.x) if opt.fun <= fm else mid), False
    warnings.warn(
        "W='ml': the marginal likelihood has no maximum for W in "
        f"[{np.exp(lo):.3g}, {np.exp(hi):.3g}]; using the bound "
        f"W = {np.exp(mid):.3g}",
        UserWarning,
        stacklevel=5,
    )
    return mid, True


def search_W(smoother, mode: str, solve, verbose: bool = False) -> WSearch:
    """Scalar ``W`` by the covariance constraint (``"auto"``) or ML (``"ml"``).

    ``solve(W, start)`` solves the problem for one ``W`` (warm start
    ``start``). The search always starts at :func:`reference_W` (never at a
    previous fit's W), so the same inputs give bit-identical results
    whatever the estimator fitted before.
    """
    l0 = np.log(reference_W(smoother))
    lo = l0 - DECADES * _STEP
    hi = l0 + DECADES * _STEP
    crit = _Criterion(smoother, mode, solve, verbose)
    if mode == "auto":
        best, at_bound = _constraint_root(crit, l0, lo, hi)
    else:
        best, at_bound = _likelihood_minimum(crit, l0, lo, hi)
    res = crit.run(best)
    history = sorted((float(np.exp(k)), float(v)) for k, v in crit.values.items())
    return WSearch(
        result=res,
        W=float(np.exp(best)),
        history=history,
        at_bound=at_bound,
        n_iter=crit.n_iter,
        converged=crit.converged,
    )
