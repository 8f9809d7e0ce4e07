"""Errors in variables: the selection corrected for noise in the library's inputs.

* The estimates against closed forms and a Monte Carlo mean (Hermite
  polynomials), the structure against pysindy's own ``powers_``.
* With no noise the corrected state's statistics are the library's as given
  (IncrementalQR's and ``robust_table_statistics``'), to rounding.
* A coefficient that errors in variables attenuate comes out unbiased.
* When it does not apply, and why (shuffled rows, a Fourier library, a target
  computed from the measured states).
* Held out (systems the rule was not developed on, fixed seeds, looked at only
  after the rule was fixed): Lu's system at 5 % noise, 0 of 8 exact without
  the correction, 8 with it; Sprott's case A and Rabinovich-Fabrikant, no
  seed lost at 1 and 5 % (Rabinovich-Fabrikant at 5 %: 2 of 8 both ways;
  since session 29's choice of the best-fitting passing candidate, 5 with
  the correction, 0 without).
"""

from __future__ import annotations

import warnings

import numpy as np
import pysindy as ps
import pytest
from dropin_records import record as _record

from pysindy_mme import FloatingFStepwise
from pysindy_mme.optimizers._checks import check_params
from pysindy_mme.optimizers._numeric import scaled_target
from pysindy_mme.optimizers.errors_in_variables import (
    CorrectedMoments,
    hermite_powers,
    monomial_structure,
)
from pysindy_mme.optimizers.incremental_qr import IncrementalQR
from pysindy_mme.optimizers.robust import robust_table_statistics
from pysindy_mme.optimizers.rules import make_rule
from pysindy_mme.optimizers.screening import screen_columns


def _lu(t, x):
    return [36 * (x[1] - x[0]), -x[0] * x[2] + 20 * x[1], x[0] * x[1] - 3 * x[2]]


def _sprott_a(t, x):
    return [x[1], -x[0] + x[1] * x[2], 1 - x[1] ** 2]


def _rabinovich(t, x, g=0.87, a=1.1):
    return [
        x[1] * (x[2] - 1 + x[0] ** 2) + g * x[0],
        x[0] * (3 * x[2] + 1 - x[0] ** 2) + g * x[1],
        -2 * x[2] * (a + x[0] * x[1]),
    ]


def _hopf(t, x, mu=0.5):
    r2 = x[0] ** 2 + x[1] ** 2
    return [mu * x[0] - x[1] - x[0] * r2, x[0] + mu * x[1] - x[1] * r2]


def _fit(theta, dx, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return FloatingFStepwise(**kwargs).fit(theta, dx)


# ------------------------------------------------------------- the estimates
def test_hermite_powers_closed_forms():
    y = np.linspace(-3, 3, 13)
    s2 = 0.7
    p = hermite_powers(y, s2, 4)
    np.testing.assert_allclose(p[0], 1.0)
    np.testing.assert_allclose(p[1], y)
    np.testing.assert_allclose(p[2], y**2 - s2)
    np.testing.assert_allclose(p[3], y**3 - 3 * s2 * y)
    np.testing.assert_allclose(p[4], y**4 - 6 * s2 * y**2 + 3 * s2**2)
    np.testing.assert_array_equal(hermite_powers(y, 0.0, 4)[4], y**4)


def test_hermite_powers_are_unbiased_where_powers_are_not():
    rng = np.random.default_rng(1)
    x, s2, n = 1.3, 0.25, 400_000
    y = x + np.sqrt(s2) * rng.standard_normal(n)
    p = hermite_powers(y, s2, 6)
    for k in range(1, 7):
        se = p[k].std() / np.sqrt(n)
        assert abs(p[k].mean() - x**k) < 4 * se, k
    # the plain powers are biased by many standard errors (y^2: by s2)
    assert abs((y**2).mean() - x**2 - s2) < 4 * (y**2).std() / np.sqrt(n)


@pytest.mark.parametrize(
    "degree, n_states, interaction_only",
    [(3, 3, False), (5, 2, False), (2, 4, False)],
)
def test_monomial_structure_is_pysindys(degree, n_states, interaction_only):
    x = np.random.default_rng(2).standard_normal((300, n_states))
    lib = ps.PolynomialLibrary(degree, interaction_only=interaction_only).fit(x)
    theta = np.asarray(lib.transform(x))
    columns = np.arange(1, theta.shape[1])  # without the bias column
    base, powers = monomial_structure(theta, columns)
    expected = lib.powers_[columns]
    # the base columns are the states, in pysindy's order
    np.testing.assert_array_equal(base, 1 + np.arange(n_states))
    np.testing.assert_array_equal(powers, expected)


def test_a_library_without_squares_is_not_read_as_polynomial():
    # interaction_only: x0 x1 is a product, but nothing says x0 is a state
    x = np.random.default_rng(2).standard_normal((300, 3))
    lib = ps.PolynomialLibrary(3, interaction_only=True).fit(x)
    theta = np.asarray(lib.transform(x))
    assert monomial_structure(theta, np.arange(1, theta.shape[1])) is None


def test_a_fourier_library_is_not_corrected():
    t, x, _ = _trajectory(level=0.05)
    theta = np.asarray(ps.FourierLibrary(n_frequencies=2).fit(x).transform(x))
    dx = ps.SmoothedFiniteDifference()._differentiate(x, t)
    info = _fit(theta, dx).errors_in_variables_
    assert not info["applied"]
    assert "correlated" in info["reason"] or "monomials" in info["reason"]


# ------------------------------------------ no noise: the library as given
def _trajectory(level, n=3000, seed=0):
    from scipy.integrate import solve_ivp

    dt = 0.005
    t = np.arange(n) * dt
    x = solve_ivp(_lu, (0, t[-1]), [-3.0, 2.0, 20.0], t_eval=t, rtol=1e-10).y.T
    rng = np.random.default_rng(seed)
    return t, x + level * x.std(axis=0) * rng.standard_normal(x.shape), x


def _states(theta, target, variance):
    n = theta.shape[0]
    sw = np.ones(n)
    screen = screen_columns(theta, sw, float(n), 1e-8)
    params = check_params(FloatingFStepwise())
    rule = make_rule(params, int(screen.eligible.sum()), float(n), n, robust=True)
    columns = np.flatnonzero(screen.eligible)
    base, powers = monomial_structure(theta, columns)
    variance = np.full(base.size, variance)
    cm = CorrectedMoments(
        theta, theta[:, base], variance, columns, powers, screen, rule
    )
    y_scale, yt = scaled_target(target)
    corrected = cm.make_state(yt, screen, float(n), 1e-8, 1.0 / y_scale)
    plain = IncrementalQR(theta, sw, yt, screen, float(n), 1e-8, y_unit=1.0 / y_scale)
    return corrected, plain, rule, yt


def test_without_noise_the_statistics_are_the_librarys_as_given():
    t, y, _ = _trajectory(level=0.01)
    theta = np.asarray(ps.PolynomialLibrary(2).fit(y).transform(y))
    dx = ps.SmoothedFiniteDifference()._differentiate(y, t)
    corrected, plain, rule, yt = _states(theta, dx[:, 1], 0.0)
    lags = rule.lags
    for j in [None, 1, 6, 3]:  # x0, x0 x2, x2 (pysindy's order)
        if j is not None:
            corrected.add(j)
            plain.add(j)
        np.testing.assert_allclose(corrected.sse(), plain.sse(), rtol=1e-9)
        np.testing.assert_allclose(corrected.coefficients(), plain.coefficients())
        cf, pf = corrected.candidate_f(), plain.candidate_f()
        np.testing.assert_array_equal(np.isfinite(cf), np.isfinite(pf))
        np.testing.assert_allclose(cf[np.isfinite(pf)], pf[np.isfinite(pf)], rtol=1e-7)
        np.testing.assert_allclose(
            corrected.in_model_f(), plain.in_model_f(), rtol=1e-7
        )
        np.testing.assert_allclose(
            corrected.robust_in_model_f(lags), plain.robust_in_model_f(lags), rtol=1e-7
        )
        rc = corrected.robust_candidate_f(lags, cf)
        rp = plain.robust_candidate_f(lags, pf)
        np.testing.assert_allclose(rc, rp, rtol=1e-7)
        out = [c for c in np.flatnonzero(np.isfinite(pf))[:3]]
        np.testing.assert_allclose(
            corrected.joint_f(out, lags), plain.joint_f(out, lags), rtol=1e-7
        )
        np.testing.assert_allclose(
            corrected.joint_f(out), plain.joint_f(out), rtol=1e-7
        )
        assert corrected.residual_lag1() == pytest.approx(plain.residual_lag1())
    support = list(plain.support)
    design = np.column_stack(
        [np.ones(len(yt)), theta[:, support] * plain.scale[support]]
    )
    cand = theta[:, [4, 5]] * plain.scale[[4, 5]]
    ref = robust_table_statistics(design, yt, cand, lags)
    got = corrected.table_statistics(support, [4, 5], lags)
    for key in ref:
        np.testing.assert_allclose(got[key], ref[key], rtol=1e-7, err_msg=key)


# ----------------------------------------------------- what it corrects
def test_an_attenuated_coefficient_comes_out_unbiased():
    # x' = -0.5 x on a slow oscillation measured with noise of a third of its
    # standard deviation: least squares on the measured x is attenuated by
    # var(x) / (var(x) + s^2) = 0.9.
    n = 4000
    t = np.arange(n) * 0.01
    x = np.sin(0.5 * t) + 0.5 * np.sin(1.3 * t + 1)
    rng = np.random.default_rng(3)
    s = np.sqrt(x.var() / 9)
    y = (x + s * rng.standard_normal(n)).reshape(-1, 1)
    target = -0.5 * x + 0.01 * rng.standard_normal(n)  # independent noise
    theta = np.column_stack([np.ones(n), y[:, 0], y[:, 0] ** 2])
    plain = _fit(theta, target, errors_in_variables=False).coef_[0, 1]
    opt = _fit(theta, target)
    assert opt.errors_in_variables_["applied"]
    np.testing.assert_allclose(
        opt.errors_in_variables_["noise_variance"], s**2, rtol=0.15
    )
    assert plain == pytest.approx(-0.5 * 0.9, rel=0.02)
    assert opt.coef_[0, 1] == pytest.approx(-0.5, rel=0.02)


def test_not_applied_to_rows_out_of_time_order():
    t, y, _ = _trajectory(level=0.05)
    theta = np.asarray(ps.PolynomialLibrary(2).fit(y).transform(y))
    dx = ps.SmoothedFiniteDifference()._differentiate(y, t)
    order = np.random.default_rng(0).permutation(len(t))
    opt = _fit(theta[order], dx[order])
    assert "Errors in variables: not corrected (rows not in time order)" in str(
        opt.summary()
    )
    info = opt.errors_in_variables_
    assert info == dict(
        applied=False,
        reason="rows not in time order",
        base_columns=(),
        noise_variance=(),
        routes=(),
    )


def test_a_target_computed_from_the_measured_states_is_fitted_as_given():
    # the target holds the library's own noise: no errors in variables
    t, y, _ = _trajectory(level=0.05)
    theta = np.asarray(ps.PolynomialLibrary(2).fit(y).transform(y))
    target = 1.0 - y[:, 0]
    opt = _fit(theta, target)
    assert opt.errors_in_variables_["applied"]
    assert opt.errors_in_variables_["routes"] == (
        "as given (the target shares the library's noise)",
    )
    np.testing.assert_allclose(opt.coef_[0, :2], [1.0, -1.0], atol=1e-9)


def test_the_larger_corrected_model_must_be_relevantly_better():
    # Brusselator at 5 %: along its limit cycle the corrected selection fits
    # the derivative's systematic error with seven terms; the selection on
    # the library as given finds the three, and they are kept.
    def brusselator(t, x, a=1.0, b=3.0):
        return [a - (b + 1) * x[0] + x[0] ** 2 * x[1], b * x[0] - x[0] ** 2 * x[1]]

    theta, dx, coef = _record(brusselator, [1.0, 1.0], 0.01, 20.0, 3, 0.05, 0)
    opt = _fit(theta, dx)
    assert "as given" in opt.errors_in_variables_["routes"]
    np.testing.assert_array_equal(opt.coef_ != 0, coef)


# ---------------------------------------------------- held out, fixed seeds
HELD_OUT = [
    # rhs, x0, dt, t_end, degree, noise, exact with the correction, without
    (_lu, [-3.0, 2.0, 20.0], 0.001, 10.0, 2, 0.05, 8, 0),
    (_lu, [-3.0, 2.0, 20.0], 0.001, 10.0, 2, 0.01, 8, 8),
    (_sprott_a, [0.0, 5.0, 0.0], 0.01, 100.0, 2, 0.05, 8, 8),
    # session 29 (of the candidates that pass, the best fit enters): 7 and
    # 7 became 8 and 8 at 1 %, 2 and 2 became 5 and 0 at 5 %
    (_rabinovich, [-1.0, 0.0, 0.5], 0.005, 50.0, 3, 0.01, 8, 8),
    (_rabinovich, [-1.0, 0.0, 0.5], 0.005, 50.0, 3, 0.05, 5, 0),
]


@pytest.mark.slow
@pytest.mark.parametrize("rhs, x0, dt, t_end, degree, level, with_, without", HELD_OUT)
def test_held_out_systems(rhs, x0, dt, t_end, degree, level, with_, without):
    hits = {True: 0, False: 0}
    for seed in range(8):
        theta, dx, coef = _record(rhs, x0, dt, t_end, degree, level, seed)
        for correct in hits:
            opt = _fit(theta, dx, errors_in_variables="auto" if correct else False)
            hits[correct] += bool(np.array_equal(opt.coef_ != 0, coef))
    assert hits[True] >= with_
    assert hits[False] <= without
    assert hits[True] >= hits[False]


def test_lu_at_five_per_cent_one_seed():
    # the fast edit loop's copy of the first held-out row
    theta, dx, coef = _record(_lu, [-3.0, 2.0, 20.0], 0.001, 10.0, 2, 0.05, 0)
    assert not np.array_equal(
        _fit(theta, dx, errors_in_variables=False).coef_ != 0, coef
    )
    np.testing.assert_array_equal(_fit(theta, dx).coef_ != 0, coef)


# ------------------------------------------ no smaller model fits better
def test_a_smaller_model_that_fits_better_is_found():
    # the library as given (no noise): a target of x0 alone, a model of three
    # wrong terms; the one-term model has the smaller residual
    t, y, x = _trajectory(level=0.01)
    theta = np.asarray(ps.PolynomialLibrary(2).fit(y).transform(y))
    noise = np.random.default_rng(4).standard_normal(len(t))
    target = 2.0 * x[:, 0] + 0.1 * noise  # noise of its own
    corrected, _, _, _ = _states(theta, target, 0.0)
    for j in (2, 3, 5):
        corrected.add(j)
    assert corrected.dominating_support() == [1]
    assert corrected.sse_of([1]) < corrected.sse()
    # the true model itself is not beaten by a smaller one
    fresh, _, _, _ = _states(theta, target, 0.0)
    fresh.add(1)
    assert fresh.dominating_support() is None
    # more models than the budget: not searched
    assert corrected.dominating_support(budget=10) is None


def test_rikitakes_restart_that_ends_larger_is_exchanged():
    # Rikitake's y' at 5 % noise (the drop-in benchmark's seed 3): the
    # restart's backward elimination from every column ends at five terms in
    # the corrected metric; the true three fit better, and replace them.
    def _rikitake(t, x, mu=2.0, a=5.0):
        return [
            -mu * x[0] + x[2] * x[1],
            -mu * x[1] + (x[2] - a) * x[0],
            1 - x[0] * x[1],
        ]

    theta, dx, coef = _record(_rikitake, [1.0, 2.0, 3.0], 0.01, 30.0, 3, 0.05, 3)
    opt = _fit(theta, dx)
    assert opt.errors_in_variables_["routes"][1].endswith(
        "then a smaller model that fits better"
    )
    np.testing.assert_array_equal(opt.coef_ != 0, coef)
    text = str(opt.summary(target=1))
    assert "Errors in variables: statistics corrected" in text
    assert "then a smaller model that fits better" in text
    last = opt.steps_[1][-1]
    assert last.threshold == 1.0 and last.partial_f > 1.0
    assert opt.n_iter_[1] == len(opt.steps_[1])
    assert not np.array_equal(
        _fit(theta, dx, errors_in_variables=False).coef_ != 0, coef
    )


def test_a_model_as_given_that_is_indefinite_when_corrected_is_not_compared():
    """Hopf normal form at 5 % noise (seed 4), the first 794 rows (a
    training fold of FloatingFStepwiseCV), alpha 0.2: x0''s selection on the
    library as given has columns that are collinear to within the noise the
    correction removes; comparing it in the corrected metric raised
    LinAlgError (a Cholesky factor of an indefinite matrix). The corrected
    selection is kept, and the summary says why."""
    theta, dx, _ = _record(_hopf, [2.0, 0.0], 0.01, 10.0, 3, 0.05, 4)
    opt = _fit(theta[:794], dx[:794], alpha=0.2)
    routes = opt.errors_in_variables_["routes"]
    assert routes[0] == "corrected, the model as given indefinite"
    assert "cannot be fitted in the corrected metric" in str(opt.summary())
    assert np.all(np.isfinite(opt.coef_))
