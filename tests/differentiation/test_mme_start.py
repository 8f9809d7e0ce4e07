"""MME's starting trajectory (``fit(..., x_guess=...)``) and the error that asks for it.

An unmeasured state starts at zero. Where the model is flat in that state at
zero (a square-root outflow from an empty tank, a weir, a dead zone), the
measured states carry no trace of it along the start, and the problem is
singular there although it is not elsewhere. The error says so and names
``x_guess``; a start where the model depends on the state solves it.
"""

from __future__ import annotations

import numpy as np
import pytest
from bad_input_support import readonly
from paper_case import T, Y, paper_mme
from scipy.integrate import solve_ivp

from pysindy_mme import MME, UnobservableError

T_WEIR = np.arange(0.0, 40.0, 0.1)
U_WEIR = np.ones((T_WEIR.size, 1))


def weir(x, t, u):
    """An upper tank ``h1`` (filled at a constant rate) spilling over a weir
    at 1 into a measured lower tank ``h2``: flat in ``h1`` below the weir."""
    h1, h2 = x[:, 0], x[:, 1]
    return np.column_stack(
        [-0.2 * h1 + u[:, 0], 0.5 * np.maximum(h1 - 1.0, 0.0) - 0.5 * h2]
    )


def _weir_record():
    sol = solve_ivp(
        lambda s, x: weir(x[None], s, np.ones((1, 1)))[0],
        (0.0, T_WEIR[-1]),
        [0.0, 0.0],
        t_eval=T_WEIR,
        rtol=1e-10,
        atol=1e-12,
    )
    x = sol.y.T
    rng = np.random.default_rng(0)
    return x, x[:, [1]] + 0.01 * rng.standard_normal((T_WEIR.size, 1))


def _weir_mme():
    return MME(weir, 2, measured=[1], noise_variance=1e-4, error_states=[1], u=U_WEIR)


def test_flat_start_is_named_and_x_guess_solves_it():
    x, y = _weir_record()
    with pytest.raises(UnobservableError, match=r"states \[0\].*x_guess=") as info:
        _weir_mme().fit(y, T_WEIR)
    assert isinstance(info.value, ValueError)  # as before it had a class
    guess = readonly(x)  # a start modified in place would fail here
    with pytest.warns(UserWarning, match="covariance constraint"):
        # the model is exact: W runs to its bound, and says so
        mme = _weir_mme().fit(y, T_WEIR, x_guess=guess)
    assert mme.converged_
    # the hidden level, never measured, follows the true one closely
    assert np.max(np.abs(mme.smoothed_x_[:, 0] - x[:, 0])) < 0.02 * np.max(x[:, 0])


def test_x_guess_is_only_the_start():
    """A well-posed problem started from its own answer, perturbed, gives the
    answer of the default start (to the solver's tolerance)."""
    plain = paper_mme().fit(Y, T)
    rng = np.random.default_rng(1)
    nudged = plain.smoothed_x_ * (
        1.0 + 0.05 * rng.standard_normal(plain.smoothed_x_.shape)
    )
    started = paper_mme().fit(Y, T, x_guess=readonly(nudged))
    scale = np.max(np.abs(plain.smoothed_x_), axis=0)
    assert np.max(np.abs(started.smoothed_x_ - plain.smoothed_x_) / scale) < 1e-5
    np.testing.assert_allclose(started.W_, plain.W_, rtol=1e-3)
