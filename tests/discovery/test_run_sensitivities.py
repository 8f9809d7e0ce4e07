"""The free run's exact sensitivities the trade-off analysis reads.

``identifiability._run_sensitivities`` chains the RK4 map's own derivatives
over the intervals by one banded solve; here it is checked against central
differences of independent sequential free runs (``simulate``), for initial
states, grey-box parameters and correction coefficients, with inputs, and
for overflow terms solved apart from RK4 (their coefficients' sensitivities
come from the split).
"""

import numpy as np
import pytest

from pysindy_mme.core.integrate import InputSignal, simulate
from pysindy_mme.core.model import ParametricModel
from pysindy_mme.discovery.identifiability import (
    GROWTH_LIMIT,
    _run_sensitivities,
    exact_trade_offs,
)
from pysindy_mme.feature_library import Overflow, PhysicsLibrary, Torricelli
from pysindy_mme.solver.output_error import OutputErrorModel


def _free_run(model, theta, x0, t, inputs, substeps):
    def rows(X, s, u):
        uu = None if u is None else np.broadcast_to(u, (X.shape[0], u.shape[-1]))
        return model(X, np.full(X.shape[0], s), uu, theta)

    return simulate(rows, x0, t, inputs, substeps, split=model.split_at(theta)).x[0]


def _central(model, theta, n_dyn, x0, t, inputs, substeps, step=1e-6):
    n = x0.size
    q0 = np.concatenate([x0, theta[:n_dyn]])
    cols = []
    for j in range(q0.size):
        e = step * max(abs(q0[j]), 1.0)
        up, down = q0.copy(), q0.copy()
        up[j] += e
        down[j] -= e
        runs = []
        for q in (up, down):
            th = theta.copy()
            th[:n_dyn] = q[n:]
            runs.append(_free_run(model, th, q[:n], t, inputs, substeps))
        cols.append((runs[0] - runs[1]) / (2 * e))
    return np.stack(cols, axis=2)


def _forced_duffing():
    """x1' = x2, x2' = -p0 x1 - p1 x2 + u + c x1^3 (the cubic a correction)."""

    def base(x, t, u, p):
        return np.column_stack([x[:, 1], -p[0] * x[:, 0] - p[1] * x[:, 1] + u[:, 0]])

    def features(z, columns):
        return np.column_stack([z[:, 0] ** 3][: len(columns)])

    model = ParametricModel(base, 2, 2, features, [(1, 0)])
    return model, np.array([1.0, 0.3, -0.8])


@pytest.mark.parametrize("hold", ["linear", "cubic"])
def test_sensitivities_equal_central_differences_of_free_runs(hold):
    model, theta = _forced_duffing()
    t = np.arange(401) * 0.05
    inputs = InputSignal(np.sin(0.9 * t), t, hold=hold)
    x0 = np.array([0.7, -0.2])
    x = _free_run(model, theta, x0, t, inputs, 2)
    S, _ = _run_sensitivities(model, theta, 3, x, t, inputs, 2)
    ref = _central(model, theta, 3, x0, t, inputs, 2)
    assert S.shape == (t.size, 2, 5)
    np.testing.assert_allclose(S[0], np.hstack([np.eye(2), np.zeros((2, 3))]))
    scale = np.max(np.abs(ref), axis=(0, 1))
    np.testing.assert_allclose(S / scale, ref / scale, rtol=0, atol=1e-6)


def test_sensitivities_through_overflow_terms_solved_apart():
    # h1' = 0.5 u - a sqrt(h1) + b over(h1, 3); h2' = a sqrt(h1) - 0.1 h2:
    # the tank fills past its rim, where the overflow's coefficient acts
    lib = PhysicsLibrary(
        [Torricelli("h1"), Overflow("h1", [3.0])], names=["h1", "h2", "u"]
    ).fit(np.ones((4, 3)))

    def base(x, t, u, p):
        return np.column_stack([0.5 * u[:, 0], -0.1 * x[:, 1]])

    def features(z, columns):
        return lib.evaluate(z, columns, exact=True)

    features.overflow_columns = lib.overflow_columns
    model = ParametricModel(base, 2, 0, features, [(0, 0), (1, 0), (0, 1)])
    assert model.overflows.positions == {2}
    theta = np.array([-0.2, 0.2, -2.0])
    t = np.arange(301) * 0.1
    inputs = InputSignal(np.ones(t.size), t)
    x0 = np.array([2.5, 1.0])
    x = _free_run(model, theta, x0, t, inputs, 2)
    assert x[:, 0].max() > 3.0  # over the rim: the overflow term acts
    S, _ = _run_sensitivities(model, theta, 3, x, t, inputs, 2)
    ref = _central(model, theta, 3, x0, t, inputs, 2)
    scale = np.max(np.abs(ref), axis=(0, 1))
    np.testing.assert_allclose(S / scale, ref / scale, rtol=0, atol=1e-5)


def _growing_product_model():
    """``x' = a b x`` with ``a`` and ``b`` grey-box parameters: only the product
    is determined, and the run grows as ``e^(a b t)``."""

    def base(x, t, u, p):
        return p[0] * p[1] * x

    t = np.linspace(0.0, 12.0, 481)
    rng = np.random.default_rng(5)
    y = 1e-3 * np.exp(t)[:, None] + 0.01 * rng.standard_normal((t.size, 1))
    engine = OutputErrorModel(
        base, 1, None, y, t, None, np.array([[1e-4]]), np.eye(1), n_physical=2
    )
    fit = engine.fit((), np.array([1.25, 0.8]), np.exp(t)[:, None] * 1e-3)
    return engine, fit


def test_the_growth_is_that_of_the_run_and_an_exact_trade_off_survives_the_cut():
    # the run amplifies a change of x(0) by e^12, past GROWTH_LIMIT at t = ln
    # 1e3 = 6.9: the check reads the run up to there, and the product a b is
    # still the only combination the data determine
    engine, fit = _growing_product_model()
    model = ParametricModel(engine.base, 1, 2)
    x = fit.x
    _, growth = _run_sensitivities(
        model, fit.theta, 2, x, engine.t, engine.inputs, engine.n_substeps
    )
    rate = float(np.prod(fit.theta))
    np.testing.assert_allclose(growth, np.exp(rate * engine.t), rtol=1e-6)
    assert growth[-1] > 100 * GROWTH_LIMIT
    (trade,) = exact_trade_offs(engine, fit, ["a", "b"], ["x"])
    assert set(trade.names) == {"a", "b"}
    assert trade.determined == ["a*b"] or trade.determined == ["b*a"]
