"""Simulated machines against independent references.

Every reference here is computed without the module's integrators: closed
forms, water and energy balances, or ``scipy.integrate.solve_ivp`` (RK45 or
Radau, tight tolerances) on right-hand sides written out again in this file.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pysindy_mme.machines import (
    Machine,
    MachineRecord,
    asymmetric_damper,
    cascaded_tanks,
    clipped_oscillator,
    damped_pendulum,
    positioning_axis,
)

TIGHT = dict(rtol=1e-12, atol=1e-14)


def _crossing_times(t, s):
    """Upward zero crossings of ``s``, by linear interpolation."""
    k = np.flatnonzero((s[:-1] < 0) & (s[1:] >= 0))
    return t[k] - s[k] * (t[k + 1] - t[k]) / (s[k + 1] - s[k])


def _held_reference(rhs, t, u, x0, method="RK45"):
    """``solve_ivp`` restarted at every sample, the input held in between."""
    x = np.empty((t.size, len(x0)))
    x[0] = x0
    for k in range(t.size - 1):
        sol = solve_ivp(
            rhs, (t[k], t[k + 1]), x[k], args=(u[k],), method=method, **TIGHT
        )
        x[k + 1] = sol.y[:, -1]
    return x


# --------------------------------------------------------------------------
# pendulum


def test_pendulum_matches_an_independent_solver():
    rec = damped_pendulum().record()
    assert rec.t.size == 2000 and rec.t[-1] == pytest.approx(19.99)

    def rhs(t, x):
        return [x[1], -4.0 * np.sin(x[0]) - 0.2 * x[1]]

    ref = solve_ivp(
        rhs,
        (0, rec.t[-1]),
        [1.0, 0.0],
        method="Radau",
        t_eval=rec.t,
        rtol=1e-10,
        atol=1e-12,
    ).y.T
    assert np.max(np.abs(rec.x - ref)) < 1e-7


@pytest.mark.parametrize("damping", [0.0, 0.2])
def test_pendulum_small_amplitude_period(damping):
    rec = damped_pendulum(damping=damping).record(x0=(0.01, 0.0))
    period = np.diff(_crossing_times(rec.t, rec.x[:, 0])).mean()
    # linear oscillator: omega_d^2 = g/L - (damping / 2)^2
    expected = 2 * np.pi / np.sqrt(4.0 - (damping / 2) ** 2)
    assert period == pytest.approx(expected, rel=2e-5)
    if damping:
        assert abs(period - np.pi) > 1e-3  # the test sees the damping


def test_pendulum_energy_decay_matches_the_damping():
    rec = damped_pendulum().record()
    th, om = rec.x.T

    def energy(th, om):
        return 0.5 * om**2 + 4.0 * (1.0 - np.cos(th))

    # the work done by damping, W' = 0.2 omega^2, integrated independently
    def rhs(t, z):
        return [z[1], -4.0 * np.sin(z[0]) - 0.2 * z[1], 0.2 * z[1] ** 2]

    ref = solve_ivp(
        rhs, (0, rec.t[-1]), [1.0, 0.0, 0.0], t_eval=rec.t, rtol=1e-10, atol=1e-12
    )
    lost = ref.y[2]
    assert np.max(np.abs(energy(th, om) - (energy(1.0, 0.0) - lost))) < 1e-7
    assert lost[-1] > 0.5 * energy(1.0, 0.0)  # the decay is substantial


def test_pendulum_noise_and_assumed_model():
    machine = damped_pendulum()
    rec = machine.record(seed=3)
    assert rec.u is None and rec.clip is None and rec.n_clipped == 0
    assert np.std(rec.y[:, 0] - rec.x[:, 0]) == pytest.approx(0.01, rel=0.1)
    assert machine.parameters == {}
    gap = machine.true_model(rec.x, rec.t) - machine.assumed_model(rec.x, rec.t)
    np.testing.assert_allclose(gap[:, 0], 0.0)
    np.testing.assert_allclose(gap[:, 1], -4.0 * np.sin(rec.x[:, 0]), atol=1e-12)


# --------------------------------------------------------------------------
# cascaded tanks


@pytest.mark.parametrize("tank", [0, 1])
def test_tank_draining_matches_torricelli(tank):
    machine = cascaded_tanks()
    k = machine.true_parameters["k1" if tank == 0 else "k2"]
    h0 = 4.0
    t = np.arange(0.0, 120.0, 4.0)
    x0 = (h0, 0.0) if tank == 0 else (0.0, h0)
    x = machine.simulate(t, np.zeros((t.size, 1)), x0)
    # sqrt(h) = sqrt(h0) - k t / 2 until empty, then empty
    closed = np.maximum(np.sqrt(h0) - k * t / 2, 0.0) ** 2
    assert closed[-1] == 0.0 and closed[1] > 0.0
    np.testing.assert_allclose(x[:, tank], closed, atol=2e-6)


def test_tanks_match_an_independent_solver_below_the_rim():
    machine = cascaded_tanks()
    p = machine.true_parameters
    t = np.arange(60) * 4.0
    u = np.repeat([3.0, 6.0, 4.0, 5.5], 15)[:, None]

    def rhs(t, h, uk):
        o1, o2 = p["k1"] * np.sqrt(h[0]), p["k2"] * np.sqrt(h[1])
        return [p["kp"] * uk[0] - o1, o1 - o2]

    x = machine.simulate(t, u, (2.0, 2.0))
    ref = _held_reference(rhs, t, u, [2.0, 2.0])
    assert np.max(np.abs(x - ref)) < 1e-7


@pytest.mark.parametrize("fraction", [1.0, 0.5])
def test_overflow_keeps_the_upper_level_at_the_rim(fraction):
    machine = cascaded_tanks(overflow_fraction=fraction)
    p = machine.true_parameters
    t = np.arange(800) * 4.0
    u = 10.0
    x = machine.simulate(t, np.full((t.size, 1), u), (2.0, 2.0))
    assert x[:, 0].max() <= 10.0
    assert np.sum(x[:, 0] == 10.0) > 500
    # water balance at the end: the lower tank drains what reaches it
    inflow = p["k1"] * np.sqrt(10.0) + fraction * (p["kp"] * u - p["k1"] * np.sqrt(10))
    assert x[-1, 1] == pytest.approx((inflow / p["k2"]) ** 2, rel=1e-8)


def test_filling_to_the_rim_matches_an_event_driven_reference():
    machine = cascaded_tanks()
    p = machine.true_parameters
    k1, k2, kp, u = p["k1"], p["k2"], p["kp"], 10.0
    t = np.arange(100) * 4.0
    x = machine.simulate(t, np.full((t.size, 1), u), (8.0, 5.0))

    def filling(t, h):
        return [kp * u - k1 * np.sqrt(h[0]), k1 * np.sqrt(h[0]) - k2 * np.sqrt(h[1])]

    def rim(t, h):
        return h[0] - 10.0

    rim.terminal = True
    first = solve_ivp(filling, (0, t[-1]), [8.0, 5.0], events=rim, **TIGHT)
    t_rim, h2_rim = first.t_events[0][0], first.y_events[0][0][1]
    assert 10.0 < t_rim < 100.0
    # at the rim all the pump's flow ends in the lower tank
    second = solve_ivp(
        lambda t, h: [kp * u - k2 * np.sqrt(h[0])],
        (t_rim, t[-1]),
        [h2_rim],
        dense_output=True,
        **TIGHT,
    )
    after = t > t_rim
    np.testing.assert_allclose(x[after, 0], 10.0)
    np.testing.assert_allclose(x[after, 1], second.sol(t[after])[0], atol=1e-5)


def test_overflowing_records_stay_below_the_rim():
    rec = cascaded_tanks().record(seed=2, u_range=(8.0, 10.0))
    assert rec.x[:, 0].max() <= 10.0 and np.sum(rec.x[:, 0] == 10.0) > 100


def test_tank_sensor_clips_quantises_and_counts():
    machine = cascaded_tanks()
    rec = machine.record()
    assert rec.t.size == 1024 and rec.t[1] == 4.0
    assert rec.measured == [1] and rec.clip == (0.0, 10.0)
    y = rec.y[:, 0]
    assert y.max() <= 10.0 and y.min() >= 0.0
    clipped = np.sum((y >= 10.0) | (y <= 0.0))
    assert rec.n_clipped == clipped > 20
    # well above the range the sensor can only say 10
    high = rec.x[:, 1] > 10.0 + 6 * 0.02
    assert high.sum() > 10 and np.all(y[high] == 10.0)
    codes = y / (10.0 / 4096)
    np.testing.assert_allclose(codes, np.round(codes), atol=1e-9)
    inside = (rec.x[:, 1] > 1.0) & (rec.x[:, 1] < 9.0)
    resid = y[inside] - rec.x[inside, 1]
    assert np.std(resid) == pytest.approx(0.02, rel=0.15)


def test_tank_input_is_multilevel_within_range():
    rec = cascaded_tanks().record(seed=1)
    u = rec.u[:, 0]
    assert u.min() >= 0.0 and u.max() <= 10.0
    runs = np.diff(np.flatnonzero(np.diff(u) != 0))
    # held 50..200 s, i.e. 12..50 samples of 4 s
    assert runs.min() >= 12 and runs.max() <= 50


def test_tank_assumed_models():
    lin, sq = cascaded_tanks(), cascaded_tanks(assumed="sqrt")
    assert set(lin.parameters) == {"a1", "b", "a2", "a3"}
    assert set(sq.parameters) == {"k1", "k2", "kp"}
    assert "overflow" in lin.missing and "sqrt" in lin.missing
    rng = np.random.default_rng(0)
    x = rng.uniform(0.5, 9.5, (20, 2))
    u = rng.uniform(0, 10, (20, 1))
    t = np.zeros(20)
    true = {k: sq.true_parameters[k] for k in ("k1", "k2", "kp")}
    # below the rim the square-root model is the truth
    np.testing.assert_allclose(sq.assumed_model(x, t, u, true), sq.true_model(x, t, u))
    out = lin.assumed_model(x, t, u, lin.parameters)
    p = lin.parameters
    np.testing.assert_allclose(out[:, 0], -p["a1"] * x[:, 0] + p["b"] * u[:, 0])
    with pytest.raises(ValueError):
        cascaded_tanks(assumed="cubic")


# --------------------------------------------------------------------------
# positioning axis


def test_encoder_readings_lie_on_the_grid_and_input_is_saturated():
    rec = positioning_axis().record(duration=5.0)
    assert rec.t.size == 5000 and rec.quantisation_step == 5e-8
    codes = rec.y[:, 0] / 5e-8
    np.testing.assert_allclose(codes, np.round(codes), rtol=0, atol=1e-6)
    assert np.max(np.abs(rec.y[:, 0] - rec.x[:, 0])) <= 2.5e-8 * (1 + 1e-9)
    assert np.abs(rec.u).max() <= 10.0
    # a strong dither drives the controller into its limits
    loud = positioning_axis().record(duration=2.0, dither=8.0)
    assert np.abs(loud.u).max() == 10.0


def test_axis_controller_tracks_and_moves():
    rec = positioning_axis().record()
    q = rec.x[:, 0]
    assert q.max() - q.min() > 0.1  # it moves between setpoints
    assert np.any(rec.x[:, 1] == 0.0)  # and sticks now and then


def test_linear_axis_matches_an_independent_integration():
    machine = positioning_axis(Fc=0.0, F0=0.0)
    rec = machine.record(duration=1.0)

    def rhs(t, x, uk):
        return [x[1], (100.0 * uk[0] - 200.0 * x[1]) / 95.0]

    ref = _held_reference(rhs, rec.t, rec.u, [0.0, 0.0])
    assert np.max(np.abs(rec.x[:, 0] - ref[:, 0])) < 1e-9
    assert np.max(np.abs(rec.x[:, 1] - ref[:, 1])) < 1e-8


@pytest.mark.parametrize("u", [0.1, -0.2, 0.169])
def test_coulomb_friction_holds_below_breakaway(u):
    machine = positioning_axis()
    t = np.arange(500) * 1e-3
    assert abs(100.0 * u + 3.0) < 20.0
    x = machine.simulate(t, np.full((t.size, 1), u), (0.0, 0.0))
    assert np.all(x == 0.0)
    stuck = machine.true_model(np.zeros((1, 2)), 0.0, np.array([[u]]))
    np.testing.assert_array_equal(stuck, 0.0)


def test_above_breakaway_the_carriage_slides():
    machine = positioning_axis()
    t = np.arange(500) * 1e-3
    x = machine.simulate(t, np.full((t.size, 1), 0.2), (0.0, 0.0))
    # M v' = 23 - 20 - 200 v from rest
    v = 3.0 / 200.0 * (1.0 - np.exp(-200.0 / 95.0 * t))
    np.testing.assert_allclose(x[:, 1], v, rtol=1e-12, atol=1e-15)


def test_velocity_reversal_matches_an_event_driven_reference():
    machine = positioning_axis()
    t = np.arange(400) * 1e-3
    u = 1.0  # F = 103 N: decelerates through zero and reverses
    x = machine.simulate(t, np.full((t.size, 1), u), (0.0, -0.2))

    def phase(sign):
        def rhs(t, x):
            return [x[1], (103.0 - 200.0 * x[1] - 20.0 * sign) / 95.0]

        return rhs

    def stop(t, x):
        return x[1]

    stop.terminal = True
    first = solve_ivp(phase(-1), (0, t[-1]), [0.0, -0.2], events=stop, **TIGHT)
    t_rev = first.t_events[0][0]
    assert 0 < t_rev < t[-1]
    second = solve_ivp(
        phase(+1),
        (t_rev, t[-1]),
        [first.y_events[0][0][0], 0.0],
        dense_output=True,
        **TIGHT,
    )
    before = t < t_rev
    ref = np.empty_like(x)
    ref[before] = solve_ivp(
        phase(-1), (0, t[-1]), [0.0, -0.2], t_eval=t[before], **TIGHT
    ).y.T
    ref[~before] = second.sol(t[~before]).T
    assert np.max(np.abs(x[:, 0] - ref[:, 0])) < 1e-9
    assert np.max(np.abs(x[:, 1] - ref[:, 1])) < 1e-8


def test_axis_models_differ_by_the_friction_and_offset():
    machine = positioning_axis()
    assert machine.parameters == {"M": 90.0, "c": 150.0}
    rng = np.random.default_rng(1)
    x = np.column_stack([rng.normal(size=30), rng.choice([-1, 1], 30) * 0.3])
    u = rng.uniform(-5, 5, (30, 1))
    p = {"M": 95.0, "c": 200.0}
    gap = machine.true_model(x, 0.0, u) - machine.assumed_model(x, 0.0, u, p)
    np.testing.assert_allclose(gap[:, 0], 0.0)
    np.testing.assert_allclose(gap[:, 1], (-20.0 * np.sign(x[:, 1]) + 3.0) / 95.0)


# --------------------------------------------------------------------------
# clipped oscillator, records in general


def test_clipped_oscillator_reports_the_ceiling():
    rec = clipped_oscillator().record()
    y = rec.y[:, 0]
    assert y.max() == 1.6 and rec.n_clipped == np.sum(y == 1.6) > 20
    assert rec.x[:, 0].max() > 1.9  # the limit cycle goes past the sensor
    assert np.all(y[rec.x[:, 0] > 1.6 + 6 * 0.05] == 1.6)


ALL = [
    positioning_axis,
    cascaded_tanks,
    damped_pendulum,
    clipped_oscillator,
    asymmetric_damper,
]


@pytest.mark.parametrize("build", ALL)
def test_seeds_reproduce_records(build):
    machine = build()
    short = {"duration": 2.0} if build is positioning_axis else {}
    a, b, c = (machine.record(s, **short) for s in (5, 5, 6))
    for name in ("t", "y", "x"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(a.y, c.y)
    if a.u is not None:
        np.testing.assert_array_equal(a.u, b.u)
    assert isinstance(machine, Machine) and isinstance(a, MachineRecord)
    assert a.y.shape == (a.t.size, len(a.measured)) == (a.t.size, 1)
    assert a.x.shape == (a.t.size, len(a.state_names))
    assert machine.missing


def test_split_halves():
    rec = cascaded_tanks().record()
    lead, trail = rec.split()
    assert lead.t.size == trail.t.size == 512
    assert trail.t[0] == rec.t[512]  # not shifted
    for name in ("t", "y", "u", "x"):
        joined = np.concatenate([getattr(lead, name), getattr(trail, name)])
        np.testing.assert_array_equal(joined, getattr(rec, name))
    assert lead.n_clipped + trail.n_clipped == rec.n_clipped
    a, b = rec.split(0.25)
    assert (a.t.size, b.t.size) == (256, 768)
    for bad in (0.0, 1.0, 1e-4):
        with pytest.raises(ValueError):
            rec.split(bad)


def test_unknown_record_option_is_refused():
    with pytest.raises(TypeError, match="unknown option"):
        damped_pendulum().record(durration=3.0)


# --------------------------------------------------------------------------
# asymmetric damper


def _damper_rhs(t, x, u, c):
    """``m = 1, k = 40``, one damping coefficient ``c`` (one direction)."""
    return [x[1], u - 40.0 * x[0] - c * x[1]]


def test_damper_matches_a_closed_form_while_moving_one_way():
    """Constant force from rest: under-damped with ``c_up`` until the first
    reversal, whose time is ``pi / omega_d``."""
    machine = asymmetric_damper()
    t = np.arange(60) * 1e-2
    x = machine.simulate(t, np.full((t.size, 1), 2.0), (0.0, 0.0))
    zeta_w, wd = 1.2 / 2, np.sqrt(40.0 - 0.6**2)
    up = t < np.pi / wd
    q = (
        2.0
        / 40.0
        * (1 - np.exp(-zeta_w * t) * (np.cos(wd * t) + zeta_w / wd * np.sin(wd * t)))
    )
    np.testing.assert_allclose(x[up, 0], q[up], atol=1e-11)
    assert np.all(x[up, 1][1:] > 0) and np.any(x[:, 1] < 0)


def test_damper_reversals_match_an_event_driven_reference():
    machine = asymmetric_damper()
    rec = machine.record(3, duration=4.0)

    def stop(t, x, u, c):
        return x[1]

    stop.terminal = True
    ref = np.empty_like(rec.x)
    ref[0] = rec.x[0]
    for k in range(rec.t.size - 1):
        t0, x = rec.t[k], ref[k]
        while True:
            c = (
                1.2
                if (x[1] > 0 or (x[1] == 0 and rec.u[k, 0] - 40 * x[0] > 0))
                else 0.6
            )
            sol = solve_ivp(
                _damper_rhs,
                (t0, rec.t[k + 1]),
                x,
                args=(rec.u[k, 0], c),
                events=stop if x[1] != 0 else None,
                method="Radau",
                **TIGHT,
            )
            if sol.status != 1:
                ref[k + 1] = sol.y[:, -1]
                break
            t0, x = sol.t[-1], np.array([sol.y[0, -1], 0.0])
    assert np.sum(np.diff(np.sign(rec.x[:, 1])) != 0) > 5  # it reverses
    np.testing.assert_allclose(rec.x, ref, atol=1e-9)


def test_damper_record_and_models():
    machine = asymmetric_damper()
    rec = machine.record(0)
    assert rec.t.size == 2000 and rec.u.shape == (2000, 1)
    assert np.std(rec.u) == pytest.approx(1.0, rel=0.05)
    assert np.std(rec.y[:, 0] - rec.x[:, 0]) == pytest.approx(1e-4, rel=0.1)
    assert machine.parameters == {"k": 36.0, "c": 0.8}
    rng = np.random.default_rng(2)
    x = rng.normal(size=(40, 2))
    u = rng.normal(size=(40, 1))
    gap = machine.true_model(x, 0.0, u) - machine.assumed_model(
        x, 0.0, u, {"k": 40.0, "c": 0.9}
    )
    np.testing.assert_allclose(gap[:, 0], 0.0)
    v = x[:, 1]
    np.testing.assert_allclose(
        gap[:, 1], -0.3 * np.maximum(v, 0) + 0.3 * np.minimum(v, 0)
    )
