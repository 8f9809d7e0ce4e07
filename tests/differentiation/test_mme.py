"""MME: the paper's Van der Pol study, nonlinear models, pysindy, options.

The solver itself is checked against independent references in
``test_transcription.py``, the observability checks in
``test_observability.py``, the noise options in ``test_measurement_noise.py``,
failures and determinism in ``test_mme_reliability.py`` and bad input in
``test_bad_input.py``; here the estimator is checked on what it is for.
The paper's 20-seed study is marked ``slow``.
"""

import pickle
import warnings

import numpy as np
import pysindy as ps
import pytest
from sklearn.base import clone

from pysindy_mme import MME, FloatingFStepwise
from pysindy_mme.systems import (
    duffing,
    forced_oscillator,
    lotka_volterra,
    van_der_pol,
)

SEEDS = range(20)


def ignorance_model(x, t):
    """The paper's assumed model for Van der Pol: x1' = x2, x2' = 0."""
    return np.column_stack([x[:, 1], np.zeros(len(x))])


def _vdp_mme(**kw):
    args = dict(measured=[0], noise_variance=0.01, error_states=[1])
    args.update(kw)
    return MME(ignorance_model, 2, **args)


# ------------------------------------------------------- the paper's example

STUDY_MODES = [
    ("white", "auto"),
    ("white", "ml"),
    ("random_walk", "auto"),
    ("random_walk", "ml"),
]


@pytest.fixture(scope="module")
def vdp_study():
    """20 noise seeds of the paper's case; per seed: errors and W."""
    system = van_der_pol()
    out = {}
    for error_model, mode in STUDY_MODES:
        rows = []
        for seed in SEEDS:
            m = system.measure(seed)
            mme = _vdp_mme(W=mode, error_model=error_model).fit(m.y, m.t)
            e = mme.smoothed_x_ - m.x
            rows.append(
                dict(
                    x1=np.var(e[:, 0]),
                    x2=np.var(e[:, 1]),
                    d=np.var(mme.d_[:, 1] - m.d[:, 1]),
                    ratio=mme.covariance_ratio_[0],
                    converged=mme.converged_,
                    W=mme.W_,
                )
            )
        key = mode if error_model == "white" else f"{error_model}-{mode}"
        out[key] = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    return out


@pytest.mark.slow
def test_van_der_pol_covariance_constraint(vdp_study):
    """W='auto' (the paper's rule): x1 as in the brief, ratio 1 on every seed.

    Paper (one noise realisation): x1 0.001814, x2 0.0141, d 0.1878.
    """
    auto = vdp_study["auto"]
    assert auto["converged"].all()
    assert np.all(np.abs(auto["ratio"] - 1.0) <= 0.05)
    assert np.median(auto["x1"]) <= 0.0010
    # at least as good as the paper's single run on the unmeasured state
    assert np.median(auto["x2"]) <= 0.0141


@pytest.mark.slow
def test_van_der_pol_maximum_likelihood(vdp_study):
    ml = vdp_study["ml"]
    assert ml["converged"].all()
    assert np.median(ml["x1"]) <= 0.0010
    auto = vdp_study["auto"]
    # ML weighs the model error as white noise and picks a smaller W than the
    # covariance constraint: it follows the data more closely
    assert np.median(ml["W"]) < np.median(auto["W"]) / 3
    assert np.median(ml["ratio"]) < 0.95
    # The covariance ratio is flat in W (0.96 at W = 0.1, 1.08 at W = 5 on
    # seed 13), so the ~7% sampling scatter of the noise's own variance moves
    # the covariance-constraint W by orders of magnitude; ML's W is stable.
    assert np.ptp(np.log10(auto["W"])) > 1.0
    assert np.ptp(np.log10(ml["W"])) < 0.3


@pytest.mark.slow
def test_van_der_pol_random_walk_error_model(vdp_study):
    """A smooth prior on d: the unmeasured state within the brief's 0.011.

    Measured medians (20 seeds): random_walk + W='ml' x1 0.00047, x2 0.0079,
    d 0.219 (white + 'auto': 0.00087, 0.0135, 0.284); covariance ratio 0.94.
    """
    white, rw_ml, rw_auto = (
        vdp_study["auto"],
        vdp_study["random_walk-ml"],
        (vdp_study["random_walk-auto"]),
    )
    assert rw_ml["converged"].all() and rw_auto["converged"].all()
    assert np.median(rw_ml["x1"]) <= 0.0010
    assert np.median(rw_ml["x2"]) <= 0.011
    assert np.median(rw_ml["d"]) < 0.8 * np.median(white["d"])
    assert 0.9 < np.median(rw_ml["ratio"]) < 1.0
    # the covariance constraint holds for either error model
    assert np.all(np.abs(rw_auto["ratio"] - 1.0) <= 0.05)


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason=(
        "brief's line 1 asks for x2 <= 0.011, d <= 0.19 and a covariance ratio "
        "within 5% of 1 together (medians of 20 seeds); no configuration meets "
        "all three: white+'auto' x2 0.0135, d 0.284 (ratio 1.000); "
        "random_walk+'ml' x2 0.0079, d 0.219, ratio 0.94. Choosing W per seed "
        "with the truth known gives d 0.220 (white) and 0.186 (random_walk): "
        "d <= 0.19 needs a W no data-driven rule here finds"
    ),
)
def test_van_der_pol_brief_thresholds_unmeasured_state_and_error(vdp_study):
    met = [
        np.median(r["x2"]) <= 0.011
        and np.median(r["d"]) <= 0.19
        and abs(np.median(r["ratio"]) - 1.0) <= 0.05
        for r in vdp_study.values()
    ]
    assert any(met)


def test_van_der_pol_through_pysindy():
    """The DESIGN.md use: SINDy fits d(x) from measurements of x1 only."""
    system = van_der_pol()
    m = system.measure(0)
    mme = MME(ignorance_model, 2, measured=[0], noise_variance=0.01, error_states=[1])
    sindy = ps.SINDy(
        differentiation_method=mme,
        optimizer=FloatingFStepwise(),
        feature_library=ps.PolynomialLibrary(degree=3),
    )
    sindy.fit(m.y, t=m.t, feature_names=["x1", "x2"])
    assert m.y.shape == (401, 1)
    assert mme.smoothed_x_.shape == (401, 2)
    assert mme.d_.shape == (401, 2)
    assert np.all(mme.d_[:, 0] == 0.0)
    names = sindy.get_feature_names()
    coef = sindy.coefficients()
    truth = {"x1": -1.0, "x2": 1.0, "x1^2 x2": -1.0}
    for name, value in truth.items():
        assert coef[1, names.index(name)] == pytest.approx(value, abs=0.3)
    others = [i for i, nm in enumerate(names) if nm not in truth]
    assert np.all(np.abs(coef[1, others]) < 0.2)
    assert np.all(coef[0] == 0.0)  # no error in x1's equation


@pytest.mark.filterwarnings("ignore:Sparsity parameter")  # x1' has no error
def test_multiple_trajectories_keep_last_call():
    system = van_der_pol()
    m0, m1 = system.measure(0), system.measure(1, x0=(-1.5, 0.5))
    mme = _vdp_mme()
    sindy = ps.SINDy(
        differentiation_method=mme,
        feature_library=ps.PolynomialLibrary(degree=3),
        optimizer=ps.STLSQ(threshold=0.05),
    )
    sindy.fit([m0.y, m1.y], t=m0.t, feature_names=["x1", "x2"])
    # the attributes describe the last trajectory
    assert np.var(mme.smoothed_x_[:, 0] - m1.x[:, 0]) < 0.002


# -------------------------------------------------------- nonlinear models


def test_nonlinear_duffing_cubic_assumed_recovers_velocity():
    """Assumed model with a wrong cubic coefficient; only x1 measured."""
    system = duffing()

    def assumed(x, t):
        return np.column_stack([x[:, 1], -x[:, 0] - 0.1 * x[:, 1] - 0.8 * x[:, 0] ** 3])

    errs = []
    for seed in range(3):
        m = system.measure(seed)
        mme = MME(assumed, 2, measured=[0], noise_variance=0.01, error_states=[1])
        mme.fit(m.y, m.t)
        assert mme.converged_
        assert mme.max_defect_ < 1e-8  # the estimate obeys the dynamics
        assert abs(mme.covariance_ratio_[0] - 1.0) < 1e-3
        errs.append(np.var(mme.smoothed_x_ - m.x, axis=0))
    errs = np.array(errs)
    # well below the noise variance 0.01, for the unmeasured state too
    assert np.all(errs[:, 0] < 0.001)
    assert np.all(errs[:, 1] < 0.003)


def test_nonlinear_lotka_volterra_one_population_measured():
    """Predators unmeasured, their equation lacks the feeding term e x1 x2.

    The initial guess sets the predators to zero (an invariant set of the
    model): Gauss-Newton has to find them from the prey alone.
    """
    system = lotka_volterra()
    m = system.measure(0)
    y = m.y[:, [0]]
    mme = MME(
        system.assumed_model, 2, measured=[0], noise_variance=0.01, error_states=[1]
    ).fit(y, m.t)
    assert mme.converged_
    e = mme.smoothed_x_ - m.x
    assert np.var(e[:, 0]) < 0.002
    # predators range over about [0.3, 3.5]: relative error of a few percent
    assert np.sqrt(np.mean(e[:, 1] ** 2)) < 0.2
    corr = np.corrcoef(mme.d_[:, 1], m.d[:, 1])[0, 1]
    assert corr > 0.9


# ------------------------------------------------------ options and inputs


def test_target_derivative_and_sample_grid_convention():
    system = van_der_pol()
    m = system.measure(2)
    mme = _vdp_mme(W=5.0, target="derivative")
    xdot = mme(m.y, m.t)
    np.testing.assert_allclose(
        xdot, ignorance_model(mme.smoothed_x_, m.t) + mme.d_, rtol=1e-12
    )
    true_xdot = system.true_model(m.x, m.t)
    assert np.sqrt(np.mean((xdot[:, 0] - true_xdot[:, 0]) ** 2)) < 0.15
    mme.set_params(target="error")
    np.testing.assert_array_equal(mme(m.y, m.t), mme.d_)


def test_inputs_from_constructor_or_fit():
    system = forced_oscillator()
    m = system.measure(0)
    kw = dict(measured=[0], noise_variance=0.01, error_states=[1], W=20.0)
    a = MME(system.assumed_model, 2, u=m.u, **kw).fit(m.y, m.t)
    b = MME(system.assumed_model, 2, **kw).fit(m.y, m.t, u=m.u)
    c = MME(system.assumed_model, 2, u=system.input_signal, **kw).fit(m.y, m.t)
    np.testing.assert_allclose(a.smoothed_x_, b.smoothed_x_)
    # the callable input is exact between samples, the array interpolated
    np.testing.assert_allclose(a.smoothed_x_, c.smoothed_x_, atol=2e-3)
    assert np.var(a.smoothed_x_[:, 1] - m.x[:, 1]) < 0.005
    # the hidden effect is 0.5 u: d must follow it
    assert np.corrcoef(a.d_[:, 1], m.d[:, 1])[0, 1] > 0.9


def test_missing_samples_and_irregular_times():
    system = van_der_pol()
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 10, 400))
    m = system.measure(0, t=t)
    y = m.y.copy()
    y[rng.choice(400, 40, replace=False)] = np.nan
    mme = _vdp_mme().fit(y, t)
    assert np.isnan(mme.residuals_).sum() == 40
    assert np.all(np.isfinite(mme.smoothed_x_))
    assert abs(mme.covariance_ratio_[0] - 1.0) < 1e-3
    assert np.var(mme.smoothed_x_[:, 0] - m.x[:, 0]) < 0.002


def test_nonlinear_measurement_function():
    """y = x1^2 + x2 measured; compare with the same data as a matrix."""
    system = van_der_pol()
    m = system.measure(0, full_state=True)

    def g(x):
        return x[:, [0]] + 0.5 * np.tanh(x[:, [1]])

    def g_jac(x):
        jac = np.zeros((len(x), 1, 2))
        jac[:, 0, 0] = 1.0
        jac[:, 0, 1] = 0.5 / np.cosh(x[:, 1]) ** 2
        return jac

    y = g(m.x) + 0.1 * np.random.default_rng(1).standard_normal((len(m.t), 1))
    kw = dict(noise_variance=0.01, error_states=[1], W=5.0)
    a = MME(ignorance_model, 2, measurement_function=g, **kw).fit(y, m.t)
    b = MME(
        ignorance_model, 2, measurement_function=g, measurement_jacobian=g_jac, **kw
    ).fit(y, m.t)
    assert a.converged_ and b.converged_
    np.testing.assert_allclose(a.smoothed_x_, b.smoothed_x_, atol=1e-6)
    assert np.var(a.smoothed_x_[:, 0] - m.x[:, 0]) < 0.005


def test_sklearn_conventions():
    mme = _vdp_mme(W=3.0)
    params = mme.get_params()
    assert params["W"] == 3.0 and params["measured"] == [0]
    c = clone(mme)
    assert c.get_params()["error_states"] == [1]
    assert not hasattr(c, "smoothed_x_")
    m = van_der_pol().measure(0)
    mme.fit(m.y, m.t)
    again = pickle.loads(pickle.dumps(mme))
    np.testing.assert_array_equal(again.smoothed_x_, mme.smoothed_x_)
    assert mme.get_params()["W"] == 3.0  # fit does not change parameters


# ------------------------------------------------------------------- misc


def test_clean_fit_emits_no_warning():
    """A clean fit emits no warning at all."""
    m = van_der_pol().measure(0)
    y, t = m.y, m.t
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _vdp_mme().fit(y, t)


def test_fitted_pysindy_model_as_assumed_model():
    """A SINDy model of the undamped oscillator, used as the assumed model."""
    system = duffing()
    t = np.arange(0, 20, 0.025)
    x = np.column_stack([np.cos(t), -np.sin(t)])
    sindy = ps.SINDy(feature_library=ps.PolynomialLibrary(degree=1))
    sindy.fit(x, t=t, x_dot=np.column_stack([x[:, 1], -x[:, 0]]))
    m = system.measure(0)
    kw = dict(measured=[0], noise_variance=0.01, error_states=[1], W=10.0)

    def oscillator(x, t):
        return np.column_stack([x[:, 1], -x[:, 0]])

    a = MME(sindy, 2, **kw).fit(m.y, m.t)
    b = MME(oscillator, 2, **kw).fit(m.y, m.t)
    np.testing.assert_allclose(a.smoothed_x_, b.smoothed_x_, atol=1e-6)
    np.testing.assert_allclose(a.d_, b.d_, atol=1e-5)
