"""FloatingFStepwise as a drop-in pysindy optimizer.

The second half carries over the generic optimizer checks of pysindy's own
test suite (``test/test_optimizers.py``: fit on simple derivative data,
coefficient shapes, complexity, not-fitted errors, alternate parameters,
sample weights, bad parameters, convergence warnings, ensembling), written
afresh for this optimizer.
"""

from __future__ import annotations

import pickle
import re
import warnings

import numpy as np
import pysindy as ps
import pytest
from pysindy.optimizers import EnsembleOptimizer
from pysindy.utils import supports_multiple_targets
from sklearn.base import clone
from sklearn.exceptions import ConvergenceWarning, NotFittedError
from sklearn.utils.validation import check_is_fitted

from pysindy_mme import FloatingFStepwise, systems
from pysindy_mme.optimizers import ConstantNotInLibraryWarning


@pytest.fixture(scope="module")
def vdp():
    system = systems.van_der_pol()
    m = system.measure(0, noise_variance=1e-4, full_state=True)
    return system, m


def fit_sindy(y, t, optimizer=None, degree=3, **kwargs):
    model = ps.SINDy(
        optimizer=FloatingFStepwise() if optimizer is None else optimizer,
        feature_library=ps.PolynomialLibrary(degree=degree),
        differentiation_method=ps.SmoothedFiniteDifference(),
    )
    return model.fit(y, t=t, **kwargs)


def support_names(model):
    names = model.get_feature_names()
    return [{names[j] for j in np.flatnonzero(row)} for row in model.coefficients()]


# --------------------------------------------------------------------- drop-in
def test_sindy_fit_print_predict_simulate_score(vdp, capsys):
    system, m = vdp
    model = fit_sindy(m.y, m.t, feature_names=["x1", "x2"])
    # The true right-hand side, term for term, no constant.
    assert support_names(model) == [{"x2"}, {"x1", "x2", "x1^2 x2"}]
    coef = dict(zip(model.get_feature_names(), model.coefficients()[1], strict=True))
    assert coef["x1"] == pytest.approx(-1.0, abs=0.05)
    assert coef["x1^2 x2"] == pytest.approx(-1.0, abs=0.05)

    model.print()
    printed = capsys.readouterr().out.splitlines()
    assert re.fullmatch(r"\(x1\)' = +(0\.99\d|1\.00\d) x2", printed[0])
    assert "x1^2 x2" in printed[1] and " 1 " not in printed[1]

    # predict: the library times coef_ (plus intercept_), by an independent path.
    theta = model.feature_library.transform(m.y)
    np.testing.assert_allclose(
        model.predict(m.y),
        np.asarray(theta) @ model.coefficients().T + model.optimizer.intercept_,
        rtol=1e-12,
    )
    assert model.score(m.y, t=m.t) > 0.99

    t_sim = m.t[:200]
    sim = model.simulate(np.asarray(system.x0), t_sim)
    assert sim.shape == (200, 2)
    assert np.max(np.abs(sim - m.x[:200])) < 0.05

    text = model.optimizer.summary(model.get_feature_names(), model.feature_names)
    assert "(x2)'" in text and "x1^2 x2" in text and "Due to regression" in text


def test_multiple_trajectories(vdp):
    system = vdp[0]
    runs = [
        system.measure(seed, noise_variance=1e-4, full_state=True, x0=x0)
        for seed, x0 in ((1, (1.0, 0.0)), (2, (-2.0, 1.0)), (3, (0.5, -0.5)))
    ]
    model = fit_sindy([r.y for r in runs], [r.t for r in runs])
    assert support_names(model) == [{"x1"}, {"x0", "x1", "x0^2 x1"}]
    # The optimizer saw all samples of all trajectories.
    assert model.optimizer.anova_[0].n == sum(r.t.size for r in runs)
    pred = model.predict([r.y for r in runs])
    assert isinstance(pred, list) and len(pred) == 3


@pytest.mark.parametrize(
    "make",
    [FloatingFStepwise.paper, lambda: FloatingFStepwise(autocorrelation=None)],
    ids=["paper", "default rule, classic F"],
)
def test_integer_weights_equal_repeated_rows(make):
    # Frequency weights: exact under classic partial F-ratios. (The robust
    # F-ratios of the default do not count repeated rows as independent
    # evidence; see test_default_weights_are_scale_free.)
    rng = np.random.default_rng(0)
    n = 120
    X = rng.standard_normal((n, 8))
    Y = np.column_stack([X[:, 0] - 0.4 * X[:, 5], 2 + X[:, 3]])
    Y = Y + 0.3 * rng.standard_normal((n, 2))
    w = rng.integers(0, 4, n)
    rows = np.repeat(np.arange(n), w)
    weighted = make().fit(X, Y, sample_weight=w)
    repeated = make().fit(X[rows], Y[rows])
    np.testing.assert_allclose(weighted.coef_, repeated.coef_, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(weighted.intercept_, repeated.intercept_, rtol=1e-10)
    for a, b in zip(weighted.steps_, repeated.steps_, strict=True):
        assert [(s.action, s.feature) for s in a] == [(s.action, s.feature) for s in b]
        np.testing.assert_allclose(
            [s.partial_f for s in a], [s.partial_f for s in b], rtol=1e-9
        )
    assert weighted.anova_[0].n == repeated.anova_[0].n == w.sum()
    # Weights that are all equal to 1 change nothing.
    plain = make().fit(X, Y)
    ones = make().fit(X, Y, sample_weight=np.ones(n))
    np.testing.assert_array_equal(plain.coef_, ones.coef_)


def test_clone_params_pickle_round_trip(vdp):
    _, m = vdp
    opt = FloatingFStepwise(f_enter=8.0, float_ratio=20.0, max_report=3)
    params = opt.get_params()
    assert params["f_enter"] == 8.0 and params["float_ratio"] == 20.0
    # (floating's default became "auto" with issue 11's default rule)
    assert params["f_remove"] is None and params["floating"] == "auto"
    assert opt.set_params(f_enter=9.0) is opt
    assert opt.f_enter == 9.0
    twin = clone(opt)
    assert twin is not opt and twin.get_params() == opt.get_params()
    with pytest.raises(NotFittedError):
        check_is_fitted(twin)

    model = fit_sindy(m.y, m.t, optimizer=opt)
    restored = pickle.loads(pickle.dumps(model))
    np.testing.assert_array_equal(restored.predict(m.y), model.predict(m.y))
    np.testing.assert_array_equal(restored.coefficients(), model.coefficients())
    assert restored.optimizer.summary() == model.optimizer.summary()
    # A clone of a fitted optimizer is unfitted and refits to the same model.
    refit = fit_sindy(m.y, m.t, optimizer=clone(model.optimizer))
    np.testing.assert_array_equal(refit.coefficients(), model.coefficients())


def test_each_equation_has_its_own_support():
    system = systems.lorenz()
    m = system.measure(0, noise_variance=1e-4, full_state=True, t=system.time(5.0))
    model = fit_sindy(m.y, m.t, optimizer=FloatingFStepwise(floating=False), degree=2)
    assert support_names(model) == [
        {"x0", "x1"},
        {"x0", "x1", "x0 x2"},
        {"x2", "x0 x1"},
    ]
    assert model.optimizer.coef_.shape == (3, 10)
    assert all(
        len(s) >= k for s, k in zip(model.optimizer.steps_, [2, 3, 2], strict=True)
    )


# ---------------------------------------------- checks from pysindy's own suite
@pytest.fixture
def ramp_1d():
    x = 2 * np.linspace(1, 100, 100).reshape(-1, 1)
    return x, 2 * np.ones((100, 1))


@pytest.fixture
def ramp_2d():
    ramp = np.linspace(1, 100, 100)
    x = np.column_stack([2 * ramp, -10 * ramp])
    return x, np.column_stack([2 * np.ones(100), -10 * np.ones(100)])


@pytest.mark.parametrize("data", ["ramp_1d", "ramp_2d"])
def test_fit_on_constant_derivatives(data, request):
    x, x_dot = request.getfixturevalue(data)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        opt = FloatingFStepwise(fit_intercept=True).fit(x, x_dot)
    # The two ramps of ramp_2d are collinear: the second is set aside.
    assert len(caught) == (1 if x.shape[1] == 2 else 0)
    assert opt.excluded_ == ({1: "collinear with f0"} if x.shape[1] == 2 else {})
    check_is_fitted(opt)
    assert opt.coef_.shape == (x_dot.shape[1], x.shape[1])
    assert opt.intercept_.shape == (x_dot.shape[1],)
    # A constant target: no function is significant, the intercept carries it.
    assert not np.any(opt.coef_)
    assert opt.complexity == np.count_nonzero(opt.intercept_) == x_dot.shape[1]
    np.testing.assert_allclose(opt.predict(x), x_dot, rtol=1e-12)
    # pysindy's convention (the default): the library has no constant column,
    # so the model is through the origin and predicts what coef_ says; a
    # warning says the constant was significant.
    with pytest.warns(ConstantNotInLibraryWarning, match="constant is significant"):
        origin = FloatingFStepwise().fit(x, x_dot)
    np.testing.assert_array_equal(origin.intercept_, 0.0)
    np.testing.assert_allclose(origin.predict(x), x @ origin.coef_.T, rtol=1e-12)


def test_not_fitted_errors():
    opt = FloatingFStepwise()
    with pytest.raises(NotFittedError):
        opt.predict(np.ones((1, 3)))
    with pytest.raises(NotFittedError):
        opt.complexity  # noqa: B018
    with pytest.raises(NotFittedError):
        opt.summary()


def test_complexity_counts_terms(ramp_2d):
    rng = np.random.default_rng(3)
    X = rng.standard_normal((80, 6))
    Y = np.column_stack([X[:, 1] + 3, X[:, 2] - X[:, 4]])
    opt = FloatingFStepwise(fit_intercept=True)
    opt.fit(X, Y + 0.01 * rng.standard_normal((80, 2)))
    assert opt.complexity == 4  # x1 and the intercept; x2 and x4


@pytest.mark.parametrize(
    "kwargs", [{"normalize_columns": True}, {"copy_X": False}, {"unbias": True}]
)
def test_compatibility_parameters_change_nothing(kwargs):
    rng = np.random.default_rng(4)
    X = rng.standard_normal((100, 5)) * [1e-3, 1.0, 1e3, 1.0, 10.0]
    y = 2e3 * X[:, 0] + 1e-3 * X[:, 2] + 0.1 * rng.standard_normal(100)
    X_before = X.copy()
    base = FloatingFStepwise().fit(X, y)
    other = FloatingFStepwise(**kwargs).fit(X, y)
    np.testing.assert_array_equal(other.coef_, base.coef_)
    np.testing.assert_array_equal(X, X_before)
    assert set(np.flatnonzero(base.coef_[0])) == {0, 2}


def test_initial_guess_is_refused_not_ignored(ramp_1d):
    x, x_dot = ramp_1d
    with pytest.raises(ValueError, match="initial_guess is not supported"):
        FloatingFStepwise(initial_guess=np.zeros((1, 1))).fit(x, x_dot)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"f_enter": 4.0, "alpha": 0.05}, "alpha=0.05 is the default rule"),
        ({"alpha_enter": 0.05, "alpha": 0.001}, "alpha=0.001 is the default rule"),
        ({"floating": False, "float_ratio": 5.0}, "floating=False never runs"),
        ({"normalize_columns": "yes"}, "normalize_columns must be True or False"),
        ({"unbias": 1}, "unbias must be True or False"),
    ],
)
def test_a_parameter_the_rule_would_not_read_raises(ramp_1d, kwargs, match):
    x, x_dot = ramp_1d
    with pytest.raises(ValueError, match=match):
        FloatingFStepwise(**kwargs).fit(x, x_dot)


def test_the_rule_parameters_that_apply_are_accepted(ramp_1d):
    x, x_dot = ramp_1d
    # defaults of the other rule's parameters are "not given"
    FloatingFStepwise(f_enter=4.0, floating=False).fit(x, x_dot)
    FloatingFStepwise(alpha=0.05, floating=True, float_ratio=5.0).fit(x, x_dot)
    FloatingFStepwise.paper().fit(x, x_dot)


def test_zero_weights_drop_samples():
    rng = np.random.default_rng(5)
    X = rng.standard_normal((101, 4))
    y = X[:, 0] - X[:, 3] + 0.2 * rng.standard_normal(101)
    w = np.ones(101)
    w[::2] = 0
    weighted = FloatingFStepwise().fit(X, y, sample_weight=w)
    subset = FloatingFStepwise().fit(X[1::2], y[1::2])
    np.testing.assert_allclose(weighted.coef_, subset.coef_, rtol=1e-12)
    assert weighted.anova_[0].n == 50


@pytest.mark.parametrize("params", [dict(f_enter=-1), dict(max_iter=0)])
def test_bad_parameters_through_sindy(params, vdp):
    _, m = vdp
    opt = FloatingFStepwise(**params)  # storing is fine, fitting is not
    with pytest.raises(ValueError, match=next(iter(params))):
        fit_sindy(m.y, m.t, optimizer=opt)


def test_max_iter_convergence_warning():
    system = systems.lorenz()
    m = system.measure(1, noise_variance=1e-4, full_state=True, t=system.time(2.0))
    with pytest.warns(ConvergenceWarning):
        model = fit_sindy(m.y, m.t, optimizer=FloatingFStepwise(max_iter=1))
    assert not model.optimizer.converged_
    assert model.optimizer.n_iter_.max() == 1


def test_supports_multiple_targets():
    assert supports_multiple_targets(FloatingFStepwise())


def test_inside_pysindy_ensemble(vdp):
    _, m = vdp
    theta = ps.PolynomialLibrary(degree=3).fit_transform(m.x)
    x_dot = systems.van_der_pol().true_model(m.x, 0.0)
    opt = EnsembleOptimizer(FloatingFStepwise(), bagging=True, n_models=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        opt.fit(theta, x_dot)
    assert opt.coef_.shape == (2, 10)
    assert len(opt.coef_list) == 3
    # Noise-free derivatives: every bag (whatever rows it draws) finds the
    # true support.
    assert np.flatnonzero(opt.coef_[0]).tolist() == [2]
    assert np.flatnonzero(opt.coef_[1]).tolist() == [1, 2, 7]
