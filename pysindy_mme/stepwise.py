"""Old import path of :class:`FloatingFStepwise` (now in :mod:`pysindy_mme.optimizers`).

Kept so that ``from pysindy_mme.stepwise import FloatingFStepwise`` keeps working.
``_screen_columns`` is here only so that old tests which patch it still import;
patching it has no effect: patch ``pysindy_mme.optimizers.stepwise.screen_columns``.
"""

from .exceptions import ExcludedFeaturesWarning, StepwiseCycleWarning
from .optimizers.screening import screen_columns as _screen_columns  # noqa: F401
from .optimizers.selection import Step
from .optimizers.stepwise import FloatingFStepwise
from .optimizers.summary import StepwiseSummary

__all__ = [
    "FloatingFStepwise",
    "Step",
    "StepwiseCycleWarning",
    "ExcludedFeaturesWarning",
    "StepwiseSummary",
]
