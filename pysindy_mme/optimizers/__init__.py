"""Optimizers: floating-F stepwise regression, its ANOVA statistics and summaries.

:class:`FloatingFStepwise` is a pysindy optimizer (``ps.SINDy(optimizer=
FloatingFStepwise())``). The modules, one job each:

* :mod:`.design`: :class:`StreamedDesign`, a library read by column blocks;
* :mod:`.screening`: library columns that can never be selected, and why;
* :mod:`.least_squares_state`: coefficients and classic partial F-ratios
  from a state's small factor, shared by the two states below;
* :mod:`.incremental_qr`: the QR state from which partial F-ratios follow;
* :mod:`.moments`, :mod:`.gram`: the same state from two passes' moments
  (tall libraries: 20,000 rows or more, up to 16 columns);
* :mod:`.errors_in_variables`, :mod:`.corrected_state`: the same state from
  the corrected moments of a polynomial library of noisy measured states;
* :mod:`.selection`: the Phase I / Phase II machine over that state;
* :mod:`.final_fit`: coefficients and ANOVA table of the chosen model;
* :mod:`.rules`: which statistic meets which threshold (default and classic);
* :mod:`.robust`: Newey-West partial F-ratios for autocorrelated residuals;
* :mod:`.stepwise`: the estimator (parameters, validation, fit);
* :mod:`.cv`: :class:`FloatingFStepwiseCV`, ``alpha`` by blocked cross-validation;
* :mod:`.anova`: statistics (ANOVA table, F critical values, accurate lstsq);
* :mod:`.tables`, :mod:`.summary`: text and HTML reports.
"""

from ..exceptions import ExcludedFeaturesWarning, StepwiseCycleWarning
from ._checks import InvalidParameterError
from ._interface import ConstantNotInLibraryWarning
from .anova import AnovaTable, f_critical, f_pvalue, fit_anova, lstsq_refined
from .cv import FloatingFStepwiseCV
from .design import StreamedDesign
from .selection import Step
from .stepwise import FloatingFStepwise
from .summary import StepwiseSummary

__all__ = [
    "AnovaTable",
    "ConstantNotInLibraryWarning",
    "ExcludedFeaturesWarning",
    "FloatingFStepwise",
    "FloatingFStepwiseCV",
    "InvalidParameterError",
    "Step",
    "StepwiseCycleWarning",
    "StepwiseSummary",
    "StreamedDesign",
    "f_critical",
    "f_pvalue",
    "fit_anova",
    "lstsq_refined",
]
