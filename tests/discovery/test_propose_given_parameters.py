"""Step 3 given the grey-box parameters: which columns each equation gets,
and the path for optimizers other than FloatingFStepwise."""

from types import SimpleNamespace

import numpy as np
import pysindy as ps

from pysindy_mme.discovery.propose import _fit_each, _given_columns
from pysindy_mme.optimizers.partial import project_out


def test_each_equation_gets_the_sensitivities_of_the_free_parameters_it_has():
    n = 50
    rng = np.random.default_rng(0)
    sens = np.zeros((n, 2, 3))
    sens[:, 0, 0] = rng.standard_normal(n)  # a1 in h1'
    sens[:, 0, 1] = rng.standard_normal(n)  # b in h1' (held as a gauge)
    sens[:, 1, 2] = rng.standard_normal(n)  # a3 in h2'
    study = SimpleNamespace(
        parameter_gauge=np.array([False, True, False]), error_states=np.array([0, 1])
    )
    given = _given_columns(study, sens)
    np.testing.assert_array_equal(given[0], sens[:, 0, [0]])
    np.testing.assert_array_equal(given[1], sens[:, 1, [2]])
    # an equation no free parameter moves gets nothing; none at all: None
    only_h1 = SimpleNamespace(
        parameter_gauge=np.array([False, True, True]), error_states=np.array([0, 1])
    )
    assert _given_columns(only_h1, sens)[1] is None
    assert _given_columns(study, None) is None


def test_another_optimizer_is_fitted_per_equation_on_the_projected_rows():
    rng = np.random.default_rng(1)
    n = 800
    h = 5.0 + 3.0 * np.sin(np.linspace(0, 20, n)) + 0.3 * rng.standard_normal(n)
    theta = np.column_stack([np.sqrt(h), np.maximum(h - 6.0, 0.0), h**2])
    a_hat = float(np.linalg.lstsq(h[:, None], 0.8 * np.sqrt(h), rcond=None)[0][0])
    d = np.column_stack([-0.8 * np.sqrt(h) + a_hat * h, 0.5 * h**2])
    given = [h[:, None], None]
    stacked = _fit_each(ps.STLSQ(threshold=0.05), theta, d, given)
    assert stacked.coef_.shape == (2, 3)
    for k, cols in enumerate([h[:, None], np.zeros((n, 0))]):
        x_p, y_p, _ = project_out(theta, d[:, [k]], cols, np.ones(n), centre=False)
        alone = ps.STLSQ(threshold=0.05).fit(x_p, y_p)
        np.testing.assert_allclose(stacked.coef_[k], alone.coef_[0], rtol=1e-12)
    # given h, the projected sqrt(h) explains the first equation alone
    assert np.flatnonzero(stacked.coef_[0]).tolist() == [0]
    assert abs(stacked.coef_[0, 0] + 0.8) < 0.01
