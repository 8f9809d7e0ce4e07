"""The study: what the assumed model gets wrong, why, the fix, and the gain.

:func:`discover` (``study.py``) runs five steps (``steps.py``), each
returning a small record the next one takes:

1. fit the assumed model to the measurements (``output_error.py``);
2. estimate the states and the model error ``d(t)`` (:class:`MME`);
3. propose terms by regressing ``d(t)`` on a library (``propose.py``);
4. confirm them on the measurements (``confirm.py``);
5. measure the gain (``gain.py``).

Arguments are checked in one place (``inputs.py``); the answer is a
:class:`Discovery` (``result.py``) with its report (``report.py``), its
tables (``summary.py``), its file (``storage.py``: ``save``/``load``) and
the :class:`ExtendedModel` (``extended.py``; as sympy or Python source:
``export.py``). Many studies at once (records, seeds, bootstrap
replicates), on local processes or a Dask cluster: ``discover_many``
(``many.py``, exported from :mod:`pysindy_mme`).
"""

from ..core.extended import ExtendedModel
from ..exceptions import DiscoveryWarning
from .estimates import TermEstimate
from .gain import Gain
from .options import StudyOptions
from .parameters import Parameter
from .result import Discovery
from .study import discover

__all__ = [
    "discover",
    "Discovery",
    "DiscoveryWarning",
    "ExtendedModel",
    "Gain",
    "Parameter",
    "StudyOptions",
    "TermEstimate",
]
