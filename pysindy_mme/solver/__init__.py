"""The numerical engine shared by MME and the output-error refits.

Direct transcription of a dynamic model over every sample (``transcription.py``:
the objective, its RK4 links and their exact sensitivities), solved by
Gauss-Newton (``gauss_newton.py``) on the banded KKT system (``kkt.py``), in
per-state internal units (``units.py``), with the checks of what the data
cannot see (``observability.py``) and the solver's result records
(``records.py``). The same transcription fits output-error models
(``output_error.py``: initial states, grey-box parameters and correction
coefficients against the measurements, with exact standard errors) and
tests them (``statistics.py``: partial F, BIC, the residual-correlation
inflation).

It knows no study and no estimator: :class:`~pysindy_mme.MME`
(``differentiation/``) and the study (``discovery/``) both import it; it
imports only ``core``.
"""

from .observability import unobservable_directions, unobservable_states
from .output_error import OutputErrorFit, OutputErrorModel
from .records import Linearization, SmootherResult
from .transcription import MMESmoother, internal_unit

__all__ = [
    "Linearization",
    "MMESmoother",
    "OutputErrorFit",
    "OutputErrorModel",
    "SmootherResult",
    "internal_unit",
    "unobservable_directions",
    "unobservable_states",
]
