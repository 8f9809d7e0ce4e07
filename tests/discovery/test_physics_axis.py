"""Acceptance case (a) of the physics issue: Coulomb friction on a real axis.

A carriage on a screw axis under a PD position loop
(:func:`pysindy_mme.machines.positioning_axis`): mass 95 kg, viscous
friction 200 N s/m, Coulomb friction 20 N that sticks at rest, and a force
offset of -3 N; the controller's voltage is held between samples; the
position is read by an encoder with a 50 nm step at 1 kHz for 25 s. The
user's grey box has the mass and the viscous friction only (guesses 90 kg,
150 N s/m). The study is given the encoder's noise (its quantisation,
``step^2 / 12``), a zero-order hold, the last fifth of the record for
validation, and the library of friction laws an engineer would offer for
the velocity: Coulomb ``sign(v)``, a Stribeck bump ``sign(v)
exp(-(v/0.02)^2)`` and an offset.

Criteria (fixed before the seeds were run): Coulomb within 3 % of
``-Fc/M``, the offset within 10 % of ``F0/M``, the mass within 5 %, and no
other term, in at least 9 of 10 seeds (0..9). The Stribeck term is the
tempting one: the plant sticks, which the smoothed ``sign`` cannot do, and
a small Stribeck bump would absorb part of that; the study drops it because
its coefficient depends on the smoothing width.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from pysindy_mme import MME, PhysicsLibrary, StudyOptions, discover
from pysindy_mme.feature_library import Coulomb, Stribeck
from pysindy_mme.machines import positioning_axis

FC, F0, MASS = 20.0, -3.0, 95.0
AXIS = positioning_axis(F0=F0)
NAMES = ["q", "v", "u"]


def axis_study(seed, duration=25.0, machine=AXIS, assumed_model=None):
    """The study of the module docstring; ``assumed_model(x, t, u)`` replaces
    the grey box (fixed constants, no parameters) when given."""
    rec = machine.record(seed, duration=duration)
    train, test = rec.split(0.8)
    noise = rec.quantisation_step**2 / 12.0 + float(rec.noise_sd[0]) ** 2
    grey_box = (
        StudyOptions(parameters=machine.parameters, feature_names=NAMES)
        if assumed_model is None
        else StudyOptions(feature_names=NAMES)
    )
    library = PhysicsLibrary(
        [Coulomb("v"), Stribeck("v", 0.02)], include_bias=True, names=NAMES
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return discover(
            train.y,
            train.t,
            u=train.u,
            assumed_model=machine.assumed_model
            if assumed_model is None
            else assumed_model,
            n_states=2,
            measured=[0],
            noise_variance=noise,
            feature_library=library,
            error_states=[1],
            validation=(test.y, test.t, test.u),
            options=grey_box,
            mme=MME(input_hold="zoh"),
        )


def axis_failures(res) -> list:
    """What is wrong with a study's answer (empty: right)."""
    terms = res.terms.get("v", {})
    mass = res.parameters["M"].value
    out = []
    if "sign(v)" not in terms:
        return [f"no Coulomb friction kept: {res.terms} ({res.conclusion})"]
    coulomb = -terms["sign(v)"] * mass
    offset = terms.get("1", np.nan) * mass
    if not coulomb == pytest.approx(FC, rel=0.03):
        out.append(f"Coulomb {coulomb:.4g} N, truth {FC:g}")
    if not offset == pytest.approx(F0, rel=0.10):
        out.append(f"offset {offset:.4g} N, truth {F0:g}")
    if not mass == pytest.approx(MASS, rel=0.05):
        out.append(f"mass {mass:.4g} kg, truth {MASS:g}")
    others = sorted(set(terms) - {"sign(v)", "1"}) + sorted(set(res.terms) - {"v"})
    if others:
        out.append(f"other terms kept: {others}")
    return out


@pytest.mark.slow
def test_axis_coulomb_and_offset_over_ten_seeds():
    failures = {}
    for seed in range(10):
        problems = axis_failures(axis_study(seed))
        if problems:
            failures[seed] = problems
    print(f"\nright in {10 - len(failures)}/10 seeds; {failures}")
    assert len(failures) <= 1, failures


@pytest.mark.slow  # a whole study: keeps the edit loop under 2 minutes
def test_axis_short_record_names_friction_and_the_smoothing():
    # 10 s of the same axis: the answer is right; the report says how the
    # kink was integrated and what half the width does (with a 50 nm encoder
    # even a 0.1 % move of the Coulomb term is many standard errors, and it
    # says so); and since a smoothed sign cannot stick, the extended model
    # misses the record by far more than the encoder's noise: "partly
    # explained", never "explained"
    res = axis_study(0, duration=10.0)
    assert axis_failures(res) == []
    assert "kinks integrated smoothed (sign(v) over" in str(res)
    assert res.conclusion == "partly explained"
    assert any("misses its record" in reason for reason in res.reasons)
    # ... and that misfit is the smoothing's, not a missing effect's
    assert_misfit_named_the_kinks(res)


def assert_misfit_named_the_kinks(res):
    assert res.conclusion == "partly explained"
    assert "integration of the smoothed kinks" in res.verdict, res.verdict
    assert not any("not in the library" in reason for reason in res.reasons)
    assert not any("hidden state" in advice for advice in res.advice)


def assert_misfit_named_an_effect_missed(res):
    assert "integration of the smoothed kinks" not in res.verdict, res.verdict
    assert any("not in the library" in reason for reason in res.reasons), (
        res.conclusion,
        res.reasons,
    )


def _fixed(mass, damping):
    """The axis' model with fixed constants (K_u = 100 N/V known)."""

    def model(x, t, u):
        return np.column_stack([x[:, 1], (100.0 * u[:, 0] - damping * x[:, 1]) / mass])

    return model


# Where the misfit left is the smoothing's and where it is an effect the
# library lacks. KINK_MISFIT_SHARE (0.7) was set on the default axis' seed 0
# (0.60 of the misfit left at half the width), the 40 kg axis at 500 Hz
# (0.58) and breakaway friction above the sliding one (0.75: sticking the
# library cannot express); seed 1, the 2 um noise and the viscous rows were
# run after it; the rows marked held out were written here first, run once.
KINK_CASES = [
    # (id, machine, seed, fixed model or None, the misfit is the kinks')
    ("default axis, seed 1", AXIS, 1, None, True),
    (
        "40 kg at 500 Hz",
        positioning_axis(M=40.0, c=80.0, Fc=8.0, F0=2.0, rate=500.0),
        0,
        None,
        True,
    ),
    (
        "60 kg, encoder with 2 um noise",
        positioning_axis(M=60.0, c=120.0, Fc=12.0, F0=-1.5, noise_sd=2e-6),
        0,
        None,
        True,
    ),
    (
        "120 kg at 800 Hz (held out)",
        positioning_axis(M=120.0, c=250.0, Fc=30.0, F0=5.0, rate=800.0),
        7,
        None,
        True,
    ),
    # a stiff kink: the refit after the smoothing artefact (a constant) is
    # dropped did not converge from the fit's trajectory ("inconclusive"
    # before session 25); it now falls back to MME's states
    (
        "150 kg at 2 kHz, no offset",
        positioning_axis(M=150.0, c=300.0, Fc=35.0, F0=0.0, rate=2000.0),
        0,
        None,
        True,
    ),
    ("breakaway friction 28 N", positioning_axis(F0=F0, Fs=28.0), 0, None, False),
    ("viscous friction fixed 5 % low", AXIS, 0, _fixed(95.0, 190.0), False),
    ("mass fixed at 80 kg (held out)", AXIS, 3, _fixed(80.0, 200.0), False),
]


@pytest.mark.slow  # eight whole studies
@pytest.mark.parametrize("case", KINK_CASES, ids=lambda c: c[0])
def test_the_misfit_left_is_named_the_kinks_only_where_it_follows_the_width(case):
    _, machine, seed, model, kinks = case
    res = axis_study(seed, duration=20.0, machine=machine, assumed_model=model)
    if res.conclusion != "partly explained":
        # the rule only reads a fit that converged and holds out of sample
        assert not kinks, (res.conclusion, res.reasons)
        assert "integration of the smoothed kinks" not in res.verdict
        return
    if kinks:
        assert_misfit_named_the_kinks(res)
    else:
        assert_misfit_named_an_effect_missed(res)
