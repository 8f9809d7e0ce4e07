"""Grey-box parameters with bounds: parsed up front, kept in every fit.

``parameters=`` takes per name a number, ``(guess, lower, upper)`` or a
:class:`Parameter`; a bad entry fails before any solve, naming the parameter.
The output-error fit never leaves the box, stops at a parameter the data push
against its bound (reported ``at_bound``, its standard error NaN, the rest
as with it held there), and is the free fit when the bounds do not bind.
"""

import warnings

import numpy as np
import pysindy as ps
import pytest

from pysindy_mme import Parameter, discover
from pysindy_mme.core.model import simulate_model
from pysindy_mme.discovery.inputs import check_study
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.solver import transcription
from pysindy_mme.solver.output_error import OutputErrorModel
from pysindy_mme.solver.transcription import box_qp
from pysindy_mme.systems import duffing

NOISE = 1e-3
INF = np.inf


def linear_oscillator(x, t, u, p):
    """The modeller's linear model: x2' = -k x1 - c x2."""
    return np.column_stack([x[:, 1], -p["k"] * x[:, 0] - p["c"] * x[:, 1]])


def _grey_box(data, parameters, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return discover(
            data.y,
            data.t,
            assumed_model=linear_oscillator,
            n_states=2,
            measured=[0],
            noise_variance=NOISE,
            error_states=[1],
            feature_library=ps.PolynomialLibrary(degree=3),
            **grouped_keywords(
                {"parameters": parameters, "feature_names": ["x1", "x2"], **kwargs}
            ),
        )


@pytest.fixture(scope="module")
def data():
    return duffing().measure(0, noise_variance=NOISE)


@pytest.fixture(scope="module")
def unbounded(data):
    return _grey_box(data, {"k": 0.7, "c": 0.13})


# ------------------------------------------------------------------ parsing
def test_parameter_is_checked_when_made():
    p = Parameter(90, lower=0)
    assert (p.value, p.lower, p.upper) == (90.0, 0.0, None)
    assert p.bounds == (0.0, INF)
    with pytest.raises(ValueError, match="lower bound 2 must be below the upper"):
        Parameter(1.0, 2.0, 0.0)
    with pytest.raises(ValueError, match="guess 5 is outside its bounds"):
        Parameter(5.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="guess must be finite"):
        Parameter(np.nan)
    with pytest.raises(TypeError, match="guess must be a number"):
        Parameter("90")


def test_every_form_gives_guesses_and_bounds(data, no_long_computation):
    study = check_study(
        data.y,
        data.t,
        assumed_model=linear_oscillator,
        parameters={"k": 0.7, "c": (0.13, 0, None), "m": Parameter(2.0, None, 3.0)},
        n_states=2,
        measured=[0],
        noise_variance=NOISE,
    )
    assert study.parameter_names == ["k", "c", "m"]
    np.testing.assert_array_equal(study.parameter_init, [0.7, 0.13, 2.0])
    np.testing.assert_array_equal(
        study.parameter_bounds, [[-INF, INF], [0.0, INF], [-INF, 3.0]]
    )
    # a guess on a bound is allowed (the box is closed)
    on_bound = check_study(
        data.y,
        data.t,
        assumed_model=linear_oscillator,
        parameters={"k": (0.7, 0.7, None), "c": 0.1},
        n_states=2,
        measured=[0],
        noise_variance=NOISE,
    )
    np.testing.assert_array_equal(on_bound.parameter_bounds[0], [0.7, INF])


@pytest.mark.parametrize(
    "spec, exc, match",
    [
        ((0.7, 2.0, 1.0), ValueError, r"parameters: k: the lower bound 2 must be"),
        ((0.7, 1.0, 1.0), ValueError, r"parameters: k: the lower bound 1 must be"),
        ((0.7, 1.0, None), ValueError, r"parameters: k: the guess 0.7 is outside"),
        ((0.7, None, 0.5), ValueError, r"parameters: k: the guess 0.7 is outside"),
        ((np.nan, 0, 1), ValueError, r"parameters: k: the guess must be finite"),
        ((np.inf, 0, None), ValueError, r"parameters: k: the guess must be finite"),
        (np.inf, ValueError, r"parameters: k must be finite"),
        ((0.7, 0.0), ValueError, r"parameters: k must be .* got 2 values"),
        ((0.7, 0.0, 1.0, 2.0), ValueError, r"parameters: k must be .* got 4 values"),
        ((0.7, np.nan, 1.0), ValueError, r"parameters: k: a bound is NaN"),
        ((0.7, "0", 1.0), TypeError, r"parameters: k: the lower bound must be"),
        ((0.7, 0.0, "1"), TypeError, r"parameters: k: the upper bound must be"),
        (("0.7", 0.0, 1.0), TypeError, r"parameters: k: the guess must be a number"),
        ("0.7", TypeError, r"parameters: k must be a number, \(guess, lower"),
        (None, TypeError, r"parameters: k must be a number, \(guess, lower"),
        (True, TypeError, r"parameters: k must be a number, \(guess, lower"),
    ],
)
def test_bad_parameter_is_named_before_any_solve(
    data, no_long_computation, spec, exc, match
):
    with pytest.raises(exc, match=match):
        _grey_box(data, {"c": 0.1, "k": spec})


# ------------------------------------------------------- the bounded solver
def test_box_qp_matches_its_optimality_conditions():
    rng = np.random.default_rng(1)
    A = rng.standard_normal((8, 5))
    S, g = A.T @ A, rng.standard_normal(5) * 3
    lower = np.array([-0.1, -INF, -0.2, 0.0, -1.0])
    upper = np.array([0.1, 0.05, INF, 0.5, 1.0])
    v, active = box_qp(S, g, lower, upper)
    assert np.all(v >= lower) and np.all(v <= upper)
    grad = S @ v - g
    free = active == 0
    np.testing.assert_allclose(grad[free], 0.0, atol=1e-10)
    assert np.all(grad[active < 0] >= -1e-10) and np.all(grad[active > 0] <= 1e-10)
    np.testing.assert_array_equal(v[active < 0], lower[active < 0])
    np.testing.assert_array_equal(v[active > 0], upper[active > 0])
    # no bound binds: the free minimiser
    v, active = box_qp(S, g, np.full(5, -1e6), np.full(5, 1e6))
    np.testing.assert_allclose(v, np.linalg.solve(S, g), rtol=1e-10)
    assert not active.any()


@pytest.fixture(scope="module")
def growing_record():
    """A spring with negative damping: ``x2' = -x1 + 0.05 x2``, x1 measured."""
    t = np.arange(0, 20 + 1e-9, 0.05)

    def truth(x, t):
        return np.column_stack([x[:, 1], -x[:, 0] + 0.05 * x[:, 1]])

    x = simulate_model(truth, np.array([1.0, 0.0]), t, rtol=1e-10, atol=1e-12)
    y = x[:, :1] + np.sqrt(NOISE) * np.random.default_rng(0).standard_normal(
        (t.size, 1)
    )
    start = np.column_stack([y[:, 0], np.gradient(y[:, 0], t)])
    return y, t, start


def _engine(record, base, n_physical, bounds=None):
    y, t, _ = record
    return OutputErrorModel(
        base,
        2,
        None,
        y,
        t,
        None,
        np.eye(1) * NOISE,
        np.eye(2)[[0]],
        n_physical=n_physical,
        bounds=bounds,
    )


def _spring(x, t, u, p):
    return np.column_stack([x[:, 1], -p[0] * x[:, 0] - p[1] * x[:, 1]])


@pytest.fixture
def trial_thetas(monkeypatch):
    """Every ``theta`` at which the solver integrates the model."""
    seen = []
    flow = transcription.MMESmoother.flow

    def recording(self, x, d, theta=None, *args, **kwargs):
        seen.append(np.array(theta, dtype=float))
        return flow(self, x, d, theta, *args, **kwargs)

    monkeypatch.setattr(transcription.MMESmoother, "flow", recording)
    return seen


def test_iterates_never_leave_the_box(growing_record, trial_thetas):
    start = growing_record[2]
    free = _engine(growing_record, _spring, 2).fit((), [1.2, 0.1], start)
    assert free.converged and free.theta[1] == pytest.approx(-0.05, abs=0.005)
    trial_thetas.clear()
    # the data want negative damping; the bound says at least 0.01
    bounds = np.array([[-INF, INF], [0.01, INF]])
    fit = _engine(growing_record, _spring, 2, bounds).fit((), [1.2, 0.1], start)
    seen = np.array(trial_thetas)
    assert len(seen) > 2 and np.all(seen[:, 1] >= 0.01)
    # pinned at the bound, a KKT point: converged, not a failed line search
    assert fit.converged and fit.message == "converged"
    assert fit.theta[1] == 0.01
    np.testing.assert_array_equal(fit.at_bound, [False, True])
    assert fit.cost > free.cost
    # the same fit as the model with c fixed at 0.01: value, cost, statistics
    held = _engine(
        growing_record,
        lambda x, t, u, p: _spring(x, t, u, np.array([p[0], 0.01])),
        1,
    ).fit((), [1.2], start)
    assert fit.theta[0] == pytest.approx(held.theta[0], rel=1e-8)
    assert fit.cost == pytest.approx(held.cost, rel=1e-8)
    assert fit.n_free == held.n_free
    assert np.isnan(fit.std_errors[1]) and np.isnan(fit.covariance[0, 1])
    assert fit.std_errors[0] == pytest.approx(held.std_errors[0], rel=1e-6)
    np.testing.assert_allclose(fit.x0_covariance, held.x0_covariance, rtol=1e-6)


def test_bounds_that_do_not_bind_change_nothing(growing_record):
    start = growing_record[2]
    free = _engine(growing_record, _spring, 2).fit((), [1.2, 0.1], start)
    for bounds, theta0 in [
        ([[0.5, 2.0], [-1.0, 1.0]], [1.2, 0.1]),
        # a guess on a bound the data pull away from: it leaves the bound
        ([[0.5, 2.0], [-0.1, 1.0]], [1.2, -0.1]),
    ]:
        fit = _engine(growing_record, _spring, 2, np.array(bounds)).fit(
            (), theta0, start
        )
        assert fit.converged and not fit.at_bound.any()
        np.testing.assert_allclose(fit.theta, free.theta, rtol=1e-8)
        np.testing.assert_allclose(fit.std_errors, free.std_errors, rtol=1e-8)
        assert fit.cost == pytest.approx(free.cost, rel=1e-10)


def test_bounds_reach_substeps_and_shape_is_checked(growing_record):
    bounds = np.array([[-INF, INF], [0.01, INF]])
    engine = _engine(growing_record, _spring, 2, bounds)
    np.testing.assert_array_equal(engine.with_substeps(2).bounds, bounds)
    # no finite bound: no bounds at all (the free solver)
    assert (
        _engine(growing_record, _spring, 2, np.tile([-INF, INF], (2, 1))).bounds is None
    )
    with pytest.raises(ValueError, match=r"bounds must have shape \(2, 2\)"):
        _engine(growing_record, _spring, 2, np.zeros((1, 2)))


# ----------------------------------------------------------- grey-box study
def test_upper_bound_below_the_truth_is_hit_and_reported(data):
    # k is 1 in truth; the assumed model alone would take it to ~1.86
    res = _grey_box(data, {"k": (0.7, None, 0.95), "c": 0.13})
    k, c = res.parameters["k"], res.parameters["c"]
    assert k.value == 0.95 and k.assumed_fit == 0.95
    assert k.at_bound and (k.lower, k.upper) == (-INF, 0.95)
    assert np.isnan(k.std_error) and np.isnan(k.ci_low) and np.isnan(k.ci_high)
    assert not c.at_bound and np.isfinite(c.std_error) and c.std_error > 0
    assert c.ci_low < c.value < c.ci_high
    fit = res.extended_fit
    assert fit.ok and np.all(np.isfinite(fit.theta)) and np.all(np.isfinite(fit.x))
    assert set(res.terms["x2"]) == {"x1^3"}
    out = res.to_dict()["parameters"]["k"]
    assert out["at_bound"] is True and out["upper"] == 0.95 and out["lower"] is None


def test_bounds_containing_the_truth_give_the_free_result(data, unbounded):
    res = _grey_box(
        data, {"k": Parameter(0.7, lower=0.5, upper=3.0), "c": (0.13, 0.01, 1.0)}
    )
    assert res.terms.keys() == unbounded.terms.keys()
    for state, terms in unbounded.terms.items():
        assert res.terms[state].keys() == terms.keys()
        for name, value in terms.items():
            assert res.terms[state][name] == pytest.approx(value, rel=1e-8)
    for name, free in unbounded.parameters.items():
        bounded = res.parameters[name]
        assert not bounded.at_bound
        assert bounded.value == pytest.approx(free.value, rel=1e-8)
        assert bounded.std_error == pytest.approx(free.std_error, rel=1e-8)
    assert res.parameters["c"].lower == 0.01 and res.parameters["k"].upper == 3.0
