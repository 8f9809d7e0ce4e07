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


def _with_exact_gradient():
    """``x' = base + c`` terms on ``x0^3`` and ``x0 x1``, the features with
    their closed-form gradient (what ``has_exact_correction_jacobian`` reads)."""
    from pysindy_mme.core.model import ParametricModel

    def base(x, t, u, p):
        return np.column_stack([x[:, 1], -p[0] * x[:, 0]])

    def features(z, columns):
        cols = [z[:, 0] ** 3, z[:, 0] * z[:, 1]]
        return np.column_stack([cols[c] for c in columns])

    def gradient(z, columns):
        g = np.zeros((z.shape[0], len(columns), z.shape[1]))
        for j, c in enumerate(columns):
            if c == 0:
                g[:, j, 0] = 3 * z[:, 0] ** 2
            else:
                g[:, j, 0], g[:, j, 1] = z[:, 1], z[:, 0]
        return g

    features.gradient = gradient
    # the same column in two equations, two columns in one equation
    model = ParametricModel(base, 2, 1, features, [(1, 0), (0, 1), (1, 1)])
    return model, np.array([1.3, -0.4, 0.25, 0.6])


def test_correction_jacobian_in_place_and_in_internal_units():
    from pysindy_mme.solver.units import Dynamics

    model, theta = _with_exact_gradient()
    assert model.has_exact_correction_jacobian
    x = np.random.default_rng(3).uniform(-2, 2, (30, 2))

    def correction(z):
        return model(z, 0.0, None, theta) - model.base_part(z, 0.0, None, theta)

    J = model.correction_jacobian(x, None, theta)
    np.testing.assert_allclose(J, rowwise_jacobian(correction, x), atol=1e-8)
    unit = np.array([0.01, 20.0])
    A = np.random.default_rng(4).standard_normal((30, 2, 2))
    before = A.copy()
    out = model.correction_jacobian(x, None, theta, out=A, unit=unit)
    assert out is A  # added where it lies
    internal = J * unit[None, None, :] / unit[None, :, None]
    np.testing.assert_allclose(out, before + internal, rtol=1e-13, atol=1e-13)
    # the solver's Jacobian in internal units against central differences of
    # the model in internal units
    dyn = Dynamics(model, unit)
    z = x / unit
    ref = rowwise_jacobian(lambda zz: dyn(zz, 0.0, None, theta), z, scale=1.0)
    np.testing.assert_allclose(dyn.jacobian(z, 0.0, None, theta), ref, rtol=1e-7)


@pytest.mark.parametrize("n", [1, 2, 3, 20])
def test_unit_scaling_column_by_column_is_numpys_broadcast(n):
    from pysindy_mme.solver.units import _scale

    rng = np.random.default_rng(n)
    a, unit = rng.standard_normal((41, n)), rng.uniform(0.1, 10.0, n)
    # the same operations: equal to the last bit, a new array
    np.testing.assert_array_equal(_scale(a, unit), a * unit)
    np.testing.assert_array_equal(_scale(a, unit, np.divide), a / unit)
    assert _scale(a, unit) is not a
    # a strided view in, a C-ordered answer out
    wide = rng.standard_normal((41, 2 * n))[:, ::2]
    np.testing.assert_array_equal(_scale(wide, unit), wide * unit)
    # shapes it does not handle go to numpy as they are
    np.testing.assert_array_equal(_scale(a[:, :1], unit[:1]), a[:, :1] * unit[:1])
