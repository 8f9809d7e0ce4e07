"""Many short records of the paper's Van der Pol case, for discover_many.

Everything a worker process must rebuild lives here, at module level of a
module on the tests' path (``pythonpath`` in pyproject.toml, which worker
processes inherit), so that it travels by reference: the assumed model,
an optimizer that breaks on purpose, a model that cannot travel at all.
"""

from __future__ import annotations

import threading

import numpy as np
import pysindy as ps
from sklearn.base import BaseEstimator

from pysindy_mme.systems import van_der_pol

__all__ = [
    "BrokenOptimizer",
    "LockedModel",
    "records",
    "same_result",
    "shared_keywords",
    "vdp_assumed",
]

VDP = van_der_pol()


def vdp_assumed(x, t):
    """The paper's ignorance model ``x1' = x2, x2' = 0`` (module level)."""
    return np.column_stack([x[:, 1], np.zeros(len(x))])


def records(n: int, first: int = 0) -> list:
    """``n`` records ``(y, t)``: seeds first..first+n-1, x1 at 40 Hz for 10 s."""
    seeds = range(first, first + n)
    return [(d.y, d.t) for d in (VDP.measure(seed) for seed in seeds)]


def shared_keywords(**overrides) -> dict:
    """discover's keywords of the paper's case, fresh objects every call."""
    keywords = dict(
        assumed_model=vdp_assumed,
        n_states=2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
        feature_library=ps.PolynomialLibrary(degree=3),
        options={"feature_names": ["x1", "x2"]},
    )
    keywords.update(overrides)
    return keywords


class BrokenOptimizer(BaseEstimator):
    """An optimizer that passes discover's checks and raises in step 3."""

    def fit(self, x, y):
        raise RuntimeError("this optimizer breaks on purpose")


class LockedModel:
    """A model holding a lock: no pickler can send it to another process."""

    def __init__(self):
        self.lock = threading.Lock()

    def __call__(self, x, t):
        return vdp_assumed(x, t)


def same_result(a, b) -> bool:
    """Two Discovery objects agree to the last bit: terms, coefficients,
    parameters and their errors, gains, simulations, report, summary."""
    assert a.to_dict() == b.to_dict()
    assert a.param_names == b.param_names
    np.testing.assert_array_equal(a.params, b.params)
    np.testing.assert_array_equal(a.bse, b.bse)
    assert a.gain.to_dict() == b.gain.to_dict()
    np.testing.assert_array_equal(a.extended_simulation, b.extended_simulation)
    assert str(a.summary()) == str(b.summary())
    assert str(a) == str(b)
    return True
