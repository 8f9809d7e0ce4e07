"""ExtendedModel: predictions, simulations and printed equations.

The fast feature evaluator is tested in ``tests/core/test_features.py``, the
integrator in ``tests/core/test_integrate.py``, the output-error refit in
``test_output_error.py``.
"""

import numpy as np
import pysindy as ps
import pytest

from pysindy_mme import ExtendedModel
from pysindy_mme.systems import forced_oscillator, van_der_pol


def _vdp_extended(coefs=(-1.0, 1.0, -1.0)):
    system = van_der_pol()
    x = system.simulate()
    lib = ps.PolynomialLibrary(degree=3).fit(x)
    names = lib.get_feature_names(["x1", "x2"])
    coef = np.zeros((2, len(names)))
    for name, c in zip(["x1", "x2", "x1^2 x2"], coefs):
        coef[1, names.index(name)] = c
    model = ExtendedModel(
        system.assumed_model, lib, coef, ["x1", "x2"], assumed_equations=["x2", "0"]
    )
    return system, x, model


def test_extended_model_equals_true_model_when_correction_is_exact():
    system, x, model = _vdp_extended()
    t = system.time()
    np.testing.assert_allclose(
        model.predict(x, t=t), system.true_model(x, t), rtol=0, atol=1e-12
    )
    sim = model.simulate(system.x0, t, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(sim, x, atol=1e-6)


def test_equations_show_assumed_and_correction_apart(capsys):
    _, _, model = _vdp_extended()
    eqs = model.equations(precision=2)
    assert eqs[0] == "[assumed] x2"
    # significant digits (issue 14): a whole number prints as one
    assert eqs[1] == "[assumed] 0  +  [correction] -1 x1 + 1 x2 - 1 x1^2 x2"
    model.print(precision=2)
    assert "(x2)' = [assumed] 0" in capsys.readouterr().out


def test_equations_never_round_a_term_away():
    """Issue 14: coefficients of 1e-5 next to 1e5 both print (no fixed decimals)."""
    system, _, model = _vdp_extended(coefs=(-1.23456e-5, 98765.4, -4.2e-4))
    eq = model.equations()[1]
    assert (
        "-1.235e-05 x1" in eq and "+ 9.877e+04 x2" in eq and "- 0.00042 x1^2 x2" in eq
    )


def test_extended_model_with_input_requires_u():
    system = forced_oscillator()
    t = system.time()
    u = system.inputs(t)
    x = system.simulate(t)
    z = np.hstack([x, u])
    lib = ps.PolynomialLibrary(degree=2).fit(z)
    names = lib.get_feature_names(["x1", "x2", "u"])
    coef = np.zeros((2, len(names)))
    coef[1, names.index("u")] = 0.5
    model = ExtendedModel(system.assumed_model, lib, coef, ["x1", "x2"], ["u"])
    np.testing.assert_allclose(
        model.predict(x, u=u, t=t), system.true_model(x, t, u), atol=1e-12
    )
    with pytest.raises(TypeError, match="u is required"):
        model.predict(x)
    sim = model.simulate(system.x0, t, u=system.input_signal, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(sim, x, atol=1e-5)
