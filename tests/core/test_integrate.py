"""The one integrator (``core/integrate.py``) against independent references.

* :class:`InputSignal`: every hold against its definition (linear
  interpolation, the held sample, Catmull-Rom cubic: exact for quadratics on
  interior intervals, third order for smooth signals), a callable exactly.
* :func:`rk4_flow`: fourth-order convergence to ``solve_ivp`` at tight
  tolerance, and its derivatives ``dPhi/dx``, ``dPhi/dp`` against central
  finite differences of the discrete map itself.
* :func:`simulate`: closed forms, the exact zero-order-hold recursion of a
  linear system, the same one-step map as :func:`rk4_flow` for every hold,
  and blow-up reported per trajectory (``diverged_at``) without an exception.
* :func:`simulate_guided`: the same trajectory as :func:`simulate`, from a
  poor guess, with inputs, and for a model that blows up; past a stretch of
  the guess where Newton cannot converge over the whole record, with the
  sequential loop confined to a short stretch; a blow-up late in a record
  reported at the sample :func:`simulate` reports it.
"""

import numpy as np
import pytest
from extended_case import vdp_extended_model
from scipy.integrate import solve_ivp

from pysindy_mme.core.integrate import (
    GUIDED_MIN_BLOCK,
    InputSignal,
    rk4_flow,
    simulate,
    simulate_guided,
    solve_recursion,
)

# ------------------------------------------------------------- InputSignal


def _grid(n=41, h=0.1):
    return np.arange(n) * h


@pytest.mark.parametrize("frac", [0.0, 0.25, 0.5, 1.0])
def test_linear_hold_interpolates_linearly(frac):
    t = _grid()
    u = np.column_stack([np.sin(t), t**2])
    sig = InputSignal(u, t, hold="linear")
    expected = (1 - frac) * u[:-1] + frac * u[1:]
    np.testing.assert_allclose(sig.on_intervals(frac), expected, rtol=0, atol=1e-15)
    s = t[:-1] + frac * np.diff(t)
    np.testing.assert_allclose(sig.at(s), expected, rtol=0, atol=1e-14)


@pytest.mark.parametrize("frac", [0.0, 0.3, 0.5, 1.0])
def test_zero_order_hold_keeps_the_sample_over_the_whole_interval(frac):
    """``u_k`` on ``[t_k, t_{k+1}]``, the right end included: the interval is
    integrated with the value that was held on it."""
    t = _grid()
    u = np.cos(3 * t)
    sig = InputSignal(u, t, hold="zoh")
    np.testing.assert_array_equal(sig.on_intervals(frac), u[:-1, None])
    if frac < 1:  # at a sample time, at() gives the sample taken then
        s = t[:-1] + frac * np.diff(t)
        np.testing.assert_array_equal(sig.at(s), u[:-1, None])
    np.testing.assert_array_equal(sig.at(t), u[:, None])


def test_cubic_hold_interpolates_and_is_exact_for_quadratics_inside():
    t = _grid(30, 0.2)
    u = 1.5 - 0.7 * t + 0.3 * t**2
    sig = InputSignal(u, t, hold="cubic")
    np.testing.assert_allclose(sig.on_intervals(0.0)[:, 0], u[:-1], atol=1e-13)
    np.testing.assert_allclose(sig.on_intervals(1.0)[:, 0], u[1:], atol=1e-13)
    for frac in (0.2, 0.5, 0.9):
        s = t[:-1] + frac * 0.2
        exact = 1.5 - 0.7 * s + 0.3 * s**2
        got = sig.on_intervals(frac)[:, 0]
        # Catmull-Rom's central-difference tangents are exact for a quadratic,
        # so the Hermite cubic is too, on every interval with two neighbours
        np.testing.assert_allclose(got[1:-1], exact[1:-1], rtol=0, atol=1e-12)
        # the end intervals reuse their end sample: not exact there
        assert abs(got[0] - exact[0]) > 1e-6


def test_cubic_hold_converges_at_third_order_linear_at_second():
    errors = {"cubic": [], "linear": []}
    for n in (41, 81, 161):
        t = np.linspace(0.0, 4.0, n)
        h = t[1] - t[0]
        u = np.sin(2 * t)
        exact = np.sin(2 * (t[:-1] + 0.5 * h))
        for hold in errors:
            got = InputSignal(u, t, hold=hold).on_intervals(0.5)[:, 0]
            errors[hold].append(np.max(np.abs(got - exact)[2:-2]))  # interior
    for hold, order in (("cubic", 3), ("linear", 2)):
        ratios = np.array(errors[hold][:-1]) / np.array(errors[hold][1:])
        assert np.all(ratios > 0.8 * 2**order), (hold, ratios)
    assert errors["cubic"][-1] < errors["linear"][-1] / 100


def test_cubic_hold_at_agrees_with_on_intervals():
    t = _grid()
    u = np.sin(t) + 0.1 * t**3
    sig = InputSignal(u, t, hold="cubic")
    s = t[:-1] + 0.5 * np.diff(t)
    np.testing.assert_allclose(sig.at(s), sig.on_intervals(0.5), rtol=1e-12)
    # at the samples it passes through them; beyond the ends it holds them
    np.testing.assert_allclose(sig.at(t)[:, 0], u, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(sig.at([t[0] - 1.0, t[-1] + 1.0])[:, 0], u[[0, -1]])
    q = t[:-1] + 0.25 * np.diff(t)
    np.testing.assert_allclose(sig.at(q), sig.on_intervals(0.25), rtol=1e-12)


def test_cubic_hold_reproduces_a_quadratic_between_interior_samples():
    # Catmull-Rom on a uniform grid is exact for quadratics (an independent
    # closed form); the end intervals reuse their end samples, so they are not.
    t = np.linspace(0.0, 2.0, 21)
    quad = 3.0 - 2.0 * t + 1.5 * t**2
    s = np.linspace(t[1], t[-2], 307)
    got = InputSignal(quad, t, hold="cubic").at(s)[:, 0]
    np.testing.assert_allclose(got, 3.0 - 2.0 * s + 1.5 * s**2, rtol=1e-12)


def test_callable_input_is_evaluated_exactly_on_any_grid():
    rng = np.random.default_rng(0)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.05, 0.15, 30))])

    def u(s):
        return np.column_stack([np.sin(s), s**3])

    sig = InputSignal(u, t, hold="zoh")  # the hold is ignored for a callable
    for frac in (0.0, 0.5, 1.0):
        s = t[:-1] + frac * np.diff(t)
        np.testing.assert_array_equal(sig.on_intervals(frac), u(s))
    np.testing.assert_array_equal(sig.grid(), u(t))
    np.testing.assert_array_equal(sig.at([0.37]), u(np.array([0.37])))


def test_subset_keeps_the_hold_and_the_samples():
    t = _grid()
    u = np.cos(t)
    sig = InputSignal(u, t, hold="cubic").subset(5, 20)
    assert sig.hold == "cubic"
    np.testing.assert_array_equal(sig.t, t[5:20])
    np.testing.assert_array_equal(sig.grid()[:, 0], u[5:20])
    assert InputSignal(None, t).subset(0, 3).is_none


def test_unknown_hold_names_the_option():
    with pytest.raises(
        ValueError, match="input_hold must be 'linear', 'zoh' or 'cubic'"
    ):
        InputSignal(np.zeros(5), _grid(5), hold="spline")


# ----------------------------------------------------------------- rk4_flow


def _duffing(p):
    """x1' = x2, x2' = -p0 x1 - p1 x2 - x1^3 + u, vectorised over rows."""

    def rhs(X, s, u):
        x1, x2 = X[:, 0], X[:, 1]
        force = 0.0 if u is None else u[:, 0]
        return np.column_stack([x2, -p[0] * x1 - p[1] * x2 - x1**3 + force])

    def jac_x(X, s, u):
        J = np.zeros((X.shape[0], 2, 2))
        J[:, 0, 1] = 1.0
        J[:, 1, 0] = -p[0] - 3 * X[:, 0] ** 2
        J[:, 1, 1] = -p[1]
        return J

    def jac_p(X, s, u):
        J = np.zeros((X.shape[0], 2, 2))
        J[:, 1, 0] = -X[:, 0]
        J[:, 1, 1] = -X[:, 1]
        return J

    return rhs, jac_x, jac_p


def _intervals(K=12, seed=0):
    rng = np.random.default_rng(seed)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.05, 0.2, K))])
    x = rng.uniform(-1.5, 1.5, (K, 2))
    return t, x


def test_rk4_flow_converges_at_fourth_order_to_solve_ivp():
    p = np.array([1.0, 0.1])
    rhs, _, _ = _duffing(p)
    t, x = _intervals()
    h = np.diff(t)
    sig = InputSignal(lambda s: np.sin(3 * s)[:, None], t)
    ref = np.array(
        [
            solve_ivp(
                lambda s, z: rhs(z[None], s, np.array([[np.sin(3 * s)]]))[0],
                (t[k], t[k + 1]),
                x[k],
                rtol=1e-13,
                atol=1e-13,
            ).y[:, -1]
            for k in range(len(h))
        ]
    )
    errors = []
    for substeps in (1, 2, 4, 8):
        phi = rk4_flow(rhs, x, t[:-1], h, sig.on_intervals, substeps).phi
        errors.append(np.max(np.abs(phi - ref)))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    # one step's error is O(h^5); halving h over the same span: about 16
    assert np.all(ratios > 12), ratios
    assert errors[-1] < 1e-6  # 8 steps of at most 0.024


@pytest.mark.parametrize("hold", ["linear", "zoh", "cubic"])
def test_rk4_flow_derivatives_match_finite_differences_of_the_map(hold):
    p = np.array([1.3, 0.2])
    rhs, jac_x, jac_p = _duffing(p)
    t, x = _intervals(K=9, seed=1)
    h = np.diff(t)
    sig = InputSignal(np.cos(2 * t), t, hold=hold)

    def phi(x, p):
        f = _duffing(p)[0]
        return rk4_flow(f, x, t[:-1], h, sig.on_intervals, substeps=3).phi

    res = rk4_flow(
        rhs, x, t[:-1], h, sig.on_intervals, 3, jac_x=jac_x, jac_p=jac_p, n_params=2
    )
    np.testing.assert_allclose(res.phi, phi(x, p), rtol=0, atol=1e-15)
    eps = 1e-6
    for j in range(2):
        step = np.zeros(2)
        step[j] = eps
        dx = (phi(x + step, p) - phi(x - step, p)) / (2 * eps)
        np.testing.assert_allclose(res.A(2)[:, :, j], dx, rtol=1e-7, atol=1e-8)
        dp = (phi(x, p + step) - phi(x, p - step)) / (2 * eps)
        np.testing.assert_allclose(res.B(2)[:, :, j], dp, rtol=1e-7, atol=1e-8)


def test_rk4_flow_derivatives_equal_the_textbook_variational_stages():
    # The derivative of the RK4 map written stage by stage as in a textbook
    # (every stage's derivative kept, summed at the end): rk4_flow sums them
    # as they come, to hold fewer arrays; the numbers must agree to rounding.
    p = np.array([1.3, 0.2])
    rhs, jac_x, jac_p = _duffing(p)
    t, x = _intervals(K=40, seed=3)
    h = np.diff(t)
    sig = InputSignal(np.cos(2 * t), t, hold="cubic")
    substeps = 2
    res = rk4_flow(
        rhs, x, t[:-1], h, sig.on_intervals, substeps, jac_x, jac_p, n_params=2
    )
    X = x.copy()
    D = np.concatenate(
        [np.repeat(np.eye(2)[None], len(x), 0), np.zeros((len(x), 2, 2))], 2
    )
    hs = (h / substeps)[:, None]
    H = hs[:, :, None]

    def dstage(Xs, s, us, Dpre):
        return np.einsum("kij,kjm->kim", jac_x(Xs, s, us), Dpre) + np.concatenate(
            [np.zeros((len(Xs), 2, 2)), jac_p(Xs, s, us)], 2
        )

    for j in range(substeps):
        s0 = t[:-1] + j * hs[:, 0]
        u = [sig.on_intervals((j + c) / substeps) for c in (0.0, 0.5, 1.0)]
        k1, d1 = rhs(X, s0, u[0]), dstage(X, s0, u[0], D)
        X2, D2 = X + 0.5 * hs * k1, D + 0.5 * H * d1
        k2, d2 = (
            rhs(X2, s0 + hs[:, 0] / 2, u[1]),
            dstage(X2, s0 + hs[:, 0] / 2, u[1], D2),
        )
        X3, D3 = X + 0.5 * hs * k2, D + 0.5 * H * d2
        k3, d3 = (
            rhs(X3, s0 + hs[:, 0] / 2, u[1]),
            dstage(X3, s0 + hs[:, 0] / 2, u[1], D3),
        )
        X4, D4 = X + hs * k3, D + H * d3
        k4, d4 = rhs(X4, s0 + hs[:, 0], u[2]), dstage(X4, s0 + hs[:, 0], u[2], D4)
        X = X + hs / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        D = D + H / 6 * (d1 + 2 * d2 + 2 * d3 + d4)
    np.testing.assert_allclose(res.phi, X, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(res.D, D, rtol=1e-13, atol=1e-13)


def test_rk4_flow_without_jacobian_returns_no_derivatives():
    rhs, _, _ = _duffing(np.array([1.0, 0.1]))
    t, x = _intervals()
    res = rk4_flow(rhs, x, t[:-1], np.diff(t), InputSignal(None, t).on_intervals)
    assert res.D is None and res.A(2) is None and res.B(2) is None


# ----------------------------------------------------------------- simulate


def test_batch_rk4_matches_closed_form_and_flags_blow_up():
    t = np.linspace(0, 2, 81)
    x = simulate(lambda x, s, u: -x, np.array([[1.0], [2.0]]), t, substeps=2).x
    np.testing.assert_allclose(x[:, :, 0], np.outer([1, 2], np.exp(-t)), rtol=1e-7)
    # x' = x^2 from 1 blows up at t = 1: the trajectory turns NaN, no exception
    run = simulate(lambda x, s, u: x**2, np.array([[1.0]]), t, substeps=2)
    x = run.x
    assert np.isnan(x[0, -1, 0]) and np.isfinite(x[0, 10, 0])
    assert 35 < run.diverged_at[0] < 45  # the sample where it left the bound


def test_blow_up_is_reported_per_trajectory_at_the_bound():
    """x' = x^2: x(t) = x0 / (1 - x0 t) passes the bound B at
    t = 1/x0 - 1/B; a decaying trajectory in the same batch is unaffected."""
    t = np.linspace(0.0, 3.0, 301)
    x0 = np.array([[1.0], [0.5], [-1.0]])
    bound = 1e3
    run = simulate(lambda x, s, u: x**2, x0, t, substeps=8, bound=bound)
    crossing = 1.0 / x0[:2, 0] - 1.0 / bound
    expected = np.searchsorted(t, crossing)  # first sample past the crossing
    np.testing.assert_array_equal(run.diverged_at[:2], expected)
    assert run.diverged_at[2] == -1
    np.testing.assert_array_equal(run.ok, [False, False, True])
    for b in range(2):
        k = run.diverged_at[b]
        assert np.all(np.isnan(run.x[b, k:])) and np.all(np.isfinite(run.x[b, :k]))
    exact = x0[2, 0] / (1.0 - x0[2, 0] * t)
    np.testing.assert_allclose(run.x[2, :, 0], exact, rtol=1e-9)


def test_non_finite_initial_state_diverges_at_sample_zero():
    run = simulate(lambda x, s, u: -x, np.array([[np.nan, 1.0], [1.0, 1.0]]), _grid())
    np.testing.assert_array_equal(run.diverged_at, [0, -1])


def test_zero_order_hold_matches_the_exact_discretisation():
    """x' = -a x + u with u held: x_{k+1} = e^{-a h} x_k + (1 - e^{-a h}) u_k / a."""
    a = 1.7
    rng = np.random.default_rng(4)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.05, 0.15, 60))])
    u = rng.standard_normal(t.size)
    sig = InputSignal(u, t, hold="zoh")
    # 16 steps per interval put RK4's own error below 1e-9 (4 leave ~4e-8);
    # a linearly interpolated u would be off by ~1e-2
    run = simulate(lambda x, s, uu: -a * x + uu, np.array([0.3]), t, sig, substeps=16)
    exact = np.empty(t.size)
    exact[0] = 0.3
    for k, h in enumerate(np.diff(t)):
        e = np.exp(-a * h)
        exact[k + 1] = e * exact[k] + (1 - e) * u[k] / a
    np.testing.assert_allclose(run.x[0, :, 0], exact, rtol=0, atol=1e-9)


@pytest.mark.parametrize("hold", ["linear", "zoh", "cubic"])
def test_simulate_takes_the_same_steps_as_rk4_flow(hold):
    """The integrator's promise: free runs and fits see one discrete map."""
    rhs, _, _ = _duffing(np.array([1.0, 0.1]))
    t = np.arange(80) * 0.05
    sig = InputSignal(np.sin(1.3 * t), t, hold=hold)

    def rhs_rows(X, s, u):  # simulate's convention: scalar time, u of shape (m,)
        uu = None if u is None else np.broadcast_to(u, (X.shape[0], u.shape[-1]))
        return rhs(X, np.full(X.shape[0], s), uu)

    x = simulate(rhs_rows, np.array([1.0, 0.0]), t, sig, substeps=2).x[0]
    phi = rk4_flow(rhs, x[:-1], t[:-1], np.diff(t), sig.on_intervals, 2).phi
    np.testing.assert_allclose(phi, x[1:], rtol=1e-13, atol=1e-13)


# ---------------------------------------------------------- simulate_guided


def _vdp(X, s, u):
    return np.column_stack([X[:, 1], -X[:, 0] + (1 - X[:, 0] ** 2) * X[:, 1]])


def _rows(rhs):
    def rhs_rows(X, s, u):
        uu = None if u is None else np.broadcast_to(u, (X.shape[0], u.shape[-1]))
        return rhs(X, np.full(X.shape[0], s), uu)

    return rhs_rows


def test_simulate_guided_equals_simulate_from_a_rough_guess():
    t = np.arange(400) * 0.025
    x0 = np.array([2.0, 0.0])
    free = simulate(_rows(_vdp), x0, t, substeps=2)
    guess = free.x[0] + 0.05 * np.random.default_rng(0).standard_normal((t.size, 2))
    guided = simulate_guided(_vdp, x0, t, None, 2, guess)
    assert guided.diverged_at[0] == -1
    np.testing.assert_allclose(guided.x[0], free.x[0], rtol=0, atol=1e-10)


@pytest.mark.parametrize("hold", ["linear", "zoh", "cubic"])
def test_simulate_guided_equals_simulate_with_inputs(hold):
    rhs, jac_x, _ = _duffing(np.array([1.0, 0.3]))
    t = np.arange(300) * 0.04
    sig = InputSignal(np.sin(0.7 * t), t, hold=hold)
    x0 = np.array([0.5, -0.2])
    free = simulate(_rows(rhs), x0, t, sig, substeps=2)
    guess = np.repeat(x0[None], t.size, axis=0)  # no idea of the trajectory
    for jac in (jac_x, None):  # analytic, or central differences
        guided = simulate_guided(rhs, x0, t, sig, 2, guess, jac_x=jac)
        np.testing.assert_allclose(guided.x[0], free.x[0], rtol=0, atol=1e-10)


def test_simulate_guided_reports_blow_up_as_simulate_does():
    t = np.linspace(0.0, 2.0, 81)

    def square(X, s, u):
        return X**2

    guess = np.ones((t.size, 1))
    guided = simulate_guided(square, np.array([1.0]), t, None, 2, guess)
    free = simulate(_rows(square), np.array([1.0]), t, substeps=2)
    assert guided.diverged_at[0] == free.diverged_at[0] > 0
    np.testing.assert_array_equal(np.isnan(guided.x), np.isnan(free.x))
    k = free.diverged_at[0]
    np.testing.assert_allclose(guided.x[0, :k], free.x[0, :k], rtol=1e-12)


def _counting(rhs):
    """``rhs`` counting its rows: one-row calls are the sequential loop's."""
    counts = {"calls": 0, "one_row": 0}

    def counted(X, s, u):
        counts["calls"] += 1
        counts["one_row"] += X.shape[0] == 1
        return rhs(X, s, u)

    return counted, counts


def test_simulate_guided_confines_the_sequential_loop_to_a_bad_stretch():
    # One sample of the guess far off the limit cycle (x1 = 30, where
    # (1 - x1^2) x2 makes the linearised RK4 step explode): Newton over the
    # whole record cannot converge, blocks can, except around that sample.
    t = np.arange(20_001) * 0.025
    x0 = np.array([2.0, 0.0])
    free = simulate(_rows(_vdp), x0, t, substeps=2).x[0]
    guess = free.copy()
    guess[12_000] = [30.0, 0.0]
    counted, counts = _counting(_vdp)
    guided = simulate_guided(counted, x0, t, None, 2, guess)
    assert guided.diverged_at[0] == -1
    np.testing.assert_allclose(guided.x[0], free, rtol=0, atol=1e-10)
    # one sequential stretch of GUIDED_MIN_BLOCK intervals (2 substeps, 4
    # stages), where the whole record would take 160,000 one-row calls
    assert 0 < counts["one_row"] <= 2 * 4 * 2 * GUIDED_MIN_BLOCK
    assert counts["calls"] < 0.02 * 4 * 2 * t.size


@pytest.mark.parametrize("hold", ["linear", "zoh", "cubic"])
def test_simulate_guided_reports_a_late_blow_up_as_simulate_does(hold):
    # dx/dt = u x^2 with u switched on at t = 3: x stays at 1, then blows
    # up near t = 4; Newton solves the early blocks, the loop finds the sample
    t = np.linspace(0.0, 6.0, 6_001)
    sig = InputSignal(np.where(t >= 3.0, 1.0, 0.0), t, hold=hold)

    def quadratic(X, s, u):
        return u * X**2

    x0 = np.array([1.0])
    free = simulate(_rows(quadratic), x0, t, sig, substeps=2)
    counted, counts = _counting(quadratic)
    guided = simulate_guided(counted, x0, t, sig, 2, np.ones((t.size, 1)))
    assert guided.diverged_at[0] == free.diverged_at[0] > 3_000
    np.testing.assert_array_equal(np.isnan(guided.x), np.isnan(free.x))
    k = free.diverged_at[0]
    # Newton's defects are 1e-12 absolute; x grows to 2e3 before the bound
    np.testing.assert_allclose(guided.x[0, :k], free.x[0, :k], rtol=1e-10)
    assert counts["one_row"] < 4 * 2 * 3_000  # the loop did not start at t = 0


def test_simulate_guided_returns_a_guess_that_is_the_run_without_derivatives():
    # a converged fit's trajectory: checked on a sample of intervals, then on
    # all of them, with no Jacobian (which would take 2 n more calls a stage)
    t = np.arange(5_001) * 0.025
    x0 = np.array([2.0, 0.0])
    free = simulate(_rows(_vdp), x0, t, substeps=2).x[0]
    counted, counts = _counting(_vdp)
    guided = simulate_guided(counted, x0, t, None, 2, free)
    np.testing.assert_array_equal(guided.x[0], free)
    assert counts["calls"] == 2 * 4 * 2
    # a guess off the run by 1e-9 at one sample is not taken for it
    off = free.copy()
    off[2_500, 1] += 1e-9
    counted, counts = _counting(_vdp)
    guided = simulate_guided(counted, x0, t, None, 2, off)
    np.testing.assert_allclose(guided.x[0], free, rtol=0, atol=1e-12)
    assert counts["calls"] > 2 * 4 * 2


@pytest.mark.parametrize("shape", [(), (4,)])
def test_solve_recursion_equals_the_recursion_stepped_in_a_loop(shape):
    rng = np.random.default_rng(5)
    K, n = 50, 3
    A = rng.normal(0, 0.6, (K, n, n))
    f = rng.normal(size=(K, n) + shape)
    z, info = solve_recursion(A, f)
    assert info == 0 and z.shape == f.shape
    prev = np.zeros((n,) + shape)
    for k in range(K):
        prev = A[k] @ prev + f[k]
        np.testing.assert_allclose(z[k], prev, rtol=1e-12, atol=1e-12)


def test_simulate_guided_of_one_sample_is_its_initial_state():
    guided = simulate_guided(
        _vdp, np.array([2.0, 0.0]), [0.0], None, 1, np.ones((1, 2))
    )
    np.testing.assert_array_equal(guided.x, [[[2.0, 0.0]]])
    assert guided.diverged_at[0] == -1


@pytest.mark.parametrize(
    "n, m", [(1, 1), (1, 4), (2, 0), (2, 3), (2, 9), (3, 4), (3, 6), (9, 2)]
)
def test_small_matmul_equals_numpys_batched_matmul(n, m):
    from pysindy_mme.core.integrate import _small_matmul

    rng = np.random.default_rng(n * 10 + m)
    J, D = rng.standard_normal((57, n, n)), rng.standard_normal((57, n, m))
    out = _small_matmul(J, D)
    assert out.shape == (57, n, m)
    np.testing.assert_allclose(out, J @ D, rtol=1e-13, atol=1e-13)
    # strided views (the flows pass slices of their arrays)
    Dw = rng.standard_normal((57, n, m + 3))[:, :, 1 : m + 1]
    np.testing.assert_allclose(_small_matmul(J, Dw), J @ Dw, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize(
    "n, r, m", [(2, 1, 2), (3, 1, 3), (2, 3, 1), (4, 2, 3), (5, 4, 3)]
)
def test_small_matmul_with_a_rectangular_inner_dimension(n, r, m):
    from pysindy_mme.core.integrate import _small_matmul

    rng = np.random.default_rng(n * 100 + r * 10 + m)
    J, D = rng.standard_normal((41, n, r)), rng.standard_normal((41, r, m))
    out = _small_matmul(J, D)
    assert out.shape == (41, n, m)
    np.testing.assert_allclose(out, J @ D, rtol=1e-13, atol=1e-13)
    if r == 1:  # single products: numpy's numbers exactly
        np.testing.assert_array_equal(out, J @ D)


def _extended_vdp():
    return vdp_extended_model()[0]


def test_an_extended_models_bare_jacobian_is_the_closed_form():
    # Van der Pol's Jacobian, [[0, 1], [-1 - 2 x1 x2, 1 - x1^2]]: the
    # assumed part by central differences, the correction exact
    rates = _extended_vdp().unchecked()
    X = np.random.default_rng(4).uniform(-3, 3, (50, 2))
    x1, x2 = X[:, 0], X[:, 1]
    ref = np.zeros((50, 2, 2))
    ref[:, 0, 1] = 1.0
    ref[:, 1, 0] = -1.0 - 2.0 * x1 * x2
    ref[:, 1, 1] = 1.0 - x1**2
    got = rates.jacobian(X, np.zeros(50), None, scale=np.ones(2))
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9)


def test_simulate_guided_runs_an_extended_model_as_simulate_does():
    # the guided run of an ExtendedModel (its bare form, its own Jacobian)
    # is the sequential RK4 run of the same right-hand side
    model = _extended_vdp()
    t = np.arange(400) * 0.025
    x0 = np.array([2.0, 0.0])
    free = simulate(_rows(_vdp), x0, t, substeps=2)
    guess = free.x[0] + 0.05 * np.random.default_rng(1).standard_normal((t.size, 2))
    guided = simulate_guided(model, x0, t, None, 2, guess)
    assert guided.diverged_at[0] == -1
    np.testing.assert_allclose(guided.x[0], free.x[0], rtol=0, atol=1e-10)


@pytest.mark.parametrize("n", [3, 8])
def test_rk4_flow_derivatives_of_many_states_equal_the_textbook_stages(n):
    # The stages' Jacobians multiply the derivatives entry by entry over the
    # rows for a few states and by numpy's batched product beyond
    # (_ROWWISE_MAX_STATES): both against the stage-by-stage einsum, with a
    # per-interval parameter Jacobian and a constant one
    rng = np.random.default_rng(n)
    W = 0.4 * rng.standard_normal((n, n))
    P = rng.standard_normal((n, 2))

    def rhs(z, s, u, p=(0.7, -0.3)):
        return np.tanh(z @ W.T) + p[0] * z[:, :1] * P[:, 0] + p[1] * P[:, 1]

    def jac_x(z, s, u):
        J = (1 - np.tanh(z @ W.T) ** 2)[:, :, None] * W[None]
        J[:, :, 0] += 0.7 * P[:, 0]
        return J

    def jac_p(z, s, u):
        return np.stack([z[:, :1] * P[:, 0], np.broadcast_to(P[:, 1], z.shape)], 2)

    K, substeps = 30, 2
    x = rng.standard_normal((K, n))
    t = np.arange(K + 1) * 0.05
    h = np.diff(t)
    res = rk4_flow(
        rhs, x, t[:-1], h, lambda frac: None, substeps, jac_x, jac_p, n_params=2
    )
    X = x.copy()
    D = np.concatenate([np.repeat(np.eye(n)[None], K, 0), np.zeros((K, n, 2))], 2)
    hs = (h / substeps)[:, None]
    H = hs[:, :, None]

    def dstage(Xs, Dpre):
        return np.einsum("kij,kjm->kim", jac_x(Xs, 0, None), Dpre) + np.concatenate(
            [np.zeros((K, n, n)), jac_p(Xs, 0, None)], 2
        )

    for _ in range(substeps):
        k1, d1 = rhs(X, 0, None), dstage(X, D)
        X2, D2 = X + 0.5 * hs * k1, D + 0.5 * H * d1
        k2, d2 = rhs(X2, 0, None), dstage(X2, D2)
        X3, D3 = X + 0.5 * hs * k2, D + 0.5 * H * d2
        k3, d3 = rhs(X3, 0, None), dstage(X3, D3)
        X4, D4 = X + hs * k3, D + H * d3
        k4, d4 = rhs(X4, 0, None), dstage(X4, D4)
        X = X + hs / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        D = D + H / 6 * (d1 + 2 * d2 + 2 * d3 + d4)
    np.testing.assert_allclose(res.phi, X, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(res.D, D, rtol=1e-13, atol=1e-13)
    assert res.D.flags.c_contiguous and res.D.shape == (K, n, n + 2)
    # the parameters' columns alone (score tests' candidates): the same
    lean = rk4_flow(
        rhs,
        x,
        t[:-1],
        h,
        lambda frac: None,
        substeps,
        jac_x,
        jac_p,
        n_params=2,
        state_columns=False,
    )
    np.testing.assert_allclose(lean.D, res.D[:, :, n:], rtol=1e-13, atol=1e-15)
