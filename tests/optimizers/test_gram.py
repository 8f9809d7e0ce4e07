"""Selection from the library's moments (tall, narrow libraries).

* Decision equivalence: the moments path (``GramState``) and the path on the
  data (``IncrementalQR``) take the same steps and give the same support,
  coefficients (to 1e-9 relative) and tables, on several systems, rules,
  sample weights and NaN rows.
* Correctness against independent references: least squares by
  ``np.linalg.lstsq``, Newey-West variances by a direct per-row, per-lag
  computation, Bartlett windows against the per-lag formula.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pysindy as ps
import pytest
from scipy.integrate import solve_ivp

from pysindy_mme.optimizers import FloatingFStepwise
from pysindy_mme.optimizers import moments as moments_module
from pysindy_mme.optimizers.gram import GramState
from pysindy_mme.optimizers.moments import library_moments, pair_vectors
from pysindy_mme.optimizers.robust import (
    long_run_covariance,
    long_run_variance,
    newey_west_lags,
)
from pysindy_mme.optimizers.screening import screen_columns


# ----------------------------------------------------------------- references
def nw_direct(u, lags):
    """Newey-West long-run covariance, one lag at a time, row by row."""
    u = np.asarray(u, dtype=float).reshape(u.shape[0], -1)
    n = u.shape[0]
    out = np.zeros((u.shape[1], u.shape[1]))
    for k in range(-min(lags, n - 1), min(lags, n - 1) + 1):
        w = 1.0 - abs(k) / (lags + 1.0)
        for t in range(max(0, -k), min(n, n - k)):
            out += w * np.outer(u[t], u[t + k])
    return out


def _trajectory(rhs, x0, n, dt, noise, seed):
    t = np.arange(n) * dt
    sol = solve_ivp(rhs, (0, t[-1]), x0, t_eval=t, rtol=1e-10, atol=1e-10)
    rng = np.random.default_rng(seed)
    x = sol.y.T
    return x + noise * x.std(axis=0) * rng.standard_normal(x.shape), dt


def _lorenz(t, x):
    return [10 * (x[1] - x[0]), x[0] * (28 - x[2]) - x[1], x[0] * x[1] - 8 / 3 * x[2]]


def _van_der_pol(t, x):
    return [x[1], (1 - x[0] ** 2) * x[1] - x[0]]


def _rossler(t, x):
    return [-x[1] - x[2], x[0] + 0.2 * x[1], 0.2 + x[2] * (x[0] - 5.7)]


def _problem(name, seed):
    """Library, derivatives (pysindy's), of a short noisy record."""
    if name == "lorenz":
        x, dt = _trajectory(_lorenz, (-8, 8, 27), 3000, 0.002, 0.01, seed)
        degree = 2
    elif name == "van_der_pol":
        x, dt = _trajectory(_van_der_pol, (2, 0), 3000, 0.01, 0.02, seed)
        degree = 3
    else:
        x, dt = _trajectory(_rossler, (1, 1, 0), 4000, 0.01, 0.01, seed)
        degree = 2
    dx = ps.SmoothedFiniteDifference()._differentiate(x, dt)
    theta = np.asarray(ps.PolynomialLibrary(degree).fit(x).transform(x))
    return theta, dx


def _fit(monkeypatch, path, make, theta, dx, **fit_kwargs):
    """Fit with the moments forced on or off; checks which path ran."""
    used = []

    def spy(*args, **kwargs):
        out = library_moments(*args, **kwargs)
        used.append(out is not None)
        return out

    monkeypatch.setattr(moments_module, "library_moments", spy)
    rows = 0 if path == "gram" else np.iinfo(np.int64).max
    monkeypatch.setattr(moments_module, "MIN_ROWS", rows)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        opt = make().fit(theta, dx, **fit_kwargs)
    assert used == ([True] if path == "gram" else [])
    return opt


def _assert_same(a, b):
    """Same steps, support, coefficients (1e-9) and tables (1e-7)."""
    for sa, sb in zip(a.steps_, b.steps_, strict=True):
        assert [(s.action, s.feature, s.phase) for s in sa] == [
            (s.action, s.feature, s.phase) for s in sb
        ]
        np.testing.assert_allclose(
            [s.partial_f for s in sa], [s.partial_f for s in sb], rtol=1e-7
        )
    np.testing.assert_array_equal(a.ind_, b.ind_)
    np.testing.assert_allclose(a.coef_, b.coef_, rtol=1e-9, atol=0)
    np.testing.assert_allclose(a.intercept_, b.intercept_, rtol=1e-9, atol=1e-300)
    np.testing.assert_array_equal(a.phase_two_, b.phase_two_)
    np.testing.assert_allclose(a.phase_one_lag1_, b.phase_one_lag1_, rtol=1e-9)
    for ja, jb in zip(a.joint_tests_, b.joint_tests_, strict=True):
        assert (ja is None) == (jb is None)
        if ja is not None:
            assert ja["restart"] == jb["restart"] and ja["n"] == jb["n"]
            assert ja["f"] == pytest.approx(jb["f"], rel=1e-7)
    for ta, tb in zip(a.anova_, b.anova_, strict=True):
        for f in dataclasses.fields(ta):
            va, vb = getattr(ta, f.name), getattr(tb, f.name)
            if isinstance(vb, (float, np.ndarray)):
                np.testing.assert_allclose(va, vb, rtol=1e-7, err_msg=f.name)
            else:
                assert va == vb, f.name


# errors_in_variables=False: these compare the two paths of the library as
# given (the corrected moments replace both; tests/optimizers/
# test_errors_in_variables.py)
RULES = {
    "default": lambda: FloatingFStepwise(errors_in_variables=False),
    "paper": FloatingFStepwise.paper,
    "alpha_enter": lambda: FloatingFStepwise(
        alpha_enter=0.01, errors_in_variables=False
    ),
    "ordinary": lambda: FloatingFStepwise(
        autocorrelation=None, errors_in_variables=False
    ),
}


@pytest.mark.parametrize("name", ["lorenz", "van_der_pol", "rossler"])
@pytest.mark.parametrize("rule", list(RULES))
def test_same_decisions(monkeypatch, name, rule):
    theta, dx = _problem(name, seed=3)
    a = _fit(monkeypatch, "gram", RULES[rule], theta, dx)
    b = _fit(monkeypatch, "direct", RULES[rule], theta, dx)
    _assert_same(a, b)


@pytest.mark.parametrize("seed", [0, 1])
def test_same_decisions_weights_and_nan_rows(monkeypatch, seed):
    theta, dx = _problem("lorenz", seed)
    rng = np.random.default_rng(seed)
    w = rng.integers(0, 4, theta.shape[0]).astype(float)  # zeros dropped
    theta, dx = theta.copy(), dx.copy()
    theta[:5], dx[:5] = np.nan, np.nan  # FiniteDifference(drop_endpoints=True)
    theta[-3:], dx[-3:] = np.nan, np.nan
    a = _fit(monkeypatch, "gram", FloatingFStepwise, theta, dx, sample_weight=w)
    b = _fit(monkeypatch, "direct", FloatingFStepwise, theta, dx, sample_weight=w)
    _assert_same(a, b)
    np.testing.assert_array_equal(a.Theta_, b.Theta_)


def test_same_decisions_joint_restart(monkeypatch):
    # Hopf normal form at 5 % noise: forward selection misses y (x^2 + y^2)
    # terms; the joint test restarts (joint_tests_ in test_default_rule).
    def hopf(t, x, mu=0.5):
        r2 = x[0] ** 2 + x[1] ** 2
        return [mu * x[0] - x[1] - x[0] * r2, x[0] + mu * x[1] - x[1] * r2]

    parts = [
        _trajectory(hopf, x0, 1500, 0.01, 0.05, 5)[0] for x0 in ((2, 0), (0.01, 0))
    ]
    theta = np.vstack([ps.PolynomialLibrary(3).fit(p).transform(p) for p in parts])
    dx = np.vstack(
        [ps.SmoothedFiniteDifference()._differentiate(p, 0.01) for p in parts]
    )
    a = _fit(monkeypatch, "gram", RULES["default"], theta, dx)
    b = _fit(monkeypatch, "direct", RULES["default"], theta, dx)
    assert any(j is not None for j in b.joint_tests_)
    _assert_same(a, b)


def test_ill_conditioned_falls_back(monkeypatch):
    # A noise-free target in the span of the library: no moments, same fit.
    rng = np.random.default_rng(0)
    X = rng.standard_normal((500, 4))
    y = X[:, 1] - 2 * X[:, 3]
    monkeypatch.setattr(moments_module, "MIN_ROWS", 0)
    opt = FloatingFStepwise().fit(X, y)
    np.testing.assert_allclose(opt.coef_[0], [0, 1, 0, -2], atol=1e-12)
    screen = screen_columns(X, np.ones(500), 500.0, 1e-8)
    mo = library_moments(X, np.ones(500), y[:, None], screen, 3)
    assert not mo.usable[0]


def test_an_exact_target_beside_noisy_ones(monkeypatch):
    # Targets may depend on each other; a noise-free one is selected on the
    # data, the others from the moments, with the same decisions.
    theta, dx = _problem("lorenz", seed=4)
    exact = theta[:, 1] - 0.5 * theta[:, 5]
    y = np.column_stack([dx, exact, dx[:, 0] + dx[:, 1]])
    a = _fit(monkeypatch, "gram", RULES["default"], theta, y)
    b = _fit(monkeypatch, "direct", RULES["default"], theta, y)
    _assert_same(a, b)
    mo = library_moments(
        theta, np.ones(len(y)), y, screen_columns(theta, np.ones(len(y)), len(y), 1e-8)
    )
    np.testing.assert_array_equal(mo.usable, [True, True, True, False, True])


def test_use_moments():
    assert moments_module.use_moments(10**6, 13)
    assert not moments_module.use_moments(1000, 13)
    assert not moments_module.use_moments(10**6, 40)


# ------------------------------------------------------- independent references
@pytest.mark.parametrize("n, lags", [(1, 3), (2, 5), (7, 10), (50, 0), (300, 4)])
def test_long_run_covariance_matches_per_lag(n, lags):
    rng = np.random.default_rng(n)
    u = rng.standard_normal((n, 3))
    u[:, 1] = np.cumsum(u[:, 1]) + 2.0  # autocorrelated, not centred
    ref = nw_direct(u, lags)
    np.testing.assert_allclose(long_run_covariance(u, lags), ref, rtol=1e-12)
    np.testing.assert_allclose(long_run_variance(u, lags), np.diag(ref), rtol=1e-12)
    assert long_run_variance(u[:, 1], lags) == pytest.approx(ref[1, 1], rel=1e-12)


def _state(seed=0, n=600, weights=True):
    """A GramState on a random autocorrelated problem, with its raw data."""
    rng = np.random.default_rng(seed)
    X = np.cumsum(rng.standard_normal((n, 5)), axis=0) / 10 + rng.standard_normal(
        (n, 5)
    )
    e = np.convolve(rng.standard_normal(n + 4), np.ones(5) / 5, "valid")
    y = 0.7 + X[:, 0] - 0.5 * X[:, 2] + 0.3 * e
    w = rng.uniform(0.5, 2.0, n) if weights else np.ones(n)
    sw = np.sqrt(w)
    screen = screen_columns(X, sw, float(w.sum()), 1e-8)
    lags = newey_west_lags(n)
    mo = library_moments(X, sw, y[:, None], screen, lags)
    state = GramState(mo, 0, screen, float(w.sum()), 1e-8)
    Xs = X * screen.scale  # the state's units
    return state, Xs, y, sw, lags


def test_coefficients_match_lstsq():
    state, Xs, y, sw, _ = _state()
    for j in (0, 2, 4):
        state.add(j)
    A = np.column_stack([sw, Xs[:, [0, 2, 4]] * sw[:, None]])
    ref = np.linalg.lstsq(A, y * sw, rcond=None)[0]
    resid = y * sw - A @ ref
    ref[1:] *= state.scale[[0, 2, 4]]  # coefficients() is in data units
    np.testing.assert_allclose(state.coefficients(), ref, rtol=1e-11)
    assert state.sse() == pytest.approx(resid @ resid, rel=1e-11)
    state.remove(2)
    A = np.column_stack([sw, Xs[:, [0, 4]] * sw[:, None]])
    ref = np.linalg.lstsq(A, y * sw, rcond=None)[0]
    ref[1:] *= state.scale[[0, 4]]
    np.testing.assert_allclose(state.coefficients(), ref, rtol=1e-11)


def test_robust_statistics_match_direct_per_row():
    state, Xs, y, sw, lags = _state(seed=1)
    state.add(0)
    state.add(2)
    n = y.size
    A = np.column_stack([sw, Xs[:, [0, 2]] * sw[:, None]])
    beta, *_ = np.linalg.lstsq(A, y * sw, rcond=None)
    e = y * sw - A @ beta
    # rows of the pseudo-inverse: b = C^T (y sw), C = A (A^T A)^-1
    C = A @ np.linalg.inv(A.T @ A)
    var = np.array([nw_direct(C[:, i] * e, lags)[0, 0] for i in range(3)])
    ref = beta**2 / (var * n / (n - 3))
    np.testing.assert_allclose(state.robust_in_model_f(lags), ref, rtol=1e-9)
    # candidate 1: its residual against the model, the enlarged model's residual
    x1 = Xs[:, 1] * sw
    r = x1 - A @ np.linalg.lstsq(A, x1, rcond=None)[0]
    g = r @ e
    v = nw_direct(r * (e - r * g / (r @ r)), lags)[0, 0] * n / (n - 4)
    classic = state.candidate_f()
    robust = state.robust_candidate_f(lags, classic)
    assert robust[1] == pytest.approx(g**2 / v, rel=1e-9)
    assert state.residual_lag1() == pytest.approx((e[:-1] @ e[1:]) / (e @ e), rel=1e-9)


def test_pseudo_rows_keep_the_cross_products():
    state, Xs, y, sw, lags = _state(seed=2)
    xs, yp, wp = state.pseudo_rows([3, 1])
    assert wp.sum() == pytest.approx(sw @ sw, rel=1e-14)
    swp = np.sqrt(wp)
    Zp = np.column_stack([swp, xs * swp[:, None], yp * swp])
    Z = np.column_stack([sw, Xs[:, [3, 1]] * sw[:, None], y * sw])
    np.testing.assert_allclose(Zp.T @ Zp, Z.T @ Z, rtol=1e-11, atol=1e-11 * n_abs(Z))


def n_abs(Z):
    return float(np.max(np.abs(Z.T @ Z)))


def test_table_effective_n_matches_direct():
    state, Xs, y, sw, lags = _state(seed=3)
    stats = state.table_statistics([0, 2], [1], lags)
    A = np.column_stack([sw, Xs[:, [0, 2]] * sw[:, None]])
    e = y * sw - A @ np.linalg.lstsq(A, y * sw, rcond=None)[0]
    ref = y.size * (e @ e) / nw_direct(e, lags)[0, 0]
    assert stats["effective_n"] == pytest.approx(ref, rel=1e-9)


def test_pair_vectors():
    rng = np.random.default_rng(0)
    U = rng.standard_normal((20, 4))
    a, b = rng.standard_normal(4), rng.standard_normal(4)
    i, j = np.triu_indices(4)
    P = U[:, i] * U[:, j]
    np.testing.assert_allclose(P @ pair_vectors(a, b)[:, 0], (U @ a) * (U @ b))
