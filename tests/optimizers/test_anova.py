"""ANOVA statistics against direct formulas, brute-force refits and tables."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from exact_reference import exact_lstsq
from scipy import stats

from pysindy_mme.optimizers.anova import (
    AnovaTable,
    f_critical,
    f_pvalue,
    fit_anova,
    lstsq_refined,
)

# The 13-row Hald cement table (public textbook data), vendored with the tests.
HALD = Path(__file__).resolve().parents[1] / "data" / "hald_cement.csv"


@pytest.fixture(scope="module")
def hald():
    data = np.genfromtxt(HALD, delimiter=",", names=True)
    X = np.column_stack([data[f"x{i}"] for i in range(1, 5)])
    return X, np.asarray(data["y"], dtype=float)


def rss(A, y):
    resid = y - A @ np.linalg.lstsq(A, y, rcond=None)[0]
    return float(resid @ resid)


def test_full_table_against_direct_formulas(hald):
    X, y = hald
    support = [0, 1, 3]
    table = fit_anova(X, y, support, candidates="all")
    n, k = len(y), len(support)
    A = np.column_stack([np.ones(n), X[:, support]])
    beta = np.linalg.lstsq(A, y, rcond=None)[0]
    fitted = A @ beta
    ss_res = np.sum((y - fitted) ** 2)
    ss_reg = np.sum((fitted - y.mean()) ** 2)
    ss_tot = np.sum((y - y.mean()) ** 2)
    dof_res = n - k - 1
    assert table.n == n
    assert (table.dof_regression, table.dof_residual, table.dof_total) == (
        k,
        dof_res,
        n - 1,
    )
    assert table.ss_residual == pytest.approx(ss_res, rel=1e-10)
    assert table.ss_regression == pytest.approx(ss_reg, rel=1e-10)
    assert table.ss_total == pytest.approx(ss_tot, rel=1e-12)
    assert table.ms_regression == pytest.approx(ss_reg / k, rel=1e-10)
    assert table.ms_residual == pytest.approx(ss_res / dof_res, rel=1e-10)
    assert table.variance_of_estimate == table.ms_residual
    assert table.std_error_of_estimate == pytest.approx(np.sqrt(ss_res / dof_res))
    f_model = (ss_reg / k) / (ss_res / dof_res)
    assert table.f_ratio == pytest.approx(f_model, rel=1e-10)
    assert table.p_value == pytest.approx(stats.f.sf(f_model, k, dof_res), rel=1e-8)
    assert table.r2 == pytest.approx(ss_reg / ss_tot, rel=1e-10)
    assert table.multiple_r == pytest.approx(np.sqrt(ss_reg / ss_tot), rel=1e-10)
    assert table.intercept == pytest.approx(beta[0], rel=1e-9)
    np.testing.assert_allclose(table.coefficients, beta[1:], rtol=1e-9)
    # Standard errors from s^2 (A^T A)^-1 (an explicit inverse: fine at this size).
    cov = ss_res / dof_res * np.linalg.inv(A.T @ A)
    np.testing.assert_allclose(table.std_errors, np.sqrt(np.diag(cov))[1:], rtol=1e-7)
    assert table.intercept_std_error == pytest.approx(np.sqrt(cov[0, 0]), rel=1e-7)
    # Partial F in the model = extra SS of dropping it / MSE (eq. 20) = t^2.
    for i, j in enumerate(support):
        rest = [c for c in support if c != j]
        reduced = np.column_stack([np.ones(n), X[:, rest]])
        expect = (rss(reduced, y) - ss_res) / (ss_res / dof_res)
        assert table.partial_f[i] == pytest.approx(expect, rel=1e-8)
        assert table.p_values[i] == pytest.approx(
            stats.f.sf(expect, 1, dof_res), rel=1e-6
        )
    # Out of the model: only x3 (eq. 19 by two refits).
    assert table.out_features == (2,)
    bigger = np.column_stack([A, X[:, 2]])
    new = rss(bigger, y)
    assert table.out_partial_f[0] == pytest.approx(
        (ss_res - new) / (new / (dof_res - 1)), rel=1e-8
    )
    assert table.out_p_values[0] == pytest.approx(
        stats.f.sf(table.out_partial_f[0], 1, dof_res - 1), rel=1e-8
    )


def test_without_intercept_uses_uncentred_totals(hald):
    X, y = hald
    table = fit_anova(X, y, [0, 1], intercept=False)
    A = X[:, [0, 1]]
    ss_res = rss(A, y)
    assert not table.has_intercept
    assert table.ss_total == pytest.approx(float(y @ y))
    assert table.ss_residual == pytest.approx(ss_res, rel=1e-10)
    assert table.dof_residual == len(y) - 2 and table.dof_total == len(y)
    assert table.intercept == 0.0 and np.isnan(table.intercept_partial_f)
    np.testing.assert_allclose(
        table.coefficients, np.linalg.lstsq(A, y, rcond=None)[0], rtol=1e-10
    )


def test_frequency_weights_equal_repeated_rows():
    rng = np.random.default_rng(1)
    n = 40
    X = rng.standard_normal((n, 4))
    y = X @ [1.0, 0.0, -2.0, 0.5] + rng.standard_normal(n)
    w = rng.integers(0, 4, n)
    rows = np.repeat(np.arange(n), w)
    a = fit_anova(X, y, [0, 2], sample_weight=w, candidates="all")
    b = fit_anova(X[rows], y[rows], [0, 2], candidates="all")
    assert a.n == b.n == w.sum()
    for name in ("ss_residual", "ss_total", "f_ratio", "r2", "intercept"):
        assert getattr(a, name) == pytest.approx(getattr(b, name), rel=1e-10)
    np.testing.assert_allclose(a.partial_f, b.partial_f, rtol=1e-10)
    np.testing.assert_allclose(a.out_partial_f, b.out_partial_f, rtol=1e-10)


def test_empty_model_and_collinear_candidate():
    rng = np.random.default_rng(2)
    X = rng.standard_normal((30, 3))
    X = np.column_stack([X, 2 * X[:, 0], np.full(30, np.inf)])
    y = X[:, 0] + 0.1 * rng.standard_normal(30)
    table = fit_anova(X, y, [], candidates=[0, 1, 3])
    assert table.dof_regression == 0 and np.isnan(table.f_ratio)
    assert table.intercept == pytest.approx(y.mean())
    assert np.all(np.isfinite(table.out_partial_f))
    with_x0 = fit_anova(X, y, [0], candidates=[3, 4])
    # 2 x0 is collinear with the model; the inf column cannot be assessed.
    assert np.isnan(with_x0.out_partial_f).all()


def test_fit_anova_rejects_bad_input():
    X = np.ones((5, 2))
    with pytest.raises(ValueError, match="y must be 1-D with 5 entries"):
        fit_anova(X, np.ones(4), [0])
    with pytest.raises(ValueError, match="support"):
        fit_anova(X, np.ones(5), [2])
    with pytest.raises(ValueError, match="sample_weight"):
        fit_anova(X, np.ones(5), [0], sample_weight=-np.ones(5))
    with pytest.raises(ValueError, match="need more than"):
        fit_anova(np.eye(3), np.ones(3), [0, 1])


def test_f_critical_matches_printed_tables():
    # Upper 5% and 1% points of F(1, v) from standard statistical tables.
    assert f_critical(0.05, 9) == pytest.approx(5.12, abs=0.005)
    assert f_critical(0.05, 10) == pytest.approx(4.96, abs=0.005)
    assert f_critical(0.01, 20) == pytest.approx(8.10, abs=0.005)
    assert f_critical(0.10, 120) == pytest.approx(2.75, abs=0.005)
    assert f_critical(0.05, 0) == np.inf
    assert f_pvalue(f_critical(0.05, 17), 1, 17) == pytest.approx(0.05, rel=1e-10)
    assert np.isnan(f_pvalue(3.0, 1, 0))


def test_refined_lstsq_is_accurate_when_plain_solvers_are_not():
    rng = np.random.default_rng(4)
    n = 150
    a, z, c = rng.standard_normal((3, n))
    A = np.column_stack([np.ones(n), a, a + 1e-9 * z, c])
    assert np.linalg.cond(A) > 1e9
    y = A @ np.array([0.5, 2.0, -1.5, 0.75])
    exact = exact_lstsq(A, y)

    def rel(x):
        return np.linalg.norm(x - exact) / np.linalg.norm(exact)

    assert rel(lstsq_refined(A, y)) < 1e-10
    # The SVD solver is three or more orders of magnitude less accurate here.
    assert rel(np.linalg.lstsq(A, y, rcond=None)[0]) > 1e3 * rel(lstsq_refined(A, y))


def test_to_text_layout(hald):
    X, y = hald
    table = fit_anova(X, y, [0, 1], candidates=[3, 2])
    text = table.to_text(["x1", "x2", "x3", "x4"], title="Hald")
    lines = text.splitlines()
    assert lines[0] == "Hald"
    for phrase in (
        "Coefficient of determination  0.97868",
        "Intercept                     52.577",
        "Due to regression",
        "Deviation about regression",
        "(intercept)",
    ):
        assert phrase in text
    regression = next(line for line in lines if "Due to regression" in line)
    assert regression.split()[3:6] == ["2", "2657.9", "1328.9"]
    out = text.split("Functions not in the model")[1]
    assert out.index("x4") < out.index("x3")
    assert str(table) == table.to_text()
    assert "f3" in str(table)
    assert isinstance(table, AnovaTable)
