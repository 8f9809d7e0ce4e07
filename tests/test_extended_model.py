"""ExtendedModel, the fast feature evaluator and the output-error refit."""

import numpy as np
import pysindy as ps
import pytest

from pysindy_mme import ExtendedModel
from pysindy_mme.core.features import SelectedFeatures
from pysindy_mme.core.integrate import simulate
from pysindy_mme.discovery.output_error import OutputErrorModel
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


def test_selected_features_fast_path_matches_transform():
    rng = np.random.default_rng(1)
    z = rng.normal(size=(50, 3))
    lib = ps.PolynomialLibrary(degree=3).fit(z)
    cols = [0, 4, 9, 15, 19]
    sel = SelectedFeatures(lib, ["a", "b", "c"], cols, z)
    assert sel.is_fast
    np.testing.assert_allclose(sel(z), np.asarray(lib.transform(z))[:, cols])


def test_selected_features_falls_back_for_unparseable_names():
    rng = np.random.default_rng(2)
    z = rng.normal(size=(40, 2))
    lib = ps.FourierLibrary(n_frequencies=2).fit(z)
    sel = SelectedFeatures(lib, ["a", "b"], [0, 3], z)
    assert not sel.is_fast
    np.testing.assert_allclose(sel(z), np.asarray(lib.transform(z))[:, [0, 3]])


def test_batch_rk4_matches_closed_form_and_flags_blow_up():
    t = np.linspace(0, 2, 81)
    x = simulate(lambda x, s, u: -x, np.array([[1.0], [2.0]]), t, substeps=2).x
    np.testing.assert_allclose(x[:, :, 0], np.outer([1, 2], np.exp(-t)), rtol=1e-7)
    # x' = x^2 from 1 blows up at t = 1: the trajectory turns NaN, no exception
    run = simulate(lambda x, s, u: x**2, np.array([[1.0]]), t, substeps=2)
    x = run.x
    assert np.isnan(x[0, -1, 0]) and np.isfinite(x[0, 10, 0])
    assert 35 < run.diverged_at[0] < 45  # the sample where it left the bound


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
