"""Issue 9.2: chaotic, many-period records - the output-error stage on hard ground.

Single shooting over a chaotic record has a cost surface full of local
minima; direct transcription from the MME estimate must not care. One true
term is removed from the assumed model; it must be named, with its
coefficient within 2 %, and nothing else, in at least 9 of 10 seeds.
"""

import warnings

import pysindy as ps
import pytest

from pysindy_mme import discover
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.systems import lorenz, rossler

SEEDS = range(10)


def _study(system, data, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return discover(
            data.y,
            data.t,
            assumed_model=system.assumed_model,
            n_states=system.n_states,
            measured=list(system.measured),
            feature_library=ps.PolynomialLibrary(degree=2),
            **grouped_keywords({"feature_names": system.feature_names, **kwargs}),
        )


def _named(res, system, rel=0.02) -> bool:
    ((state, expected),) = system.hidden_terms.items()
    found = {s: t for s, t in res.terms.items() if t}
    if set(found) != {state} or set(found[state]) != set(expected):
        return False
    return all(
        found[state][k] == pytest.approx(v, rel=rel) for k, v in expected.items()
    )


@pytest.mark.slow
def test_lorenz_all_states_measured_every_equation_suspect():
    """Lorenz, all three states measured with noise sd 0.2 (10 time units at
    dt 0.005), ``-x1 x3`` removed from x2'; every equation may be wrong."""
    system = lorenz()
    hits = 0
    for seed in SEEDS:
        data = system.measure(seed, noise_variance=0.04)
        res = _study(system, data, noise_variance=0.04, error_states=[0, 1, 2])
        hits += _named(res, system)
    print(f"\nLorenz: missing term named within 2 %, nothing else, in {hits}/10")
    assert hits >= 9


@pytest.mark.slow
def test_rossler_only_y_measured():
    """Rossler, only y measured (noise sd 0.2, 30 time units at 20 Hz), ``x z``
    removed from z': seen only through y, via two unmeasured states."""
    system = rossler()
    hits = 0
    for seed in SEEDS:
        data = system.measure(seed)
        res = _study(
            system,
            data,
            noise_variance=system.noise_variance,
            error_states=list(system.error_states),
        )
        hits += _named(res, system)
    print(f"\nRossler: missing term named within 2 %, nothing else, in {hits}/10")
    assert hits >= 9


def test_a_long_chaotic_record_is_explained_and_its_spread_run_named():
    """Lorenz over 20 time units (its growth e^18 along the record), all three
    states measured: the free run's sensitivities to the three initial states
    turn into the growing mode's, which once read as "x1(0), x2(0) and x3(0)
    trade off exactly" and left the study inconclusive. The identifiability
    check reads the run up to a growth of GROWTH_LIMIT; the held-out run of
    the (right) extended model, spread by its 50-sample start beyond the
    noise, is named among the reasons and marked in the gain table."""
    system = lorenz()
    data = system.measure(0, noise_variance=0.04, t=system.time(20.0))
    res = _study(system, data, noise_variance=0.04, error_states=[0, 1, 2])
    assert _named(res, system)
    assert not res.trade_offs
    assert res.conclusion == "explained", res.reasons
    runs = res.gain.validation_runs
    assert runs["extended"].determined_until is not None
    assert any("not determined by its initial state" in r for r in res.reasons)
    assert "SPREAD BY ITS START: from t = " in str(res)
    assert "n/a" not in res.verdict
