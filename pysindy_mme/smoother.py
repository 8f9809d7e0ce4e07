"""Old import path of the MME solver; see :mod:`pysindy_mme.differentiation`."""

from .differentiation.observability import unobservable_states
from .differentiation.transcription import MMESmoother, SmootherResult, internal_unit
from .exceptions import DivergenceError

__all__ = [
    "DivergenceError",
    "MMESmoother",
    "SmootherResult",
    "internal_unit",
    "unobservable_states",
]
