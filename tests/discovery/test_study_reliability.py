"""discover reliability: determinism, no mutation, unit invariance on the
paper's Van der Pol case, failures of a step reported on the result, and
Ctrl-C reaching the user.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pysindy as ps
import pytest
from paper_case import DATA as _DATA
from paper_case import VDP, T, Y
from paper_case import paper_discover as _discover
from reliability_support import (
    assert_same_global_random_state,
    global_random_state,
    readonly,
)

import pysindy_mme.differentiation.mme as mme_module
import pysindy_mme.discovery.inputs as discovery_inputs
from pysindy_mme import discover
from pysindy_mme.discovery import DiscoveryWarning
from pysindy_mme.solver.output_error import OutputErrorModel
from pysindy_mme.systems import lotka_volterra

# ------------------------------------------------------ determinism and units


@pytest.fixture(scope="module")
def vdp_discovery():
    """The paper's case through discover, once (about 2 s)."""
    before = global_random_state()
    y, t = readonly(Y), readonly(T)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = _discover(y, t, feature_library=ps.PolynomialLibrary(degree=3))
    assert_same_global_random_state(before)
    np.testing.assert_array_equal(y, _DATA.y)
    np.testing.assert_array_equal(t, _DATA.t)
    return result


def test_discover_is_deterministic(vdp_discovery):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        again = _discover(
            readonly(Y), readonly(T), feature_library=ps.PolynomialLibrary(degree=3)
        )
    assert json.dumps(again.to_dict(), sort_keys=True) == json.dumps(
        vdp_discovery.to_dict(), sort_keys=True
    )
    np.testing.assert_array_equal(
        again.extended_simulation, vdp_discovery.extended_simulation
    )
    np.testing.assert_array_equal(again.mme.smoothed_x_, vdp_discovery.mme.smoothed_x_)


@pytest.mark.parametrize(
    "unit",
    [
        1e-6,
        1e6,
    ],
)
def test_vdp_discover_selects_the_same_terms_in_any_units(unit, vdp_discovery):
    """x -> unit * x maps the assumed model x1' = x2, x2' = 0 onto itself and
    the library onto itself (each term's coefficient rescales), so with the
    noise variance scaled by unit**2 the same terms must be found; only their
    coefficients change (x1^2 x2's by unit**-2)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scaled = _discover(
            Y * unit,
            T,
            noise_variance=0.01 * unit**2,
            feature_library=ps.PolynomialLibrary(degree=3),
        )
    assert set(vdp_discovery.terms["x2"]) == {"x1", "x2", "x1^2 x2"}
    assert set(scaled.terms["x2"]) == set(vdp_discovery.terms["x2"])
    for name, power in (("x1", 0), ("x2", 0), ("x1^2 x2", 2)):
        assert scaled.terms["x2"][name] * unit**power == pytest.approx(
            vdp_discovery.terms["x2"][name], rel=1e-3
        )


# ----------------------------------------------- failures mid-computation


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_discover_reports_mme_non_convergence(monkeypatch):
    class OneIterationMME(mme_module.MME):
        def fit(self, y, t=1.0, u=None):
            self.max_iter = 1
            return super().fit(y, t, u)

    monkeypatch.setattr(discovery_inputs, "MME", OneIterationMME)
    system = lotka_volterra()
    data = system.measure(0)
    with pytest.warns(DiscoveryWarning, match="MME did not converge"):
        result = discover(
            data.y,
            data.t,
            assumed_model=system.assumed_model,
            n_states=2,
            measured=[0, 1],
            noise_variance=0.01,
            error_states=[1],
            feature_library=ps.PolynomialLibrary(degree=2),
        )
    assert result.mme.converged_ is False
    assert any("MME did not converge" in note for note in result.warnings)
    assert "MME did not converge" in str(result)


def test_discover_reports_refit_non_convergence(monkeypatch):
    original = OutputErrorModel.fit

    def not_converging(self, *args, **kwargs):
        result = original(self, *args, **kwargs)
        return dataclasses.replace(result, converged=False, message="forced")

    monkeypatch.setattr(OutputErrorModel, "fit", not_converging)
    with pytest.warns(DiscoveryWarning, match="refit"):
        result = _discover(feature_library=ps.PolynomialLibrary(degree=3))
    # the report names the terms the data determine least, and what to try
    (note,) = [n for n in result.warnings if "refit of the extended" in n]
    assert "least determined ones: " in note and "Try:" in note
    for name in result.terms["x2"]:
        assert f"{name} in x2'" in note


class _Interrupt:
    """A model that raises KeyboardInterrupt after ``calls`` evaluations
    (never, for ``calls=None``: it then counts the evaluations)."""

    def __init__(self, calls=None):
        self.left = calls
        self.made = 0

    def __call__(self, x, t):
        self.made += 1
        if self.left is not None and self.made > self.left:
            raise KeyboardInterrupt
        return VDP.assumed_model(x, t)


@pytest.fixture(scope="module")
def calls_in_a_clean_run():
    counter = _Interrupt()
    _discover(assumed_model=counter, feature_library=ps.PolynomialLibrary(degree=2))
    return counter.made


# Where in the study the interrupt falls: the first call, early (MME's W
# search), half-way (proposals, refits) and at the very last model call.
@pytest.mark.parametrize("fraction", [0.0, 0.05, 0.5, 1.0])
def test_discover_can_be_interrupted(fraction, calls_in_a_clean_run):
    """Ctrl-C inside the user's model reaches the user, at any stage (MME's
    W search, refits), and is never turned into another error. (MME alone:
    ``tests/differentiation/test_mme_reliability.py``.)"""
    calls = int(fraction * (calls_in_a_clean_run - 1))
    with pytest.raises(KeyboardInterrupt):
        _discover(
            assumed_model=_Interrupt(calls),
            feature_library=ps.PolynomialLibrary(degree=2),
        )
