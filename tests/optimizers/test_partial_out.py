"""FloatingFStepwise.fit(..., partial_out=...): selection given regressors
every model holds (Frisch-Waugh-Lovell), checked against a joint least
squares solved by numpy, and on a hidden effect that a re-fitted parameter
half mimics."""

import warnings

import numpy as np
import pytest

from pysindy_mme import FloatingFStepwise
from pysindy_mme.optimizers.partial import project_out


def _tank(seed, n=1500):
    """A level ``h`` and the model error of ``h' = -a h`` (``a`` fitted) when
    the truth is ``h' = -k sqrt(h)``: ``d = -k sqrt(h) + a_hat h`` plus noise.

    The library holds the true ``sqrt(h)`` and look-alikes that bend the
    other way (overflow-like ramps ``max(h - c, 0)``) and a constant.
    """
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 60.0, n)
    h = 5.0 + 3.0 * np.sin(0.31 * t) + 1.5 * np.sin(0.83 * t + 1.0)
    k = 0.8
    # the linear model's best rate along this trajectory
    a_hat = float(np.linalg.lstsq(h[:, None], k * np.sqrt(h), rcond=None)[0][0])
    d = -k * np.sqrt(h) + a_hat * h + 0.01 * rng.standard_normal(n)
    names = ["sqrt(h)"] + [f"over(h, {c})" for c in (4, 6, 8)] + ["1"]
    theta = np.column_stack(
        [np.sqrt(h)] + [np.maximum(h - c, 0.0) for c in (4, 6, 8)] + [np.ones(n)]
    )
    return theta, d, h, names, k


def test_coefficients_equal_the_joint_least_squares():
    rng = np.random.default_rng(0)
    n = 400
    x = rng.standard_normal((n, 5))
    nuisance = np.column_stack(
        [rng.standard_normal(n), x[:, 0] + rng.standard_normal(n)]
    )
    y = 2.0 * x[:, 1] - 1.5 * x[:, 3] + nuisance @ [0.7, -0.4] + 0.3
    y = y + 0.05 * rng.standard_normal(n)
    opt = FloatingFStepwise(fit_intercept=True).fit(x, y, partial_out=[nuisance])
    support = np.flatnonzero(opt.coef_[0])
    assert list(support) == [1, 3]
    # numpy's least squares on the constant, the nuisance and the support
    design = np.column_stack([np.ones(n), nuisance, x[:, support]])
    reference = np.linalg.lstsq(design, y, rcond=None)[0]
    np.testing.assert_allclose(opt.coef_[0, support], reference[3:], rtol=1e-9)
    # the constant is the joint one, with the columns as given
    np.testing.assert_allclose(opt.intercept_[0], reference[0], rtol=1e-9)
    table = opt.anova_[0]
    residual = y - design @ reference
    s2 = residual @ residual / (n - design.shape[1])
    se = np.sqrt(s2 * np.linalg.inv(design.T @ design)[0, 0])
    np.testing.assert_allclose(table.intercept_std_error, se, rtol=1e-9)
    assert opt.n_partialled_.tolist() == [2]


def test_weighted_projection_matches_repeated_rows():
    rng = np.random.default_rng(1)
    n = 300
    x = rng.standard_normal((n, 4))
    nuisance = rng.standard_normal((n, 1))
    y = x[:, 2] - 0.5 * nuisance[:, 0] + 0.1 * rng.standard_normal(n)
    w = rng.integers(1, 4, n).astype(float)
    weighted = FloatingFStepwise(fit_intercept=True, f_enter=4.0, f_remove=3.9)
    weighted.fit(x, y, sample_weight=w, partial_out=[nuisance])
    rep = np.repeat(np.arange(n), w.astype(int))
    repeated = FloatingFStepwise(fit_intercept=True, f_enter=4.0, f_remove=3.9)
    repeated.fit(x[rep], y[rep], partial_out=[nuisance[rep]])
    np.testing.assert_allclose(weighted.coef_, repeated.coef_, rtol=1e-9, atol=1e-12)


def test_each_target_gets_its_own_columns_and_none_means_nothing():
    rng = np.random.default_rng(2)
    n = 500
    x = rng.standard_normal((n, 6))
    nuis = rng.standard_normal((n, 1))
    y = np.column_stack([x[:, 0] + 0.9 * nuis[:, 0], x[:, 4] - x[:, 5]])
    y = y + 0.05 * rng.standard_normal((n, 2))
    opt = FloatingFStepwise(fit_intercept=True).fit(x, y, partial_out=[nuis, None])
    plain = FloatingFStepwise(fit_intercept=True).fit(x, y[:, 1])
    assert np.flatnonzero(opt.coef_[0]).tolist() == [0]
    np.testing.assert_allclose(opt.coef_[1], plain.coef_[0], rtol=1e-12)
    assert opt.n_partialled_.tolist() == [1, 0]


def test_dependent_columns_count_once():
    rng = np.random.default_rng(3)
    n = 200
    a = rng.standard_normal(n)
    nuisance = np.column_stack([a, 2.0 * a + 1.0, np.full(n, 5.0)])  # rank 1 beside 1
    x_p, y_p, rank = project_out(
        rng.standard_normal((n, 3)), rng.standard_normal((n, 1)), nuisance, np.ones(n)
    )
    assert rank == 1
    assert abs(float(a @ (y_p[:, 0] - y_p.mean()))) < 1e-9 * n


def test_an_insignificant_joint_constant_is_dropped():
    """``y = x1 + 3 n`` with ``n`` far from zero: centred, ``n`` would leave
    a large constant; in the joint model there is none, so it is dropped and
    the coefficients are refit without it (as numpy's least squares)."""
    rng = np.random.default_rng(5)
    n = 600
    x = rng.standard_normal((n, 3))
    nuisance = 10.0 + rng.standard_normal((n, 1))
    y = x[:, 1] + 3.0 * nuisance[:, 0] + 0.05 * rng.standard_normal(n)
    opt = FloatingFStepwise(fit_intercept=True).fit(x, y, partial_out=[nuisance])
    assert opt.intercept_dropped_[0] and opt.intercept_[0] == 0.0
    design = np.column_stack([nuisance, x[:, 1]])
    reference = np.linalg.lstsq(design, y, rcond=None)[0]
    np.testing.assert_allclose(opt.coef_[0, 1], reference[1], rtol=1e-9)
    assert np.flatnonzero(opt.coef_[0]).tolist() == [1]


def test_a_refitted_parameter_no_longer_makes_a_look_alike():
    """The hidden effect: ``-k sqrt(h)`` beside a linear model's ``-a h``.

    Without ``partial_out`` the stepwise regression explains ``d`` by
    look-alikes (the ramps, a constant): the shape ``sqrt(h)`` alone cannot
    explain ``-k sqrt(h) + a h``. Given ``h`` (the parameter's sensitivity),
    it finds ``sqrt(h)`` with ``-k``, and nothing else, on every seed.
    """
    found = 0
    for seed in range(5):
        theta, d, h, names, k = _tank(seed)
        given = FloatingFStepwise(fit_intercept=True).fit(
            theta, d, feature_names=names, partial_out=[h[:, None]]
        )
        support = [names[j] for j in np.flatnonzero(given.coef_[0])]
        if support == ["sqrt(h)"] and abs(given.coef_[0, 0] + k) < 0.01 * k:
            found += 1
    assert found == 5
    theta, d, h, names, k = _tank(0)
    plain = FloatingFStepwise(fit_intercept=True).fit(theta, d, feature_names=names)
    assert [names[j] for j in np.flatnonzero(plain.coef_[0])] != ["sqrt(h)"]


def test_summary_says_what_was_projected_out_and_inputs_are_kept():
    theta, d, h, names, _ = _tank(0)
    copies = theta.copy(), d.copy(), h.copy()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the constant column stays usable
        opt = FloatingFStepwise(fit_intercept=True).fit(
            theta, d, feature_names=names, partial_out=[h]
        )
    assert "partial_out: 1 column projected out" in str(opt.summary())
    for before, after in zip(copies, (theta, d, h)):
        np.testing.assert_array_equal(before, after)


def test_nan_rows_are_dropped_from_the_columns_too():
    theta, d, h, names, _ = _tank(0)
    theta_nan, d_nan = theta.copy(), d.copy()
    theta_nan[[0, -1]] = np.nan  # FiniteDifference(drop_endpoints=True)'s rows
    with_nan = FloatingFStepwise(fit_intercept=True).fit(
        theta_nan, d_nan, partial_out=[h[:, None]]
    )
    without = FloatingFStepwise(fit_intercept=True).fit(
        theta[1:-1], d[1:-1], partial_out=[h[1:-1, None]]
    )
    np.testing.assert_allclose(with_nan.coef_, without.coef_, rtol=1e-12)


@pytest.mark.parametrize(
    "partial_out, match",
    [
        (np.ones((10, 1)), "one entry per target"),
        ([np.ones((9, 1)), None], "has 2 entries but y has 1"),
        ([np.ones((9, 1))], r"partial_out\[0\] must have shape \(n_samples, k\)"),
        ([np.full((10, 1), np.nan)], r"partial_out\[0\] contains NaN"),
        ([np.ones((10, 8))], "no degrees of freedom"),
        ([np.ones((10, 1)) * 1j], "Complex"),
    ],
)
def test_bad_partial_out_is_a_clear_value_error(partial_out, match):
    x = np.random.default_rng(0).standard_normal((10, 2))
    with pytest.raises(ValueError, match=match):
        FloatingFStepwise().fit(x, x[:, 0], partial_out=partial_out)


def test_partial_out_needs_an_in_memory_library():
    from pysindy_mme.optimizers import StreamedDesign

    x = np.random.default_rng(0).standard_normal((50, 4))
    design = StreamedDesign(lambda a, b: x[:, a:b], 50, 4)
    with pytest.raises(ValueError, match="in-memory array"):
        FloatingFStepwise().fit(design, x[:, 0], partial_out=[x[:, :1]])
