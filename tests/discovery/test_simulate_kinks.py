"""Issue 19: simulating models with kinks (Coulomb friction ``sign(v)``).

``ExtendedModel.simulate`` integrates a correction with a kink or a jump by
fixed-step RK4 on the sample grid (``method="auto"``), where LSODA at
``rtol = 1e-9`` crawled through every discontinuity. Every check here is
against a reference that does not share the code under test: a closed-form
solution, a hand-written RK4 loop on plain floats at 16 times the steps,
the exact zero-order-hold discretisation of a linear model.
"""

import math
import warnings

import numpy as np
import pysindy as ps
import pytest
from extended_case import vdp_extended_model

from pysindy_mme import (
    DiscoveryWarning,
    DivergenceError,
    ExtendedModel,
    PhysicsLibrary,
    PowerLibrary,
)
from pysindy_mme.core.model import simulate_model
from pysindy_mme.feature_library import Coulomb, SmoothCoulomb
from pysindy_mme.machines import positioning_axis

# ---------------------------------------------------------------------------
# (a) a block with Coulomb friction, one reversal: closed form

A, B, G, V0 = 1.0, 2.0, 3.0, -2.0  # v' = -A v - B sign(v) + G, v(0) = V0


def _block(x, t):
    v = x[:, 1]
    return np.column_stack([v, -A * v - B * np.sign(v) + G])


def _block_exact(t):
    """``(q, v)`` of the block from ``(0, V0)``, and the reversal time.

    ``v < 0``: ``v' = -A v + B + G``, ``v -> v1 = (G + B)/A``; ``v`` reaches 0
    at ``ts = ln((v1 - V0)/v1)/A``, then ``v' = -A v - B + G`` with ``v ->
    v2 = (G - B)/A > 0``: no sticking (``G > B``), one reversal.
    """
    v1, v2 = (G + B) / A, (G - B) / A
    ts = math.log((v1 - V0) / v1) / A
    before = np.minimum(t, ts)
    after = np.maximum(t - ts, 0.0)
    decay = -np.expm1(-A * before)
    q_before = v1 * before + (V0 - v1) * decay / A
    v_before = v1 + (V0 - v1) * (1.0 - decay)
    q_s = v1 * ts + (V0 - v1) * -math.expm1(-A * ts) / A
    q_after = q_s + v2 * after + v2 * np.expm1(-A * after) / A
    v_after = -v2 * np.expm1(-A * after)
    x = np.where((t < ts)[:, None], np.column_stack([q_before, v_before]), 0.0)
    x[t >= ts] = np.column_stack([q_after, v_after])[t >= ts]
    return x, ts


@pytest.mark.parametrize("dt", [0.03, 0.05, 0.1])
@pytest.mark.parametrize("substeps", [1, 2, 4, 8, 16])
def test_rk4_through_a_reversal_against_the_closed_form(dt, substeps):
    """The step that crosses the jump of ``B sign(v)`` (size 2 B) errs by a
    fraction of ``2 B h``; we allow ``B h`` (``h = dt / substeps``), and the
    smooth stretch before the reversal is exact to RK4's ``O(h^4)``."""
    t = np.arange(0.0, 3.0 + 1e-9, dt)
    exact, ts = _block_exact(t)
    x = simulate_model(_block, [0.0, V0], t, method="rk4", substeps=substeps)
    h = dt / substeps
    assert np.max(np.abs(x - exact)) <= B * h
    before = t < ts - dt
    assert np.max(np.abs(x[before] - exact[before])) <= max(0.05 * h**4, 1e-12)


def test_rk4_error_through_a_reversal_shrinks_with_the_step():
    t = np.arange(0.0, 3.0 + 1e-9, 0.1)
    exact, _ = _block_exact(t)
    errors = [
        np.max(
            np.abs(
                simulate_model(_block, [0.0, V0], t, method="rk4", substeps=s) - exact
            )
        )
        for s in (1, 16)
    ]
    assert errors[1] < errors[0] / 4  # first order at the jump, at least


# ---------------------------------------------------------------------------
# (b) a fitted extended model of a positioning axis, 25,000 samples

M, C, K_U = 95.0, 200.0, 100.0  # the axis' mass, viscous friction, motor gain


def _axis_assumed(x, t, u):
    return np.column_stack([x[:, 1], (K_U * u[:, 0] - C * x[:, 1]) / M])


@pytest.fixture(scope="module")
def axis():
    """A 25,000-sample record of the PD-controlled axis (Coulomb friction 20 N,
    offset 3 N, sticking) and an ExtendedModel whose Coulomb and offset terms
    are fitted to it by least squares on the sliding samples."""
    rec = positioning_axis().record()
    v, u = rec.x[:, 1], rec.u[:, 0]
    dt = rec.t[1] - rec.t[0]
    residual = np.diff(v) / dt - (K_U * u[:-1] - C * 0.5 * (v[:-1] + v[1:])) / M
    sliding = (np.abs(v[:-1]) > 1e-3) & (np.sign(v[:-1]) == np.sign(v[1:]))
    design = np.column_stack([np.sign(v[:-1]), np.ones(v.size - 1)])
    (coulomb, offset), *_ = np.linalg.lstsq(
        design[sliding], residual[sliding], rcond=None
    )
    assert coulomb == pytest.approx(-20.0 / M, rel=1e-3)
    assert offset == pytest.approx(3.0 / M, rel=1e-2)
    z = np.hstack([rec.x, rec.u])
    # smoothing=0: the exact sign, which the reference below integrates
    lib = PhysicsLibrary([Coulomb("v")], names=["q", "v", "u"], smoothing=0).fit(z)
    coef = np.array([[0.0], [coulomb]])

    def model(substeps=4):
        return ExtendedModel(
            _axis_assumed,
            lib,
            coef,
            ["q", "v"],
            ["u"],
            intercept=[0.0, offset],
            z_reference=z[::50],
            substeps=substeps,
        )

    return rec, model, coulomb, offset


def _axis_reference(x0, t, u, substeps, coulomb, offset):
    """The same model by hand: RK4 on floats, ``u[k]`` held on each interval."""
    q, v = float(x0[0]), float(x0[1])
    out = np.empty((t.size, 2))
    out[0] = q, v

    def acc(v, uk):
        s = 1.0 if v > 0 else (-1.0 if v < 0 else 0.0)
        return (K_U * uk - C * v) / M + coulomb * s + offset

    for k in range(t.size - 1):
        h = (t[k + 1] - t[k]) / substeps
        uk = float(u[k, 0])
        for _ in range(substeps):
            k1 = acc(v, uk)
            v2 = v + 0.5 * h * k1
            k2 = acc(v2, uk)
            v3 = v + 0.5 * h * k2
            k3 = acc(v3, uk)
            v4 = v + h * k3
            k4 = acc(v4, uk)
            q += h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
            v += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        out[k + 1] = q, v
    return out


def test_fitted_axis_model_simulates_25000_samples_like_a_fine_reference(axis):
    """``simulate`` with its defaults (``auto``: RK4, the model's substeps)
    on the whole record, against RK4 at 16 times the steps.

    Tolerances: while the carriage sticks (|force| < Fc) the coarse run's
    ``v`` chatters about 0 within ``2 |coulomb| h``; the position, which
    integrates that chatter, within 0.1 % of its range.
    """
    rec, model, coulomb, offset = axis
    assert rec.t.size == 25_000
    em = model(substeps=1)  # a study sets its own number; 1 keeps this fast
    assert em.kinked_terms == ["sign(v)"]
    x = em.simulate(rec.x[0], rec.t, rec.u, input_hold="zoh")
    ref = _axis_reference(rec.x[0], rec.t, rec.u, 16, coulomb, offset)
    h = rec.t[1] - rec.t[0]
    assert np.all(np.isfinite(x))
    assert np.max(np.abs(x[:, 1] - ref[:, 1])) <= 2.0 * abs(coulomb) * h
    assert np.max(np.abs(x[:, 0] - ref[:, 0])) <= 1e-3 * np.ptp(ref[:, 0])


# ---------------------------------------------------------------------------
# (c) what "auto" picks


def test_auto_integrates_a_kinked_correction_with_rk4(axis):
    rec, model, _, _ = axis
    em, n = model(), 2000
    t, u, x0 = rec.t[:n], rec.u[:n], rec.x[0]
    auto = em.simulate(x0, t, u, input_hold="zoh")
    np.testing.assert_array_equal(
        auto, em.simulate(x0, t, u, method="rk4", substeps=4, input_hold="zoh")
    )
    assert not np.array_equal(
        auto, em.simulate(x0, t, u, method="rk4", substeps=2, input_hold="zoh")
    )


_vdp_model = vdp_extended_model


def test_auto_integrates_a_smooth_correction_with_lsoda():
    em, t = _vdp_model()
    assert em.kinked_terms == []
    auto = em.simulate([1.0, 0.0], t)
    np.testing.assert_array_equal(auto, em.simulate([1.0, 0.0], t, method="LSODA"))
    # and RK4 on the same grid agrees to its own accuracy
    rk4 = em.simulate([1.0, 0.0], t, method="rk4")
    np.testing.assert_allclose(rk4, auto, atol=1e-5)


def test_kinked_terms_from_the_library_or_the_names():
    z = np.random.default_rng(0).standard_normal((50, 2))
    # PhysicsLibrary says which columns are kinked; a smooth effect is not
    smooth = PhysicsLibrary([SmoothCoulomb("v", 0.01)], names=["q", "v"]).fit(z)
    em = ExtendedModel(lambda x, t: 0 * x, smooth, [[0.0], [-1.0]], ["q", "v"])
    assert em.kinked_terms == []
    # other libraries by their names: sign( in a CustomLibrary, |x| in PowerLibrary
    custom = ps.CustomLibrary(
        [lambda a: np.sign(a), lambda a: a**2],
        [lambda a: f"sign({a})", lambda a: f"{a}^2"],
    ).fit(z)
    names = custom.get_feature_names(["q", "v"])
    coef = np.zeros((2, len(names)))
    coef[1, names.index("v^2")] = -1.0
    em = ExtendedModel(lambda x, t: 0 * x, custom, coef, ["q", "v"])
    assert em.kinked_terms == []  # only active terms count
    coef[1, names.index("sign(v)")] = -1.0
    em = ExtendedModel(lambda x, t: 0 * x, custom, coef, ["q", "v"])
    assert em.kinked_terms == ["sign(v)"]
    power = PowerLibrary().fit(z)
    names = power.get_feature_names(["q", "v"])
    coef = np.zeros((2, len(names)))
    coef[1, names.index("v |v|")] = -0.3
    em = ExtendedModel(lambda x, t: 0 * x, power, coef, ["q", "v"])
    assert em.kinked_terms == ["v |v|"]


# ---------------------------------------------------------------------------
# (d) LSODA out of budget on a model not known to be kinked

KAPPA = 210.0  # x' = -200 (x - cos t) - 10 x: stiff next to 0.01 s samples


def _stiff_model():
    lib = ps.PolynomialLibrary(degree=2).fit(np.linspace(-1, 1, 20)[:, None])
    names = lib.get_feature_names(["x"])
    coef = np.zeros((1, len(names)))
    coef[0, names.index("x")] = -10.0

    def assumed(x, t):
        return -200.0 * (x[:, 0] - np.cos(t))  # one state: (n,) is fine

    return ExtendedModel(assumed, lib, coef, ["x"])


def _stiff_exact(t, x0):
    steady = 200.0 * (KAPPA * np.cos(t) + np.sin(t)) / (KAPPA**2 + 1.0)
    return (x0 - 200.0 * KAPPA / (KAPPA**2 + 1.0)) * np.exp(-KAPPA * t) + steady


def test_auto_falls_back_to_rk4_when_lsoda_exhausts_its_budget():
    """A budget of 300 evaluations for 1,001 samples stands in for a model
    that is too stiff, or has an undeclared kink, for LSODA's default one."""
    em = _stiff_model()
    t = np.linspace(0.0, 10.0, 1001)
    with pytest.raises(DivergenceError, match="more than 300 model evaluations"):
        em.simulate([1.0], t, method="LSODA", max_evaluations=300)
    with pytest.warns(DiscoveryWarning, match="more than 300 model evaluations"):
        x = em.simulate([1.0], t, max_evaluations=300)
    np.testing.assert_array_equal(x, em.simulate([1.0], t, method="rk4"))
    # h * KAPPA = 0.53 with 4 substeps: RK4 is stable and accurate
    np.testing.assert_allclose(x[:, 0], _stiff_exact(t, 1.0), atol=1e-4)
    # with its default budget LSODA manages, and auto does not warn
    with warnings.catch_warnings():
        warnings.simplefilter("error", DiscoveryWarning)
        lsoda = em.simulate([1.0], t)
    np.testing.assert_allclose(lsoda[:, 0], _stiff_exact(t, 1.0), atol=1e-7)


def test_fallback_that_diverges_still_raises_or_gives_nan():
    """On samples 0.4 s apart RK4 with 4 substeps is unstable on the stiff
    model (h KAPPA = 21, beyond RK4's 2.79): the fallback's own divergence
    is reported like any other, with a hint."""
    em = _stiff_model()
    unstable = np.linspace(0.0, 400.0, 1001)
    with (
        pytest.warns(DiscoveryWarning),
        pytest.raises(
            DivergenceError, match=r"near t = .* state 0 was .*\(fixed-step RK4"
        ),
    ):
        em.simulate([1.0], unstable, max_evaluations=300)
    with pytest.warns(DiscoveryWarning):
        x = em.simulate([1.0], unstable, max_evaluations=300, on_divergence="nan")
    assert np.isnan(x[-1, 0]) and np.isfinite(x[0, 0])


# ---------------------------------------------------------------------------
# the rest of the RK4 path: inputs, divergence, arguments


def test_input_hold_reaches_the_integrator():
    """``x' = -x + u`` with ``u[k]`` held: the exact discretisation
    ``x[k+1] = e^-h x[k] + (1 - e^-h) u[k]``."""
    lib = ps.PolynomialLibrary(degree=1).fit(np.zeros((5, 2)))
    coef = np.zeros((1, len(lib.get_feature_names(["x", "u"]))))
    em = ExtendedModel(lambda x, t, u: -x + u, lib, coef, ["x"], ["u"])
    t = np.arange(0.0, 5.0 + 1e-9, 0.1)
    u = np.sign(np.sin(3.0 * t))[:, None]
    exact = np.empty(t.size)
    exact[0] = 0.5
    for k in range(t.size - 1):
        exact[k + 1] = math.exp(-0.1) * exact[k] - math.expm1(-0.1) * u[k, 0]
    zoh = em.simulate([0.5], t, u, method="rk4", input_hold="zoh")[:, 0]
    np.testing.assert_allclose(zoh, exact, atol=1e-8)
    lsoda = em.simulate([0.5], t, u, method="LSODA", input_hold="zoh")[:, 0]
    np.testing.assert_allclose(lsoda, exact, atol=1e-7)
    linear = em.simulate([0.5], t, u, method="rk4")[:, 0]
    assert np.max(np.abs(linear - exact)) > 1e-2  # the hold matters here


def test_rk4_divergence_names_time_and_state():
    t = np.linspace(0.0, 2.0, 201)  # x' = x^2 from 1 blows up at t = 1

    def square(x, t):
        return x**2

    with pytest.raises(
        DivergenceError,
        match=r"near t = 1\.\d+: it (left the bound|stopped being finite); "
        r"state 0 was .* at t = ",
    ):
        simulate_model(square, [1.0], t, method="rk4", on_divergence="raise")
    x = simulate_model(square, [1.0], t, method="rk4")
    stop = int(np.argmax(np.isnan(x[:, 0])))
    assert 0.95 < t[stop] < 1.1 and np.all(np.isfinite(x[:stop]))
    assert np.all(np.isnan(x[stop:]))


def test_bad_arguments():
    t = np.linspace(0.0, 1.0, 11)
    with pytest.raises(ValueError, match="substeps"):
        simulate_model(_block, [0.0, 1.0], t, method="rk4", substeps=0)
    with pytest.raises(ValueError, match="method must be"):
        simulate_model(_block, [0.0, 1.0], t, method="euler")
    with pytest.raises(ValueError, match="input_hold"):
        simulate_model(_block, [0.0, 1.0], t, method="rk4", input_hold="step")
    em, _ = _vdp_model()
    with pytest.raises(ValueError, match="substeps"):
        em.simulate([1.0, 0.0], t, substeps=1.5)
