"""statsmodels' names on a Discovery: params, bse, tvalues, pvalues, conf_int.

Checked against the result's own tables (the report's numbers) and against
the definitions (bse from the covariance, intervals from Student t), so that
a user who knows ``results.params`` / ``results.conf_int()`` from statsmodels
reads the same numbers the report prints.
"""

import numpy as np
import pytest
from results_case import study
from scipy import stats


@pytest.fixture(scope="module")
def grey():
    return study(grey=True)


def test_names_and_values_match_the_report_tables(grey):
    names = grey.param_names
    params = grey.params
    assert len(names) == params.size == grey.bse.size
    k = len(grey.parameters)
    assert names[:k] == list(grey.parameters)
    for j, estimate in enumerate(grey.parameters.values()):
        assert params[j] == pytest.approx(estimate.value, rel=1e-12)
        if np.isfinite(estimate.std_error):
            assert grey.bse[j] == pytest.approx(estimate.std_error, rel=1e-12)
    for j, te in enumerate(grey.term_estimates, start=k):
        assert names[j] == f"{te.feature} in {te.state}'"
        assert params[j] == pytest.approx(te.coefficient, rel=1e-12)
        assert grey.bse[j] == pytest.approx(te.std_error, rel=1e-12)
        assert grey.pvalues[j] == pytest.approx(te.p_value, rel=1e-6, abs=1e-300)


def test_intervals_follow_student_t(grey):
    ci95 = grey.conf_int()
    for j, te in enumerate(grey.term_estimates, start=len(grey.parameters)):
        assert ci95[j] == pytest.approx([te.ci_low, te.ci_high], rel=1e-12)
    ci99 = grey.conf_int(alpha=0.01)
    finite = np.isfinite(grey.bse)
    half = stats.t.ppf(0.995, grey.df_resid) * grey.bse[finite]
    np.testing.assert_allclose(ci99[finite, 1] - grey.params[finite], half, rtol=1e-12)
    assert np.all(ci99[finite, 1] - ci99[finite, 0] > ci95[finite, 1] - ci95[finite, 0])
    np.testing.assert_allclose(grey.tvalues, grey.params / grey.bse)
    assert grey.nobs == grey.study.y.size
    assert 0 < grey.df_resid < grey.nobs


@pytest.mark.parametrize("alpha", [0.0, 1.0, -0.1, 2])
def test_conf_int_rejects_a_level_outside_zero_one(grey, alpha):
    with pytest.raises(ValueError, match="alpha must lie strictly between 0 and 1"):
        grey.conf_int(alpha)


def test_a_loaded_result_has_the_same_numbers(grey, tmp_path):
    from pysindy_mme import Discovery

    path = tmp_path / "grey.npz"
    grey.save(path)
    loaded = Discovery.load(path)
    assert loaded.param_names == grey.param_names
    np.testing.assert_array_equal(loaded.params, grey.params)
    np.testing.assert_array_equal(loaded.bse, grey.bse)
    np.testing.assert_array_equal(loaded.conf_int(0.1), grey.conf_int(0.1))
