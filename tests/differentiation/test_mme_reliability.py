"""MME reliability: determinism, no mutation, units far from one, and failures
during a computation that end in a clear exception or a warning plus a flag
on the result, never in a hang or a silent wrong answer.
"""

from __future__ import annotations

import random

import numpy as np
import pytest
from paper_case import DATA as _DATA
from paper_case import VDP, T, Y
from paper_case import paper_mme as _mme
from paper_case import paper_mme_fit as _mme_fit
from reliability_support import (
    assert_same_global_random_state,
    global_random_state,
    readonly,
)
from sklearn.exceptions import ConvergenceWarning

from pysindy_mme import MME
from pysindy_mme.exceptions import DivergenceError
from pysindy_mme.systems import lotka_volterra


def _mme_outputs(m):
    return [
        m.smoothed_x_,
        m.d_,
        m.d_intervals_,
        m.derivative_,
        m.residuals_,
        np.atleast_1d(m.W_),
        m.covariance_ratio_,
        np.atleast_1d(m.cost_),
    ]


# ---------------------------------------------------------------- determinism


def test_mme_is_deterministic_pure_and_leaves_inputs_alone():
    np.random.seed(1234)  # noqa: NPY002 - a known global state to compare
    random.seed(1234)
    before = global_random_state()
    y, t = readonly(Y), readonly(T)
    a = _mme_fit(y, t)
    b = _mme_fit(y, t)
    for u, v in zip(_mme_outputs(a), _mme_outputs(b)):
        np.testing.assert_array_equal(u, v)  # bit for bit
    assert_same_global_random_state(before)
    np.testing.assert_array_equal(y, _DATA.y)
    np.testing.assert_array_equal(t, _DATA.t)
    # Nonlinear model, both states measured, missing samples.
    system = lotka_volterra()
    data = system.measure(1)
    y2 = readonly(np.where(np.arange(data.t.size)[:, None] % 7 == 3, np.nan, data.y))
    args = dict(measured=[0, 1], noise_variance=0.01, error_states=[1])
    c = MME(system.assumed_model, 2, **args).fit(y2, readonly(data.t))
    d = MME(system.assumed_model, 2, **args).fit(y2, readonly(data.t))
    for u, v in zip(_mme_outputs(c), _mme_outputs(d)):
        np.testing.assert_array_equal(u, v)
    assert_same_global_random_state(before)


def test_mme_refit_of_the_same_estimator_is_bit_identical():
    fresh = _mme_fit()
    reused = _mme()
    reused.fit(Y[:200], T[:200])  # another record first
    reused.fit(Y, T)
    for u, v in zip(_mme_outputs(fresh), _mme_outputs(reused)):
        np.testing.assert_array_equal(u, v)


# ---------------------------------------------------------------------- units


@pytest.mark.parametrize("unit", [1e-9, 1e10])
def test_mme_units_far_from_one(unit):
    base = _mme_fit()
    scaled = _mme_fit(Y * unit, T, noise_variance=0.01 * unit**2)
    np.testing.assert_allclose(scaled.smoothed_x_ / unit, base.smoothed_x_, atol=1e-6)


# ----------------------------------------------- failures mid-computation


def test_mme_not_converging_warns_and_flags():
    system = lotka_volterra()
    data = system.measure(0)
    mme = MME(
        system.assumed_model,
        2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
        W=10.0,
        max_iter=1,
    )
    with pytest.warns(ConvergenceWarning, match="Gauss-Newton did not converge"):
        mme.fit(data.y[:, [0]], data.t)
    assert mme.converged_ is False
    assert mme.n_iter_ == 1
    assert np.all(np.isfinite(mme.smoothed_x_))  # the last iterate, flagged


def test_mme_exploding_model_is_a_clear_error():
    """x' = x^3 from x ~ 10 leaves the double range within one 25 ms step."""
    t = np.arange(0, 2, 0.025)
    y = 10.0 + 0.1 * np.random.default_rng(0).standard_normal(t.size)
    with pytest.raises(DivergenceError, match="blows up within one sample interval"):
        MME(lambda x, t: x**3, 1, noise_variance=0.01).fit(y, t)
    assert issubclass(DivergenceError, FloatingPointError)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_mme_model_with_finite_time_blowup_is_a_divergence_error():
    with pytest.raises(DivergenceError, match="unstable|blows up"):
        _mme_fit(
            assumed_model=lambda x, t: np.column_stack([x[:, 1], 50 * x[:, 1] ** 3])
        )


def test_mme_stiff_model_in_wrong_units_is_named():
    with pytest.raises(DivergenceError, match="blows up within one sample interval"):
        _mme_fit(assumed_model=lambda x, t: np.column_stack([x[:, 1], -1e11 * x[:, 0]]))


class _Interrupt:
    """A model that raises KeyboardInterrupt after ``calls`` evaluations."""

    def __init__(self, calls):
        self.left = calls

    def __call__(self, x, t):
        self.left -= 1
        if self.left < 0:
            raise KeyboardInterrupt
        return VDP.assumed_model(x, t)


@pytest.mark.parametrize("calls", [0, 5, 200])
def test_mme_can_be_interrupted(calls):
    """Ctrl-C inside the user's model reaches the user, at any stage (first
    evaluation, W search), and is never turned into another error. (discover:
    ``tests/discovery/test_study_reliability.py``.)"""
    with pytest.raises(KeyboardInterrupt):
        _mme_fit(assumed_model=_Interrupt(calls))
