"""A solve that ends at its last linearisation (a linear problem's exact
step) reads the residuals and defects from it instead of integrating the
record again: the same numbers, to the last bit, as recomputing them."""

import dataclasses

import numpy as np
import pytest

from pysindy_mme import MME
from pysindy_mme.solver.gauss_newton import GaussNewton
from pysindy_mme.solver.output_error import OutputErrorModel


def _linear_output_error():
    """x' = c1 u1 + c2 u2 with linearly interpolated inputs: a linear problem."""
    rng = np.random.default_rng(4)
    t = np.linspace(0.0, 6.0, 401)
    u = np.column_stack([np.sin(1.3 * t), np.cos(0.7 * t + 0.4)])
    x = 0.3 + np.concatenate([[0.0], np.cumsum(np.diff(t) * (u[1:, 0] + u[:-1, 0]))])
    y = (x + 0.05 * rng.standard_normal(t.size))[:, None]

    def base(z, tt, uu, p):
        return np.zeros_like(z)

    def features(z, cols):
        return z[:, 1:][:, list(cols)]

    engine = OutputErrorModel(base, 1, features, y, t, u, np.eye(1) * 0.0025, np.eye(1))
    fit = engine.fit([(0, 0), (0, 1)], np.zeros(2), np.zeros((t.size, 1)))
    return (fit.cost, fit.theta, fit.x, fit.converged, fit.joined)


def _linear_mme():
    """MME of a double integrator (x1' = x2, x2' = d) from noisy x1."""
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 8.0, 0.025)
    y = np.sin(t) + 0.1 * rng.standard_normal(t.size)
    mme = MME(
        lambda x, tt: np.column_stack([x[:, 1], 0.0 * x[:, 0]]),
        2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
    ).fit(y, t)
    return (
        mme.smoothed_x_,
        mme.d_,
        mme.residuals_,
        mme.cost_,
        mme.max_defect_,
        mme.log_likelihood_,
    )


def _run(make, recompute, monkeypatch):
    original = GaussNewton._result
    reused = []

    def result(self, W, x, d, theta, lam, lin, *rest):
        reused.append(lin.x is x and lin.d is d and lin.theta is theta)
        if recompute:  # a linearisation that is not at x: integrate again
            lin = dataclasses.replace(lin, x=lin.x.copy())
        return original(self, W, x, d, theta, lam, lin, *rest)

    monkeypatch.setattr(GaussNewton, "_result", result)
    out = make()
    monkeypatch.setattr(GaussNewton, "_result", original)
    return out, reused


@pytest.mark.parametrize("make", [_linear_output_error, _linear_mme])
def test_reusing_the_last_linearisation_changes_no_number(make, monkeypatch):
    fast, reused = _run(make, False, monkeypatch)
    slow, _ = _run(make, True, monkeypatch)
    assert any(reused)  # the case exercises the reuse
    for a, b in zip(fast, slow):
        np.testing.assert_array_equal(a, b)
