"""The report at sampling rates and record lengths a study was not set on.

Found in session 24 on the paper's Van der Pol case itself, whose terms the
study finds exactly at every rate and length: over 100 s or more at 40 Hz
the verdict was "inconclusive" because two precise estimates (standard
errors 0.06 %) were correlated -1.000 on the limit cycle; at 4 kHz and
above the free runs on held-out data started from an initial state the
50-sample window had not determined (the exact terms were called
look-alikes, the gain was that of the initial state); and at 40 kHz the
memory test called for a hidden state. The rules that changed are
:data:`~pysindy_mme.discovery.doubts.PRECISE_RELATIVE_SE`,
:func:`~pysindy_mme.protocols.runs.determined_window` and the missing-state
claim in :func:`~pysindy_mme.discovery.conclusion.conclude`.

The development cases are the Van der Pol records the defects were found
on. The held-out cases are systems those rules were not looked at on
(Duffing, Lotka-Volterra), run once after the rules were set; every one
must find its hidden terms exactly and report them as an explanation with
none of the three false doubts.
"""

from __future__ import annotations

import warnings

import pysindy as ps
import pytest

from pysindy_mme import discover
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.systems import duffing, lotka_volterra, van_der_pol

FALSE_DOUBTS = (
    "trade off",
    "told apart",
    "look-alikes",
    "a state the model does not have is likely",
)


def _study(system, seconds, rate, seed=0):
    data = system.measure(seed, t=system.time(seconds, rate))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return discover(
            data.y,
            data.t,
            assumed_model=system.assumed_model,
            n_states=len(system.state_names),
            measured=list(system.measured),
            noise_variance=system.noise_variance,
            error_states=list(system.error_states),
            feature_library=ps.PolynomialLibrary(degree=3),
            **grouped_keywords({"feature_names": list(system.feature_names)}),
        )


def _check(system, res):
    found = {eq: set(terms) for eq, terms in res.terms.items()}
    assert found == {eq: set(t) for eq, t in system.hidden_terms.items()}, res.terms
    assert res.conclusion == "explained", res.verdict
    text = str(res)
    assert not [d for d in FALSE_DOUBTS if d in text], text


@pytest.mark.slow
@pytest.mark.parametrize(
    "seconds, rate",
    [(100, 40), (10, 4_000), (10, 40_000)],
    ids=["100 s at 40 Hz", "10 s at 4 kHz", "10 s at 40 kHz"],
)
def test_development_van_der_pol(seconds, rate):
    system = van_der_pol()
    res = _study(system, seconds, rate)
    _check(system, res)
    # the held-out free run of the exact model sits at the noise
    assert res.gain.validation_rmse_extended[0] < 1.2 * 0.1


@pytest.mark.slow
@pytest.mark.parametrize(
    "make, factor", [(duffing, 100), (lotka_volterra, 100)], ids=["duffing", "lv"]
)
def test_held_out_systems_at_a_hundred_times_their_rate(make, factor):
    system = make()
    res = _study(system, system.t_end, system.rate_hz * factor)
    _check(system, res)
