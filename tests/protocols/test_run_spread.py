"""How far an initial state's standard error spreads a free run
(``protocols/spread.py``), and what the study makes of a run it spreads.

The propagation is checked against closed forms (a scalar linear model, RK4's
own growth factor; an undamped oscillator, the rotation of the covariance)
and, on Van der Pol, against a second method: whole runs from perturbed
initial states in an independent RK4 loop, differenced.
"""

import numpy as np
import pytest

import pysindy_mme.protocols.spread as spread_module
from pysindy_mme.core.integrate import simulate_guided
from pysindy_mme.discovery.conclusion import Evidence, conclude
from pysindy_mme.protocols.spread import (
    SPREAD_LIMIT,
    determined_until,
    run_spread,
)


def _run(f, x0, t, substeps, guess):
    return simulate_guided(f, np.asarray(x0, float), t, None, substeps, guess).x[0]


def test_a_scalar_linear_run_spreads_by_rk4s_own_growth_factor():
    a, t = 0.3, np.linspace(0.0, 10.0, 201)
    h = t[1] - t[0]

    def f(x, t, u=None):
        return a * x

    x = _run(f, [1.0], t, 1, np.exp(a * t)[:, None])
    spread = run_spread(f, x, t, None, 1, lambda x: x, np.array([[0.01**2]]))
    z = a * h
    factor = 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    np.testing.assert_allclose(spread[:, 0], 0.01 * factor ** np.arange(t.size))


def test_an_undamped_oscillator_rotates_its_initial_covariance():
    # x1' = x2, x2' = -x1 with x1 measured: var(x1(t)) = s1^2 cos^2 + s2^2 sin^2
    t = np.linspace(0.0, 10.0, 201)

    def f(x, t, u=None):
        return np.column_stack([x[:, 1], -x[:, 0]])

    x = _run(f, [1.0, 0.0], t, 4, np.column_stack([np.cos(t), -np.sin(t)]))
    cov = np.diag([0.01**2, 0.02**2])
    spread = run_spread(f, x, t, None, 4, lambda x: x[:, :1], cov)
    expected = np.hypot(0.01 * np.cos(t), 0.02 * np.sin(t))
    np.testing.assert_allclose(spread[:, 0], expected, rtol=1e-6)


def _rk4_loop(f, x0, t):
    """An independent fixed-step RK4 run, one sample at a time."""
    x = np.empty((t.size, x0.size))
    x[0] = x0
    for k in range(t.size - 1):
        h, s, z = t[k + 1] - t[k], t[k], x[k][None]
        k1 = f(z, s)
        k2 = f(z + h / 2 * k1, s + h / 2)
        k3 = f(z + h / 2 * k2, s + h / 2)
        k4 = f(z + h * k3, s + h)
        x[k + 1] = (z + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4))[0]
    return x


def test_a_nonlinear_run_spreads_as_differenced_whole_runs_say():
    # Van der Pol, x1 measured, a correlated initial covariance: each column
    # of its square root pushed through whole runs of an independent loop
    def f(x, t, u=None):
        return np.column_stack([x[:, 1], -x[:, 0] + x[:, 1] - x[:, 0] ** 2 * x[:, 1]])

    t = np.linspace(0.0, 8.0, 321)
    x0 = np.array([1.5, 0.2])
    x = _rk4_loop(f, x0, t)
    cov = np.array([[4e-4, 1e-4], [1e-4, 9e-4]])
    spread = run_spread(f, _run(f, x0, t, 1, x), t, None, 1, lambda x: x[:, :1], cov)
    w, V = np.linalg.eigh(cov)
    root = V * np.sqrt(w)
    eps = 1e-6
    columns = [
        (
            _rk4_loop(f, x0 + eps * root[:, j], t)
            - _rk4_loop(f, x0 - eps * root[:, j], t)
        )
        / (2 * eps)
        for j in range(2)
    ]
    expected = np.sqrt(sum(c[:, 0] ** 2 for c in columns))
    np.testing.assert_allclose(spread[:, 0], expected, rtol=1e-5)


def test_an_undetermined_initial_state_spreads_the_whole_run():
    t = np.linspace(0.0, 1.0, 11)

    def f(x, t, u=None):
        return -x

    x = _run(f, [1.0], t, 1, np.exp(-t)[:, None])
    cov = np.array([[np.nan]])
    assert np.all(np.isinf(run_spread(f, x, t, None, 1, lambda x: x, cov)))


def test_determined_until_is_the_first_scored_time_past_the_limit():
    t = np.arange(6.0)
    spread = np.array(
        [[0.0, 5.0], [0.0, 0.0], [0.1, 0.2], [3.0, 0.0], [0.0, 0.0], [9, 9]]
    )
    noise = np.array([1.0, 1.0]) / SPREAD_LIMIT
    assert determined_until(spread, noise, t) == 0.0
    assert determined_until(spread, noise, t, first=1) == 3.0
    assert determined_until(spread[:3], noise, t[:3], first=1) is None


def _evidence(out_extended, spread):
    return Evidence(
        contradicted=True,
        consistency="chi2 = 900 on 400 dof",
        terms=["x1^2 x2 in x2'"],
        assumed_converged=True,
        extended_converged=True,
        rmse_assumed=np.array([1.3]),
        rmse_extended=np.array([0.1]),
        noise_floor=np.array([0.1]),
        channel_names=["x1"],
        out_assumed=np.array([0.5]),
        out_extended=np.array([out_extended]),
        out_source="a held-out stretch",
        out_spread=spread,
    )


SPREAD = "the extended model's run on a held-out stretch is not determined by its start"


@pytest.mark.parametrize("out_extended", [2.0, 0.48])  # worse / too small a gain
def test_a_run_its_start_spreads_is_not_called_the_models_failure(out_extended):
    plain = conclude(_evidence(out_extended, None))
    spread = conclude(_evidence(out_extended, SPREAD))
    assert plain.label == ("not explained" if out_extended > 0.5 else "inconclusive")
    assert spread.label == "inconclusive"
    assert any(SPREAD in r for r in spread.reasons)
    assert any("KStepAhead" in a for a in spread.advice)


def test_an_explanation_names_the_spread_among_its_reasons():
    found = conclude(_evidence(0.11, SPREAD))
    assert found.label == "explained"
    assert SPREAD in found.reasons


def test_blocks_of_the_run_chain_into_the_same_spread(monkeypatch):
    # blocks of 7 intervals (a last one short) against the run in one block
    def f(x, t, u=None):
        return np.column_stack([x[:, 1], -x[:, 0] + x[:, 1] - x[:, 0] ** 2 * x[:, 1]])

    t = np.linspace(0.0, 8.0, 321)
    x = _rk4_loop(f, np.array([1.5, 0.2]), t)
    cov = np.array([[4e-4, 1e-4], [1e-4, 9e-4]])
    whole = run_spread(f, x, t, None, 1, lambda x: x, cov)
    monkeypatch.setattr(spread_module, "BLOCK", 7)
    blocks = run_spread(f, x, t, None, 1, lambda x: x, cov)
    np.testing.assert_allclose(blocks, whole, rtol=1e-12)


def test_the_window_states_covariance_matches_its_errors_over_seeds():
    # what the spread starts from: the paper's held-out window (16 samples of
    # x1 at 40 Hz, x2 unmeasured), the true model fitted to it; over 30 noise
    # seeds the state's error in the units of its covariance is chi-square
    # with 2 dof (mean 2, sd of a 30-seed mean 0.37)
    from types import SimpleNamespace

    from pysindy_mme.core.integrate import InputSignal
    from pysindy_mme.protocols.runs import _window_fit
    from pysindy_mme.protocols.spread import noise_covariance_of
    from pysindy_mme.systems import van_der_pol

    system = van_der_pol()
    study = SimpleNamespace(
        offsets=False,
        noise_cov=np.array([[0.01]]),
        measurement=np.array([[1.0, 0.0]]),
        n_states=2,
    )

    def model(x, t, u=None):
        return system.true_model(x, t)

    chi2 = []
    for seed in range(30):
        data = system.measure(seed)
        rows = slice(data.t.size - 80, data.t.size - 64)
        y, t, x = data.y[rows], data.t[rows], data.x[rows]
        fit = _window_fit(study, model, None, 1, y, t, InputSignal(None, t), x)
        error = fit.x[0] - x[0]
        chi2.append(error @ np.linalg.solve(noise_covariance_of(fit), error))
    assert 1.0 < np.mean(chi2) < 3.2
