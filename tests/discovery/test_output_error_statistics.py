"""Issue 9.4: output-error statistics against independent references.

With the dynamics ``x' = c1 u1 + c2 u2 + c3 u3`` (known inputs) and ``y = x``
measured, the RK4 map with linearly interpolated inputs is the trapezoid
rule, so ``y_k = x_0 + sum_j c_j W_jk`` exactly, ``W_jk`` the cumulative
trapezoid integrals of ``u_j``: an ordinary linear regression. Its
coefficients and covariance ``s^2 (X^T X)^-1`` are computed here in exact
rational arithmetic; the transcription solver must agree with them even
when the coefficients span ten orders of magnitude (``cond(X^T X)`` beyond
1e20, where a plain inverse of the normal matrix is garbage).
"""

import numpy as np
import pytest
from exact_reference import exact_lstsq, exact_normal_inverse

from pysindy_mme.solver.output_error import OutputErrorModel
from pysindy_mme.solver.statistics import residual_inflation

COEFS = np.array([1e-4, 1.0, 1e6])
AMPLITUDES = np.array([1e4, 1.0, 1e-6])  # each term contributes O(1)


def _record(seed, n=600):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 6.0, n)
    u = np.column_stack(
        [
            AMPLITUDES[0] * np.sin(1.3 * t),
            AMPLITUDES[1] * np.cos(0.7 * t + 0.4),
            AMPLITUDES[2] * np.sin(2.1 * t) ** 2,
        ]
    )
    h = np.diff(t)
    W = np.vstack([np.zeros(3), np.cumsum(0.5 * h[:, None] * (u[1:] + u[:-1]), 0)])
    x = 0.3 + W @ COEFS
    y = x + 0.05 * rng.standard_normal(n)
    return t, u, y[:, None], W


def _fit(t, u, y):
    def base(x, tt, uu, p):
        return np.zeros_like(x)

    def features(z, cols):  # library columns: the three inputs
        return z[:, 1:][:, list(cols)]

    engine = OutputErrorModel(base, 1, features, y, t, u, np.eye(1) * 0.0025, np.eye(1))
    start = np.zeros((t.size, 1))
    return engine.fit([(0, 0), (0, 1), (0, 2)], np.zeros(3), start)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_coefficients_and_errors_match_exact_least_squares(seed):
    t, u, y, W = _record(seed)
    fit = _fit(t, u, y)
    assert fit.converged
    X = np.column_stack([np.ones(t.size), W])
    exact = exact_lstsq(X, y[:, 0])
    np.testing.assert_allclose(fit.theta, exact[1:], rtol=1e-6)
    assert fit.x[0, 0] == pytest.approx(exact[0], rel=1e-6)
    resid = y[:, 0] - X @ exact
    s2 = resid @ resid / (t.size - 4)
    inflation = residual_inflation(resid[:, None], np.eye(1) * 0.0025)
    cov = exact_normal_inverse(X) * s2 * inflation
    se_exact = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(fit.std_errors, se_exact[1:], rtol=0.10)
    assert np.sqrt(fit.x0_covariance[0, 0]) == pytest.approx(se_exact[0], rel=0.10)
    # the problem is as badly scaled as promised
    assert np.linalg.cond(X.T @ X) > 1e18


def test_a_naive_normal_inverse_would_fail_here():
    """Why the reference is exact: float64 (X^T X)^-1 is far off on this problem."""
    t, u, y, W = _record(0)
    X = np.column_stack([np.ones(t.size), W])
    naive = np.sqrt(np.abs(np.diag(np.linalg.pinv(X.T @ X))))
    exact = np.sqrt(np.diag(exact_normal_inverse(X)))
    assert np.max(np.abs(naive / exact - 1)) > 0.5
