"""Units do not change answers: the same study in two unit systems.

A change of units of the states, ``x -> D x`` with ``D`` diagonal (metres to
millimetres, or one state in other units than the next), maps the assumed
model onto ``f_D(x) = D f(D^-1 x)``, the measurements onto ``D y`` and the
noise sd onto ``D sd``. ``discover`` must then reach the same conclusion,
keep the same terms with the same coefficients once rescaled (a term
``prod_k x_k^p_k`` in the equation of state ``i`` has its coefficient
multiplied by ``D_i / prod_k D_k^p_k``), the same grey-box parameters, and
the same free-run RMSEs in physical units, each to within 1 %.

Measured before the solver had one unit per state (it had one for all, near
the noise sd): metres and millimetres kept different terms on the Bouc-Wen
record (a score test that compared a unit-dependent number with the cost
dropped ``y^3`` in metres), states 1e5 apart in scale made MME's KKT system
look singular, two channels of very different noise put W out of its search
range. Each case below failed then.

Fast cases run in the edit loop (about 15 s); the full Bouc-Wen records
(8192 samples, two and three states) are marked slow.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pysindy as ps
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from pysindy_mme import MME, discover
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.feature_library.power import PowerLibrary
from pysindy_mme.machines import hysteretic_oscillator
from pysindy_mme.systems import duffing, lotka_volterra

RTOL = 0.01  # the acceptance tolerance: 1 %


# ----------------------------------------------------------------- helpers
def in_units(f, D, form):
    """The model ``f`` in units ``x_D = D x``: ``D f(D^-1 x_D)``."""
    D = np.asarray(D, dtype=float)
    if form == "p":

        def g(x, t, u, p):
            return np.asarray(f(x / D, t, u, p)) * D

    elif form == "u":

        def g(x, t, u):
            return np.asarray(f(x / D, t, u)) * D

    else:

        def g(x, t):
            return np.asarray(f(x / D, t)) * D

    return g


def study(y, t, model, D, measured, noise_sd, **kw):
    """``discover`` on data in units ``D`` (the states'; inputs unchanged)."""
    Dm = np.asarray(D, dtype=float)[measured]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the same notes in any units
        return discover(
            np.asarray(y) * Dm,
            t,
            assumed_model=model,
            measured=measured,
            noise_variance=(np.asarray(noise_sd, dtype=float) * Dm) ** 2,
            **grouped_keywords(kw),
        )


_FACTOR = re.compile(r"^\|?([A-Za-z_]\w*)\|?(?:\^(\d+))?$")


def to_base_units(coefficient, state, feature, D, names):
    """A coefficient of ``feature`` in ``state``' in units ``D``, in base units.

    ``names``: the states' names (the inputs are not rescaled).
    """
    scale = {name: float(d) for name, d in zip(names, D)}
    value = coefficient / scale[state]
    if feature == "1":
        return value
    for factor in feature.split():
        match = _FACTOR.match(factor)
        assert match, f"cannot read the powers of {feature!r}"
        name, power = match.group(1), int(match.group(2) or 1)
        value *= scale.get(name, 1.0) ** power
    return value


def assert_same_study(base, other, D):
    """``other`` (units ``D``) says what ``base`` (units 1) says, within 1 %."""
    D = np.asarray(D, dtype=float)
    names = list(base.state_names)
    assert other.conclusion == base.conclusion
    found = {
        (state, feature): to_base_units(c, state, feature, D, names)
        for state, terms in other.terms.items()
        for feature, c in terms.items()
    }
    expected = {
        (state, feature): c
        for state, terms in base.terms.items()
        for feature, c in terms.items()
    }
    assert set(found) == set(expected)
    for key, value in expected.items():
        assert found[key] == pytest.approx(value, rel=RTOL), key
    for name, estimate in base.parameters.items():
        mine = other.parameters[name]
        assert mine.value == pytest.approx(estimate.value, rel=RTOL), name
        assert mine.assumed_fit == pytest.approx(estimate.assumed_fit, rel=RTOL)
    Dm = D[list(base.measured)]
    a, b = base.gain, other.gain
    pairs = [("rmse_assumed",), ("rmse_extended",)]
    if a.validation_rmse_assumed is not None:
        pairs += [("validation_rmse_assumed",), ("validation_rmse_extended",)]
    for (field,) in pairs:
        physical = np.asarray(getattr(b, field), dtype=float) / Dm
        np.testing.assert_allclose(
            physical, np.asarray(getattr(a, field), dtype=float), rtol=RTOL
        )


# ----------------------------------------------- Duffing: any two state units
_DUFFING = duffing()
_DUFFING_DATA = _DUFFING.measure(seed=0)


def _duffing_study(D):
    return study(
        _DUFFING_DATA.y,
        _DUFFING_DATA.t,
        in_units(_DUFFING.assumed_model, D, "x"),
        D,
        [0],
        [np.sqrt(_DUFFING.noise_variance)],
        n_states=2,
        error_states=[1],
        feature_names=["x1", "x2"],
    )


@pytest.fixture(scope="module")
def duffing_base():
    return _duffing_study([1.0, 1.0])


@settings(max_examples=2)
@given(exponents=st.tuples(st.floats(-4.0, 4.0), st.floats(-4.0, 4.0)))
@example(exponents=(3.0, 3.0))  # metres to millimetres
@example(exponents=(-3.0, 2.0))  # the two states 1e5 apart in scale
def test_duffing_study_is_the_same_in_any_units(exponents, duffing_base, case_counter):
    """The cubic spring a linear model misses, found in any units."""
    case_counter["discover"] += 1
    D = 10.0 ** np.asarray(exponents)
    assert_same_study(duffing_base, _duffing_study(D), D)


# ------------------------------- Lotka-Volterra: two channels, nonlinear model
def test_two_channels_in_very_different_units(case_counter):
    """Both states measured, their noise sd 1e5 apart; the assumed model is
    nonlinear (its finite-difference Jacobian must not depend on units)."""
    case_counter["discover"] += 2
    system = lotka_volterra()
    data = system.measure(seed=0)
    sd = [np.sqrt(system.noise_variance)] * 2

    def run(D):
        return study(
            data.y,
            data.t,
            in_units(system.assumed_model, D, "x"),
            D,
            [0, 1],
            sd,
            n_states=2,
            error_states=[1],
            feature_names=["x1", "x2"],
        )

    D = [1e3, 1e-2]
    assert_same_study(run([1.0, 1.0]), run(D), D)


# ------------------------- Bouc-Wen: grey-box parameters, an input, metres/mm
def _hysteretic_study(record, D, three_states=False):
    machine = hysteretic_oscillator()
    kw = dict(
        u=record.u,
        parameters=dict(machine.parameters),
        input_hold="zoh",
    )
    if not three_states:
        model = in_units(machine.assumed_model, D, "p")
        return study(
            record.y,
            record.t,
            model,
            D,
            [0],
            record.noise_sd,
            n_states=2,
            error_states=[1],
            feature_names=["y", "v", "u"],
            **kw,
        )

    def hidden(x, t, u, p):
        # z: the hysteretic force per unit mass, a state nobody measured
        y, v, z = x[:, 0], x[:, 1], x[:, 2]
        uu = np.asarray(u, dtype=float).reshape(len(x), -1)[:, 0]
        return np.column_stack(
            [v, (uu - p["c"] * v - p["k"] * y) / p["m"] + z, np.zeros(len(x))]
        )

    library = ps.GeneralizedLibrary(
        [
            PowerLibrary(
                powers=(1,),
                abs_powers=(1,),
                signed_abs_products=False,
                power_products=False,
            )
        ],
        inputs_per_library=[[1, 2]],
    )
    return study(
        record.y,
        record.t,
        in_units(hidden, D, "p"),
        D,
        [0],
        record.noise_sd,
        n_states=3,
        error_states=[2],
        feature_names=["y", "v", "z", "u"],
        feature_library=library,
        **kw,
    )


@pytest.fixture(scope="module")
def short_bouc_wen():
    record = hysteretic_oscillator().record(seed=0, n_samples=2048)
    return record, _hysteretic_study(record, [1.0, 1.0])


@pytest.mark.parametrize(
    "D",
    [(1e3, 1e3), (1e-3, 1e2)],
    ids=["millimetres", "states-1e5-apart"],
)
def test_bouc_wen_short_record_in_other_units(D, short_bouc_wen, case_counter):
    """A displacement of ~1e-3 m and a velocity of ~0.3 m/s under a 50 N
    force: metres and millimetres (and a mix) keep the same terms."""
    case_counter["discover"] += 1
    record, base = short_bouc_wen
    assert_same_study(base, _hysteretic_study(record, D), D)


@pytest.fixture(scope="module")
def bouc_wen():
    """The full record and its studies in base units (computed on demand)."""
    record = hysteretic_oscillator().record(seed=0)
    cache = {}

    def base(three_states):
        if three_states not in cache:
            n = 3 if three_states else 2
            cache[three_states] = _hysteretic_study(record, [1.0] * n, three_states)
        return cache[three_states]

    return record, base


@pytest.mark.slow
@pytest.mark.parametrize(
    "three_states, D",
    [(False, (1e3, 1e3)), (True, (1e3, 1e3, 1e3)), (True, (1e-3, 1.0, 1e3))],
    ids=["two-mm", "hidden-z-mm", "hidden-z-1e6-apart"],
)
def test_bouc_wen_record_in_other_units(three_states, D, bouc_wen, case_counter):
    """The full record, the two-state model and the one with a hidden
    hysteretic state (whose unit, an acceleration, scales too): metres and
    millimetres, and the hidden state 1e6 times the displacement's scale."""
    case_counter["discover"] += 1
    record, base = bouc_wen
    other = _hysteretic_study(record, D, three_states)
    assert_same_study(base(three_states), other, D)


# ------------------------------------- MME alone: the estimate and likelihood
@pytest.mark.parametrize("error_model", ["white", "random_walk"])
@pytest.mark.parametrize("W", ["auto", "ml"])
def test_mme_estimate_transforms_with_each_states_units(error_model, W):
    """States, model error, W and the marginal likelihood follow a change of
    units of each state exactly (to rounding), including factors that are
    not powers of ten: ``log p`` of data in units ``D`` is that in base
    units ``- N log D_y + sum_i log D_i`` (one free initial state each,
    the random walk's model error one more)."""
    system = duffing()
    data = system.measure(seed=1)
    fits = []
    for D in ([1.0, 1.0], [1e-3, 1e2], [25.4, 1e-3]):
        D = np.asarray(D)
        mme = MME(
            in_units(system.assumed_model, D, "x"),
            2,
            measured=[0],
            noise_variance=system.noise_variance * D[0] ** 2,
            error_states=[1],
            error_model=error_model,
            W=W,
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fits.append((D, mme.fit(data.y * D[0], data.t)))
    _, base = fits[0]
    for D, mme in fits[1:]:
        np.testing.assert_allclose(
            mme.smoothed_x_ / D, base.smoothed_x_, rtol=1e-6, atol=1e-9
        )
        np.testing.assert_allclose(
            mme.d_[:, 1] / D[1], base.d_[:, 1], rtol=1e-6, atol=1e-6
        )
        assert mme.W_ * D[1] ** 2 == pytest.approx(base.W_, rel=1e-6)
        n_x0 = np.log(D).sum() + (np.log(D[1]) if error_model != "white" else 0.0)
        shift = -data.t.size * np.log(D[0]) + n_x0
        assert mme.log_likelihood_ == pytest.approx(
            base.log_likelihood_ + shift, abs=1e-6
        )
