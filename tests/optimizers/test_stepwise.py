"""FloatingFStepwise against independent references.

* the textbook: Draper & Smith's stepwise regression of the Hald cement data,
  every partial F-ratio recomputed here by brute-force least squares;
* closed-form ANOVA quantities computed directly in the test;
* exact rational arithmetic (``fractions``) for an ill-conditioned problem;
* constructed problems for Phase II, cycles and set-aside columns.

Bad input has its table in ``test_bad_input.py``.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from exact_reference import exact_lstsq
from scipy import stats
from sklearn.exceptions import ConvergenceWarning

from pysindy_mme.optimizers import (
    ConstantNotInLibraryWarning,
    ExcludedFeaturesWarning,
    FloatingFStepwise,
    StepwiseCycleWarning,
)
from pysindy_mme.optimizers.rules import ClassicRule

# The 13-row Hald cement table (public textbook data), vendored with the tests.
HALD = Path(__file__).resolve().parents[1] / "data" / "hald_cement.csv"


@pytest.fixture(scope="module")
def hald():
    data = np.genfromtxt(HALD, delimiter=",", names=True)
    X = np.column_stack([data[f"x{i}"] for i in range(1, 5)])
    return X, np.asarray(data["y"], dtype=float)


def sse(X, y, cols):
    """Residual sum of squares of y on [1, X[:, cols]] by np.linalg.lstsq."""
    A = np.column_stack([np.ones(len(y))] + [X[:, j] for j in cols])
    resid = y - A @ np.linalg.lstsq(A, y, rcond=None)[0]
    return float(resid @ resid)


def f_enter_brute(X, y, model, j):
    """Partial F of adding column j to ``model`` (eq. 19), by two refits."""
    dof = len(y) - len(model) - 2
    new = sse(X, y, model + [j])
    return (sse(X, y, model) - new) / (new / dof)


def f_remove_brute(X, y, model, j):
    """Partial F of column j in ``model`` (eq. 20), by two refits."""
    dof = len(y) - len(model) - 1
    full = sse(X, y, model)
    return (sse(X, y, [c for c in model if c != j]) - full) / (full / dof)


# --------------------------------------------------------------- Hald / Draper & Smith
def test_hald_draper_smith_sequence(hald):
    X, y = hald
    # fit_intercept: Hald's model has a constant, and no column carries it
    opt = FloatingFStepwise(
        f_enter=4, f_remove=4, floating=False, fit_intercept=True
    ).fit(X, y)
    steps = opt.steps_[0]
    # Draper & Smith: x4 enters, x1 enters, x2 enters, x4 leaves.
    assert [(s.action, s.feature) for s in steps] == [
        ("add", 3),
        ("add", 0),
        ("add", 1),
        ("remove", 3),
    ]
    expected = [
        f_enter_brute(X, y, [], 3),
        f_enter_brute(X, y, [3], 0),
        f_enter_brute(X, y, [3, 0], 1),
        f_remove_brute(X, y, [3, 0, 1], 3),
    ]
    got = [s.partial_f for s in steps]
    np.testing.assert_allclose(got, expected, rtol=5e-5)  # 4 significant digits
    # The published values (Draper & Smith, 2 decimals).
    np.testing.assert_allclose(got, [22.80, 108.22, 5.03, 1.86], atol=0.005)
    # Each added function had the largest F of entry among the candidates.
    for model, chosen in (([], 3), ([3], 0), ([3, 0], 1)):
        others = [j for j in range(4) if j not in model]
        fs = {j: f_enter_brute(X, y, model, j) for j in others}
        assert max(fs, key=fs.get) == chosen
    # Final model y = 52.577 + 1.468 x1 + 0.662 x2.
    assert opt.intercept_[0] == pytest.approx(52.577, abs=5e-4)
    np.testing.assert_allclose(opt.coef_[0], [1.468, 0.662, 0, 0], atol=5e-4)
    assert opt.coef_[0, 2] == 0 and opt.coef_[0, 3] == 0
    assert opt.converged_ and not opt.cycle_detected_
    assert [s.n_terms for s in steps] == [1, 2, 3, 2]


def test_hald_significance_levels_stop_at_x1_x4(hald):
    X, y = hald
    opt = FloatingFStepwise(alpha_enter=0.05, alpha_remove=0.10, floating=False)
    opt.fit(X, y)
    assert set(np.flatnonzero(opt.coef_[0])) == {0, 3}
    # x2's p-value of entry given {x1, x4}, recomputed independently: 0.0517.
    f_x2 = f_enter_brute(X, y, [3, 0], 1)
    p_x2 = stats.f.sf(f_x2, 1, len(y) - 4)
    assert p_x2 == pytest.approx(0.0517, abs=5e-4)
    assert p_x2 > 0.05
    # The thresholds are F critical values at the current residual dof.
    thresholds = [s.threshold for s in opt.steps_[0]]
    np.testing.assert_allclose(
        thresholds, [stats.f.ppf(0.95, 1, 11), stats.f.ppf(0.95, 1, 10)], rtol=1e-12
    )


def test_alpha_remove_defaults_to_matlab_rule(hald):
    X, y = hald
    a = FloatingFStepwise(alpha_enter=0.05, floating=False).fit(X, y)
    b = FloatingFStepwise(alpha_enter=0.05, alpha_remove=0.10, floating=False)
    b.fit(X, y)
    np.testing.assert_array_equal(a.coef_, b.coef_)
    assert "alpha_remove = 0.1" in a.summary()


def test_hald_anova_closed_forms(hald):
    X, y = hald
    opt = FloatingFStepwise(f_enter=4, f_remove=4, floating=False).fit(X, y)
    table = opt.anova_[0]
    n, k = len(y), 2
    A = np.column_stack([np.ones(n), X[:, 0], X[:, 1]])
    fitted = A @ np.linalg.lstsq(A, y, rcond=None)[0]
    ss_res = np.sum((y - fitted) ** 2)
    ss_tot = np.sum((y - y.mean()) ** 2)
    ss_reg = np.sum((fitted - y.mean()) ** 2)  # eq. (12)
    assert table.ss_residual == pytest.approx(ss_res, rel=1e-10)
    assert table.ss_total == pytest.approx(ss_tot, rel=1e-12)
    assert table.ss_regression == pytest.approx(ss_reg, rel=1e-10)
    assert table.r2 == pytest.approx(1 - ss_res / ss_tot, rel=1e-10)
    assert table.multiple_r == pytest.approx(np.sqrt(1 - ss_res / ss_tot), rel=1e-10)
    f_model = (ss_reg / k) / (ss_res / (n - k - 1))
    assert table.f_ratio == pytest.approx(f_model, rel=1e-10)
    assert (table.dof_regression, table.dof_residual, table.dof_total) == (2, 10, 12)
    # Draper & Smith: R^2 = 0.979, F = 229.5 for y ~ x1 + x2.
    assert table.r2 == pytest.approx(0.9787, abs=5e-4)
    assert table.f_ratio == pytest.approx(229.5, abs=0.05)
    # The strongest out-of-model functions: x4 then x3 (partial F 1.86, 1.83).
    assert table.out_features[:2] == (3, 2)
    np.testing.assert_allclose(
        table.out_partial_f[:2],
        [f_enter_brute(X, y, [0, 1], 3), f_enter_brute(X, y, [0, 1], 2)],
        rtol=1e-9,
    )


def test_summary_reads_like_table_ii(hald):
    X, y = hald
    opt = FloatingFStepwise(f_enter=4, f_remove=4, floating=False)
    opt.fit(X, y, feature_names=["x1", "x2", "x3", "x4"], target_names=["y"])
    text = opt.summary()
    for phrase in (
        "Coefficient of determination",
        "Multiple corr. coefficient",
        "Variance of estimate",
        "Std error of estimate",
        "Intercept",
        "Due to regression",
        "Deviation about regression",
        "Total",
        "Functions in the model",
        "Functions not in the model",
        "Step history",
        "(y)'",
    ):
        assert phrase in text
    history = text.split("Step history")[1].splitlines()
    assert any("remove" in line and "x4" in line for line in history)
    assert "52.577" in text and "229.5" in text
    # Names passed to summary() override; generic names otherwise.
    other = opt.summary(feature_names=["a", "b", "c", "d"], target_names=["q"])
    assert "(q)'" in other and " d " in other
    generic = FloatingFStepwise(f_enter=4, floating=False).fit(X, y).summary()
    assert "f3" in generic and "target 0" in generic
    with pytest.raises(ValueError, match="feature_names"):
        opt.summary(feature_names=["a"])
    with pytest.raises(ValueError, match="target"):
        opt.summary(target=3)


# ------------------------------------------------- every step vs brute force
def _correlated_problem(seed):
    rng = np.random.default_rng(seed)
    n, p = 150, 25
    mix = 0.5 * rng.standard_normal((p, p)) + np.eye(p)
    X = rng.standard_normal((n, p)) @ mix
    beta = np.zeros(p)
    beta[rng.choice(p, 5, replace=False)] = rng.uniform(0.3, 1.0, 5)
    return X, X @ beta + rng.standard_normal(n)


@pytest.mark.parametrize("seed", [0, 1, 5, 6])
def test_every_step_matches_brute_force_refits(seed):
    """Replay the selection with two lstsq refits per partial F-ratio.

    Checks, at every step, the partial F, that the chosen function is the
    best (largest entry F / smallest in-model F), the threshold of its phase,
    and at the end that the brute-force rules allow no further step. The
    incremental updates (additions, and the Phase II removals these problems
    trigger) must agree with refits from scratch.
    """
    X, y = _correlated_problem(seed)
    f_in, ratio = 4.0, 10.0
    opt = FloatingFStepwise(
        f_enter=f_in, f_remove=f_in, floating=True, float_ratio=ratio
    ).fit(X, y)
    model = []
    removals = 0
    for step in opt.steps_[0]:
        inside = {j: f_remove_brute(X, y, model, j) for j in model}
        floating = max(inside.values()) / ratio if step.phase == 2 and model else 0
        threshold = max(f_in, floating)
        assert step.threshold == pytest.approx(threshold, rel=1e-9)
        if step.action == "add":
            outside = {
                j: f_enter_brute(X, y, model, j)
                for j in range(X.shape[1])
                if j not in model
            }
            assert step.feature == max(outside, key=outside.get)
            assert step.partial_f == pytest.approx(outside[step.feature], rel=1e-9)
            assert step.partial_f >= threshold
            model.append(step.feature)
        else:
            assert step.feature == min(inside, key=inside.get)
            assert step.partial_f == pytest.approx(inside[step.feature], rel=1e-9)
            assert step.partial_f < threshold
            model.remove(step.feature)
            removals += 1
    assert removals >= 1
    assert set(np.flatnonzero(opt.coef_[0])) == set(model)
    inside = {j: f_remove_brute(X, y, model, j) for j in model}
    outside = [f_enter_brute(X, y, model, j) for j in range(25) if j not in model]
    threshold = max(f_in, max(inside.values()) / ratio)
    assert min(inside.values()) >= threshold > max(outside)
    np.testing.assert_allclose(
        opt.anova_[0].partial_f, [inside[j] for j in sorted(model)], rtol=1e-9
    )


# ---------------------------------------------------------------------- Phase II
def _weak_term_problem(seed=0, n=400):
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, 8))
    # x0 is strong; x1 is significant (F ~ 100) but F(x0)/F(x1) >> 10.
    y = 3.0 * X[:, 0] + 0.15 * X[:, 1] + 0.3 * rng.standard_normal(n)
    return X, y


def test_phase_two_removes_weak_but_significant_term():
    X, y = _weak_term_problem()
    phase1 = FloatingFStepwise.paper(floating=False).fit(X, y)
    assert set(np.flatnonzero(phase1.coef_[0])) == {0, 1}
    f_x1 = f_remove_brute(X, y, [0, 1], 1)
    f_x0 = f_remove_brute(X, y, [0, 1], 0)
    assert 10 < f_x1 < f_x0 / 10  # significant, yet weak by the floating rule

    full = FloatingFStepwise.paper().fit(X, y)
    assert set(np.flatnonzero(full.coef_[0])) == {0}
    last = full.steps_[0][-1]
    assert (last.phase, last.action, last.feature) == (2, "remove", 1)
    assert last.partial_f == pytest.approx(f_x1, rel=1e-9)
    assert last.threshold == pytest.approx(f_x0 / 10, rel=1e-9)
    # A looser ratio keeps it.
    loose = FloatingFStepwise.paper(float_ratio=1e4).fit(X, y)
    assert set(np.flatnonzero(loose.coef_[0])) == {0, 1}
    # The default keeps it too when rows are in time order: white residuals
    # do not engage Phase II.
    default = FloatingFStepwise(time_ordered=True).fit(X, y)
    assert set(np.flatnonzero(default.coef_[0])) == {0, 1}
    assert not default.phase_two_[0] and abs(default.phase_one_lag1_[0]) < 0.2
    # These rows (independent draws) do not look like samples in time order:
    # the default then uses the ordinary test and Phase II (time_ordered).
    auto = FloatingFStepwise().fit(X, y)
    assert not auto.rows_in_time_order_ and auto.phase_two_[0]
    assert set(np.flatnonzero(auto.coef_[0])) == {0}


def test_phase_two_cycle_resolved_by_overall_f():
    # Removing x1 (F < F(x0)/10) lowers F(x0) so much that x1 re-enters: a
    # natural 2-cycle of the floating rule. The selection stops, warns, and
    # keeps the model of the cycle with the larger overall F-ratio: {x0, x1}.
    rng = np.random.default_rng(3)
    n = 300
    X = rng.standard_normal((n, 5))
    y = X[:, 0] + 0.28 * X[:, 1] + 0.01 * rng.standard_normal(n)
    with pytest.warns(StepwiseCycleWarning, match="cycle"):
        opt = FloatingFStepwise.paper().fit(X, y)
    assert opt.cycle_detected_
    assert set(np.flatnonzero(opt.coef_[0])) == {0, 1}
    actions = [(s.phase, s.action, s.feature) for s in opt.steps_[0]]
    assert (2, "remove", 1) in actions and actions[-1] == (2, "add", 1)
    assert opt.n_iter_[0] == len(opt.steps_[0]) < 10


def test_cycle_detection_with_inconsistent_thresholds(monkeypatch):
    # Force a removal threshold above the entry threshold (fit() refuses that
    # combination of parameters): x0 enters and leaves for ever without the
    # cycle check.
    X, y = _weak_term_problem()
    monkeypatch.setattr(ClassicRule, "thresholds", lambda self, k: (10.0, 1e12))
    opt = FloatingFStepwise.paper(max_iter=10_000)
    with pytest.warns(StepwiseCycleWarning):
        opt.fit(X, y)
    assert opt.cycle_detected_
    # The cycle {} -> {x0} -> {} is found at its first repeat; the model of
    # the cycle with the larger overall F-ratio, {x0}, is reached by one more
    # step and kept.
    assert [(s.action, s.feature) for s in opt.steps_[0]] == [
        ("add", 0),
        ("remove", 0),
        ("add", 0),
    ]
    assert set(np.flatnonzero(opt.coef_[0])) == {0}


def test_max_iter_warns_and_flags():
    X, y = _weak_term_problem()
    with pytest.warns(ConvergenceWarning, match="max_iter=1"):
        opt = FloatingFStepwise(max_iter=1).fit(X, y)
    assert not opt.converged_
    assert opt.n_iter_[0] == 1
    assert "did not settle" in opt.summary()
    # Exactly enough iterations is not a failure.
    needed = FloatingFStepwise().fit(X, y).n_iter_[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConvergenceWarning)
        assert FloatingFStepwise(max_iter=int(needed)).fit(X, y).converged_


# ------------------------------------------------------------ intercept handling
def test_intercept_kept_or_dropped():
    rng = np.random.default_rng(5)
    n = 200
    X = rng.standard_normal((n, 4))
    noise = 0.1 * rng.standard_normal(n)
    y0 = 2 * X[:, 0] + noise - noise.mean()  # no constant at all
    y1 = 2 * X[:, 0] + 1.5 + noise
    Y = np.column_stack([y0, y1])
    opt = FloatingFStepwise(fit_intercept=True).fit(X, Y)
    assert opt.intercept_dropped_.tolist() == [True, False]
    assert opt.intercept_[0] == 0.0
    assert opt.intercept_[1] == pytest.approx(1.5, abs=0.05)
    # Dropped: coefficients refit through the origin (an independent lstsq).
    through = np.linalg.lstsq(X[:, [0]], y0, rcond=None)[0]
    assert opt.coef_[0, 0] == pytest.approx(through[0], rel=1e-12)
    # The ANOVA table still describes the fit with intercept.
    assert opt.anova_[0].has_intercept
    with_c = np.linalg.lstsq(np.column_stack([np.ones(n), X[:, 0]]), y0, rcond=None)
    assert opt.anova_[0].intercept == pytest.approx(with_c[0][0], abs=1e-12)
    kept = FloatingFStepwise(drop_insignificant_constant=False, fit_intercept=True)
    kept.fit(X, y0)
    assert not kept.intercept_dropped_[0]
    assert kept.coef_[0, 0] == pytest.approx(with_c[0][1], rel=1e-12)
    # The default (pysindy's convention, no constant column here): always
    # through the origin, intercept_ 0, and a warning where the constant
    # was significant.
    with pytest.warns(
        ConstantNotInLibraryWarning, match="constant is significant in target 1"
    ):
        default = FloatingFStepwise().fit(X, Y)
    assert default.intercept_dropped_.tolist() == [True, True]
    np.testing.assert_array_equal(default.intercept_, 0.0)
    np.testing.assert_array_equal(default.coef_[0], opt.coef_[0])
    through1 = np.linalg.lstsq(X[:, default.ind_[1]], y1, rcond=None)[0]
    np.testing.assert_allclose(default.coef_[1, default.ind_[1]], through1, rtol=1e-12)
    assert "fit_intercept is False: coef_ is refit through the origin" in str(
        default.summary()
    )


def test_constant_library_column_carries_intercept():
    rng = np.random.default_rng(6)
    n = 150
    Z = rng.standard_normal((n, 3))
    X = np.column_stack([np.full(n, 2.0), Z])  # a constant column of value 2
    y = 4.0 + Z[:, 1] + 0.05 * rng.standard_normal(n)
    opt = FloatingFStepwise().fit(X, y)
    assert opt.constant_feature_ == 0
    assert opt.intercept_[0] == 0.0
    assert opt.coef_[0, 0] * 2.0 == pytest.approx(opt.anova_[0].intercept, rel=1e-12)
    np.testing.assert_allclose(
        opt.predict(X),  # 1-D, as y
        opt.anova_[0].intercept + opt.anova_[0].coefficients[0] * Z[:, 1],
        rtol=1e-12,
    )
    assert opt.ind_[0].tolist() == [True, False, True, False]


# ---------------------------------------------------------- numerical soundness
def test_set_aside_columns_never_selected_and_reported():
    rng = np.random.default_rng(7)
    n = 120
    G = rng.standard_normal((n, 4))
    y = 2 * G[:, 0] - G[:, 2] + 0.5 + 0.1 * rng.standard_normal(n)
    bad_inf = G[:, 1].copy()
    bad_inf[5] = np.inf
    bad_nan = G[:, 1].copy()
    bad_nan[9] = np.nan
    columns = {
        4: (G[:, 0].copy(), "duplicate of f0"),
        5: (-3 * G[:, 2] + 7, "collinear with f2"),
        6: (np.zeros(n), "all zero"),
        7: (np.ones(n), None),  # carries the intercept
        8: (np.full(n, 5.0), "constant"),
        9: (bad_inf, "non-finite"),
        10: (bad_nan, "non-finite"),
        11: (1 + 1e-12 * G[:, 3], "collinear with the constant"),
    }
    X = np.column_stack([G] + [col for col, _ in columns.values()])
    X_before = X.copy()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        opt = FloatingFStepwise().fit(X, y)
    excluded_warnings = [w for w in caught if w.category is ExcludedFeaturesWarning]
    assert len(excluded_warnings) == 1
    message = str(excluded_warnings[0].message)
    assert [w for w in caught if issubclass(w.category, RuntimeWarning)] == []
    for j, (_, reason) in columns.items():
        if reason is None:
            assert j not in opt.excluded_
            continue
        assert reason in opt.excluded_[j]
        assert f"f{j}:" in message
        assert opt.coef_[0, j] == 0
    np.testing.assert_array_equal(X, X_before)  # input untouched (NaN-aware)
    assert set(np.flatnonzero(opt.coef_[0])) == {0, 2, 7}
    assert opt.constant_feature_ == 7
    # Non-finite values in unused columns do not spoil predictions.
    assert np.all(np.isfinite(opt.predict(X)))


def test_collinear_combination_never_fully_selected():
    rng = np.random.default_rng(8)
    n = 200
    G = rng.standard_normal((n, 5))
    X = np.column_stack([G, G[:, 0] + G[:, 1]])  # exact 3-way collinearity
    y = 2 * G[:, 0] - G[:, 1] + G[:, 3] + 0.01 * rng.standard_normal(n)
    opt = FloatingFStepwise(floating=False, f_enter=1e-3, f_remove=1e-3).fit(X, y)
    chosen = np.flatnonzero(opt.coef_[0])
    # Even with (almost) no significance requirement the selected columns stay
    # linearly independent: the dependent one became ineligible.
    assert not {0, 1, 5} <= set(chosen)
    assert np.linalg.matrix_rank(X[:, chosen]) == chosen.size


def test_ill_conditioned_coefficients_match_exact_solution():
    rng = np.random.default_rng(0)
    n = 200
    a, z, c = rng.standard_normal((3, n))
    b = a + 1e-9 * z  # nearly collinear with a
    X = np.column_stack([a, b, c, rng.standard_normal((n, 10))])
    A = np.column_stack([np.ones(n), a, b, c])
    assert 1e9 < np.linalg.cond(A) < 1e10
    y = 0.5 + A[:, 1:] @ np.array([2.0, -1.5, 0.75])
    opt = FloatingFStepwise(tolerance=1e-12, fit_intercept=True).fit(X, y)
    assert set(np.flatnonzero(opt.coef_[0])) == {0, 1, 2}
    exact = exact_lstsq(A, y)
    got = np.r_[opt.intercept_[0], opt.coef_[0, :3]]
    assert np.linalg.norm(got - exact) / np.linalg.norm(exact) < 1e-8
    # np.linalg.lstsq on the same support is less accurate here (~1e-7).
    # With the default tolerance the near-duplicate is set aside instead.
    with pytest.warns(ExcludedFeaturesWarning, match="f1: collinear with f0"):
        FloatingFStepwise().fit(X, y)


def test_noise_free_target_exact_support_without_phase_two():
    rng = np.random.default_rng(9)
    n = 300
    X = rng.standard_normal((n, 60))
    true = [3, 17, 29, 44]
    y = X[:, true] @ np.array([1.0, -2.0, 0.5, 3.0])
    for floating in (False, True):
        opt = FloatingFStepwise(floating=floating).fit(X, y)
        assert sorted(np.flatnonzero(opt.coef_[0])) == true
        np.testing.assert_allclose(
            opt.coef_[0, true], [1.0, -2.0, 0.5, 3.0], rtol=1e-12
        )
        assert opt.intercept_[0] == 0.0 or abs(opt.intercept_[0]) < 1e-13


@pytest.mark.parametrize("value", [0.0, 3.25])
def test_constant_target_is_not_an_error(value):
    rng = np.random.default_rng(10)
    X = rng.standard_normal((50, 5))
    y = np.full(50, value)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no division or convergence warnings
        opt = FloatingFStepwise(fit_intercept=True).fit(X, y)
        text = opt.summary()
    assert not np.any(opt.coef_)
    assert opt.steps_ == [[]]
    assert opt.intercept_[0] == pytest.approx(value, abs=1e-14)
    np.testing.assert_allclose(opt.predict(X), value, atol=1e-14)
    assert "no function entered" in text


def test_targets_have_independent_supports():
    rng = np.random.default_rng(11)
    n = 200
    X = rng.standard_normal((n, 10))
    Y = np.column_stack(
        [X[:, 1] - X[:, 4], 2 * X[:, 7], X[:, 0] + X[:, 2] + X[:, 9]]
    ) + 0.05 * rng.standard_normal((n, 3))
    opt = FloatingFStepwise().fit(X, Y)
    supports = [set(np.flatnonzero(row)) for row in opt.coef_]
    assert supports == [{1, 4}, {7}, {0, 2, 9}]
    assert opt.ind_.sum(axis=1).tolist() == [2, 1, 3]
    assert len(opt.anova_) == len(opt.steps_) == 3
    # history_: pysindy meaning, coef_ after every step, ending at coef_.
    assert len(opt.history_) == 1 + sum(len(s) for s in opt.steps_) + 3
    np.testing.assert_array_equal(opt.history_[-1], opt.coef_)
    assert not np.any(opt.history_[0])
