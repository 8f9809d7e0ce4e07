"""Analysis of variance for a linear regression on a chosen set of functions.

This module holds the statistics only (no selection logic): the ANOVA table of
the paper's Table II (Kolodziej & Mook, eqs. 10-20), partial F-ratios of the
functions in and out of a model, F critical values, and an accurate
least-squares solver. :class:`~pysindy_mme.optimizers.FloatingFStepwise`
selects the functions; :func:`fit_anova` then describes the chosen model from
scratch, by a direct QR least-squares fit, so it also serves as an
independent check of the incremental computations done during selection.

Sample weights are *frequency* weights: a weight of 3 counts a sample three
times, so the number of observations is ``sum(sample_weight)`` and a weighted
fit equals an unweighted fit on rows repeated by their (integer) weights.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from scipy import stats

from ._numeric import safe_ratio
from .tables import anova_html, anova_text

__all__ = [
    "AnovaTable",
    "fit_anova",
    "f_critical",
    "f_pvalue",
    "lstsq_refined",
]


def f_critical(alpha, dof_residual):
    """Partial F-ratio a single function needs to be significant at ``alpha``.

    The ``1 - alpha`` quantile of the F distribution with ``(1, dof_residual)``
    degrees of freedom (what MATLAB's ``stepwisefit`` compares against).
    ``inf`` when there are no residual degrees of freedom.
    """
    dof = np.asarray(dof_residual, dtype=float)
    with np.errstate(invalid="ignore"):
        crit = stats.f.ppf(1.0 - alpha, 1.0, np.where(dof >= 1, dof, 1.0))
    return np.where(dof >= 1, crit, np.inf)[()]


def f_pvalue(f_ratio, dof_numerator, dof_residual):
    """Upper tail probability of an F-ratio (``nan`` where undefined)."""
    f_ratio = np.asarray(f_ratio, dtype=float)
    if dof_residual < 1 or dof_numerator < 1:
        return np.full(f_ratio.shape, np.nan)[()]
    with np.errstate(invalid="ignore"):
        return stats.f.sf(f_ratio, dof_numerator, dof_residual)[()]


def lstsq_refined(A, b, qr=None):
    """Least-squares solution of ``A x = b`` by Householder QR plus one refinement.

    The residual of the first solution is recomputed in extended precision
    (``numpy.longdouble``) and a correction solved with the same QR factor.
    For consistent (small residual) problems this brings the error from
    ``eps * cond(A)`` down to about ``eps``: with ``cond(A) ~ 1e9`` the plain
    solution has ~1e-8 relative error, the refined one ~1e-12.

    Parameters
    ----------
    A : ndarray (n, k), full column rank, k <= n
    b : ndarray (n,) or (n, m)
    qr : tuple (Q, R), optional
        The reduced QR factors of ``A`` if already computed.

    Returns
    -------
    x : ndarray (k,) or (k, m)
    """
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float)
    if A.shape[1] == 0:
        return np.zeros((0,) + b.shape[1:])
    Q, R = np.linalg.qr(A) if qr is None else qr
    x = scipy.linalg.solve_triangular(R, Q.T @ b)
    # Extended precision residual: cheap (O(n k)) since k is small here.
    ld = np.longdouble
    resid = b.astype(ld) - A.astype(ld) @ x.astype(ld)
    return x + scipy.linalg.solve_triangular(R, Q.T @ resid.astype(float))


@dataclass(frozen=True)
class AnovaTable:
    """ANOVA table of a least-squares fit (the paper's Table II).

    The regression is ``y ~ intercept + sum_i coefficients[i] * X[:, features[i]]``
    (without intercept when ``has_intercept`` is False; the total sum of
    squares is then uncentred).

    Attributes
    ----------
    n : float
        Number of observations (sum of frequency weights).
    has_intercept : bool
    dof_regression, dof_residual, dof_total : float
        ``k``, ``n - k - 1`` and ``n - 1`` (``n - k`` and ``n`` without intercept).
    ss_regression, ss_residual, ss_total : float
        Eqs. (12), (13) and their sum.
    ms_regression, ms_residual : float
        Mean squares (eq. 11). ``ms_residual`` is the variance of estimate.
    f_ratio, p_value : float
        Overall F-ratio (eq. 10) and its p-value.
    r2, multiple_r : float
        Coefficient of determination and multiple correlation coefficient.
    intercept, intercept_std_error, intercept_partial_f : float
        The fitted constant, its standard error and partial F (``t**2``); 0, nan,
        nan without intercept.
    features : tuple of int
        Library column of each function in the model.
    coefficients, std_errors, partial_f, p_values : ndarray (k,)
        Per function in the model; ``partial_f`` is eq. (20): the F-ratio of
        removing that function with all the others kept.
    out_features : tuple of int
        Library columns not in the model that were assessed.
    out_partial_f, out_p_values : ndarray
        Their partial F-ratios of entry (eq. 19) and p-values (``nan`` for a
        column that is collinear with the model).
    robust : bool
        Whether the robust statistics below were computed (the default rule
        of :class:`~pysindy_mme.optimizers.FloatingFStepwise`); otherwise
        they are empty or ``nan``.
    hac_lags : int
        Newey-West bandwidth of the robust statistics.
    robust_partial_f, robust_p_values : ndarray (k,)
        Newey-West robust partial F-ratio of each function in the model and
        its p-value (``F(1, dof_residual)``).
    intercept_robust_partial_f : float
        The same for the constant.
    out_robust_partial_f, out_robust_p_values : ndarray
        Robust partial F-ratios of entry of ``out_features`` and p-values.
    n_candidates : int
        Family size of the multiplicity correction: the number of eligible
        candidates outside the model (1: no correction).
    lag1_autocorrelation : float
        Lag-1 autocorrelation of the weighted residual, rows in the order given.
    effective_n : float
        The number of independent observations the residual is worth:
        rows x variance / long-run variance (Newey-West). Far below ``n``
        means strongly autocorrelated residuals: classic F-ratios overstate
        the evidence by about ``n / effective_n``.
    """

    n: float
    has_intercept: bool
    dof_regression: float
    dof_residual: float
    dof_total: float
    ss_regression: float
    ss_residual: float
    ss_total: float
    ms_regression: float
    ms_residual: float
    f_ratio: float
    p_value: float
    r2: float
    multiple_r: float
    intercept: float
    intercept_std_error: float
    intercept_partial_f: float
    features: tuple
    coefficients: np.ndarray
    std_errors: np.ndarray
    partial_f: np.ndarray
    p_values: np.ndarray
    out_features: tuple = ()
    out_partial_f: np.ndarray = field(default_factory=lambda: np.zeros(0))
    out_p_values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    robust: bool = False
    hac_lags: int = 0
    robust_partial_f: np.ndarray = field(default_factory=lambda: np.zeros(0))
    robust_p_values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    intercept_robust_partial_f: float = np.nan
    out_robust_partial_f: np.ndarray = field(default_factory=lambda: np.zeros(0))
    out_robust_p_values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    n_candidates: int = 1
    lag1_autocorrelation: float = np.nan
    effective_n: float = np.nan

    @property
    def variance_of_estimate(self) -> float:
        """Residual mean square (the paper's "variance of estimate")."""
        return self.ms_residual

    @property
    def std_error_of_estimate(self) -> float:
        """Square root of the variance of estimate."""
        return float(np.sqrt(self.ms_residual))

    @property
    def adjusted_p_values(self) -> np.ndarray:
        """Bonferroni-adjusted p-values of the functions in the model.

        ``min(1, n_candidates * p)`` of the robust p-values (of the classic
        ones without robust statistics): a function stays in the model of the
        default rule when this is at most ``alpha``.
        """
        p = self.robust_p_values if self.robust else self.p_values
        return np.minimum(1.0, self.n_candidates * np.asarray(p, dtype=float))

    @property
    def out_adjusted_p_values(self) -> np.ndarray:
        """Bonferroni-adjusted p-values of entry of ``out_features``."""
        p = self.out_robust_p_values if self.robust else self.out_p_values
        return np.minimum(1.0, self.n_candidates * np.asarray(p, dtype=float))

    @property
    def intercept_p_value(self) -> float:
        """p-value of the intercept's partial F (``nan`` without intercept)."""
        return float(f_pvalue(self.intercept_partial_f, 1, self.dof_residual))

    def to_text(self, feature_names=None, title=None) -> str:
        """The table as text, laid out like the paper's Table II.

        Parameters
        ----------
        feature_names : sequence of str, optional
            Name of every library column (indexed by column); ``f0, f1, ...``
            when omitted.
        title : str, optional
            First line of the text.
        """
        return anova_text(self, feature_names, title)

    def to_html(self, feature_names=None, title=None) -> str:
        """The table as HTML (what notebooks show); same content as :meth:`to_text`."""
        return anova_html(self, feature_names, title)

    def _repr_html_(self) -> str:
        return self.to_html()

    def __str__(self) -> str:
        return self.to_text()


def fit_anova(
    X,
    y,
    support,
    intercept: bool = True,
    sample_weight=None,
    candidates=None,
    tolerance: float = 1e-8,
) -> AnovaTable:
    """ANOVA table of the least-squares fit of ``y`` on ``X[:, support]``.

    Computed from scratch: one QR least-squares solve (with a refinement step,
    see :func:`lstsq_refined`) for the coefficients, the inverse of the
    triangular factor for the standard errors, and for each candidate the
    sum of squares it would remove from the residual (eq. 19).

    Parameters
    ----------
    X : array-like (n_samples, n_features)
        The library. Only the columns in ``support`` and ``candidates`` are
        read, so other columns may hold non-finite values.
    y : array-like (n_samples,)
    support : sequence of int
        Columns in the model, in the order they are reported.
    intercept : bool, default True
        Fit a constant (not one of the columns of ``X``).
    sample_weight : array-like (n_samples,), optional
        Frequency weights (``n = sum(sample_weight)``).
    candidates : sequence of int or "all", optional
        Columns not in the model whose partial F-ratio of entry is reported;
        ``"all"`` for every other column. None (default) reports none.
    tolerance : float, default 1e-8
        A candidate whose residual after projecting out the model is smaller
        than ``tolerance`` times its (centred) norm is collinear with the model;
        its partial F-ratio is reported as ``nan``.

    Returns
    -------
    AnovaTable
    """
    X, y, support, candidates, rows, sw, n = _check_inputs(
        X, y, support, candidates, sample_weight
    )

    # Index columns first: X may be a large library of which few are read.
    A = X[:, support][rows] * sw[:, None]
    if intercept:
        A = np.column_stack([sw, A])
    yw = y[rows] * sw
    if not np.all(np.isfinite(A)):
        raise ValueError("X has non-finite values in the support columns")
    k = len(support)
    p = A.shape[1]
    if n - p < 1:
        raise ValueError(
            f"{p} parameters need more than {p} observations, got n = {n:g}"
        )

    Q, R = np.linalg.qr(A)
    beta = lstsq_refined(A, yw, qr=(Q, R))
    resid = yw - A @ beta
    ss_res = float(resid @ resid)
    ss_tot, dof_total = _total_sum_of_squares(yw, sw, n, intercept)
    dof_res = n - p
    ss_reg = max(ss_tot - ss_res, 0.0)
    ms_res = ss_res / dof_res
    ms_reg = ss_reg / k if k else np.nan
    with np.errstate(divide="ignore", invalid="ignore"):
        f_ratio = safe_ratio(ms_reg, ms_res) if k else np.nan
        r2 = ss_reg / ss_tot if ss_tot > 0 else np.nan

    # Covariance of the coefficients: s^2 (A^T A)^-1 = s^2 R^-1 R^-T.
    Rinv = scipy.linalg.solve_triangular(R, np.eye(p))
    diag = np.einsum("ij,ij->i", Rinv, Rinv)
    std_err = np.sqrt(ms_res * diag)
    partial = safe_ratio(beta**2, ms_res * diag)
    pvals = np.atleast_1d(f_pvalue(partial, 1, dof_res))

    out_f = _entry_f(
        X[:, candidates][rows] * sw[:, None] if candidates else None,
        Q,
        resid,
        sw,
        n,
        intercept,
        dof_res,
        tolerance,
    )
    out_p = (
        np.atleast_1d(f_pvalue(out_f, 1, dof_res - 1)) if candidates else np.zeros(0)
    )

    off = 1 if intercept else 0
    return AnovaTable(
        n=n,
        has_intercept=bool(intercept),
        dof_regression=float(k),
        dof_residual=float(dof_res),
        dof_total=float(dof_total),
        ss_regression=float(ss_reg),
        ss_residual=ss_res,
        ss_total=float(ss_tot),
        ms_regression=float(ms_reg),
        ms_residual=float(ms_res),
        f_ratio=float(f_ratio),
        p_value=float(f_pvalue(f_ratio, k, dof_res)) if k else np.nan,
        r2=float(r2),
        multiple_r=float(np.sqrt(r2)) if np.isfinite(r2) else np.nan,
        intercept=float(beta[0]) if intercept else 0.0,
        intercept_std_error=float(std_err[0]) if intercept else np.nan,
        intercept_partial_f=float(partial[0]) if intercept else np.nan,
        features=tuple(support),
        coefficients=beta[off:].copy(),
        std_errors=std_err[off:].copy(),
        partial_f=partial[off:].copy(),
        p_values=pvals[off:].copy(),
        out_features=tuple(candidates),
        out_partial_f=out_f,
        out_p_values=out_p,
    )


def _check_inputs(X, y, support, candidates, sample_weight):
    """Arrays and index lists of :func:`fit_anova`, checked.

    Returns ``X, y, support, candidates``, the rows of positive weight, the
    square roots of their weights and ``n``, the sum of the weights.
    """
    X = np.asarray(X, dtype=float)
    y = np.asarray(y, dtype=float)
    if X.ndim != 2:
        raise ValueError(f"X must be 2-D, got shape {X.shape}")
    if y.ndim != 1 or y.shape[0] != X.shape[0]:
        raise ValueError(
            f"y must be 1-D with {X.shape[0]} entries (one per row of X), "
            f"got shape {y.shape}"
        )
    support = [int(j) for j in np.atleast_1d(np.asarray(support, dtype=int))]
    if any(j < 0 or j >= X.shape[1] for j in support):
        raise ValueError(f"support {support} is out of range for {X.shape[1]} columns")
    if len(set(support)) != len(support):
        raise ValueError(f"support {support} repeats a column")
    if isinstance(candidates, str):
        if candidates != "all":
            raise ValueError(
                f'candidates must be "all", None or indices, got {candidates!r}'
            )
        chosen = set(support)
        candidates = [j for j in range(X.shape[1]) if j not in chosen]
    elif candidates is None:
        candidates = []
    else:
        candidates = [int(j) for j in np.atleast_1d(np.asarray(candidates, dtype=int))]

    if sample_weight is None:
        w = np.ones(X.shape[0])
    else:
        w = np.broadcast_to(np.asarray(sample_weight, dtype=float), (X.shape[0],))
        if np.any(~np.isfinite(w)) or np.any(w < 0):
            raise ValueError("sample_weight must be finite and non-negative")
    keep = w > 0
    rows = slice(None) if np.all(keep) else keep
    return X, y, support, candidates, rows, np.sqrt(w[keep]), float(w[keep].sum())


def _total_sum_of_squares(yw, sw, n, intercept):
    """Total sum of squares (centred with an intercept) and its dof."""
    if intercept:
        dev = yw - (float(yw @ sw) / n) * sw
        return float(dev @ dev), n - 1
    return float(yw @ yw), n


def _entry_f(C, Q, resid, sw, n, intercept, dof_res, tolerance):
    """Partial F-ratios of entry (eq. 19) of the weighted candidate columns ``C``.

    ``Q`` is the orthonormal basis of the model (its weighted columns), ``resid``
    its weighted residual. ``nan`` for a column that is collinear with the model
    or has non-finite values.
    """
    if C is None:
        return np.zeros(0)
    ss_res = float(resid @ resid)
    good = np.all(np.isfinite(C), axis=0)
    C = np.where(good, C, 0.0)
    # Twice-projected (Gram-Schmidt "twice is enough") residuals.
    Rc = C - Q @ (Q.T @ C)
    Rc -= Q @ (Q.T @ Rc)
    nr2 = np.einsum("ij,ij->j", Rc, Rc)
    # A column nearly in the span of the model (relative to its own size,
    # centred when there is an intercept) cannot enter: its F is noise.
    Cc = C - np.outer(sw, (sw @ C) / n) if intercept else C
    cn2 = np.einsum("ij,ij->j", Cc, Cc)
    ok = good & (nr2 > tolerance**2 * cn2) & (cn2 > 0) & (dof_res - 1 >= 1)
    g = Rc.T @ resid
    red = np.where(ok, g**2 / np.where(ok, nr2, 1.0), 0.0)
    red = np.minimum(red, ss_res)
    out_f = np.where(
        ok, safe_ratio(red * (dof_res - 1), np.maximum(ss_res - red, 0.0)), np.nan
    )
    return out_f
