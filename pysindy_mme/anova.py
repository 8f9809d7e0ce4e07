"""Analysis of variance for a linear regression on a chosen set of functions.

This module holds the statistics only (no selection logic): the ANOVA table of
the paper's Table II (Kolodziej & Mook, eqs. 10-20), partial F-ratios of the
functions in and out of a model, F critical values, and an accurate
least-squares solver. :class:`~pysindy_mme.stepwise.FloatingFStepwise`
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

    @property
    def variance_of_estimate(self) -> float:
        """Residual mean square (the paper's "variance of estimate")."""
        return self.ms_residual

    @property
    def std_error_of_estimate(self) -> float:
        """Square root of the variance of estimate."""
        return float(np.sqrt(self.ms_residual))

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

        def name(j):
            if feature_names is not None and j < len(feature_names):
                return str(feature_names[j])
            return f"f{j}"

        def num(v, width=12):
            return f"{_fmt(v):>{width}}"

        lines = [] if title is None else [title]
        lines += [
            f"  Coefficient of determination  {_fmt(self.r2)}",
            f"  Multiple corr. coefficient    {_fmt(self.multiple_r)}",
            f"  Variance of estimate          {_fmt(self.variance_of_estimate)}",
            f"  Std error of estimate         {_fmt(self.std_error_of_estimate)}",
        ]
        if self.has_intercept:
            lines.append(f"  Intercept                     {_fmt(self.intercept)}")
        else:
            lines.append("  Intercept                     none (through the origin)")
        lines += [
            "",
            f"  {'Source of variation':<26}{'dof':>8}{'SS':>12}{'MS':>12}"
            f"{'F-ratio':>12}{'p-value':>12}",
            f"  {'Due to regression':<26}{_fmt(self.dof_regression):>8}"
            f"{num(self.ss_regression)}{num(self.ms_regression)}"
            f"{num(self.f_ratio)}{num(self.p_value)}",
            f"  {'Deviation about regression':<26}{_fmt(self.dof_residual):>8}"
            f"{num(self.ss_residual)}{num(self.ms_residual)}",
            f"  {'Total':<26}{_fmt(self.dof_total):>8}{num(self.ss_total)}",
            "",
            "  Functions in the model",
            f"  {'function':<20}{'coefficient':>14}{'std error':>12}"
            f"{'partial F':>12}{'p-value':>12}",
        ]
        for j, c, se, f, p in zip(
            self.features,
            self.coefficients,
            self.std_errors,
            self.partial_f,
            self.p_values,
            strict=True,
        ):
            lines.append(f"  {name(j):<20}{num(c, 14)}{num(se)}{num(f)}{num(p)}")
        if self.has_intercept:
            lines.append(
                f"  {'(intercept)':<20}{num(self.intercept, 14)}"
                f"{num(self.intercept_std_error)}{num(self.intercept_partial_f)}"
                f"{num(f_pvalue(self.intercept_partial_f, 1, self.dof_residual))}"
            )
        if not self.features and not self.has_intercept:
            lines.append("  (none)")
        lines += ["", "  Functions not in the model (strongest)"]
        if len(self.out_features):
            lines.append(f"  {'function':<20}{'partial F':>14}{'p-value':>12}")
            for j, f, p in zip(
                self.out_features, self.out_partial_f, self.out_p_values, strict=True
            ):
                lines.append(f"  {name(j):<20}{num(f, 14)}{num(p)}")
        else:
            lines.append("  (none assessed)")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.to_text()


def _fmt(v) -> str:
    """Four significant digits, switching to exponent form for extremes."""
    v = float(v)
    if not np.isfinite(v):
        return str(v)
    if v == int(v) and abs(v) < 1e7:
        return str(int(v))
    if v != 0 and (abs(v) >= 1e6 or abs(v) < 1e-3):
        return f"{v:.4g}"
    return f"{v:.5g}"


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
    sw = np.sqrt(w[keep])
    n = float(w[keep].sum())
    rows = slice(None) if np.all(keep) else keep

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
    if intercept:
        ybar = float(yw @ sw) / n
        dev = yw - ybar * sw
        ss_tot = float(dev @ dev)
        dof_total = n - 1
    else:
        ss_tot = float(yw @ yw)
        dof_total = n
    dof_res = n - p
    ss_reg = max(ss_tot - ss_res, 0.0)
    ms_res = ss_res / dof_res
    ms_reg = ss_reg / k if k else np.nan
    with np.errstate(divide="ignore", invalid="ignore"):
        f_ratio = _safe_ratio(ms_reg, ms_res) if k else np.nan
        r2 = ss_reg / ss_tot if ss_tot > 0 else np.nan

    # Covariance of the coefficients: s^2 (A^T A)^-1 = s^2 R^-1 R^-T.
    Rinv = scipy.linalg.solve_triangular(R, np.eye(p))
    diag = np.einsum("ij,ij->i", Rinv, Rinv)
    std_err = np.sqrt(ms_res * diag)
    partial = _safe_ratio(beta**2, ms_res * diag)
    pvals = np.atleast_1d(f_pvalue(partial, 1, dof_res))

    out_f = np.full(len(candidates), np.nan)
    if candidates:
        C = X[:, candidates][rows] * sw[:, None]
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
            ok, _safe_ratio(red * (dof_res - 1), np.maximum(ss_res - red, 0.0)), np.nan
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


def _safe_ratio(num, den):
    """``num / den`` with ``x / 0 = inf`` (x > 0) and ``0 / 0 = 0``, no warnings."""
    num = np.asarray(num, dtype=float)
    den = np.asarray(den, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = num / den
    out = np.where(den > 0, out, np.where(num > 0, np.inf, 0.0))
    return out[()]
