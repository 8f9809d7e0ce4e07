"""Whether a free run's miss of held-out data is the uncertainty of its fit
(``protocols/uncertainty.py``), checked against independent references.

* The miss's distribution (noise plus a weighted sum of chi-squares) against
  scipy's chi-square where it has a closed form.
* The covariance of the fitted quantities with the initial state against an
  exact least-squares problem (``tests/exact_reference.py``).
* The start's columns with an offset against the closed form of an undamped
  oscillator.
* The coefficients' draws reproduce the covariance they are drawn from.
"""

import numpy as np
import pytest
from exact_reference import exact_lstsq, exact_normal_inverse
from scipy import stats

from pysindy_mme.core.integrate import simulate_guided
from pysindy_mme.discovery.conclusion import FIT_FACTOR
from pysindy_mme.protocols.spread import spread_columns
from pysindy_mme.protocols.uncertainty import (
    AT_THE_NOISE,
    MISS_LEVEL,
    MissColumns,
    RunUncertainty,
    coefficient_draws,
    miss_p_value,
    run_uncertainty,
)
from pysindy_mme.solver.output_error import OutputErrorFit, OutputErrorModel


def test_the_run_at_the_noise_is_the_conclusions_fit_factor():
    assert AT_THE_NOISE == FIT_FACTOR


@pytest.mark.parametrize(
    "observed, weights, reference",
    [
        (3.0, [0.5], stats.chi2.sf(4.0, 1)),  # 1 + 0.5 chi2_1 >= 3
        (4.0, [0.5] * 3, stats.chi2.sf(6.0, 3)),  # 1 + 0.5 chi2_3 >= 4
        (1.0 + 2.0 * 9.21, [2.0, 2.0], stats.chi2.sf(9.21, 2)),
    ],
)
def test_the_miss_of_a_noise_free_mean_is_a_weighted_chi_square(
    observed, weights, reference
):
    p, _ = miss_p_value(observed, weights, np.inf)
    # Monte Carlo over 200,000 draws: a few standard errors
    assert p == pytest.approx(reference, abs=4 * np.sqrt(reference / 2e5) + 1e-5)


def test_the_noise_alone_is_its_own_chi_square():
    # no coefficient draws: the mean square of K m noise readings
    p, upper = miss_p_value(1.3, [], 100)
    assert p == pytest.approx(stats.chi2.sf(130.0, 100), rel=1e-9)
    assert upper == pytest.approx(stats.chi2.ppf(1 - MISS_LEVEL, 100) / 100, rel=0.02)


def test_the_answer_is_the_same_on_every_call():
    assert miss_p_value(5.0, [1.0, 0.3], 400) == miss_p_value(5.0, [1.0, 0.3], 400)


def test_expected_miss_is_the_noise_plus_the_columns_mean_square():
    rng = np.random.default_rng(3)
    K = 400
    draws = [0.02 * rng.standard_normal((K, 2)) for _ in range(3)]
    start = 0.01 * rng.standard_normal((K, 2, 2))
    observed = np.ones((K, 2), bool)
    sd = np.array([0.01, 0.02])
    found = run_uncertainty(draws, start, observed, np.array([0.05, 0.06]), sd)
    cols = np.concatenate([np.stack(draws, axis=2), start], axis=2) / sd[None, :, None]
    mean_square = np.mean(np.sum(cols**2, axis=2))  # over samples and channels
    assert found.expected == pytest.approx(np.sqrt(1 + mean_square), rel=1e-12)
    assert found.observed == pytest.approx(np.sqrt((25 + 9) / 2), rel=1e-12)
    assert found.directions == 3


def test_a_miss_far_beyond_the_columns_is_the_models():
    K = 200
    observed = np.ones((K, 1), bool)
    tiny = [np.full((K, 1), 1e-3)]
    far = run_uncertainty(tiny, None, observed, np.array([0.1]), np.array([0.01]))
    assert far.beyond and far.p_value < MISS_LEVEL
    near = run_uncertainty(
        [np.full((K, 1), 0.05)], None, observed, np.array([0.05]), np.array([0.01])
    )
    assert not near.beyond and near.p_value > 0.1


def test_a_draw_that_diverges_concludes_nothing():
    K = 50
    found = run_uncertainty(
        [np.full((K, 1), np.inf)],
        None,
        np.ones((K, 1), bool),
        np.array([1.0]),
        np.array([0.01]),
    )
    assert not found.beyond and not np.isfinite(found.expected)
    assert "diverges" in found.sentence() and "not measured" in found.sentence()


def test_unobserved_readings_do_not_count():
    K = 100
    observed = np.ones((K, 1), bool)
    observed[::2] = False
    draws = [np.where(observed, 0.02, 1e6)]  # the huge values are never read
    found = run_uncertainty(draws, None, observed, np.array([0.03]), np.array([0.01]))
    assert found.expected == pytest.approx(np.sqrt(1 + 4.0), rel=1e-12)


def test_several_records_share_the_draws_and_keep_their_own_starts():
    rng = np.random.default_rng(5)
    parts = [
        MissColumns(
            [rng.standard_normal((k, 1)) for _ in range(2)],
            rng.standard_normal((k, 1, 2)),
            np.ones((k, 1), bool),
            np.array([1.0]),
        )
        for k in (30, 50)
    ]
    both = MissColumns.stacked(parts)
    assert len(both.draws) == 2 and both.draws[0].shape == (80, 1)
    assert both.start.shape == (80, 1, 4)
    # the first record's start is zero on the second record's rows
    assert np.all(both.start[30:, :, :2] == 0) and np.all(both.start[:30, :, 2:] == 0)
    np.testing.assert_array_equal(both.start[:30, :, :2], parts[0].start)
    uneven = MissColumns([], None, np.ones((5, 1), bool), np.array([1.0]))
    assert MissColumns.stacked([parts[0], uneven]) is None


def test_a_result_records_what_it_was_computed_from():
    cols = MissColumns(
        [np.full((10, 1), 0.5)], None, np.ones((10, 1), bool), np.array([1.0])
    )
    found = cols.uncertainty(np.array([1.2]))
    assert isinstance(found, RunUncertainty) and found.columns is cols
    assert "columns" not in repr(found)


# -- the covariance of the fitted quantities with the initial state ----------
def _linear_record(seed, n=300):
    # x' = c1 u1 + c2 u2 with y = x: the RK4 map with linearly interpolated
    # inputs is the trapezoid rule, so y_k = x_0 + W_k c, a linear regression
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 6.0, n)
    u = np.column_stack([np.sin(1.3 * t), np.cos(0.7 * t + 0.4)])
    h = np.diff(t)
    W = np.vstack([np.zeros(2), np.cumsum(0.5 * h[:, None] * (u[1:] + u[:-1]), 0)])
    y = 0.3 + W @ np.array([0.8, -0.5]) + 0.05 * rng.standard_normal(n)
    return t, u, y[:, None], W


def _linear_fit(t, u, y):
    def base(x, tt, uu, p):
        return np.zeros_like(x)

    def features(z, cols):
        return z[:, 1:][:, list(cols)]

    engine = OutputErrorModel(base, 1, features, y, t, u, np.eye(1) * 0.0025, np.eye(1))
    engine.noise_inflation = 1.0  # compared with the plain least-squares formula
    return engine.fit([(0, 0), (0, 1)], np.zeros(2), np.zeros((t.size, 1)))


@pytest.mark.parametrize("seed", [0, 1])
def test_the_covariance_with_the_initial_state_is_least_squares(seed):
    t, u, y, W = _linear_record(seed)
    fit = _linear_fit(t, u, y)
    X = np.column_stack([np.ones(t.size), W])
    exact = exact_lstsq(X, y[:, 0])
    resid = y[:, 0] - X @ exact
    cov = exact_normal_inverse(X) * (resid @ resid / (t.size - 3))
    np.testing.assert_allclose(fit.covariance, cov[1:, 1:], rtol=1e-6)
    np.testing.assert_allclose(fit.theta_x0_covariance[:, 0], cov[1:, 0], rtol=1e-6)
    assert fit.x0_covariance[0, 0] == pytest.approx(cov[0, 0], rel=1e-6)


def _bare_fit(slots, theta, cov, **fields):
    """An :class:`OutputErrorFit` with its statistics given, no solver."""
    return OutputErrorFit(
        slots=slots,
        theta=theta,
        x=np.zeros((4, 2)),
        converged=True,
        message="",
        rank_deficient=False,
        n_iter=1,
        _cov=cov,
        **fields,
    )


def test_a_fit_without_its_statistics_has_no_cross_covariance():
    # as a file of version 4 stored it: no covariance with the initial state
    fit = _bare_fit(
        ((0, 0),),
        np.array([1.0]),
        (np.eye(1), np.eye(2)),
        cost=1.0,
        n_residuals=4,
        n_free=3,
    )
    assert fit.theta_x0_covariance.shape == (1, 2)
    assert np.all(np.isnan(fit.theta_x0_covariance))


# -- the start's columns, with an offset -------------------------------------
def test_an_offset_adds_to_the_oscillators_rotated_covariance():
    # x1' = x2, x2' = -x1, y = x1 + offset; (x1(0), x2(0), offset) with a
    # joint covariance: y's change is c1 cos t + c2 sin t + c3 for the
    # columns c of its square root, so var = a^T S a with a = (cos, sin, 1)
    t = np.linspace(0.0, 10.0, 201)

    def f(x, t, u=None):
        return np.column_stack([x[:, 1], -x[:, 0]])

    guess = np.column_stack([np.cos(t), -np.sin(t)])
    x = simulate_guided(f, np.array([1.0, 0.0]), t, None, 4, guess).x[0]
    S = np.array([[4e-4, 1e-4, -3e-4], [1e-4, 9e-4, 2e-4], [-3e-4, 2e-4, 5e-4]])
    cols = np.concatenate(
        [HZ for _, HZ in spread_columns(f, x, t, None, 4, lambda x: x[:, :1], S)]
    )
    a = np.column_stack([np.cos(t), np.sin(t), np.ones_like(t)])
    expected = np.einsum("ki,ij,kj->k", a, S, a)
    np.testing.assert_allclose(np.sum(cols[:, 0, :] ** 2, axis=1), expected, rtol=1e-6)


# -- the coefficients' draws ---------------------------------------------------
def _fit_with(cov, held=None):
    p = cov.shape[0]
    fit = _bare_fit(
        tuple((1, j) for j in range(p - 1)),
        np.arange(1.0, p + 2.0),  # one physical parameter, p - 1 terms, an offset
        (np.pad(cov, ((0, 1), (0, 1))), np.eye(2)),
        cost=8.0,
        n_residuals=12,
        n_free=4,
        n_physical=1,
        n_offsets=1,
        _inflation=2.0,
    )
    if held is not None:
        fit.at_bound = np.asarray(held[:1], bool)
        fit.at_wall = np.asarray(held[1:], bool)
    return fit


def test_the_draws_reproduce_the_noise_share_of_the_covariance():
    rng = np.random.default_rng(2)
    B = rng.standard_normal((3, 3))
    cov = B @ B.T + 0.1 * np.eye(3)
    fit = _fit_with(cov)
    moved = np.array([d - fit.theta for d in coefficient_draws(fit, lambda f: f.theta)])
    assert moved.shape == (3, 4)
    assert np.all(moved[:, 3] == 0)  # the offset is the window's to fit
    s2 = fit.residual_variance * fit.inflation  # 8 / 8 * 2
    np.testing.assert_allclose(moved[:, :3].T @ moved[:, :3], cov / s2, rtol=1e-10)


def test_a_quantity_held_on_a_bound_is_not_drawn():
    cov = np.diag([1.0, 4.0, 9.0])
    fit = _fit_with(cov, held=[True, False, False])
    moved = np.array([d - fit.theta for d in coefficient_draws(fit, lambda f: f.theta)])
    assert moved.shape[0] == 2 and np.all(moved[:, 0] == 0)


def test_no_draws_without_a_finite_covariance():
    fit = _fit_with(np.full((3, 3), np.nan))
    assert coefficient_draws(fit, lambda f: f.theta) is None
