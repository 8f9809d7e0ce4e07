"""The per-term and per-parameter records of a study (terms, parameters).

Their own module because the result, its tables and its file format all
read them, and none of those should import another for them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ParameterEstimate", "TermEstimate"]


@dataclass(frozen=True)
class TermEstimate:
    """One identified correction term.

    Attributes
    ----------
    state : str
        The equation it corrects (``state``').
    feature : str
        Library feature name.
    coefficient : float
        Output-error coefficient (fitted to the measurements).
    regression_coefficient : float
        Coefficient from the stepwise regression of ``d(t)`` (biased to 0;
        NaN for a term the regression did not propose).
    std_error : float
        NaN when the data do not determine it.
    ci_low, ci_high : float
        95 % confidence interval of ``coefficient``.
    partial_f : float
        Partial F-ratio in the stepwise regression (NaN for other optimizers
        or terms it did not propose).
    p_value : float
        Wald test of ``coefficient`` in the output-error fit.
    rms_term : float
        RMS of the term (coefficient times function) along the fitted
        trajectory: its size in the units of ``state``'.
    share_of_correction : float
        ``rms_term`` over the RMS of the whole correction of that equation.
    share_of_dynamics : float
        ``rms_term`` over the RMS of the extended model's ``state``'.
    """

    state: str
    feature: str
    coefficient: float
    regression_coefficient: float
    std_error: float
    ci_low: float
    ci_high: float
    partial_f: float
    p_value: float
    rms_term: float = float("nan")
    share_of_correction: float = float("nan")
    share_of_dynamics: float = float("nan")


@dataclass(frozen=True)
class ParameterEstimate:
    """One parameter of the assumed model (grey box), fitted to the data.

    Attributes
    ----------
    name : str
    initial : float
        The user's guess.
    assumed_fit : float
        Fitted with the assumed model alone (step 1).
    value : float
        Fitted jointly with the correction (the extended model's value).
    std_error, ci_low, ci_high : float
        Of ``value`` (95 % interval; NaN when not determined, or at a bound).
    lower, upper : float
        The user's bounds (``-inf`` / ``inf``: none).
    at_bound : bool
        ``value`` is on a bound the data push it against: the data would
        take it further, so it is a limit, not an estimate (its standard
        error is NaN, the others' are computed with it held there).
    gauge : bool
        Held at the guess because it trades off exactly with other
        quantities (a scale the data do not determine,
        ``Discovery.trade_offs``): fixed, not estimated (no standard error;
        the others are estimated relative to it).
    """

    name: str
    initial: float
    assumed_fit: float
    value: float
    std_error: float
    ci_low: float
    ci_high: float
    lower: float = -np.inf
    upper: float = np.inf
    at_bound: bool = False
    gauge: bool = False

    @property
    def change(self) -> float:
        """Relative change of ``value`` from ``initial``."""
        return (self.value - self.initial) / self.initial if self.initial else np.nan
