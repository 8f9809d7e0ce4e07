"""The W search: maximum likelihood against the Kalman likelihood, and a
covariance constraint that cannot be met.

The paper's 20-seed comparison of the W rules is in ``test_mme.py`` (slow).
"""

import numpy as np
import pytest
from kalman_reference import kalman_rts

from pysindy_mme import MME
from pysindy_mme.systems import duffing, van_der_pol


def test_maximum_likelihood_W_maximises_the_kalman_likelihood():
    """W='ml' lands on the maximum of the independent Kalman likelihood."""
    system = duffing()
    m = system.measure(5, t=np.arange(0, 15, 0.05))
    A = np.array([[0.0, 1.0], [-1.0, -0.1]])
    mme = MME(
        system.assumed_model,
        2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
        W="ml",
    ).fit(m.y, m.t)
    C, R, B = np.array([[1.0, 0.0]]), np.array([[0.01]]), np.array([[0.0], [1.0]])

    def ll(w):
        return -0.5 * kalman_rts(A, B, C, R, np.array([[w]]), m.y, m.t)[2]

    best = ll(mme.W_)
    assert best >= ll(mme.W_ * 1.05) and best >= ll(mme.W_ / 1.05)
    assert mme.log_likelihood_ == pytest.approx(best, abs=1e-4)


@pytest.mark.parametrize("noise_variance", [50.0, 1e3])
def test_covariance_constraint_without_solution_warns_and_flags(noise_variance):
    # A noise variance 5e3 or 1e5 times the real one: the assumed model alone
    # fits "within the noise", no W in the search range meets the constraint.
    system = van_der_pol()
    m = system.measure(0)
    mme = MME(
        system.assumed_model,
        2,
        measured=[0],
        noise_variance=noise_variance,
        error_states=[1],
    )
    with pytest.warns(UserWarning, match="covariance constraint cannot be met"):
        mme.fit(m.y, m.t)
    assert mme.W_at_bound_ is True
    assert mme.covariance_ratio_[0] < 1
    assert np.all(np.isfinite(mme.smoothed_x_))
