"""Every exception and warning the package raises, in one place.

All are exported from :mod:`pysindy_mme`, so that callers can catch or filter
them by class (``warnings.simplefilter("error", DiscoveryWarning)``).
"""

from __future__ import annotations

__all__ = [
    "DivergenceError",
    "DiscoveryWarning",
    "StepwiseCycleWarning",
    "ExcludedFeaturesWarning",
]


class DivergenceError(FloatingPointError):
    """A model or an iteration produced non-finite or exploding values."""


class DiscoveryWarning(UserWarning):
    """Something in the study did not go as it should; the result says what."""


class StepwiseCycleWarning(UserWarning):
    """The selection returned to a model it had already visited and stopped there."""


class ExcludedFeaturesWarning(UserWarning):
    """Some library columns can never be selected (non-finite, constant, ...)."""
