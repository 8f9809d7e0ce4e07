"""ModelFunction, the one wrapper of a user's model: shapes checked with a
hint, inputs detected from the signature, pysindy models through
``predict``, Jacobians against closed forms, free runs against closed forms.
"""

import numpy as np
import pysindy as ps
import pytest

from pysindy_mme.core.model import (
    ModelFunction,
    as_model_function,
    rowwise_jacobian,
    simulate_model,
)


def _oscillator(x, t):
    return np.column_stack([x[:, 1], -x[:, 0]])


def _forced(x, t, u):
    return np.column_stack([x[:, 1], -x[:, 0] + u[:, 0]])


def test_calls_with_and_without_input():
    x = np.array([[1.0, 2.0], [3.0, 4.0]])
    f = ModelFunction(_oscillator, 2)
    assert not f.takes_input
    np.testing.assert_array_equal(f(x, [0.0, 1.0]), [[2.0, -1.0], [4.0, -3.0]])
    g = ModelFunction(_forced, 2)
    assert g.takes_input
    np.testing.assert_array_equal(g(x, 0.0, np.array([[1.0], [2.0]]))[:, 1], [0, -1])
    assert ModelFunction(lambda *args: args[0], 2).takes_input  # *args: may take u


def test_one_state_may_return_a_flat_array():
    f = ModelFunction(lambda x, t: -x[:, 0], 1)
    np.testing.assert_array_equal(f(np.array([[1.0], [2.0]]), 0.0), [[-1.0], [-2.0]])


def test_wrong_shapes_are_named_and_transposed_results_get_a_hint():
    x = np.ones((5, 2))
    with pytest.raises(ValueError, match=r"returned an array of shape \(5, 1\)"):
        ModelFunction(lambda x, t: x[:, :1], 2)(x, 0.0)
    with pytest.raises(ValueError, match="equations as rows"):
        ModelFunction(lambda x, t: np.array([x[:, 1], x[:, 0]]), 2)(x, 0.0)
    with pytest.raises(ValueError, match=r"^my_model returned"):
        ModelFunction(lambda x, t: x[:, :1], 2, name="my_model")(x, 0.0)
    with pytest.raises(TypeError, match="assumed_model must be a callable"):
        ModelFunction(3.0, 2)


def test_check_names_the_first_non_finite_sample():
    f = ModelFunction(lambda x, t: np.log(x), 2)
    x = np.array([[1.0, 1.0], [2.0, 2.0], [-1.0, 1.0]])
    with np.errstate(invalid="ignore"):
        with pytest.raises(ValueError, match=r"non-finite values \(first at sample 2"):
            f.check(x, 0.0)


def test_unchecked_is_the_same_function():
    x = np.random.default_rng(0).standard_normal((7, 2))
    u = np.ones((7, 1))
    for func in (_oscillator, _forced):
        f = ModelFunction(func, 2)
        np.testing.assert_array_equal(f.unchecked()(x, 0.0, u), f(x, 0.0, u))


def test_jacobian_against_the_closed_form():
    def duffing(x, t):
        return np.column_stack([x[:, 1], -x[:, 0] - 0.1 * x[:, 1] - x[:, 0] ** 3])

    x = np.random.default_rng(1).uniform(-2, 2, (20, 2))
    exact = np.zeros((20, 2, 2))
    exact[:, 0, 1] = 1.0
    exact[:, 1, 0] = -1.0 - 3 * x[:, 0] ** 2
    exact[:, 1, 1] = -0.1
    jac = ModelFunction(duffing, 2).jacobian(x, 0.0)
    np.testing.assert_allclose(jac, exact, rtol=1e-8, atol=1e-9)
    # a row-wise map with more outputs than inputs, large arguments
    z = np.array([[1e6, -3.0], [0.5, 2.0]])
    out = rowwise_jacobian(lambda z: np.column_stack([z[:, 0] * z[:, 1], z[:, 0]]), z)
    assert out.shape == (2, 2, 2)
    np.testing.assert_allclose(out[:, 0, 0], z[:, 1], rtol=1e-9)
    np.testing.assert_allclose(out[:, 0, 1], z[:, 0], rtol=1e-9)
    np.testing.assert_allclose(out[:, 1], [[1.0, 0.0], [1.0, 0.0]], atol=1e-9)


def test_a_fitted_sindy_model_is_called_through_predict():
    t = np.linspace(0, 10, 401)
    x = np.column_stack([np.cos(t), -np.sin(t)])
    sindy = ps.SINDy(feature_library=ps.PolynomialLibrary(degree=1))
    sindy.fit(x, t=t, x_dot=_oscillator(x, t))
    f = as_model_function(sindy, 2)
    assert f.takes_input  # predict(x, u=...) is how pysindy takes inputs
    z = np.random.default_rng(2).standard_normal((9, 2))
    np.testing.assert_allclose(f(z, 0.0), _oscillator(z, 0.0), atol=1e-10)
    assert as_model_function(f, 2) is f  # idempotent


def test_simulate_model_against_closed_forms():
    t = np.linspace(0.0, 6.0, 121)
    x = simulate_model(_oscillator, [1.0, 0.0], t)
    np.testing.assert_allclose(x, np.column_stack([np.cos(t), -np.sin(t)]), atol=1e-7)
    # x' = -x + u with u = 1 (array, interpolated): x = 1 - (1 - x0) e^-t
    decay = simulate_model(
        lambda x, t, u: -x + u, [0.25], t, u=np.ones((t.size, 1)), n_states=1
    )
    np.testing.assert_allclose(decay[:, 0], 1 - 0.75 * np.exp(-t), atol=1e-7)
