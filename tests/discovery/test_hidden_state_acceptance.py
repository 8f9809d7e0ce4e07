"""Issue 23 acceptance: a state nobody measured, suspected, estimated, its law found.

A hysteretic oscillator (Bouc-Wen, exponent 1): ``m y'' + c y' + k y + F = u``
with ``F' = alpha v - beta gamma |v| F - beta delta v |F|``; displacement
measured with noise 5 % of its sd, multisine force, m, c, k guessed 20 % off.

HELD-OUT CASE. The constants, band, amplitude and seeds below were written
once, in the published range of the Bouc-Wen benchmark (Noel & Schoukens
2016 use m = 2, c = 10, k = 5e4, alpha = 5e4, beta = 1e3, gamma = 0.8,
delta = -1.1), and were NOT used while the method was developed (that used
the benchmark's own constants, ``hysteretic_oscillator()``'s defaults, and
seeds 0-9). Do not tune the method on them.

With ``hidden_states={"z": "v"}`` the state enters as ``v' = ... + z``, so
``z = -F / m`` and its law is ``z' = -(alpha / m) v - beta gamma |v| z +
beta delta v |z|``.
"""

import warnings

import numpy as np
import pysindy as ps
import pytest

from pysindy_mme import discover
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.feature_library.power import PowerLibrary
from pysindy_mme.machines import hysteretic_oscillator

HELD_OUT = dict(m=1.6, c=7.0, k=3.5e4, alpha=6.5e4, beta=1.4e3, gamma=0.65, delta=-0.85)
RECORDING = dict(u_rms=35.0, band=(4.0, 120.0), n_samples=8192, noise_share=0.05)
SEEDS = range(100, 110)
LAW = {
    "v": -HELD_OUT["alpha"] / HELD_OUT["m"],
    "|v| z": -HELD_OUT["beta"] * HELD_OUT["gamma"],
    "v |z|": HELD_OUT["beta"] * HELD_OUT["delta"],
}


def _library(variables):
    power = PowerLibrary(
        powers=(1,), abs_powers=(1,), signed_abs_products=False, power_products=False
    )
    return ps.GeneralizedLibrary([power], inputs_per_library=[variables])


def _study(seed, variables, hidden=True, constants=HELD_OUT, recording=RECORDING):
    machine = hysteretic_oscillator(**constants)
    record = machine.record(seed=seed, **recording)
    options = dict(
        u=record.u,
        assumed_model=machine.assumed_model,
        parameters=dict(machine.parameters),
        n_states=2,
        measured=[0],
        noise_variance=float(record.noise_sd[0]) ** 2,
        feature_library=_library(variables),
        feature_names=["y", "v", "u"],
        input_hold="zoh",
    )
    if hidden:
        options["hidden_states"] = {"z": "v"}
    else:
        options["error_states"] = [1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return discover(record.y, record.t, **grouped_keywords(options))


def _law_found(res, law=LAW) -> tuple:
    terms = res.terms.get("z", {})
    errors = {
        name: abs(terms[name] / value - 1) if name in terms else np.inf
        for name, value in law.items()
    }
    ok = (
        set(terms) == set(law)
        and set(res.terms) <= {"z"}
        and all(e <= 0.02 for e in errors.values())
    )
    return ok, errors, sorted(set(terms) - set(law))


@pytest.mark.slow
@pytest.mark.parametrize(
    "variables, label", [([1, 2], "(v, z)"), ([0, 1, 2], "(y, v, z)")]
)
def test_hidden_state_law_within_two_percent_in_nine_of_ten(variables, label):
    right, lines = 0, []
    for seed in SEEDS:
        res = _study(seed, variables)
        ok, errors, extra = _law_found(res)
        right += ok
        lines.append(
            f"seed {seed}: {'ok' if ok else 'NO'} "
            + ", ".join(f"{k} {100 * e:.2f}%" for k, e in errors.items())
            + (f"; extra {extra}" if extra else "")
            + f"; {res.conclusion}"
        )
    print(f"\nlibrary {label}: law within 2 % in {right}/10\n" + "\n".join(lines))
    assert right >= 9


@pytest.mark.slow
def test_without_the_state_the_study_names_a_missing_state():
    named, lines = 0, []
    for seed in SEEDS:
        res = _study(seed, [0, 1], hidden=False)
        suspected = any(m.suspected for m in res.memory)
        said = "hidden_states={'z': 'v'}" in " ".join(res.advice)
        ok = res.conclusion != "explained" and suspected and said
        named += ok
        lines.append(f"seed {seed}: {res.conclusion}, missing state named: {said}")
    print(f"\n[y, v] only: missing state named in {named}/10\n" + "\n".join(lines))
    assert named >= 9


@pytest.mark.slow
def test_the_law_through_a_fit_that_does_not_join_yet():
    """Development constants (the machine's defaults), seed 3, library of (y,
    v, z): the confirmation reaches the law through a fit of v, z, |y| v and
    |v| z whose trajectory does not quite join (largest defect 1e-3). A rule
    that refused every such fit lost |v| z and v |z| here for two sessions
    unnoticed (``bench_hidden_state.py`` found it); the fit is taken because
    its model, run as a model, still improves significantly on the current one.
    """
    machine = hysteretic_oscillator()
    p = machine.true_parameters
    law = {
        "v": -p["alpha"] / p["m"],
        "|v| z": -p["beta"] * p["gamma"],
        "v |z|": p["beta"] * p["delta"],
    }
    res = _study(3, [0, 1, 2], constants={}, recording={})
    ok, errors, extra = _law_found(res, law)
    assert ok, (errors, extra, res.terms)
