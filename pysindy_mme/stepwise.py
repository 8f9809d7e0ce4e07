"""Floating-F stepwise regression: the paper's modified stepwise regression (MSR).

:class:`FloatingFStepwise` is a pysindy optimizer. For every target (every
equation) it selects library functions one at a time by partial F-ratios
(Kolodziej & Mook, section III):

* Phase I (Draper & Smith's stepwise regression): in each iteration, if a
  function in the model has a partial F-ratio (eq. 20) below ``F_remove``,
  the weakest one leaves; otherwise the candidate with the largest partial
  F-ratio of entry (eq. 19) enters if it reaches ``F_enter``.
* Phase II (the floating threshold): the threshold becomes the largest
  partial F-ratio in the model divided by ``float_ratio``; the weakest
  function below it leaves (one per iteration, all partial F-ratios and the
  threshold are then recomputed); when none is below it, candidates must
  reach ``max(F_enter, floating threshold)`` to enter.

The selection never refits the model per candidate. It keeps an orthonormal
basis ``Q`` of the model columns, the projections ``Q^T X`` of the library and
the current residual, from which every candidate's partial F-ratio follows in
``O(n_candidates)``; adding a function costs one pass over the library
(``O(n_samples * n_candidates)``), removing one ``O(n_samples * k^2 +
k^2 * n_candidates)`` for ``k`` functions in the model (see :class:`_Path`).
The library is never copied.

Units: partial F-ratios do not depend on the scale of a column or of the
target, but sums of squares of values near ``1e+-154`` overflow or underflow.
Every library column and every target is therefore multiplied by a power of
two that brings its largest magnitude into ``[0.5, 1)`` (exact in floating
point, applied on the fly: the library is still not copied), so that data in
any units select the same terms; coefficients are converted back at the end.

Cycles: the floating threshold can send the selection round a loop (e.g.
removing a term lowers the strongest partial F-ratio, hence the threshold,
and the term re-enters). Decisions depend only on (phase, model), so a
repeated state is a true cycle: the selection warns
(:class:`StepwiseCycleWarning`) and stops at the model of the cycle with the
largest overall F-ratio, which the paper reads as the better representation.
"""

from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg
from pysindy.optimizers import BaseOptimizer
from scipy.linalg.lapack import dtrtri
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils.validation import check_is_fitted

from .anova import AnovaTable, f_critical, fit_anova, lstsq_refined
from .core.validation import check_positive_number, check_probability
from .exceptions import ExcludedFeaturesWarning, StepwiseCycleWarning

__all__ = [
    "FloatingFStepwise",
    "Step",
    "StepwiseCycleWarning",
    "ExcludedFeaturesWarning",
]

# Temporaries of size n_samples x block are capped at this many doubles (8 MB).
_BLOCK_ELEMENTS = 1 << 20
# A target reproduced to this relative accuracy is fitted to rounding level:
# partial F-ratios computed from a rounding-noise residual are meaningless, so
# no further function may enter.
_EXACT_FIT_RTOL = 1e-12
_EPS = np.finfo(float).eps
# Columns whose raw products x^T v could overflow (|x| * n beyond 2**1000) or
# whose values are deep in the subnormal range cannot be used reliably.
_HUGE = 2.0**1000
_TINY = 2.0**-960


def _pow2_scale(max_abs):
    """Powers of two ``s`` with ``max_abs * s`` in ``[0.5, 1)``.

    1 where ``max_abs`` is 0 or not finite.
    """
    max_abs = np.asarray(max_abs, dtype=float)
    ok = np.isfinite(max_abs) & (max_abs > 0)
    _, exponent = np.frexp(np.where(ok, max_abs, 1.0))
    return np.where(ok, np.ldexp(1.0, -exponent), 1.0)


@dataclass(frozen=True)
class Step:
    """One addition or removal made by :class:`FloatingFStepwise`.

    Attributes
    ----------
    iteration : int
        1-based iteration number (per target).
    phase : int
        1 (fixed thresholds) or 2 (floating threshold).
    action : str
        ``"add"`` or ``"remove"``.
    feature : int
        Library column index.
    name : str
        Its name (``feature_names`` given to ``fit``, else ``"f<index>"``).
    partial_f : float
        The function's partial F-ratio that triggered the step (of entry for
        an addition, eq. 19; in the model for a removal, eq. 20).
    threshold : float
        The threshold it was compared with.
    n_terms : int
        Number of functions in the model after the step (constant excluded).
    """

    iteration: int
    phase: int
    action: str
    feature: int
    name: str
    partial_f: float
    threshold: float
    n_terms: int


def _plural(count: int, word: str) -> str:
    return f"{count} {word}" + ("" if count == 1 else "s")


def _safe_div(num, den):
    """``num / den`` with ``x / 0 = inf`` for x > 0 and ``0 / 0 = 0``, silently."""
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.asarray(num, dtype=float) / den
    return np.where(den > 0, out, np.where(np.asarray(num) > 0, np.inf, 0.0))


def _blocks(n_rows: int, n_cols: int):
    """Column slices whose ``n_rows x width`` temporaries stay small."""
    width = max(1, _BLOCK_ELEMENTS // max(n_rows, 1))
    for start in range(0, n_cols, width):
        yield slice(start, min(start + width, n_cols))


@dataclass
class _Screen:
    """Which library columns may be selected, and their weighted statistics."""

    carrier: int | None  # exactly constant column that carries the intercept
    carrier_value: float
    excluded: dict  # column -> reason
    eligible: np.ndarray  # bool (p,): may be selected
    mean: np.ndarray  # (p,) weighted column means
    cn2: np.ndarray  # (p,) squared norms of the centred weighted columns
    un2: np.ndarray  # (p,) squared norms of the weighted columns
    scale: np.ndarray  # (p,) power of two each column is multiplied by


def _xt(x, v, eligible):
    """``x.T @ v`` with the columns that are not eligible (maybe non-finite) zeroed."""
    with np.errstate(all="ignore"):  # inf * 0 in set-aside columns
        out = x.T @ v
    return np.where(eligible, out, 0.0)


def _screen_columns(x, sw, n_eff, tolerance) -> _Screen:
    """Set aside columns that can never be selected; find the intercept carrier.

    Set aside: non-finite values, all-zero columns, constant columns other than
    the first (which carries the intercept), columns collinear with the
    constant, and columns collinear with an earlier column (exact duplicates
    included; the first one is kept), and columns too large or too small for
    double precision. One blockwise pass over ``x``.

    All statistics refer to the columns multiplied by ``scale`` (a power of
    two per column bringing its largest magnitude into ``[0.5, 1)``).
    """
    n, p = x.shape
    w = sw**2
    finite = np.ones(p, dtype=bool)
    exact_const = np.zeros(p, dtype=bool)
    mean = np.zeros(p)
    cn2 = np.zeros(p)
    fprint = np.zeros(p)
    max_abs = np.zeros(p)
    scale = np.ones(p)
    # A fixed random direction: collinear columns have equal |fingerprint|.
    g = np.random.default_rng(20240601).standard_normal(n)
    for blk in _blocks(n, p):
        B = x[:, blk]
        fin = np.all(np.isfinite(B), axis=0)
        finite[blk] = fin
        if not np.all(fin):
            B = np.where(fin, B, 0.0)
        top = np.maximum(B.max(axis=0), -B.min(axis=0))
        sc = _pow2_scale(top)
        max_abs[blk] = top
        scale[blk] = sc
        exact_const[blk] = fin & np.all(B == B[:1], axis=0)
        with np.errstate(over="ignore", invalid="ignore"):  # "huge" columns
            m = (w @ B) / n_eff
            C = B - m  # centred: accurate for near-constants
        C *= sw[:, None]
        C *= sc  # scaled before squaring (exact: powers of two)
        mean[blk] = m * sc
        cn2[blk] = np.einsum("ij,ij->j", C, C)
        fprint[blk] = g @ C
    un2 = np.where(finite, cn2 + n_eff * mean**2, 0.0)
    allzero = finite & (un2 == 0)
    excluded = {}
    carrier = None
    carrier_value = 0.0
    for j in np.flatnonzero(~finite):
        excluded[int(j)] = "non-finite values"
    for j in np.flatnonzero(allzero):
        excluded[int(j)] = "all zero"
    huge = finite & (max_abs * max(n, 1) > _HUGE)
    tiny = finite & ~allzero & (max_abs < _TINY)
    for j in np.flatnonzero(huge):
        excluded[int(j)] = (
            f"values too large for double precision (max |value| "
            f"{max_abs[j]:.3g}); rescale the data"
        )
    for j in np.flatnonzero(tiny):
        excluded[int(j)] = (
            f"values too small for double precision (max |value| "
            f"{max_abs[j]:.3g}); rescale the data"
        )
    for j in np.flatnonzero(exact_const & ~allzero):
        if carrier is None:
            carrier = int(j)
            carrier_value = float(x[0, j])
        else:
            excluded[int(j)] = f"constant (the intercept is carried by f{carrier})"
    near_const = finite & ~allzero & ~exact_const & (cn2 <= tolerance**2 * un2)
    for j in np.flatnonzero(near_const):
        excluded[int(j)] = "collinear with the constant"
    ok = finite & ~allzero & ~exact_const & ~near_const & ~huge & ~tiny
    fprint = np.abs(_safe_div(fprint, np.sqrt(cn2)))

    # Pairwise collinearity: candidate pairs have close fingerprints (within
    # ||g|| * 4 * tolerance, plus rounding); each candidate pair is then
    # verified on the centred columns.
    idx = np.flatnonzero(ok)
    order = idx[np.argsort(fprint[idx], kind="stable")]
    a = fprint[order]
    window = np.linalg.norm(g) * 4.0 * tolerance + 1e-9 * (1.0 + a)
    hi = np.searchsorted(a, a + window, side="right")
    for s in np.flatnonzero(hi > np.arange(a.size) + 1):
        if int(order[s]) in excluded:
            continue  # its partners are found from the column it repeats
        for t in range(s + 1, hi[s]):
            i, j = sorted((int(order[s]), int(order[t])))
            if j in excluded:
                continue
            ui = (x[:, i] * scale[i] - mean[i]) * sw / np.sqrt(cn2[i])
            uj = (x[:, j] * scale[j] - mean[j]) * sw / np.sqrt(cn2[j])
            resid = uj - (ui @ uj) * ui
            if np.linalg.norm(resid) < tolerance:
                if np.array_equal(x[:, i], x[:, j]):
                    excluded[j] = f"duplicate of f{i}"
                else:
                    excluded[j] = f"collinear with f{i}"
    eligible = ok.copy()
    eligible[list(excluded)] = False
    return _Screen(
        carrier=carrier,
        carrier_value=carrier_value,
        excluded=dict(sorted(excluded.items())),
        eligible=eligible,
        mean=mean,
        cn2=np.where(eligible, cn2, 0.0),
        un2=np.where(eligible, un2, 0.0),
        scale=scale,
    )


class _Path:
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
    :func:`_screen_columns`), applied on the fly; ``yw`` is the weighted
    target already scaled to unit magnitude, and ``y_unit`` the factor that
    converts its coefficients back to the units of the data.
    """

    def __init__(self, x, sw, yw, screen: _Screen, n_eff, tolerance, y_unit=1.0):
        self.x = x
        self.scale = screen.scale
        self.y_unit = y_unit
        self.sw = sw
        self.yw = yw
        self.carrier = screen.carrier
        self.carrier_value = screen.carrier_value
        self.eligible = screen.eligible
        self.cn2 = screen.cn2
        self.un2 = screen.un2
        self.n_eff = n_eff
        self.tol2 = tolerance**2
        n, p = x.shape
        self.support = []  # library columns, in the order of Q's columns 1..k
        self.in_model = np.zeros(p, dtype=bool)
        cap = 8
        self.Q = np.zeros((n, cap), order="F")
        self.C = np.zeros((cap, p))
        norm_sw = float(np.linalg.norm(sw))
        self.Q[:, 0] = sw / norm_sw
        self.C[0] = np.where(self.eligible, screen.mean * norm_sw, 0.0)
        self.T = np.array([[norm_sw]])
        self.z = np.array([self.Q[:, 0] @ yw])
        self.e = yw - self.Q[:, 0] * self.z[0]
        self.e -= self.Q[:, 0] * (self.Q[:, 0] @ self.e)
        self.floor2 = (_EXACT_FIT_RTOL * float(np.linalg.norm(yw))) ** 2
        self.sst = self.sse()  # centred total sum of squares
        self.nr2 = self.cn2.copy()
        self._exact_g()

    @property
    def k(self) -> int:
        return len(self.support)

    def sse(self) -> float:
        return float(self.e @ self.e)

    def exact_fit(self) -> bool:
        return self.sse() <= self.floor2

    def _exact_g(self):
        """``g = X^T e`` by a product with the library (resets rounding drift)."""
        self.g = _xt(self.x, self.sw * self.e, self.eligible) * self.scale
        self.g[self.in_model] = 0.0
        self.g_sse = self.sse()

    def coefficients(self) -> np.ndarray:
        """Least-squares coefficients of ``[constant, support...]`` (data units)."""
        beta = scipy.linalg.solve_triangular(self.T, self.z) * self.y_unit
        beta[1:] *= self.scale[self.support]
        return beta

    def overall_f(self) -> float:
        """Model F-ratio MSR / MSE (eq. 10); 0 for the constant-only model."""
        k = self.k
        if k == 0:
            return 0.0
        sse = self.sse()
        return float(_safe_div((self.sst - sse) / k, sse / (self.n_eff - k - 1)))

    def in_model_f(self) -> np.ndarray:
        """Partial F-ratios (eq. 20) of ``[constant, support...]``: ``t**2``."""
        k = self.k
        Tinv, info = dtrtri(self.T, lower=0)
        if info != 0:  # pragma: no cover - T is nonsingular by construction
            Tinv = np.linalg.pinv(self.T)
        beta = Tinv @ self.z
        diag = np.einsum("ij,ij->i", Tinv, Tinv)
        s2 = self.sse() / (self.n_eff - k - 1)
        return _safe_div(beta**2, s2 * diag)

    def candidate_f(self) -> np.ndarray:
        """Partial F-ratios of entry (eq. 19); ``-inf`` where not eligible."""
        sse = self.sse()
        dof_new = self.n_eff - self.k - 2
        elig = self.eligible & ~self.in_model & (self.nr2 > self.tol2 * self.cn2)
        if dof_new < 1:
            elig[:] = False
        with np.errstate(divide="ignore", invalid="ignore"):
            red = np.where(elig, self.g**2 / np.where(elig, self.nr2, 1.0), 0.0)
        red = np.minimum(red, sse)
        f = _safe_div(red * dof_new, np.maximum(sse - red, 0.0))
        return np.where(elig, f, -np.inf)

    def _grow(self):
        cap = self.Q.shape[1]
        if self.k + 1 < cap:
            return
        Q = np.zeros((self.Q.shape[0], 2 * cap), order="F")
        Q[:, :cap] = self.Q
        C = np.zeros((2 * cap, self.C.shape[1]))
        C[:cap] = self.C
        self.Q, self.C = Q, C

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
        cq = _xt(self.x, self.sw * q, self.eligible) * self.scale
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
            err = _EPS * (old + 2 * np.sqrt(old * self.un2)) / self.nr2
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


class FloatingFStepwise(BaseOptimizer):
    """Stepwise regression on partial F-ratios with a floating threshold.

    The modified stepwise regression (MSR) of Kolodziej & Mook as a pysindy
    optimizer: ``ps.SINDy(optimizer=FloatingFStepwise())``. Each target
    (equation) gets its own support. Phase I is Draper & Smith's stepwise
    regression with fixed thresholds; Phase II (``floating=True``) raises the
    threshold to the largest partial F-ratio in the model divided by
    ``float_ratio`` and removes the functions below it, one at a time.

    Parameters
    ----------
    f_enter : float, default 10.0
        Partial F-ratio a candidate needs to enter (the paper's ``F*``).
    f_remove : float, optional
        A function in the model whose partial F-ratio falls below this leaves.
        Defaults to ``f_enter``; must not exceed it (the selection could cycle).
    alpha_enter, alpha_remove : float in (0, 1), optional
        Significance levels. When ``alpha_enter`` is given they replace
        ``f_enter``/``f_remove``: the thresholds become
        ``scipy.stats.f.ppf(1 - alpha, 1, dof_E)`` at the current residual
        degrees of freedom (as MATLAB's ``stepwisefit``): ``dof_E`` of the
        enlarged model for entry, of the current model for removal.
        ``alpha_remove`` defaults to ``max(alpha_enter, 0.10)`` (MATLAB's
        default) and must be ``>= alpha_enter``.
    floating : bool, default True
        Run Phase II.
    float_ratio : float, default 10.0
        Phase II threshold = largest partial F-ratio in the model divided by
        this (the paper: one order of magnitude). Must be ``>= 1``.
    max_iter : int, default 1000
        Maximum number of additions plus removals per target. Reaching it
        raises a ``ConvergenceWarning`` and sets ``converged_`` to False.
    drop_insignificant_constant : bool, default True
        The constant is always in the regression while functions are selected
        and is never a candidate. At the end, if its partial F-ratio (its
        ``t**2``) is below the removal threshold, the selected functions are
        refit through the origin and the intercept reported as 0, so that
        dynamics without a constant term print without a ``1`` term and
        supports can be compared exactly. ``anova_`` still describes the fit
        with intercept (the paper's Table II has an Intercept row).
    tolerance : float, default 1e-8
        Collinearity tolerance: a candidate whose residual after projecting
        out the model is below ``tolerance`` times its centred norm cannot
        enter. Also used to set aside columns collinear with the constant or
        with an earlier column before selection starts.
    max_report : int, default 10
        Number of strongest functions not in the model listed in ``anova_``
        and :meth:`summary`.
    normalize_columns, copy_X, initial_guess, unbias
        Accepted for compatibility with pysindy's ``BaseOptimizer`` and
        ignored: selection by partial F-ratios is invariant to column scale,
        the input is never modified, selection always starts from the
        constant-only model (a non-None ``initial_guess`` raises a warning),
        and coefficients are already ordinary least squares on the support.

    Attributes
    ----------
    coef_ : ndarray (n_targets, n_features)
        Least-squares coefficients on the selected functions (zero elsewhere).
        If the library has a constant column (e.g. pysindy's ``"1"``), the
        intercept is carried by it; otherwise by ``intercept_``.
    intercept_ : ndarray (n_targets,)
        The fitted constant when the library has no constant column (0 when it
        has one, or when the constant was dropped).
    ind_ : ndarray of bool (n_targets, n_features)
        The support of each target.
    Theta_ : ndarray (n_samples, n_features)
        The library matrix that was fitted (a float view of ``x``, not a copy).
    history_ : list of ndarray
        ``coef_`` after each step (pysindy's meaning), starting from zeros.
    anova_ : list of :class:`~pysindy_mme.anova.AnovaTable`
        Final ANOVA table of each target (with intercept).
    steps_ : list of list of :class:`Step`
        The additions and removals of each target, in order.
    n_iter_ : ndarray of int (n_targets,)
        Steps taken per target.
    converged_ : bool
        False if some target hit ``max_iter``.
    cycle_detected_ : bool
        True if some target returned to a model already visited in the same
        phase (a cycle); a :class:`StepwiseCycleWarning` was raised and the
        selection stopped at the model of the cycle with the largest overall
        F-ratio.
    intercept_dropped_ : ndarray of bool (n_targets,)
        Whether the constant was dropped (``drop_insignificant_constant``).
    excluded_ : dict
        ``{column index: reason}`` for columns that can never be selected:
        non-finite values, all zero, constant (a second constant column),
        collinear with the constant, duplicate of / collinear with an earlier
        column, values too large (``|x| * n_samples > 2**1000``) or too small
        (``max |x| < 2**-960``) for double precision. They are listed in one
        :class:`ExcludedFeaturesWarning` per fit.
    constant_feature_ : int or None
        The library column that carries the intercept, if any.
    feature_names_, target_names_ : list of str or None
        Names given to :meth:`fit` (pysindy does not pass them: see
        :meth:`summary`).
    n_features_in_ : int

    Notes
    -----
    ``sample_weight`` are frequency weights: the number of observations in the
    degrees of freedom is ``sum(sample_weight)``, so a fit with integer weights
    equals a fit on rows repeated by their weights. Rows of weight 0 are
    ignored.

    The target must be finite: unlike pysindy's own optimizers, rows with NaN
    targets (e.g. the end points of ``FiniteDifference(drop_endpoints=True)``)
    are an error rather than silently dropped.

    Phase II compares partial F-ratios with the strongest one, so a true term
    whose contribution is small next to the others (Lorenz's ``-x2`` in
    ``x2'``, a light damping) is removed with the default ``float_ratio=10``;
    raise ``float_ratio`` or set ``floating=False`` for such multi-scale
    dynamics (see ``tests/test_stepwise_vs_stlsq.py``).

    A target reproduced to rounding level (relative residual ``< 1e-12``,
    noise-free data) takes no further functions, Phase II does not rank the
    (then meaningless) partial F-ratios, and the constant is dropped only if
    the fit stays exact without it.

    Inside ``ps.SINDy`` the optimizer does not see the feature names; print
    the ANOVA tables with
    ``model.optimizer.summary(model.get_feature_names(), model.feature_names)``.

    Examples
    --------
    >>> import pysindy as ps
    >>> model = ps.SINDy(optimizer=FloatingFStepwise(),
    ...                  feature_library=ps.PolynomialLibrary(degree=3))
    >>> model.fit(x, t=t)  # doctest: +SKIP
    >>> print(model.optimizer.summary(model.get_feature_names(),
    ...                               model.feature_names))  # doctest: +SKIP
    """

    # LinearRegression's tags read ``positive``; coefficients are unconstrained.
    positive = False

    def __init__(
        self,
        f_enter=10.0,
        f_remove=None,
        alpha_enter=None,
        alpha_remove=None,
        floating=True,
        float_ratio=10.0,
        max_iter=1000,
        drop_insignificant_constant=True,
        tolerance=1e-8,
        max_report=10,
        normalize_columns=False,
        copy_X=True,
        initial_guess=None,
        unbias=False,
    ):
        # Parameters are only stored here (scikit-learn convention); fit
        # validates them. BaseOptimizer.__init__ is not called because it
        # validates and reshapes.
        self.f_enter = f_enter
        self.f_remove = f_remove
        self.alpha_enter = alpha_enter
        self.alpha_remove = alpha_remove
        self.floating = floating
        self.float_ratio = float_ratio
        self.max_iter = max_iter
        self.drop_insignificant_constant = drop_insignificant_constant
        self.tolerance = tolerance
        self.max_report = max_report
        self.normalize_columns = normalize_columns
        self.copy_X = copy_X
        self.initial_guess = initial_guess
        self.unbias = unbias

    def set_params(self, **params):
        """Set parameters (scikit-learn API); returns ``self``."""
        super(BaseOptimizer, self).set_params(**params)
        return self

    # ------------------------------------------------------------------ checks
    def _validate_params(self) -> dict:
        f_enter = check_positive_number(self.f_enter, "f_enter")
        if self.f_remove is None:
            f_remove = f_enter
        else:
            f_remove = check_positive_number(self.f_remove, "f_remove")
            if f_remove > f_enter:
                raise ValueError(
                    f"f_remove ({f_remove}) must not exceed f_enter ({f_enter}): "
                    "a function could enter and leave forever"
                )
        alpha_enter = alpha_remove = None
        if self.alpha_enter is not None:
            alpha_enter = check_probability(self.alpha_enter, "alpha_enter")
            if self.alpha_remove is None:
                alpha_remove = max(alpha_enter, 0.10)
            else:
                alpha_remove = check_probability(self.alpha_remove, "alpha_remove")
                if alpha_remove < alpha_enter:
                    raise ValueError(
                        f"alpha_remove ({alpha_remove}) must be >= alpha_enter "
                        f"({alpha_enter}): a function could enter and leave forever"
                    )
        elif self.alpha_remove is not None:
            raise ValueError(
                "alpha_remove requires alpha_enter (significance levels replace "
                "f_enter/f_remove only when alpha_enter is given)"
            )
        for name in ("floating", "drop_insignificant_constant"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise TypeError(
                    f"{name} must be True or False, got {getattr(self, name)!r}"
                )
        float_ratio = check_positive_number(
            self.float_ratio, "float_ratio", minimum=1.0, strict=False
        )
        for name, minimum in (("max_iter", 1), ("max_report", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Integral):
                raise TypeError(f"{name} must be an integer, got {value!r}")
            if value < minimum:
                raise ValueError(f"{name} must be >= {minimum}, got {value}")
        tolerance = check_positive_number(self.tolerance, "tolerance")
        if tolerance >= 1:
            raise ValueError(f"tolerance must be < 1, got {tolerance}")
        return dict(
            f_enter=f_enter,
            f_remove=f_remove,
            alpha_enter=alpha_enter,
            alpha_remove=alpha_remove,
            float_ratio=float_ratio,
            tolerance=tolerance,
        )

    @staticmethod
    def _validate_data(x, y, sample_weight):
        try:
            x = np.asarray(x, dtype=float)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"x must be a numeric array: {exc}") from None
        if x.ndim != 2:
            raise ValueError(
                f"x must be 2-D (n_samples, n_features), got shape {x.shape}"
            )
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

    def _thresholds(self, k: int, n_eff: float, p: dict):
        """(entry, removal) thresholds for a model with ``k`` functions."""
        if p["alpha_enter"] is None:
            return p["f_enter"], p["f_remove"]
        return (
            float(f_critical(p["alpha_enter"], n_eff - k - 2)),
            float(f_critical(p["alpha_remove"], n_eff - k - 1)),
        )

    # --------------------------------------------------------------------- fit
    def _reduce(self, x, y, **kwargs):
        """Not used: :meth:`fit` does the whole work (it needs the raw weights)."""
        raise NotImplementedError("FloatingFStepwise.fit does not call _reduce")

    def fit(self, x_, y, sample_weight=None, feature_names=None, target_names=None):
        """Select the functions of each target and fit them by least squares.

        Parameters
        ----------
        x_ : array-like (n_samples, n_features)
            The library (pysindy's Theta). Columns with non-finite values are
            set aside, not an error.
        y : array-like (n_samples,) or (n_samples, n_targets)
            Targets (time derivatives); must be finite.
        sample_weight : float or array-like (n_samples,), optional
            Non-negative frequency weights.
        feature_names : sequence of str, optional
            Names of the library columns (used by ``steps_`` and :meth:`summary`).
        target_names : sequence of str, optional
            Names of the targets.

        Returns
        -------
        self
        """
        params = self._validate_params()
        x, y, w = self._validate_data(x_, y, sample_weight)
        n_features = x.shape[1]
        if feature_names is not None and len(feature_names) != n_features:
            raise ValueError(
                f"feature_names has {len(feature_names)} names but x has "
                f"{n_features} columns"
            )
        if target_names is not None and len(target_names) != y.shape[1]:
            raise ValueError(
                f"target_names has {len(target_names)} names but y has "
                f"{y.shape[1]} columns"
            )
        if self.initial_guess is not None:
            warnings.warn(
                "FloatingFStepwise ignores initial_guess: selection always "
                "starts from the constant-only model",
                UserWarning,
                stacklevel=2,
            )
        self.feature_names_ = None if feature_names is None else list(feature_names)
        self.target_names_ = None if target_names is None else list(target_names)
        self.n_features_in_ = n_features
        self.Theta_ = x

        keep = w > 0
        if not np.all(keep):
            x, y, w = x[keep], y[keep], w[keep]
        sw = np.sqrt(w)
        n_eff = float(w.sum())
        tol = params["tolerance"]

        screen = _screen_columns(x, sw, n_eff, tol)
        self.excluded_ = screen.excluded
        self.constant_feature_ = screen.carrier
        if screen.excluded:
            listed = "; ".join(
                f"{self._name(j)}: {why}" for j, why in screen.excluded.items()
            )
            warnings.warn(
                f"{len(screen.excluded)} library column(s) can never be selected "
                f"({listed})",
                ExcludedFeaturesWarning,
                stacklevel=2,
            )

        n_targets = y.shape[1]
        coef = np.zeros((n_targets, n_features))
        intercept = np.zeros(n_targets)
        self.history_ = [coef.copy()]
        self.anova_ = []
        self.steps_ = []
        self.n_iter_ = np.zeros(n_targets, dtype=int)
        self.intercept_dropped_ = np.zeros(n_targets, dtype=bool)
        self.converged_ = True
        self.cycle_detected_ = False
        for t in range(n_targets):
            # The target in units of its largest magnitude (an exact power of
            # two): squares can then neither overflow nor underflow.
            y_scale = float(_pow2_scale(np.max(np.abs(y[:, t]), initial=0.0)))
            yt = y[:, t] * y_scale
            path = _Path(x, sw, yt * sw, screen, n_eff, tol, y_unit=1.0 / y_scale)
            steps = self._select(path, t, coef, params, n_eff)
            self.steps_.append(steps)
            self.n_iter_[t] = len(steps)
            row, icpt, table, dropped = self._final_fit(
                path, x, yt, w, screen, params, n_eff
            )
            coef[t] = row
            intercept[t] = icpt
            self.anova_.append(table)
            self.intercept_dropped_[t] = dropped
            self.history_.append(coef.copy())
            del path
        self.coef_ = coef
        self.intercept_ = intercept
        self.ind_ = coef != 0
        return self

    def _name(self, j: int) -> str:
        names = getattr(self, "feature_names_", None)
        return str(names[j]) if names is not None else f"f{j}"

    def _select(self, path: _Path, target: int, coef, params, n_eff) -> list:
        """Phases I and II for one target; returns the steps taken."""
        steps = []
        phase = 1
        start = (1, frozenset())
        visited = {start}
        trail = [start]  # states in the order visited
        trail_f = [0.0]  # their overall F-ratios
        goal = None  # after a cycle: the state of the cycle to stop at
        replay_left = 0
        while True:
            k = path.k
            enter_thr, remove_thr = self._thresholds(k, n_eff, params)
            f_in = path.in_model_f()[1:] if k else np.zeros(0)
            # At an exact fit (noise-free target) every partial F-ratio is
            # infinite in principle; rounding-level values cannot be ranked,
            # so the floating threshold does not apply.
            if phase == 2 and k and not path.exact_fit():
                floating = float(np.max(f_in)) / params["float_ratio"]
                enter_thr = max(enter_thr, floating)
                remove_thr = max(remove_thr, floating)
            action = None
            if k and float(np.min(f_in)) < remove_thr:
                i = int(np.argmin(f_in))
                action = ("remove", path.support[i], float(f_in[i]), remove_thr)
            elif not path.exact_fit():
                f_cand = path.candidate_f()
                if f_cand.size:
                    best = int(np.argmax(f_cand))
                    # -inf marks "not eligible"; +inf (exact improvement) may enter.
                    if f_cand[best] > -np.inf and f_cand[best] >= enter_thr:
                        action = ("add", best, float(f_cand[best]), enter_thr)
            if action is None:
                if phase == 1 and self.floating:
                    phase = 2
                    key = (2, frozenset(path.support))
                    visited.add(key)
                    trail.append(key)
                    trail_f.append(path.overall_f())
                    continue
                break
            if len(steps) >= self.max_iter:
                self.converged_ = False
                warnings.warn(
                    f"FloatingFStepwise reached max_iter={self.max_iter} on target "
                    f"{target} before the selection settled; the last model is kept",
                    ConvergenceWarning,
                    stacklevel=3,
                )
                break
            kind, pos, fval, thr = action
            if kind == "add":
                path.add(pos)
                # Same value as the F of entry, but free of the cancellation in
                # SSE_old - reduction when the new term explains nearly all.
                fval = float(path.in_model_f()[-1])
            else:
                path.remove(pos)
            feature = int(pos)
            steps.append(
                Step(
                    iteration=len(steps) + 1,
                    phase=phase,
                    action=kind,
                    feature=feature,
                    name=self._name(feature),
                    partial_f=fval,
                    threshold=float(thr),
                    n_terms=path.k,
                )
            )
            self._record_history(path, target, coef)
            key = (phase, frozenset(path.support))
            if goal is not None:
                # Replaying the cycle (decisions depend only on the state).
                replay_left -= 1
                if key == goal or replay_left <= 0:
                    break
                continue
            if key in visited:
                # A cycle: the rules alone would go round forever. Of the
                # models in the cycle keep the one with the largest overall
                # F-ratio (the paper reads a rising model F-ratio as a better
                # representation), reached by replaying the cycle.
                self.cycle_detected_ = True
                first = trail.index(key)
                cycle, cycle_f = trail[first:], trail_f[first:]
                goal = cycle[int(np.argmax(cycle_f))]
                warnings.warn(
                    f"FloatingFStepwise returned to a model it had already visited "
                    f"(target {target}, phase {phase}, iteration {len(steps)}): a "
                    f"cycle of {len(cycle)} models; stopping at the one with the "
                    "largest overall F-ratio",
                    StepwiseCycleWarning,
                    stacklevel=3,
                )
                if goal == key:
                    break
                replay_left = len(cycle)
                continue
            visited.add(key)
            trail.append(key)
            trail_f.append(path.overall_f())
        return steps

    def _record_history(self, path: _Path, target: int, coef) -> None:
        beta = path.coefficients()
        row = np.zeros(coef.shape[1])
        row[path.support] = beta[1:]
        if path.carrier is not None:
            row[path.carrier] = beta[0] / path.carrier_value
        current = coef.copy()
        current[target] = row
        self.history_.append(current)

    def _final_fit(self, path: _Path, x, y, w, screen: _Screen, params, n_eff):
        """Coefficients on the support (accurate QR solve) and the ANOVA table.

        ``y`` is the target scaled like the path's (``path.y_unit`` converts
        back). The fit runs on the support and reported columns only, each
        multiplied by its power-of-two ``screen.scale``; the table and the
        coefficients are then converted to the units of the data (exactly).
        """
        support = np.sort(np.asarray(path.support, dtype=int))
        top = []
        if self.max_report > 0:
            f_cand = path.candidate_f()
            order = np.argsort(-f_cand, kind="stable")
            order = order[np.isfinite(f_cand[order])][: self.max_report]
            top = [int(i) for i in order]
        k = support.size
        cols = np.concatenate([support, np.asarray(top, dtype=int)])
        xs = x[:, cols] * screen.scale[cols]
        table = fit_anova(
            xs,
            y,
            np.arange(k),
            intercept=True,
            sample_weight=w,
            candidates=np.arange(k, cols.size),
            tolerance=params["tolerance"],
        )
        col_unit = screen.scale[support]
        y_unit = np.float64(path.y_unit)

        def squared_units(value):
            # Sums of squares of data near 1e+-154 may not be representable
            # (inf or 0); the selection itself ran on the scaled target.
            with np.errstate(over="ignore", under="ignore"):
                return float(value * y_unit * y_unit)

        table = replace(
            table,
            features=tuple(int(j) for j in support),
            out_features=tuple(top),
            coefficients=table.coefficients * col_unit * y_unit,
            std_errors=table.std_errors * col_unit * y_unit,
            intercept=float(table.intercept * y_unit),
            intercept_std_error=float(table.intercept_std_error * y_unit),
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
        if path.exact_fit():
            # Noise-free target: the constant's t**2 is a ratio of rounding
            # errors. It is needed only if the fit without it is not exact.
            resid = y * sw - xw @ origin
            insignificant = float(resid @ resid) <= path.floor2
        else:
            _, remove_thr = self._thresholds(len(support), n_eff, params)
            insignificant = not table.intercept_partial_f >= remove_thr
        dropped = bool(self.drop_insignificant_constant and insignificant)
        if dropped:
            icpt = 0.0
            row[support] = origin * col_unit * y_unit
        else:
            icpt = table.intercept
            row[support] = table.coefficients
            if screen.carrier is not None:
                row[screen.carrier] = icpt / screen.carrier_value
                icpt = 0.0
        return row, icpt, table, dropped

    # ----------------------------------------------------------------- predict
    def predict(self, x):
        """``x @ coef_.T + intercept_``, reading only the columns in use.

        Columns with zero coefficients are not read, so non-finite values in
        set-aside library columns do not spoil predictions.
        """
        check_is_fitted(self, "coef_")
        x = np.asarray(x, dtype=float)
        if x.ndim != 2 or x.shape[1] != self.coef_.shape[1]:
            raise ValueError(
                f"x must have shape (n_samples, {self.coef_.shape[1]}), got {x.shape}"
            )
        used = np.flatnonzero(np.any(self.coef_ != 0, axis=0))
        return x[:, used] @ self.coef_[:, used].T + self.intercept_

    # ----------------------------------------------------------------- summary
    def summary(self, feature_names=None, target_names=None, target=None) -> str:
        """ANOVA tables (the paper's Table II) and step histories as text.

        Parameters
        ----------
        feature_names : sequence of str, optional
            Library column names, e.g. ``model.get_feature_names()``. Defaults
            to the names given to :meth:`fit`, else ``f0, f1, ...``.
        target_names : sequence of str, optional
            Target names, e.g. ``model.feature_names`` (shown as ``x0'``...).
            Defaults to the names given to :meth:`fit`, else ``target 0``...
        target : int, optional
            Only this target.

        Returns
        -------
        str
        """
        check_is_fitted(self, "coef_")
        n_targets = self.coef_.shape[0]
        if feature_names is None:
            feature_names = self.feature_names_
        if feature_names is not None and len(feature_names) != self.coef_.shape[1]:
            raise ValueError(
                f"feature_names has {len(feature_names)} names but the library has "
                f"{self.coef_.shape[1]} columns"
            )
        if target_names is None:
            target_names = self.target_names_
        if target_names is not None:
            if len(target_names) != n_targets:
                raise ValueError(
                    f"target_names has {len(target_names)} names but there are "
                    f"{n_targets} targets"
                )
            labels = [f"({name})'" for name in target_names]
        else:
            labels = [f"target {t}" for t in range(n_targets)]
        if target is None:
            targets = range(n_targets)
        else:
            if not isinstance(target, numbers.Integral) or not 0 <= target < n_targets:
                raise ValueError(f"target must be an index in [0, {n_targets - 1}]")
            targets = [int(target)]

        def name(j):
            return str(feature_names[j]) if feature_names is not None else f"f{j}"

        if self.alpha_enter is None:
            f_remove = self.f_enter if self.f_remove is None else self.f_remove
            rule = f"F_enter = {self.f_enter:g}, F_remove = {f_remove:g}"
        else:
            a_rem = (
                max(self.alpha_enter, 0.10)
                if self.alpha_remove is None
                else self.alpha_remove
            )
            rule = f"alpha_enter = {self.alpha_enter:g}, alpha_remove = {a_rem:g}"
        if self.floating:
            rule += f", Phase II floating ratio = {self.float_ratio:g}"
        else:
            rule += ", Phase II off"
        out = [f"FloatingFStepwise: {rule}"]
        if self.excluded_:
            out.append("Library columns set aside (never selected):")
            out += [f"  {name(j)}: {why}" for j, why in self.excluded_.items()]
        for t in targets:
            table: AnovaTable = self.anova_[t]
            out.append("")
            out.append(
                table.to_text(
                    feature_names,
                    title=f"=== {labels[t]}: final model ANOVA table "
                    f"({_plural(len(self.steps_[t]), 'step')}, n = {table.n:g}) ===",
                )
            )
            if self.intercept_dropped_[t]:
                out.append(
                    "  Note: the intercept's partial F "
                    f"({table.intercept_partial_f:.4g}) is below the removal "
                    "threshold; coef_ is refit through the origin."
                )
            out.append("")
            out.append("  Step history")
            if self.steps_[t]:
                out.append(
                    f"  {'iter':>4} {'phase':>5} {'action':<7}{'function':<20}"
                    f"{'partial F':>12}{'threshold':>12}{'terms':>7}"
                )
                for s in self.steps_[t]:
                    out.append(
                        f"  {s.iteration:>4} {s.phase:>5} {s.action:<7}"
                        f"{name(s.feature):<20}{s.partial_f:>12.5g}"
                        f"{s.threshold:>12.5g}{s.n_terms:>7}"
                    )
            else:
                out.append("  (no function entered)")
        if not self.converged_:
            out.append("\nWARNING: max_iter was reached; the selection did not settle.")
        if self.cycle_detected_:
            out.append("\nWARNING: a cycle was detected; the selection stopped there.")
        return "\n".join(out)
