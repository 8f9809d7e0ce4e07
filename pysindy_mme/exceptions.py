"""Every exception and warning the package raises, in one place.

All are exported from :mod:`pysindy_mme`, so that callers can catch or filter
them by class (``warnings.simplefilter("error", DiscoveryWarning)``).
"""

from __future__ import annotations

__all__ = [
    "DivergenceError",
    "UnobservableError",
    "DiscoveryWarning",
    "StepwiseCycleWarning",
    "ExcludedFeaturesWarning",
    "NotSavedError",
    "StudiesFailedError",
]


class DivergenceError(FloatingPointError):
    """A model or an iteration produced non-finite or exploding values."""


class UnobservableError(ValueError):
    """The measurements do not determine the states along the trajectory solved.

    Raised by :class:`~pysindy_mme.MME` when its Gauss-Newton system is
    singular. Either the measurement setup cannot see a state anywhere
    (``measured``, ``measurement_matrix``, ``error_states``), or the model
    is flat in that state along the current trajectory: a square-root
    outflow ``sqrt(max(h, 0))`` at an empty tank, a dead zone, friction at
    rest, where an unmeasured state started at zero leaves no trace in the
    measured ones. For the second, start from a trajectory where it does
    (``MME.fit(..., x_guess=...)``). A ``ValueError``, as before it had a
    class of its own.
    """


class DiscoveryWarning(UserWarning):
    """Something in the study did not go as it should; the result says what."""


class StepwiseCycleWarning(UserWarning):
    """The selection returned to a model it had already visited and stopped there."""


class ExcludedFeaturesWarning(UserWarning):
    """Some library columns can never be selected (non-finite, constant, ...)."""


class NotSavedError(AttributeError):
    """A loaded result lacks what this needs: user code or a fitted estimator.

    :meth:`Discovery.save <pysindy_mme.Discovery.save>` keeps numbers, not
    code; the message names the missing piece and how to supply it. An
    ``AttributeError``, so that ``getattr(result.mme, name, default)`` and
    ``hasattr`` treat what was not saved as absent.
    """


class StudiesFailedError(RuntimeError):
    """Some studies of :func:`~pysindy_mme.discover_many` raised.

    Raised after every study has run; the message names each failed record
    and its exception.

    Attributes
    ----------
    results : list
        One entry per record, in order: the result of each study that
        finished, a :class:`~pysindy_mme.discovery.many.StudyFailure` (with
        ``index``, ``exception``, ``traceback``) for each that raised.
    failures : list
        The failures alone.
    """

    def __init__(self, results, failures):
        self.results = list(results)
        self.failures = list(failures)
        lines = "\n".join(f"  {f}" for f in self.failures)
        super().__init__(
            f"{len(self.failures)} of {len(self.results)} studies failed "
            f"(the others' results are in .results):\n{lines}"
        )

    def __reduce__(self):
        return type(self), (self.results, self.failures)
