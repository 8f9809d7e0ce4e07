"""Validation protocols: how both models are scored on data they were not fitted to.

* :class:`LeadingWindow` - the benchmarks' free run: initial state from a
  record's leading window, then the model runs free (the default with a
  validation record);
* :class:`KStepAhead` - predictions ``k`` samples ahead, each from a state
  fitted to the samples before it;
* :class:`HeldOut` - a stretch of the fitting data held out, both models
  refitted without it, then scored on it by one of the above (the default
  without a validation record).

``discover(validation=...)`` takes a record (a :class:`LeadingWindow` on it)
or any of these objects; :meth:`Discovery.validate` takes one for a new
record; the report and the plot print the protocol's own description; the
command line builds them from ``--validation``, ``--validation-window``
and ``--k-step``. The interface is :class:`ValidationProtocol`
(``base.py``); a new protocol is a subclass and an export here.

A free run's :class:`RunUncertainty` (``uncertainty.py``) says whether its
miss of data the model was not fitted to is the uncertainty of the model's
coefficients and start, or the model's own.
"""

from .base import ValidationContext, ValidationOutcome, ValidationProtocol
from .held_out import HeldOut
from .k_step import KStepAhead
from .leading_window import LeadingWindow
from .runs import FreeRun
from .uncertainty import RunUncertainty

__all__ = [
    "FreeRun",
    "HeldOut",
    "KStepAhead",
    "LeadingWindow",
    "RunUncertainty",
    "ValidationContext",
    "ValidationOutcome",
    "ValidationProtocol",
]
