"""Property-based tests (hypothesis) of ``discover``: a few short records
(each runs MME, a regression and refits), always including the paper's
library kind (Table I, with singular negative powers) and a record too short
for a cubic library. Every run ends in a sane result or the documented
error, with only documented warnings.

The hypothesis profile ("ci": derandomised, fixed example counts) is set in
``tests/conftest.py``, which also prints how many cases each entry point
received.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pysindy as ps
from hypothesis import example, given, settings
from hypothesis import strategies as st
from reliability_support import readonly, warning_types
from sklearn.exceptions import ConvergenceWarning

from pysindy_mme import (
    ExcludedFeaturesWarning,
    PowerLibrary,
    StepwiseCycleWarning,
    StudyOptions,
    discover,
)
from pysindy_mme.discovery import DiscoveryWarning
from pysindy_mme.systems import van_der_pol

_DISCOVERY_LIBRARIES = {
    "poly2": lambda: ps.PolynomialLibrary(degree=2),
    "poly3": lambda: ps.PolynomialLibrary(degree=3),
    "power": lambda: PowerLibrary(powers=(-1, 1, 2), abs_powers=(1,)),
}


def _discovery_problem(t_end, seed, noise_variance, missing, library):
    """A short Van der Pol record (20 Hz), x1 measured, as in the paper."""
    system = van_der_pol()
    t = system.time(t_end, 20.0)
    y = system.measure(seed, noise_variance=noise_variance, t=t).y.copy()
    if missing:
        y[np.random.default_rng(seed).random(y.shape) < 0.1] = np.nan
    return system, t, y, noise_variance, _DISCOVERY_LIBRARIES[library]()


discovery_problems = st.builds(
    _discovery_problem,
    t_end=st.sampled_from([2.0, 5.0]),
    seed=st.integers(0, 1000),
    noise_variance=st.sampled_from([1e-4, 1e-2]),
    missing=st.booleans(),
    library=st.sampled_from(sorted(_DISCOVERY_LIBRARIES)),
)


@settings(max_examples=4)
@given(problem=discovery_problems)
# Cases the search must always include: the paper's library kind (Table I,
# with singular negative powers) and a record too short for a cubic library.
@example(problem=_discovery_problem(5.0, 7, 1e-2, True, "power"))
@example(problem=_discovery_problem(0.35, 3, 1e-2, False, "poly3"))
def test_discover_sane_or_documented_error(problem, case_counter):
    case_counter["discover"] += 1
    system, t, y, noise_variance, library = problem
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        try:
            result = discover(
                readonly(y),
                readonly(t),
                assumed_model=system.assumed_model,
                n_states=2,
                measured=[0],
                noise_variance=noise_variance,
                error_states=[1],
                feature_library=library,
                options=StudyOptions(feature_names=["x1", "x2"]),
            )
        except ValueError as exc:
            assert "samples are needed" in str(exc), exc  # record too short
            return
    allowed = {
        DiscoveryWarning,
        ExcludedFeaturesWarning,
        StepwiseCycleWarning,
        ConvergenceWarning,
        UserWarning,
    }
    assert warning_types(record) <= allowed, [str(w.message) for w in record]
    assert set(result.terms) == {"x2"}
    names = set(result.library_feature_names) | {"1"}
    for feature, coefficient in result.terms["x2"].items():
        assert feature in names and np.isfinite(coefficient)
    x_hat = result.mme.smoothed_x_
    rhs = result.extended_model.predict(x_hat)
    assert rhs.shape == x_hat.shape and np.all(np.isfinite(rhs))
    for rmse in (result.gain.rmse_assumed, result.gain.rmse_extended):
        assert rmse.shape == (1,) and np.all(np.isfinite(rmse) & (rmse > 0))
    if result.found_correction:
        assert result.gain.rmse_extended[0] <= result.gain.rmse_assumed[0]
    assert "x2" in str(result)
    json.dumps(result.to_dict())
