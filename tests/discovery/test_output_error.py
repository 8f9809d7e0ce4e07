"""The output-error refit: unbiased coefficients with honest standard errors.

A six-seed statistical study (``slow``); the covariances against exact
rational least squares are in ``test_output_error_statistics.py``.
"""

import numpy as np
import pysindy as ps
import pytest

from pysindy_mme.core.features import SelectedFeatures
from pysindy_mme.core.integrate import simulate
from pysindy_mme.solver.output_error import OutputErrorModel
from pysindy_mme.systems import van_der_pol


@pytest.mark.slow
def test_output_error_refit_is_unbiased_and_its_errors_are_honest():
    """Coefficients from the refit scatter around the truth as their std errors say."""
    system = van_der_pol()
    lib = ps.PolynomialLibrary(degree=3)
    z_scores = []
    for seed in range(6):
        data = system.measure(seed)
        lib.fit(data.x)
        names = lib.get_feature_names(["x1", "x2"])
        cols = [names.index(n) for n in ("x1", "x2", "x1^2 x2")]
        sel = SelectedFeatures(lib, ["x1", "x2"], cols, data.x)

        def base(x, t, u, p):
            return system.assumed_model(x, t)

        problem = OutputErrorModel(
            base,
            2,
            sel,
            data.y,
            data.t,
            None,
            np.eye(1) * 0.01,
            np.eye(2)[[0]],
        )
        # start where the single-shooting version of this test started: the
        # model with coefficients (-0.7, 0.7, -0.7) simulated from (1.05, 0.1)
        c0 = np.array([-0.7, 0.7, -0.7])

        def start_model(x, s, u, c0=c0):
            xd = system.assumed_model(x, np.full(len(x), s))
            xd[:, 1] += (
                c0[0] * x[:, 0] + c0[1] * x[:, 1] + c0[2] * x[:, 0] ** 2 * x[:, 1]
            )
            return xd

        start = simulate(start_model, np.array([1.05, 0.1]), data.t, substeps=2).x[0]
        fit = problem.fit([(1, 0), (1, 1), (1, 2)], c0, start)
        assert fit.converged
        truth = np.array([1.0, 0.0, -1.0, 1.0, -1.0])
        params = np.concatenate([fit.x[0], fit.theta])
        se = np.concatenate([np.sqrt(np.diag(fit.x0_covariance)), fit.std_errors])
        z_scores.append((params - truth) / se)
        assert fit.cost / fit.n_residuals == pytest.approx(1.0, abs=0.25)
    z = np.array(z_scores)
    # standardised errors: mean near 0, spread near 1 (6 seeds x 5 parameters)
    assert abs(z.mean()) < 0.6
    assert 0.4 < z.std() < 1.8
