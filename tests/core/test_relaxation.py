"""Overflow terms solved exactly around RK4 (core/relaxation.py).

References: the closed form of a linear relaxation above a level, central
differences of the split map, a fine RK4 of the whole right-hand side, and
the cascaded tanks' own clamp (machines.py, written independently).
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pysindy_mme.core.integrate import InputSignal, rk4_flow, simulate
from pysindy_mme.core.model import ParametricModel
from pysindy_mme.core.relaxation import Overflows
from pysindy_mme.feature_library import Overflow, PhysicsLibrary, Torricelli

# one state h (column 0 over level 1), a second state g fed by the overflow;
# slots: (0, col 0) relaxation a, (1, col 0) route c
COLUMNS = {0: (0, 1.0)}
SLOTS = [(0, 0), (1, 0)]


def test_the_step_is_the_closed_form_of_the_relaxation():
    over = Overflows(SLOTS, COLUMNS, 2)
    a, c, h = -3.0, 0.7, 0.4
    X = np.array([[1.5, 2.0], [0.5, 2.0]])  # above and below the level
    out, _ = over.step(X, h, np.array([a, c]))
    e0 = 0.5
    assert out[0, 0] == pytest.approx(1.0 + e0 * np.exp(a * h), rel=1e-14)
    # g' = c e(t): g gains c e0 (exp(a h) - 1) / a
    assert out[0, 1] == pytest.approx(2.0 + c * e0 * np.expm1(a * h) / a, rel=1e-14)
    np.testing.assert_array_equal(out[1], X[1])  # below the level: untouched
    np.testing.assert_array_equal(X, [[1.5, 2.0], [0.5, 2.0]])  # not in place


def test_an_infinitely_stiff_wall_is_a_clamp_with_the_excess_routed():
    over = Overflows(SLOTS, COLUMNS, 2)
    out, _ = over.step(np.array([[1.8, 0.0]]), 1.0, np.array([-1e4, 1e4]))
    np.testing.assert_allclose(out, [[1.0, 0.8]], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("a", [-2.0, -1e-7, 0.0, 0.3])
def test_the_derivatives_are_those_of_the_map(a):
    """D update against central differences in the start and both coefficients."""
    over = Overflows(SLOTS, COLUMNS, 2)
    h = np.array([[0.3], [0.3]])
    X = np.array([[1.4, 0.2], [1.05, -1.0]])
    coefs = np.array([a, 0.6])

    def run(x, cf):
        return over.step(x, h, cf)[0]

    D0 = np.zeros((2, 2, 4))
    D0[:, :, :2] = np.eye(2)
    _, D = over.step(X, h, coefs, D0, column_of=lambda k: 2 + k)
    eps = 1e-6
    for j in range(2):
        dx = np.zeros(2)
        dx[j] = eps
        fd = (run(X + dx, coefs) - run(X - dx, coefs)) / (2 * eps)
        np.testing.assert_allclose(D[:, :, j], fd, rtol=1e-7, atol=1e-9)
    for k in range(2):
        dc = np.zeros(2)
        dc[k] = eps
        fd = (run(X, coefs + dc) - run(X, coefs - dc)) / (2 * eps)
        np.testing.assert_allclose(D[:, :, 2 + k], fd, rtol=1e-6, atol=1e-9)


def _library():
    lib = PhysicsLibrary(
        [Torricelli("h1"), Overflow("h1", [3.0])], names=["h1", "h2", "u"]
    )
    return lib.fit(np.ones((4, 3)))


def _tank_model(a, c):
    """h1' = 0.5 u - 0.2 sqrt(h1) + a over(h1, 3); h2' = 0.2 sqrt(h1) - 0.1 h2
    + c over(h1, 3); the Torricelli term and the overflow as correction terms."""
    lib = _library()

    def base(x, t, u, p):
        return np.column_stack([0.5 * u[:, 0], -0.1 * x[:, 1]])

    def features(z, columns):
        return lib.evaluate(z, columns, exact=True)

    features.overflow_columns = lib.overflow_columns
    slots = [(0, 0), (1, 0), (0, 1), (1, 1)]
    model = ParametricModel(base, 2, 0, features, slots)
    return model, np.array([-0.2, 0.2, a, c])


def test_the_model_takes_its_overflow_terms_out_of_the_right_hand_side():
    model, theta = _tank_model(-5.0, 5.0)
    assert model.overflows.positions == {2, 3}
    x = np.array([[4.0, 1.0]])
    u = np.array([[1.0]])
    rhs = model(x, np.zeros(1), u, theta)
    np.testing.assert_allclose(rhs, [[0.5 - 0.4, 0.4 - 0.1]])
    # their parameter derivatives come from the split, not the right-hand side
    assert not model.param_jacobian(x, np.zeros(1), u, theta)[:, :, 2:].any()


def _reference(a, c, x0, T, u=1.0):
    """The whole right-hand side, by an adaptive stiff solver at tight tolerances."""

    def f(t, x):
        e = max(x[0] - 3.0, 0.0)
        s = 0.2 * np.sqrt(max(x[0], 0.0))
        return [0.5 * u - s + a * e, s - 0.1 * x[1] + c * e]

    sol = solve_ivp(f, (0, T), x0, method="Radau", rtol=1e-11, atol=1e-12)
    return sol.y[:, -1]


@pytest.mark.parametrize("a", [-0.5, -50.0, -5000.0])
def test_the_split_flow_converges_to_the_whole_model(a):
    """Strang splitting: second order for a soft wall; for a stiff one first
    order while the wall holds the state at the level (the outflow is then
    evaluated above it within each step), and stable at any stiffness,
    where plain RK4 on the whole right-hand side is not."""
    model, theta = _tank_model(a, -a)
    x0 = np.array([[2.9, 1.0]])
    T = 6.0
    ref = _reference(a, -a, x0[0], T)
    inputs = InputSignal(np.ones((2, 1)), np.array([0.0, T]), "zoh")

    def end_state(m, n):
        """One interval of ``n`` RK4 steps of model ``m`` (its split, if any)."""
        return rk4_flow(
            lambda X, s, u: m(X, s, u, theta),
            x0,
            np.zeros(1),
            np.array([T]),
            lambda frac: inputs.on_intervals(frac, slice(0, 1)),
            n,
            split=m.split_at(theta),
        ).phi[0]

    errors = [float(np.max(np.abs(end_state(model, n) - ref))) for n in (50, 100, 200)]
    if a == -0.5:
        assert errors[-1] < 1e-5
        assert errors[0] / errors[1] > 3.5  # second order (4 in the limit)
    else:
        assert errors[-1] < 1e-3
        assert errors[0] / errors[1] > 1.8 and errors[1] / errors[2] > 1.8
    # plain RK4 on the whole right-hand side at 50 steps: unstable when stiff
    if a != -0.5:
        full = ParametricModel(
            model.base,
            2,
            0,
            lambda z, c: _library().evaluate(z, c, exact=True),
            model.slots,
        )
        assert not full.overflows and full.split_at(theta) is None
        assert not np.all(np.abs(end_state(full, 50) - ref) < 1e-2)


def test_the_flow_derivatives_with_the_split_are_those_of_the_map():
    """rk4_flow's D (state and coefficients) against central differences."""
    model, theta = _tank_model(-4.0, 3.0)
    x0 = np.array([[2.95, 1.0], [3.3, 0.5], [1.0, 2.0]])
    K = len(x0)
    t0, h = np.zeros(K), np.full(K, 2.0)
    u = np.ones((K, 1))

    def flow(x, th, jac=False):
        return rk4_flow(
            lambda X, s, uu: model(X, s, uu, th),
            x,
            t0,
            h,
            lambda frac: u,
            8,
            jac_x=(lambda X, s, uu: model.jacobian(X, s, uu, th)) if jac else None,
            jac_p=(lambda X, s, uu: model.param_jacobian(X, s, uu, th)),
            n_params=4,
            split=model.split_at(th, 2 if jac else None),
        )

    D = flow(x0, theta, jac=True).D
    eps = 1e-6
    for j in range(2):
        dx = np.zeros(2)
        dx[j] = eps
        fd = (flow(x0 + dx, theta).phi - flow(x0 - dx, theta).phi) / (2 * eps)
        np.testing.assert_allclose(D[:, :, j], fd, rtol=1e-5, atol=1e-7)
    for k in range(4):
        dth = np.zeros(4)
        dth[k] = eps
        fd = (flow(x0, theta + dth).phi - flow(x0, theta - dth).phi) / (2 * eps)
        np.testing.assert_allclose(D[:, :, 2 + k], fd, rtol=1e-5, atol=1e-7)


def test_a_stiff_wall_reproduces_the_machines_clamp():
    """The cascaded tanks' truth clamps h1 at the rim and routes the excess
    (machines.py, its own RK4 and projection); an overflow term with a very
    stiff wall and full routing, solved by the split, gives the same run."""
    from pysindy_mme.machines import cascaded_tanks

    m = cascaded_tanks(assumed="linear", duration=1200.0)
    rec = next(r for r in map(m.record, range(20)) if r.x[:, 0].max() >= 10.0)
    k1, k2, kp, rim = (m.true_parameters[k] for k in ("k1", "k2", "kp", "h_max"))
    lib = PhysicsLibrary(
        [Torricelli("h1"), Torricelli("h2"), Overflow("h1", [rim])],
        names=["h1", "h2", "u"],
    ).fit(np.ones((4, 3)))
    coef = {(0, 0): -k1, (1, 0): k1, (1, 1): -k2, (0, 2): -1e6, (1, 2): 1e6}

    class Rates:
        def __init__(self):
            over = Overflows(list(coef), lib.overflow_columns(), 2)
            self.split = over.bound(np.array(list(coef.values())))
            self.smooth = [s for k, s in enumerate(coef) if k not in over.positions]

        def __call__(self, x, s, u):
            z = np.hstack([x, np.broadcast_to(np.ravel(u), (len(x), 1))])
            cols = lib.evaluate(z, exact=True)
            out = np.zeros_like(x)
            out[:, 0] += kp * float(np.ravel(u)[0])
            for i, c in self.smooth:
                out[:, i] += coef[(i, c)] * cols[:, c]
            return out

    inputs = InputSignal(rec.u, rec.t, "zoh")
    run = simulate(Rates(), rec.x[0], rec.t, inputs, substeps=20)
    assert run.ok[0]
    assert rec.x[:, 0].max() == pytest.approx(rim)  # the record reaches the rim
    np.testing.assert_allclose(run.x[0], rec.x, atol=2e-3)
