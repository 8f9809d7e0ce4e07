"""FloatingFStepwise reliability: determinism, no mutation, column-order and
unit invariance on the paper's Van der Pol case, and failures during a fit
that end in a warning plus a flag on the result.

These came from the former cross-package reliability suite; they belong in
``tests/optimizers/`` (owned with the optimizers at the time of the move):
move them there and delete this file. The generated (hypothesis) stepwise
properties are in ``tests/properties/test_stepwise_properties.py``.
"""

from __future__ import annotations

import warnings

import numpy as np
import pysindy as ps
import pytest
from reliability_support import (
    assert_same_global_random_state,
    global_random_state,
    readonly,
)
from sklearn.exceptions import ConvergenceWarning

from pysindy_mme import (
    MME,
    ExcludedFeaturesWarning,
    FloatingFStepwise,
    PowerLibrary,
    StepwiseCycleWarning,
)
from pysindy_mme.systems import van_der_pol

VDP = van_der_pol()
_DATA = VDP.measure(0)

_RNG = np.random.default_rng(5)
X_LIB = readonly(_RNG.standard_normal((20, 3)))


# ---------------------------------------------------------------- determinism


def test_stepwise_is_deterministic_pure_and_leaves_inputs_alone():
    rng = np.random.default_rng(11)
    X = rng.standard_normal((300, 40))
    X[:, 7] = X[:, 3]  # a duplicate
    X[5, 9] = np.nan  # a non-finite column
    y = np.column_stack([X[:, 3] - 0.5 * X[:, 20], X[:, 1] ** 2])
    y += 0.1 * rng.standard_normal(y.shape)
    w = rng.integers(1, 4, 300).astype(float)
    Xr, yr, wr = readonly(X), readonly(y), readonly(w)
    before = global_random_state()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcludedFeaturesWarning)
        a = FloatingFStepwise().fit(Xr, yr, sample_weight=wr)
        b = FloatingFStepwise().fit(Xr, yr, sample_weight=wr)
        c = FloatingFStepwise()
        c.fit(Xr[:100], yr[:100])  # the same object, fitted on something else first
        c.fit(Xr, yr, sample_weight=wr)
    assert_same_global_random_state(before)
    for other in (b, c):
        np.testing.assert_array_equal(a.coef_, other.coef_)
        np.testing.assert_array_equal(a.intercept_, other.intercept_)
        assert a.steps_ == other.steps_
        assert a.excluded_ == other.excluded_
    for got, orig in ((Xr, X), (yr, y), (wr, w)):
        np.testing.assert_array_equal(got, orig)


# ------------------------------------------------- column order and units


@pytest.fixture(scope="module")
def vdp_model_error():
    """MME on the paper's case: the estimated states and d(t) in x2'."""
    m = MME(
        VDP.assumed_model, 2, measured=[0], noise_variance=0.01, error_states=[1]
    ).fit(readonly(_DATA.y), readonly(_DATA.t))
    return m.smoothed_x_, m.d_[:, 1]


@pytest.mark.parametrize(
    "library",
    [ps.PolynomialLibrary(degree=3), PowerLibrary()],
    ids=["PolynomialLibrary(3)", "PowerLibrary (Table I)"],
)
def test_vdp_selected_terms_do_not_depend_on_column_order(library, vdp_model_error):
    x_hat, d = vdp_model_error
    lib = library.fit(x_hat)
    with np.errstate(all="ignore"):
        theta = np.asarray(lib.transform(x_hat))
    names = np.asarray(lib.get_feature_names(["x1", "x2"]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcludedFeaturesWarning)
        base = FloatingFStepwise().fit(theta, d)
        selected = set(names[np.flatnonzero(base.coef_[0])])
        assert selected  # the correction is found at all
        if isinstance(library, ps.PolynomialLibrary):
            assert selected == {"x1", "x2", "x1^2 x2"}  # the paper's answer
        rng = np.random.default_rng(0)
        for _ in range(8):
            perm = rng.permutation(theta.shape[1])
            opt = FloatingFStepwise().fit(theta[:, perm], d)
            assert set(names[perm][np.flatnonzero(opt.coef_[0])]) == selected
            np.testing.assert_allclose(
                opt.predict(theta[:, perm]), base.predict(theta), rtol=1e-9, atol=1e-12
            )


@pytest.mark.parametrize("unit", [1e-6, 1e6])
def test_vdp_regression_selects_the_same_terms_in_any_units(unit, vdp_model_error):
    x_hat, d = vdp_model_error
    lib = ps.PolynomialLibrary(degree=3).fit(x_hat)
    names = np.asarray(lib.get_feature_names(["x1", "x2"]))
    base = FloatingFStepwise().fit(np.asarray(lib.transform(x_hat)), d)
    scaled = FloatingFStepwise().fit(np.asarray(lib.transform(x_hat * unit)), d * unit)
    assert set(names[np.flatnonzero(scaled.coef_[0])]) == set(
        names[np.flatnonzero(base.coef_[0])]
    )


# ----------------------------------------------- failures mid-computation


def test_stepwise_cycle_warns_flags_and_stops():
    # The paper's Phase II: removing x1 (F < F(x0)/10) lowers F(x0) so much
    # that x1 re-enters.
    rng = np.random.default_rng(3)
    X = rng.standard_normal((300, 5))
    y = X[:, 0] + 0.28 * X[:, 1] + 0.01 * rng.standard_normal(300)
    with pytest.warns(StepwiseCycleWarning, match="cycle of 2 models"):
        opt = FloatingFStepwise.paper(max_iter=100_000).fit(X, y)
    assert opt.cycle_detected_ is True
    assert opt.converged_ is True
    assert opt.n_iter_[0] < 10  # stopped at the repeat, not at max_iter
    assert "a cycle was detected" in opt.summary()


def test_stepwise_max_iter_warns_and_flags():
    with pytest.warns(ConvergenceWarning, match="max_iter=1"):
        opt = FloatingFStepwise(max_iter=1).fit(X_LIB, np.asarray(X_LIB) @ [1.0, 1, 1])
    assert opt.converged_ is False
    assert "did not settle" in opt.summary()


def test_stepwise_unusable_columns_are_set_aside_and_reported():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((50, 8))
    y = X[:, 0] - X[:, 1] + 0.05 * rng.standard_normal(50)
    X[3, 2] = np.nan
    X[:, 3] = 0.0
    X[:, 4] = X[:, 0]
    X[:, 5] = 1.0
    X[:, 6] = 2.0
    X[:, 7] = 1e305 * X[:, 1]  # |x| * n_samples beyond the double range
    with pytest.warns(ExcludedFeaturesWarning, match="can never be selected"):
        opt = FloatingFStepwise().fit(X, y)
    reasons = opt.excluded_
    assert reasons[2] == "non-finite values"
    assert reasons[3] == "all zero"
    assert reasons[4] == "duplicate of f0"
    assert reasons[6].startswith("constant")
    assert reasons[7].startswith("values too large for double precision")
    assert opt.constant_feature_ == 5
    assert set(np.flatnonzero(opt.coef_[0])) == {0, 1}  # no constant: dropped
