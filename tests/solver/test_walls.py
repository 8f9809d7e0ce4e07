"""Walls: an overflow term in its own state's equation, bounded at -WALL_DECAY/dt.

The cascaded tanks' truth (machines.py) clamps the upper tank at its rim and
routes the excess into the lower tank. With the square-root model's own
outflows known, an output-error fit of ``over(h1, 10)`` in ``h1'`` (a wall)
and in ``h2'`` (the route) from the clamp must end on the wall limit, held
there like a parameter on a bound, with the route taking the machine's
fraction of the excess. A soft weir (a simulated tank whose outflow over the
weir is proportional to the height above it) keeps its finite coefficient.
"""

import numpy as np
import pytest

from pysindy_mme.core.integrate import InputSignal, simulate
from pysindy_mme.feature_library import Overflow, PhysicsLibrary
from pysindy_mme.machines import cascaded_tanks
from pysindy_mme.solver.output_error import WALL_DECAY, OutputErrorModel

K1, K2, KP = 0.1, 0.09, 0.036


class Columns:
    """``over(h1, 10)``: values, gradient and the overflow declaration."""

    def __init__(self):
        self.lib = PhysicsLibrary([Overflow("h1", [10.0])], names=["h1", "h2", "u"])
        self.lib.fit(np.ones((4, 3)))

    def __call__(self, z, columns):
        return self.lib.evaluate(z, columns, exact=True)

    def gradient(self, z, columns):
        return self.lib.gradient(z, columns, exact=True)

    def overflow_columns(self):
        return self.lib.overflow_columns()


def sqrt_tanks(x, t, u, p):
    o1 = K1 * np.sqrt(np.maximum(x[:, 0], 0.0))
    o2 = K2 * np.sqrt(np.maximum(x[:, 1], 0.0))
    return np.column_stack([-o1 + KP * u[:, 0], o1 - o2])


def engine_for(t, y, u):
    return OutputErrorModel(
        sqrt_tanks,
        2,
        Columns(),
        y,
        t,
        InputSignal(u, t, "zoh"),
        np.array([[0.02**2]]),
        np.array([[0.0, 1.0]]),
        n_substeps=8,
    )


SLOTS = [(0, 0), (1, 0)]  # over(h1, 10) in h1' (the wall) and in h2' (the route)


@pytest.mark.parametrize("fraction", [1.0, 0.5])
def test_a_rim_ends_on_the_wall_limit_with_the_machines_fraction(fraction):
    # pump never below 4 V: the upper tank never empties (sqrt has no slope
    # at 0, where Gauss-Newton cannot close the defects to 1e-6)
    m = cascaded_tanks(assumed="sqrt", overflow_fraction=fraction, duration=2048.0)
    rec = next(
        r
        for r in (
            m.record(s, sensor_range=(-100.0, 100.0), u_range=(4.0, 10.0))
            for s in range(20)
        )
        if np.mean(r.x[:, 0] >= 10.0) > 0.05
    )
    engine = engine_for(rec.t, rec.y, rec.u)
    limit = engine.wall_limit
    assert limit == pytest.approx(WALL_DECAY / 4.0)  # 0.25 Hz
    fit = engine.fit(SLOTS, [-limit, 0.5 * limit], rec.x, max_iter=50)
    assert fit.joined and fit.converged
    assert fit.at_wall.tolist() == [True, False]
    assert fit.held.tolist() == [True, False]
    assert fit.n_free == 2 + 1  # the initial state and the route
    wall, route = fit.coefficients
    assert wall == -limit
    assert route / limit == pytest.approx(fraction, abs=0.05)
    se = fit.std_errors
    assert np.isnan(se[0]) and 0 < se[1] < 0.05 * route
    # the machine's own trajectory: noise-level residuals (no misfit left)
    assert fit.residual_variance == pytest.approx(1.0, abs=0.15)


def test_a_soft_weir_keeps_its_coefficient():
    """Flow over a weir ``c max(h1 - 10, 0)`` (c = 0.02/s, all of it into the
    lower tank), simulated by plain RK4 of the whole right-hand side."""
    c = 0.02
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 2048.0, 4.0)
    u = np.repeat(rng.uniform(6.0, 10.0, t.size // 50 + 1), 50)[: t.size, None]

    def rhs(x, s, uu):
        e = np.maximum(x[:, 0] - 10.0, 0.0)
        out = sqrt_tanks(x, s, np.broadcast_to(uu, (len(x), 1)), None)
        return out + np.column_stack([-c * e, c * e])

    run = simulate(rhs, np.array([9.0, 8.0]), t, InputSignal(u, t, "zoh"), 40)
    x = run.x[0]
    assert np.mean(x[:, 0] > 10.5) > 0.2  # the weir is busy
    y = x[:, [1]] + 0.02 * rng.standard_normal((t.size, 1))
    engine = engine_for(t, y, u)
    fit = engine.fit(SLOTS, [-0.05, 0.05], x, max_iter=50)
    assert fit.joined and fit.converged
    assert not fit.at_wall.any()
    np.testing.assert_allclose(fit.coefficients, [-c, c], rtol=0.1)
