"""Whether a free run is the model's, or rounding's.

The gain compares free runs: each model simulated from its fitted initial
state over the record. A model that is unstable along the data amplifies a
change of that state without bound (the Lotka-Volterra model without the
predator's gain over 75 s: prey growing as e^t once the predators have died
out, a factor of 1e32). Its run is then set by the last digits it is solved
to, not by the model: the study's Newton-solved run (every interval joined to
:data:`~pysindy_mme.core.integrate.GUIDED_TOL` of the trajectory's scale)
stays at ``x1 = 0`` from ``x1(0) = -9e-15`` and scores an RMSE of 2.26, where
an independent RK4 run from the same state scores 6e14. Both are runs of the
model within rounding, and neither RMSE measures the model.

Out of sample the same question has a larger perturbation: each run starts
from a state estimated from a short window, known to its standard error.
:func:`spread_sentence` says where that error, carried along the run
(:mod:`pysindy_mme.protocols.spread`), spreads it by more than the noise.

:func:`rounding_sets_run` reads the fit's last linearisation (its interval
maps' Jacobians along the fitted trajectory, which a joined fit shares with
its free run) and finds where a change of the initial state at that
precision has grown to :data:`ROUNDING_SHARE` of the noise: from there on the
run is not determined, and the report says so beside its RMSE.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.integrate import GUIDED_TOL, perturbation_growth

__all__ = [
    "ROUNDING_SHARE",
    "RoundingSet",
    "rounding_sets_run",
    "rounding_note",
    "spread_from",
    "spread_sentence",
]

#: a free run counts as set by rounding where a change of its initial state
#: at the precision it is solved to has grown to this share of the noise
#: (internal units are the noise's standard deviation of each measured state)
ROUNDING_SHARE = 0.1


@dataclass(frozen=True)
class RoundingSet:
    """Where a fit's free run stops being determined by its model.

    Attributes
    ----------
    time : float
        The first sample time at which a change of the initial state of
        ``GUIDED_TOL`` times the run's scale moves a state by more than
        :data:`ROUNDING_SHARE` of the noise.
    growth : float
        The largest amplification of a change of the initial state over the
        record (``inf``: beyond floating point).
    """

    time: float
    growth: float


def rounding_sets_run(fit, t, record_slices) -> RoundingSet | None:
    """Where rounding sets ``fit``'s free run (None: nowhere, or unknown).

    ``fit``: an :class:`~pysindy_mme.solver.output_error.OutputErrorFit`
    that still holds its linearisation (before ``keep_statistics``);
    ``t``: the record's times; ``record_slices``: the samples of each record
    (each run starts from its record's own initial state).
    """
    state = getattr(fit, "_state", None)
    if state is None or not fit.ok:
        return None
    solver, res = state
    lin = getattr(res, "_lin", None)
    A = getattr(lin, "A", None)
    if A is None or A.ndim != 3:
        return None
    unit = np.asarray(solver.unit, dtype=float)
    x = np.asarray(fit.x, dtype=float)
    found = None
    for part in record_slices:
        start, stop = part.start, part.stop
        if stop - start < 2:
            continue
        # the run's own precision (simulate_guided), in internal units
        scale = max(1.0, float(np.max(np.abs(x[start:stop]))))
        push = GUIDED_TOL * scale * float(np.sum(1.0 / unit))
        growth = perturbation_growth(A[start : stop - 1])
        over = push * growth > ROUNDING_SHARE
        if not over.any():
            continue
        k = int(np.argmax(over))
        worst = float(np.max(growth))
        if found is None or t[start + k] < found.time:
            found = RoundingSet(time=float(t[start + k]), growth=worst)
    return found


def rounding_note(model_name: str, where: RoundingSet, rmse) -> str:
    """The report's note on a run that rounding sets (see module docstring)."""
    rmse_text = ", ".join(f"{v:.4g}" for v in np.atleast_1d(rmse))
    grows = (
        "beyond floating point"
        if not np.isfinite(where.growth)
        else f"by up to {where.growth:.2g}"
    )
    return (
        f"the {model_name} model's free run is set by rounding from t = "
        f"{where.time:.6g} on: the model amplifies a change of its initial state "
        f"{grows} along the record, so a change at the last digits the run is "
        f"solved to ({GUIDED_TOL:g} of its scale) moves it there by more than "
        f"{ROUNDING_SHARE:g} of the noise. Its in-sample RMSE ({rmse_text}) is that "
        "of one of many runs of the model within rounding (an independent "
        "simulation from the same state can end far away), and a gain over it "
        "measures that run, not the model: the model is unstable along the data"
    )


def spread_from(gain, name: str) -> float | None:
    """The time from which model ``name``'s out-of-sample run is spread by
    its initial state's estimate beyond the noise (None: nowhere, or no
    such run)."""
    run = (gain.validation_runs or {}).get(name)
    return getattr(run, "determined_until", None)


def spread_sentence(gain, name: str) -> str | None:
    """Model ``name``'s out-of-sample run as the conclusion and the notes
    name it when its start's estimate spreads it beyond the noise (None:
    determined throughout)."""
    when = spread_from(gain, name)
    if when is None:
        return None
    return (
        f"the {name} model's run on {gain.validation_source} is not determined "
        f"by its initial state from t = {when:.6g} on: the estimate of that state "
        f"from the leading {gain.validation_window} samples (its standard error "
        "from the noise, carried along the run by the model) spreads the run by "
        "more than the noise there, so even a perfect model can miss the data "
        "there by more than the noise"
    )
