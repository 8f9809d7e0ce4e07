"""What a library needs before any of its targets is selected.

The screen (eligible columns, their scales, the first step's products), the
entry/removal rule (which depends on the number of eligible columns and on
whether the rows are in time order) and, for a tall, narrow library, the
moments the selection then reads instead of the rows.
"""

from __future__ import annotations

import numpy as np

from .errors_in_variables import Correction, correction_for
from .gram import first_step_vectors
from .moments import tall_moments
from .robust import rows_look_time_ordered
from .rules import make_rule
from .screening import screen_columns

__all__ = ["prepare_library"]


def prepare_library(x, y, w, params, autocorrelation, time_ordered, correct=True):
    """``(screen, rule, moments, in_time_order, correction)`` of library ``x``
    and targets ``y``.

    ``w``: positive frequency weights; ``params``: the checked parameters
    (:func:`~._checks.check_params`); ``time_ordered``: whether the robust
    rule may read the rows as a time series, or ``"auto"`` to read it from
    the screened library (:func:`~.robust.rows_look_time_ordered`);
    ``correct``: whether the errors-in-variables correction may apply
    (``params["errors_in_variables"]`` "auto"; see
    :mod:`.errors_in_variables`). ``correction`` says whether it did and why
    not; when it did, ``moments`` are the corrected ones.
    """
    sw = np.sqrt(w)  # (the screen's pass also gives the first step's X^T e)
    screen = screen_columns(
        x, sw, float(w.sum()), params["tolerance"], first_step_vectors(sw, y)
    )
    if isinstance(time_ordered, str):
        time_ordered = rows_look_time_ordered(x, screen.eligible)
    time_ordered = bool(time_ordered)
    rule = make_rule(
        params,
        int(screen.eligible.sum()),
        float(w.sum()),
        x.shape[0],
        robust=autocorrelation is not None and time_ordered,
    )
    correction = Correction(False, "errors_in_variables=False")
    if not (correct and isinstance(x, np.ndarray)):
        correction = Correction(False, "partial_out or a streamed library")
    elif params.get("errors_in_variables") == "auto":
        correction = correction_for(x, w, screen, rule, time_ordered)
    if correction.applied:
        return screen, rule, correction.moments, time_ordered, correction
    moments = tall_moments(x, w, y, screen, rule.lags if rule.robust else None)
    return screen, rule, moments, time_ordered, correction
