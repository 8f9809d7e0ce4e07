"""The cascaded tanks' study arguments, shared by the tests that run them.

:func:`tanks_arguments` gives ``discover``'s (and ``prepare_study``'s)
arguments for a record of :func:`~pysindy_mme.machines.cascaded_tanks`: only
the lower level measured, the sensor's noise as white noise plus its 12-bit
steps, both equations suspect, the machine's grey-box parameters, a
zero-order input hold (the pump holds its voltage).
"""

from __future__ import annotations

from pysindy_mme import MME, StudyOptions

__all__ = ["sensor_variance", "tanks_arguments"]

NAMES = ["h1", "h2", "u"]


def sensor_variance(rec) -> float:
    """Noise variance of the level sensor: white noise plus 12-bit steps."""
    step = rec.quantisation_step or 0.0
    return float(rec.noise_sd[0]) ** 2 + step**2 / 12.0


def tanks_arguments(machine, rec, library=None, validation=None) -> dict:
    """``discover(**tanks_arguments(...))`` on record ``rec`` of ``machine``;
    ``validation`` a record of the same machine (or None)."""
    args = dict(
        y=rec.y,
        t=rec.t,
        u=rec.u,
        assumed_model=machine.assumed_model,
        n_states=2,
        measured=[1],
        noise_variance=sensor_variance(rec),
        error_states=[0, 1],
        feature_library=library,
        options=StudyOptions(parameters=machine.parameters, feature_names=NAMES),
        mme=MME(input_hold="zoh"),
    )
    if validation is not None:
        args["validation"] = (validation.y, validation.t, validation.u)
    return args
