"""FloatingFStepwiseCV: blocked folds, the chosen level, pysindy use, bad input."""

from __future__ import annotations

import numpy as np
import pysindy as ps
import pytest
from sklearn.base import clone

from pysindy_mme.optimizers import FloatingFStepwise, FloatingFStepwiseCV
from pysindy_mme.optimizers.cv import blocked_folds
from pysindy_mme.systems import van_der_pol


def test_blocked_folds_are_contiguous_and_spare_the_gap():
    n, k, gap = 103, 4, 3
    tested = []
    for train, test in blocked_folds(n, k, gap):
        assert np.array_equal(test, np.arange(test[0], test[-1] + 1))
        assert np.intersect1d(train, test).size == 0
        # No training row within `gap` rows of the block.
        dist = np.abs(train[:, None] - test[None, :]).min()
        assert dist == gap + 1
        assert train.size + test.size == n - 2 * gap + (test[0] < gap) * (
            gap - test[0]
        ) + (n - 1 - test[-1] < gap) * (gap - (n - 1 - test[-1]))
        tested.append(test)
    np.testing.assert_array_equal(np.concatenate(tested), np.arange(n))


def _problem(seed=0, n=300):
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, 15))
    Y = np.column_stack([X[:, 0] - 0.5 * X[:, 3], 2 + X[:, 7]])
    return X, Y + 0.3 * rng.standard_normal((n, 2))


def test_cv_errors_match_an_independent_recomputation():
    X, Y = _problem()
    alphas = (1e-4, 0.3)
    cv = FloatingFStepwiseCV(alphas=alphas, n_splits=3, gap=2).fit(X, Y)
    scale = Y.var(axis=0)
    expected = np.zeros((2, 3))
    for b, (train, test) in enumerate(blocked_folds(len(X), 3, 2)):
        for i, alpha in enumerate(alphas):
            opt = FloatingFStepwise(alpha=alpha).fit(X[train], Y[train])
            err = (opt.predict(X[test]) - Y[test]) ** 2 / scale
            expected[i, b] = err.mean()
    np.testing.assert_allclose(cv.cv_errors_, expected, rtol=1e-10)
    assert cv.alpha_ == alphas[int(np.argmin(expected.mean(axis=1)))]
    # The refit is an ordinary FloatingFStepwise at the chosen level.
    ref = FloatingFStepwise(alpha=cv.alpha_).fit(X, Y)
    np.testing.assert_array_equal(cv.coef_, ref.coef_)
    one_se = FloatingFStepwiseCV(alphas=alphas, n_splits=3, gap=2, selection="1se")
    assert one_se.fit(X, Y).alpha_ <= cv.alpha_


def test_inside_sindy_with_summary_and_clone():
    system = van_der_pol()
    m = system.measure(0, noise_variance=1e-4, full_state=True)
    model = ps.SINDy(
        optimizer=FloatingFStepwiseCV(alphas=(1e-4, 0.01, 0.1), n_splits=3),
        feature_library=ps.PolynomialLibrary(degree=3),
        differentiation_method=ps.SmoothedFiniteDifference(),
    )
    model.fit(m.y, t=m.t, feature_names=["x1", "x2"])
    names = np.array(model.get_feature_names())
    found = [set(names[np.flatnonzero(row)]) for row in model.coefficients()]
    assert found == [{"x2"}, {"x1", "x2", "x1^2 x2"}]
    text = model.optimizer.summary(model.get_feature_names(), model.feature_names)
    assert text.startswith("FloatingFStepwiseCV: 3 contiguous blocks")
    assert "<- chosen" in text and "Due to regression" in text
    assert "<pre>" in text._repr_html_()
    twin = clone(model.optimizer)
    assert twin.get_params()["n_splits"] == 3 and not hasattr(twin, "alpha_")


@pytest.mark.parametrize(
    "params, error, match",
    [
        (dict(alphas=()), ValueError, "alphas must be a non-empty sequence"),
        (dict(alphas=(0.01, 1.0)), ValueError, "alphas must lie strictly between"),
        (dict(n_splits=1), ValueError, "n_splits must be >= 2"),
        (dict(n_splits=2.5), TypeError, "n_splits must be an integer"),
        (dict(gap=-1), ValueError, "gap must be a non-negative integer"),
        (dict(n_splits=50, gap=5), ValueError, "too few for n_splits=50"),
        (dict(selection="best"), ValueError, "selection must be '1se' or 'min'"),
        (
            dict(estimator=ps.STLSQ()),
            TypeError,
            "estimator must be a FloatingFStepwise",
        ),
        (
            dict(estimator=FloatingFStepwise.paper()),
            ValueError,
            "estimator uses the classic rule",
        ),
    ],
)
def test_bad_parameters(params, error, match):
    X, Y = _problem()
    with pytest.raises(error, match=match):
        FloatingFStepwiseCV(**params).fit(X, Y)
