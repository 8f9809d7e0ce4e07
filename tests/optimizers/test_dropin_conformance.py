"""FloatingFStepwise as a drop-in pysindy optimizer (issue 21).

The printed model is the model that predicts (the constant in ``coef_``,
never in an ``intercept_`` that pysindy neither prints nor ensembles); rows
that are all NaN are dropped as pysindy's ``BaseOptimizer.fit`` drops them;
rows not in time order (shuffled, bootstrapped, the windows of a weak
library) are recognised and the default rule falls back to the ordinary
test there.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pysindy as ps
import pytest
from scipy.integrate import solve_ivp

from pysindy_mme import FloatingFStepwise
from pysindy_mme.optimizers import ConstantNotInLibraryWarning


# --------------------------------------------------- x' = 1 - x, a constant term
def _relaxation(n=400, noise=1e-3, seed=0):
    t = np.linspace(0, 8, n)
    x = 1 - 0.9 * np.exp(-t)  # x' = 1 - x from x(0) = 0.1
    rng = np.random.default_rng(seed)
    return t, (x + noise * rng.standard_normal(n)).reshape(-1, 1)


def _assert_printed_is_predicting(model, x):
    """predict(x) is the library times the printed coefficients, nothing else."""
    theta = np.asarray(model.feature_library.transform(x))
    np.testing.assert_allclose(
        model.predict(x), theta @ model.coefficients().T, rtol=1e-12, atol=1e-12
    )
    np.testing.assert_array_equal(model.optimizer.intercept_, 0.0)


def test_constant_in_coef_on_the_bias_column():
    t, x = _relaxation()
    model = ps.SINDy(
        optimizer=FloatingFStepwise(),
        feature_library=ps.PolynomialLibrary(degree=2, include_bias=True),
    ).fit(x, t=t)
    names = model.get_feature_names()
    coef = model.coefficients()[0]
    assert coef[names.index("1")] == pytest.approx(1.0, abs=0.01)
    assert coef[names.index("x0")] == pytest.approx(-1.0, abs=0.01)
    assert re.search(r"0\.99\d 1 \+", model.equations()[0])
    _assert_printed_is_predicting(model, x)
    np.testing.assert_allclose(model.predict(np.array([[0.0]])), [[1.0]], atol=0.01)


def test_no_bias_column_fits_through_the_origin_and_says_so():
    # The case: without a constant column the constant went into
    # intercept_, which predict used and print did not show.
    t, x = _relaxation()
    model = ps.SINDy(
        optimizer=FloatingFStepwise(),
        feature_library=ps.PolynomialLibrary(degree=2, include_bias=False),
    )
    with pytest.warns(
        ConstantNotInLibraryWarning, match="constant is significant in target 0"
    ):
        model.fit(x, t=t)
    _assert_printed_is_predicting(model, x)
    assert model.optimizer.intercept_dropped_[0]
    # Outside SINDy, fit_intercept=True keeps scikit-learn's meaning.
    theta = np.asarray(model.feature_library.transform(x))
    x_dot = 1 - x[:, 0]
    opt = FloatingFStepwise(fit_intercept=True).fit(theta, x_dot)
    assert opt.intercept_[0] == pytest.approx(1.0, abs=1e-6)
    assert opt.coef_[0, 0] == pytest.approx(-1.0, abs=1e-6)


@pytest.mark.parametrize("include_bias", [True, False])
def test_ensemble_keeps_the_constant_it_prints(include_bias):
    t, x = _relaxation()
    np.random.seed(1)  # noqa: NPY002 (pysindy's bagging draws from it)
    ensemble = ps.EnsembleOptimizer(opt=FloatingFStepwise(), bagging=True, n_models=8)
    model = ps.SINDy(
        optimizer=ensemble,
        feature_library=ps.PolynomialLibrary(degree=2, include_bias=include_bias),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        model.fit(x, t=t)
    _assert_printed_is_predicting(model, x)
    # Bootstrap rows are not in time order: the inner fits saw that.
    assert not ensemble.opt.rows_in_time_order_
    if include_bias:  # the truth at x = 0 is 1 (it was predicted 0.0)
        np.testing.assert_allclose(model.predict(np.array([[0.0]])), [[1.0]], atol=0.02)


# ------------------------------------------------------------------ NaN rows
def test_nan_end_rows_dropped_as_pysindy_drops_them():
    t, x = _relaxation(noise=0.0)
    lib = ps.PolynomialLibrary(degree=2)
    fd = ps.FiniteDifference(drop_endpoints=True)
    x_dot = fd(x, t)
    assert np.isnan(x_dot[0, 0]) and np.isnan(x_dot[-1, 0])
    ours = ps.SINDy(
        optimizer=FloatingFStepwise(), feature_library=lib, differentiation_method=fd
    ).fit(x, t=t)
    stlsq = ps.SINDy(
        optimizer=ps.STLSQ(), feature_library=lib, differentiation_method=fd
    ).fit(x, t=t)
    assert set(np.flatnonzero(ours.coefficients()[0])) == set(
        np.flatnonzero(stlsq.coefficients()[0])
    )
    # Exactly the fit on the interior rows.
    theta = np.asarray(lib.fit(x).transform(x))
    inner = FloatingFStepwise().fit(theta[1:-1], x_dot[1:-1])
    np.testing.assert_array_equal(ours.coefficients(), inner.coef_)
    assert ours.optimizer.Theta_.shape[0] == x.shape[0] - 2
    # Their weights go with them; a row with some finite targets is an error.
    w = np.linspace(1, 2, x.shape[0])
    weighted = FloatingFStepwise().fit(theta, x_dot, sample_weight=w)
    ref = FloatingFStepwise().fit(theta[1:-1], x_dot[1:-1], sample_weight=w[1:-1])
    np.testing.assert_array_equal(weighted.coef_, ref.coef_)
    two = np.column_stack([x_dot[:, 0], np.nan_to_num(x_dot[:, 0])])
    with pytest.raises(ValueError, match=r"contains NaN \(first at row 0, column 0"):
        FloatingFStepwise().fit(theta, two)
    # A row whose library values are all NaN goes too.
    theta_nan = theta.copy()
    theta_nan[5] = np.nan
    dropped = FloatingFStepwise().fit(theta_nan[1:-1], x_dot[1:-1])
    np.testing.assert_array_equal(
        dropped.coef_,
        FloatingFStepwise()
        .fit(np.delete(theta, [0, 5, -1], 0), np.delete(x_dot, [0, 5, -1], 0))
        .coef_,
    )


# ---------------------------------------------------------- rows in time order
def _lorenz(T=10.0, dt=0.002):
    def rhs(_, s):
        x, y, z = s
        return [10 * (y - x), x * (28 - z) - y, x * y - 8 / 3 * z]

    t = np.arange(0, T, dt)
    sol = solve_ivp(rhs, (0, T), [-8, 8, 27], t_eval=t, rtol=1e-10, atol=1e-10)
    return t, sol.y.T


LORENZ_SUPPORT = [{"x0", "x1"}, {"x0", "x1", "x0 x2"}, {"x2", "x0 x1"}]


def _false_terms(model):
    names = model.get_feature_names()
    return sum(
        len({names[j] for j in np.flatnonzero(row)} - true)
        for row, true in zip(model.coefficients(), LORENZ_SUPPORT, strict=True)
    )


def test_time_order_detected_or_declared():
    t, x = _lorenz(T=4.0, dt=0.005)
    lib = ps.PolynomialLibrary(degree=2)
    theta = np.asarray(lib.fit(x).transform(x))
    x_dot = ps.SmoothedFiniteDifference()(x, t)
    ordered = FloatingFStepwise(floating=False).fit(theta, x_dot)
    assert ordered.rows_in_time_order_ and ordered.anova_[0].robust
    shuffle = np.random.default_rng(0).permutation(x.shape[0])
    shuffled = FloatingFStepwise().fit(theta[shuffle], x_dot[shuffle])
    assert not shuffled.rows_in_time_order_
    assert not shuffled.anova_[0].robust and shuffled.phase_two_.all()
    assert "rows not in time order: the ordinary test" in str(shuffled.summary())
    declared = FloatingFStepwise(time_ordered=True).fit(theta[shuffle], x_dot[shuffle])
    assert declared.rows_in_time_order_ and declared.anova_[0].robust
    # A sample_weight pattern (every other row weighted 0) keeps the order.
    w = np.tile([1.0, 0.0], x.shape[0] // 2 + 1)[: x.shape[0]]
    assert FloatingFStepwise().fit(theta, x_dot, sample_weight=w).rows_in_time_order_


def _weak_lorenz_false_terms(optimizer, seeds, t, x_clean, noise=0.05):
    counts = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        x = x_clean + noise * x_clean.std(axis=0) * rng.standard_normal(x_clean.shape)
        np.random.seed(seed)  # noqa: NPY002 (the windows' random centres)
        lib = ps.WeakPDELibrary(
            function_library=ps.PolynomialLibrary(degree=2, include_bias=False),
            spatiotemporal_grid=t,
        )
        model = ps.SINDy(feature_library=lib, optimizer=optimizer())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model.fit(x, t=t)
        counts.append(_false_terms(model))
    return counts, model


def test_weak_library_default_keeps_no_false_terms():
    """Lorenz, WeakPDELibrary, 5 % noise: rows are windows at random centres.

    Measured over 20 seeds (``test_weak_library_compared``): the Newey-West
    default kept false terms in 17 (30 in all); with the fallback, 1 seed
    has one, like the paper's rule; STLSQ none.
    """
    t, x = _lorenz()
    counts, model = _weak_lorenz_false_terms(FloatingFStepwise, range(6), t, x)
    assert not model.optimizer.rows_in_time_order_
    assert sum(c == 0 for c in counts) >= 5, counts


@pytest.mark.slow
def test_weak_library_compared():
    t, x = _lorenz()
    seeds = range(20)
    found = {
        name: _weak_lorenz_false_terms(make, seeds, t, x)[0]
        for name, make in (
            ("default", FloatingFStepwise),
            ("paper", FloatingFStepwise.paper),
            ("STLSQ", ps.STLSQ),
            ("declared in time order", lambda: FloatingFStepwise(time_ordered=True)),
        )
    }
    clean = {name: sum(c == 0 for c in counts) for name, counts in found.items()}
    print(f"\nseeds without a false term (of 20): {clean}")
    print(f"false terms: { {k: sum(v) for k, v in found.items()} }")
    assert clean["default"] >= 17  # measured 19
    assert clean["default"] >= clean["paper"] - 1  # measured 19 and 19
    assert clean["declared in time order"] <= 8  # measured 3: what the fallback fixes
