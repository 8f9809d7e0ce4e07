"""A cheap Duffing study whose assumed model is a module-level function.

Shared by the tests of results as objects (``tests/discovery/
test_results_objects.py``): a module-level model pickles (by reference) and
can be handed to ``Discovery.load(path, assumed_model=...)`` and to the
exported Python source. 300 samples of the Duffing oscillator
(``pysindy_mme.systems.duffing``), position measured: a study of about a
second that keeps ``x1^3`` in ``x2'``.
"""

from __future__ import annotations

import numpy as np
import pysindy as ps

from pysindy_mme import discover
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.systems import duffing

__all__ = [
    "duffing_assumed",
    "duffing_true",
    "duffing_grey",
    "decay",
    "study",
    "N_SAMPLES",
]

N_SAMPLES = 300


def duffing_assumed(x, t):
    """The linear damped oscillator (the Duffing system's assumed model)."""
    return np.column_stack([x[:, 1], -x[:, 0] - 0.1 * x[:, 1]])


def duffing_true(x, t):
    """The Duffing oscillator itself (nothing left to find)."""
    return np.column_stack([x[:, 1], -x[:, 0] - 0.1 * x[:, 1] - x[:, 0] ** 3])


def duffing_grey(x, t, u, p):
    """The same with the stiffness ``k`` a grey-box parameter."""
    return np.column_stack([x[:, 1], -p["k"] * x[:, 0] - 0.1 * x[:, 1]])


def decay(x, t):
    """``x' = -x`` for one state, answered as a flat ``(n_rows,)`` array."""
    return -x[:, 0]


def study(grey: bool = False, model=None):
    """``discover`` on the first ``N_SAMPLES`` samples of seed 0 (``model``:
    another assumed model ``f(x, t)``)."""
    system = duffing()
    data = system.measure(0)
    options = dict(
        n_states=2,
        measured=[0],
        noise_variance=system.noise_variance,
        error_states=[1],
        feature_library=ps.PolynomialLibrary(degree=3),
        feature_names=list(system.feature_names),
    )
    if grey:
        options.update(assumed_model=duffing_grey, parameters={"k": (1.1, 0.0, None)})
    else:
        options.update(assumed_model=model or duffing_assumed)
    return discover(data.y[:N_SAMPLES], data.t[:N_SAMPLES], **grouped_keywords(options))
