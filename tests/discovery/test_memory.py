"""The memory test of the model error (pysindy_mme.discovery.memory).

References are built by hand: a model error that is a static function of
the states (however non-smooth) must not be called memory; the output of a
hysteresis (a state of its own, driven by the velocity) must be.
"""

import numpy as np
import pytest

from pysindy_mme.discovery.memory import MemoryEvidence, memory_evidence


def _oscillation(n=4000, seed=0):
    """A displacement and velocity of a multi-tone motion, sampled finely."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 40.0, n)
    freqs = np.array([0.31, 0.57, 0.83, 1.21])
    phases = rng.uniform(0, 2 * np.pi, freqs.size)
    w = 2 * np.pi * freqs
    y = np.sin(w * t[:, None] + phases).sum(axis=1)
    v = (w * np.cos(w * t[:, None] + phases)).sum(axis=1)
    return t, np.column_stack([y, v])


def _bouc_wen_force(t, v, alpha=1.0, beta=2.0, gamma=0.5, delta=0.5):
    """Hysteretic force driven by ``v`` (explicit Euler on a fine grid)."""
    z = np.zeros_like(v)
    for k in range(t.size - 1):
        dt = t[k + 1] - t[k]
        dz = alpha * v[k] - beta * (gamma * abs(v[k]) * z[k] + delta * v[k] * abs(z[k]))
        z[k + 1] = z[k] + dt * dz
    return z


def test_static_nonsmooth_error_is_not_memory():
    t, x = _oscillation()
    rng = np.random.default_rng(1)
    # Coulomb friction and a cubic spring: static, one of them a jump
    g = -0.8 * np.sign(x[:, 1]) - 0.3 * x[:, 0] ** 3
    d = np.zeros_like(x)
    d[:, 1] = g + 0.05 * g.std() * rng.standard_normal(t.size)
    (ev,) = memory_evidence(x, d, error_states=[1])
    assert isinstance(ev, MemoryEvidence)
    assert ev.r2_static > 0.8
    assert not ev.suspected


def test_hysteresis_is_memory():
    t, x = _oscillation()
    z = _bouc_wen_force(t, x[:, 1])
    d = np.zeros_like(x)
    d[:, 1] = -z
    (ev,) = memory_evidence(x, d, error_states=[1])
    assert ev.suspected
    assert ev.r2_history - ev.r2_static >= 0.25
    assert ev.lag >= 1
    assert "predictable" in ev.describe("v")


def test_a_lag_never_reaches_across_records():
    t, x = _oscillation(n=2000)
    z = _bouc_wen_force(t, x[:, 1])
    d = np.zeros_like(x)
    d[:, 1] = -z
    one = memory_evidence(x, d, error_states=[1])[0]
    two = memory_evidence(x, d, error_states=[1], starts=(0, 1000))[0]
    assert two.suspected == one.suspected
    assert np.isfinite(two.r2_history)


def test_default_error_states_are_those_with_an_error():
    t, x = _oscillation(n=1000)
    d = np.zeros_like(x)
    d[:, 1] = np.sign(x[:, 1])
    out = memory_evidence(x, d)
    assert [m.state for m in out] == [1]


@pytest.mark.parametrize("constant", [0.0, 3.0])
def test_a_constant_error_gives_no_evidence(constant):
    t, x = _oscillation(n=1000)
    d = np.zeros_like(x)
    d[:, 1] = constant
    (ev,) = memory_evidence(x, d, error_states=[1])
    assert not ev.suspected


def test_the_neighbour_average_is_scikit_learns_regressor():
    from sklearn.neighbors import KNeighborsRegressor

    from pysindy_mme.discovery.memory import N_NEIGHBOURS, _knn_predict

    rng = np.random.default_rng(3)
    f = rng.standard_normal((3000, 4))
    y = np.sin(f[:, 0]) + 0.1 * rng.standard_normal(3000)
    train, test = f[:2400], f[2400:]
    expected = (
        KNeighborsRegressor(n_neighbors=N_NEIGHBOURS).fit(train, y[:2400]).predict(test)
    )
    got = _knn_predict(train, y[:2400], test)
    np.testing.assert_allclose(got, expected, rtol=1e-12)
