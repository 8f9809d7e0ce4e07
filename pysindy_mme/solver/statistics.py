"""Tests and criteria on output-error fits, valid when residuals are correlated.

A right model fitted to white measurement noise leaves white residuals;
real records leave correlated ones (unmodelled disturbances), and every
test would then overstate significance. The AR(1) variance inflation of the
residuals (:func:`residual_inflation`) corrects the partial F-test
(:func:`partial_f_p_value`), the Wald tests and the BIC
(:func:`better_bic` compares two fits at one inflation).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy import stats

if TYPE_CHECKING:  # annotations only: output_error imports this module
    from .output_error import OutputErrorFit

__all__ = ["better_bic", "partial_f_p_value", "residual_inflation"]


def partial_f_p_value(small: OutputErrorFit, big: OutputErrorFit, n_added=1) -> float:
    """p-value of the partial F-test: ``big`` (``n_added`` more terms) vs
    ``small``."""
    if not (np.isfinite(big.cost) and np.isfinite(small.cost)):
        return 1.0
    if big.cost <= 0:
        return 0.0
    # the residual variance of the bigger model; statistic and degrees of
    # freedom corrected for correlated residuals (OutputErrorFit.inflation)
    f_stat = ((small.cost - big.cost) / n_added) / big.residual_variance
    f_stat /= big.inflation
    return float(stats.f.sf(f_stat, n_added, big.dof)) if f_stat > 0 else 1.0


def better_bic(a: OutputErrorFit, b: OutputErrorFit) -> bool:
    """Whether ``a`` has the lower BIC than ``b``, both at the same inflation."""
    c = min(a.inflation, b.inflation)
    return a.bic(c) < b.bic(c)


def residual_inflation(residuals, R) -> float:
    """AR(1) variance inflation ``(1 + rho) / (1 - rho)`` of whitened residuals.

    ``rho`` is the lag-1 autocorrelation pooled over channels and observed
    pairs; 1 when ``rho`` is not significantly above 0 (``< 2 / sqrt(n)``).
    """
    r = np.asarray(residuals, dtype=float)
    if r.ndim == 1:
        r = r[:, None]
    L = np.linalg.cholesky(np.linalg.inv(np.asarray(R, dtype=float))).T
    w = np.where(np.isfinite(r), r, 0.0) @ L.T
    pair = np.isfinite(r[1:]) & np.isfinite(r[:-1])
    num = float(np.sum(np.where(pair, w[1:] * w[:-1], 0.0)))
    den = float(np.sum(np.where(np.isfinite(r), w * w, 0.0)))
    n = int(pair.sum())
    if den <= 0 or n < 3:
        return 1.0
    rho = num / den
    if rho <= 2.0 / np.sqrt(n):
        return 1.0
    rho = min(rho, 0.999)
    return float((1.0 + rho) / (1.0 - rho))
