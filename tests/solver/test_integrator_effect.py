"""How far a fit would move with twice the RK4 steps (``integrator_effect``).

Against a second method, the refit with twice the steps; and, at a step far
inside RK4's accuracy, the two integrators agree to rounding and the answer
is exactly no move, found without the KKT system.
"""

import numpy as np

from pysindy_mme.solver.output_error import OutputErrorModel
from pysindy_mme.systems import van_der_pol

SLOTS = [(1, 1), (1, 2), (1, 7)]  # x1, x2, x1^2 x2 in x2'


def _features(z, cols):
    x1, x2 = z[:, 0], z[:, 1]
    library = {1: x1, 2: x2, 7: x1**2 * x2}
    return np.column_stack([library[c] for c in cols])


def _ignorance(x, t, u, p):
    return np.column_stack([x[:, 1], np.zeros(len(x))])


def _fit(seconds, rate):
    system = van_der_pol()
    t = system.time(seconds, rate)
    data = system.measure(3, t=t)
    engine = OutputErrorModel(
        _ignorance, 2, _features, data.y, data.t, None, np.eye(1) * 0.01, np.eye(2)[:1]
    )
    fit = engine.fit(SLOTS, np.array([-1.0, 1.0, -1.0]), data.x, tol=1e-12)
    assert fit.converged
    return engine, fit


def test_the_prediction_matches_a_refit_with_twice_the_steps():
    # 20 Hz: RK4's error is visible (a move of 1e-6), small enough for the
    # linearised prediction to be within its second-order error (5 %)
    engine, fit = _fit(20, 20)
    dtheta, change = engine.integrator_effect(fit)
    finer = engine.with_substeps(2 * engine.n_substeps)
    refit = finer.fit(fit.slots, fit.theta, fit.x, tol=1e-12)
    moved = refit.theta - fit.theta
    assert change > 0 and np.all(np.abs(moved) > 5e-7)
    np.testing.assert_allclose(dtheta, moved, rtol=0.1)


def test_no_move_at_a_step_far_inside_rk4s_accuracy(monkeypatch):
    engine, fit = _fit(2, 20_000)

    def no_kkt(fit):
        raise AssertionError("the KKT system is not needed for no change")

    monkeypatch.setattr(engine, "_kkt_at", no_kkt)
    dtheta, change = engine.integrator_effect(fit)
    assert change == 0.0
    np.testing.assert_array_equal(dtheta, 0.0)
