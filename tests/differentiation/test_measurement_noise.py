"""MME's measurement noise option: ``noise_variance="auto"``.

The noise floor estimator itself (``core/noise.py``) is tested in
``tests/core/test_noise.py``; the checks of a given noise (co)variance are in
``test_bad_input.py``, a noise too large for the data in ``test_weight.py``.
"""

import numpy as np
import pytest

from pysindy_mme import MME
from pysindy_mme.differentiation import difference_noise_variance
from pysindy_mme.systems import van_der_pol


def ignorance_model(x, t):
    """The paper's assumed model for Van der Pol: x1' = x2, x2' = 0."""
    return np.column_stack([x[:, 1], np.zeros(len(x))])


def _vdp_mme(**kw):
    args = dict(measured=[0], noise_variance=0.01, error_states=[1])
    args.update(kw)
    return MME(ignorance_model, 2, **args)


def test_noise_variance_auto_estimates_and_warns():
    system = van_der_pol()
    m = system.measure(0)
    est = difference_noise_variance(m.y)
    assert est[0] == pytest.approx(0.01, rel=0.25)
    with pytest.warns(UserWarning, match="estimated the measurement noise"):
        mme = _vdp_mme(noise_variance="auto").fit(m.y, m.t)
    np.testing.assert_allclose(mme.noise_variance_, [[est[0]]])
