"""Observability: what the measurements cannot determine is found and named.

Unobservable directions are found at any noise level and growth rate
(structurally before the solver, numerically from the linearisation when the
structure cannot tell), a weakly determined problem is not declared singular,
and a stiff model is not mistaken for an unobservable one. The structural
cases that are bad input (a state no measurement sees) are in
``test_bad_input.py``.
"""

import numpy as np
import pytest

from pysindy_mme import MME
from pysindy_mme.core.model import ModelFunction
from pysindy_mme.solver import MMESmoother, unobservable_states
from pysindy_mme.systems import van_der_pol


def _data():
    m = van_der_pol().measure(0)
    return m.y, m.t


@pytest.mark.parametrize(
    "error_model, named",
    [
        ("white", r"\[\+1 x0 -1 x1\]"),
        ("random_walk", r"-1 x1 \S+ d0 \(model error of x0\) \S+ d1 \(model error"),
    ],
)
def test_unobservable_state_found_numerically(error_model, named):
    """Every state is measured, yet not observable: the singular KKT is named.

    y sees only x0 + x1 and both states are pure integrators of their model
    errors, so the initial value of x0 - x1 is undetermined (no prior on the
    initial state). The structural check cannot see this; the zero pivot of
    the KKT factorisation does, and the error names the direction.
    """

    def model(x, t):
        return np.zeros_like(x)

    y, t = _data()
    mme = MME(
        model,
        2,
        measurement_matrix=[[1.0, 1.0]],
        noise_variance=0.01,
        error_states=[0, 1],
        W=1.0,
        error_model=error_model,
    )
    with pytest.raises(ValueError, match=r"not all observable.*" + named):
        mme.fit(y, t)


@pytest.mark.parametrize("noise_variance", [1e-12, 1e-2, 1.0, 1e8])
@pytest.mark.parametrize("rate", [0.0, 60.0])
def test_unobservable_direction_is_found_at_any_noise_level(noise_variance, rate):
    """y sees only x0 + x1 of x' = rate x + d: x0(0) - x1(0) is undetermined.

    In floating point the KKT pivot of that direction is rounding (~1e-16
    relative), not zero, and a tiny W gives well-posed problems pivots as
    small; the observability of the linearisation settles it (at 1.0 the
    old pivot test let this through silently). With ``rate = 60`` the
    transition matrices grow 4.5-fold per step (1e260 over 400 steps): they
    are renormalised, so the direction is still named.
    """
    t = np.arange(1000) * 0.025
    y = np.sqrt(noise_variance) * (
        10 * np.sin(t)[:, None] + np.random.default_rng(0).standard_normal((t.size, 1))
    )
    mme = MME(
        lambda x, t: rate * x,
        2,
        measurement_matrix=[[1.0, 1.0]],
        noise_variance=noise_variance,
        error_states=[0, 1],
        W=1.0 / noise_variance,
    )
    with pytest.raises(ValueError, match=r"not all observable.*\[\+1 x0 -1 x1\]"):
        mme.fit(y, t)


def test_weakly_determined_problem_is_not_declared_singular(monkeypatch):
    """At W = 1e-12 times the reference (the bottom of the W search) the
    unmeasured velocity is nearly free and the KKT pivots span ~17 decades,
    like a singular problem's: the observability check must be consulted
    and clear it; the estimate then follows the data."""
    checks = []
    original = MMESmoother._unobservable_directions

    def spy(self, lin, *args):
        checks.append(original(self, lin, *args))
        return checks[-1]

    monkeypatch.setattr(MMESmoother, "_unobservable_directions", spy)
    m = van_der_pol().measure(0)
    mme = MME(
        lambda x, t: np.column_stack([x[:, 1], np.zeros(len(x))]),
        2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
        W=0.025 / 0.01 * 1e-12,
    ).fit(m.y, m.t)
    assert checks and all(c == [] for c in checks)  # consulted, found none
    assert mme.converged_
    assert np.all(np.isfinite(mme.smoothed_x_))
    np.testing.assert_allclose(mme.smoothed_x_[:, 0], m.y[:, 0], atol=1e-4)


def test_stiff_equation_does_not_hide_the_coupling_of_another():
    """x1' = x2, x2' = -1e11 x1 (a model in the wrong units): df1/dx2 = 1 is
    tiny next to 1e11, but only relative to another equation; x2 drives the
    measured x1 and is observable."""
    model = ModelFunction(lambda x, t: np.column_stack([x[:, 1], -1e11 * x[:, 0]]), 2)
    x = np.random.default_rng(0).standard_normal((50, 2))
    t = np.arange(50) * 0.025
    assert unobservable_states(model, x, t, None, np.array([[True, False]])) == []
    # and a state that drives nothing measured is still found
    model3 = ModelFunction(
        lambda x, t: np.column_stack([x[:, 1], -1e11 * x[:, 0], 1e-12 * x[:, 2]]), 3
    )
    x3 = np.random.default_rng(1).standard_normal((50, 3))
    assert unobservable_states(model3, x3, t, None, np.array([[1, 0, 0]])) == [2]
