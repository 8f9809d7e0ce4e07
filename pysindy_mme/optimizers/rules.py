"""Entry and removal rules: which statistic is compared with which threshold.

* :class:`FamilywiseRule` (the default): robust (Newey-West) partial F-ratios
  against the Bonferroni critical value for the number of candidates still
  outside the model, so that the chance of admitting any false function in a
  step is at most ``alpha`` however wide the library; and a function must
  be relevant as well as significant (``MIN_EFFECT``).
* :class:`ClassicRule`: classic partial F-ratios against a fixed threshold
  (the paper's ``F*``) or a per-test significance level (MATLAB's
  ``stepwisefit``), as Draper & Smith describe stepwise regression.

A rule gives the selection machine its statistics (``in_model_f``,
``candidate_f``) and thresholds; Phase II (the floating threshold) always
works on classic F-ratios, as the paper defines it.
"""

from __future__ import annotations

import numpy as np

from .anova import f_critical
from .robust import newey_west_lags

__all__ = [
    "MIN_EFFECT",
    "PAPER_F",
    "PAPER_RATIO",
    "ClassicRule",
    "FamilywiseRule",
    "make_rule",
]

# The paper's F* and float ratio (Kolodziej & Mook: "F* is chosen to be ten";
# the floating threshold one order of magnitude below the strongest).
PAPER_F = 10.0
PAPER_RATIO = 10.0

# Significance is not relevance. Under the default rule a function enters
# (or stays) only if it also reduces the residual sum of squares by at least
# this share of what remains with it in the model: Cohen's f^2 = classic
# partial F / residual degrees of freedom >= MIN_EFFECT. Up to about 10,000
# rows the Bonferroni threshold (F of 10 to 20) already implies it, so it
# changes nothing on records of ordinary length; with a million rows an
# F-test calls any systematic error of the derivative estimate significant
# (full-state Lorenz, dt 0.002, 1 % noise, SmoothedFiniteDifference: false
# x z and y z with robust F 60-100 but f^2 2e-5 to 7e-5, where the weakest
# true term, -y in y', has f^2 8e-3). On the drop-in benchmark's records the
# weakest true term has f^2 0.004 (Lorenz at 5 % noise).
MIN_EFFECT = 1e-3


class ClassicRule:
    """Classic partial F-ratios; fixed thresholds or per-test levels.

    Parameters
    ----------
    f_enter, f_remove : float or None
        Fixed thresholds (used when ``alpha_enter`` is None).
    alpha_enter, alpha_remove : float or None
        Per-test significance levels: thresholds are F critical values at the
        current residual degrees of freedom.
    n_eff : float
        Number of observations (sum of the frequency weights).
    """

    robust = False
    lags = 0
    joint_alpha = None  # the classic rule is Draper & Smith's, as published

    def __init__(self, f_enter, f_remove, alpha_enter, alpha_remove, n_eff):
        self.f_enter = f_enter
        self.f_remove = f_remove
        self.alpha_enter = alpha_enter
        self.alpha_remove = alpha_remove
        self.n_eff = n_eff

    def thresholds(self, k: int):
        """(entry, removal) thresholds for a model with ``k`` functions."""
        if self.alpha_enter is None:
            return self.f_enter, self.f_remove
        return (
            float(f_critical(self.alpha_enter, self.n_eff - k - 2)),
            float(f_critical(self.alpha_remove, self.n_eff - k - 1)),
        )

    def constant_threshold(self, k: int) -> float:
        """The constant is dropped at the end if its partial F is below this."""
        return self.thresholds(k)[1]

    def family_size(self, k: int) -> int:
        return 1

    def in_model_f(self, state) -> np.ndarray:
        return state.in_model_f()[1:]

    def candidate_f(self, state, classic) -> np.ndarray:
        return classic

    # The classic rule is Draper & Smith's: significance only.
    def relevant_in_model(self, state) -> np.ndarray:
        return np.ones(state.k, dtype=bool)

    def relevant_candidates(self, state, classic) -> np.ndarray:
        return np.ones(classic.shape, dtype=bool)


class FamilywiseRule:
    """Robust partial F-ratios against a Bonferroni level over the candidates.

    A function enters (or stays) when its partial F-ratio reaches the
    ``1 - alpha / m`` quantile of ``F(1, dof)``, where ``m`` is the number of
    eligible candidates outside the model: the largest of ``m`` null
    F-ratios exceeds it with probability at most ``alpha``. With
    ``robust=True`` the F-ratios are Newey-West robust (:mod:`.robust`).

    Parameters
    ----------
    alpha : float
        Family-wise significance level of one step.
    n_candidates : int
        Number of eligible library columns.
    n_eff : float
        Number of observations (sum of the frequency weights).
    n_rows : int
        Number of rows (sets the Newey-West bandwidth).
    robust : bool
        Newey-West robust F-ratios (else classic ones).
    """

    def __init__(self, alpha, n_candidates, n_eff, n_rows, robust=True):
        self.alpha = alpha
        self.n_candidates = int(n_candidates)
        self.n_eff = n_eff
        self.robust = bool(robust)
        self.lags = newey_west_lags(n_rows) if robust else 0
        # candidates left out by forward selection are tested jointly at alpha
        self.joint_alpha = alpha

    def family_size(self, k: int) -> int:
        """Number of candidates outside a model of ``k`` functions (at least 1)."""
        return max(self.n_candidates - k, 1)

    def thresholds(self, k: int):
        level = self.alpha / self.family_size(k)
        return (
            float(f_critical(level, self.n_eff - k - 2)),
            float(f_critical(level, self.n_eff - k - 1)),
        )

    def constant_threshold(self, k: int) -> float:
        # The constant is one prespecified term, not picked among candidates:
        # a single test at level alpha.
        return float(f_critical(self.alpha, self.n_eff - k - 1))

    def in_model_f(self, state) -> np.ndarray:
        if not self.robust:
            return state.in_model_f()[1:]
        return state.robust_in_model_f(self.lags)[1:]

    def candidate_f(self, state, classic) -> np.ndarray:
        """The rule's F-ratios of entry, from the state's classic ones
        (``state.candidate_f()``, computed once per step by the caller)."""
        if not self.robust:
            return classic
        return state.robust_candidate_f(self.lags, classic)

    def relevant_in_model(self, state) -> np.ndarray:
        """Whether each function in the model has f^2 >= ``MIN_EFFECT``."""
        dof = state.n_eff - state.k - 1
        return state.in_model_f()[1:] >= MIN_EFFECT * dof

    def relevant_candidates(self, state, classic) -> np.ndarray:
        """Whether each candidate would have f^2 >= ``MIN_EFFECT`` once in
        (``classic``: the state's classic F-ratios of entry)."""
        dof = state.n_eff - state.k - 2
        return classic >= MIN_EFFECT * dof


def make_rule(params, n_candidates: int, n_eff: float, n_rows: int, robust: bool):
    """The rule validated parameters select: the default unless thresholds given.

    ``robust``: Newey-West F-ratios for the default rule (``autocorrelation``
    given and rows in time order).
    """
    if params["f_enter"] is None and params["alpha_enter"] is None:
        return FamilywiseRule(
            params["alpha"], n_candidates, n_eff, n_rows, robust=robust
        )
    return ClassicRule(
        params["f_enter"],
        params["f_remove"],
        params["alpha_enter"],
        params["alpha_remove"],
        n_eff,
    )
