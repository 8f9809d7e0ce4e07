"""Exact support recovery: FloatingFStepwise against pysindy's STLSQ.

Noisy full-state measurements of three systems, two noise levels each, 20
seeds, pysindy's ``SmoothedFiniteDifference`` and ``PolynomialLibrary(degree=3)``,
STLSQ with default settings. A fit counts when every equation has exactly the
terms of the true right-hand side (the true support is read off the true
model by an exact least-squares fit on random points, independent of either
optimizer).

Findings these tests pin down (counts are printed; run with ``-s`` or ``-rA``):

* The default ``FloatingFStepwise()`` is never more than one seed behind
  STLSQ (issue 11's criterion), and far ahead at the higher noise levels.
* Phase I alone of the paper's rule (Draper & Smith's stepwise regression
  with ``F* = 10``, ``FloatingFStepwise.paper(floating=False)``) also does.
* The paper's rule (``FloatingFStepwise.paper()``: Phase II with
  ``float_ratio=10``) matches or beats STLSQ on the paper's Van der Pol
  example, but on Duffing and Lorenz it removes one true term in every run: a
  term whose partial F-ratio, though large (Lorenz ``-x2`` in ``x2'``:
  F ~ 1e3), is below a tenth of the strongest term's (~3e5). Duffing's
  damping ``-0.1 x2`` likewise. (These were strict xfails while the paper's
  rule was the default.)
* No float_ratio serves both: the paper's own Table II needs one below 44.4,
  Lorenz's ``-x2`` one above ~200 (``test_no_float_ratio_serves_both_...``).
"""

from __future__ import annotations

import warnings

import numpy as np
import pysindy as ps
import pytest

from pysindy_mme import FloatingFStepwise, systems
from pysindy_mme.optimizers import fit_anova

# Many-seed statistical studies: not in the edit loop (pytest -m "not slow").
pytestmark = pytest.mark.slow

N_SEEDS = 20

CASES = [
    ("van_der_pol", 0.1),
    ("van_der_pol", 0.01),
    ("duffing", 0.01),
    ("duffing", 0.001),
    ("lorenz", 0.1),
    ("lorenz", 0.01),
]

OPTIMIZERS = {
    "STLSQ": ps.STLSQ,
    "default": FloatingFStepwise,
    "paper": FloatingFStepwise.paper,
    "Phase I only": lambda: FloatingFStepwise.paper(floating=False),
}


def true_support(system) -> np.ndarray:
    points = np.random.default_rng(0).standard_normal((300, system.n_states)) * 3
    library = ps.PolynomialLibrary(degree=3).fit(points)
    exact = np.linalg.lstsq(
        library.transform(points), system.true_model(points, 0.0), rcond=None
    )[0].T
    return np.abs(exact) > 1e-8


@pytest.fixture(scope="module")
def counts():
    """{(system, noise): {optimizer: exact-support count over the seeds}}."""
    results = {}
    for name, noise in CASES:
        system = getattr(systems, name)()
        support = true_support(system)
        hits = dict.fromkeys(OPTIMIZERS, 0)
        for seed in range(N_SEEDS):
            m = system.measure(seed, noise_variance=noise, full_state=True)
            for label, make in OPTIMIZERS.items():
                model = ps.SINDy(
                    optimizer=make(),
                    feature_library=ps.PolynomialLibrary(degree=3),
                    differentiation_method=ps.SmoothedFiniteDifference(),
                )
                with warnings.catch_warnings():
                    # Lorenz's x3' equation meets a Phase II 2-cycle (resolved,
                    # tested elsewhere); STLSQ may warn too.
                    warnings.simplefilter("ignore")
                    model.fit(m.y, t=m.t)
                found = model.coefficients() != 0
                hits[label] += int(np.array_equal(found, support))
        results[(name, noise)] = hits
    return results


def report(case, hits):
    print(
        f"\n{case[0]} noise var {case[1]:g} ({N_SEEDS} seeds): "
        + ", ".join(f"{label} {n}/{N_SEEDS}" for label, n in hits.items())
    )


VDP_CASES = [c for c in CASES if c[0] == "van_der_pol"]
MULTISCALE_CASES = [c for c in CASES if c[0] in ("duffing", "lorenz")]


def _id(case):
    return f"{case[0]}-{case[1]}"


# Measured (default / STLSQ of 20): Van der Pol 0.1: 14 / 1, 0.01: 20 / 19;
# Duffing 0.01: 4 / 5, 0.001: 20 / 7; Lorenz 0.1: 12 / 3, 0.01: 17 / 16.
# Duffing at noise variance 0.01 (about 10% of the states' spread, beyond
# the drop-in benchmark's 5%) is the one case the default trails: the light
# damping -0.1 x2 has a robust partial F of 5-10, below the Bonferroni level.
@pytest.mark.parametrize("case", CASES, ids=_id)
def test_default_is_never_more_than_one_seed_behind_stlsq(counts, case):
    hits = counts[case]
    report(case, hits)
    assert hits["default"] >= hits["STLSQ"] - 1


@pytest.mark.parametrize("case", VDP_CASES, ids=_id)
def test_paper_rule_recovers_van_der_pol_as_often_as_stlsq(counts, case):
    hits = counts[case]
    report(case, hits)
    assert hits["paper"] >= hits["STLSQ"]


@pytest.mark.parametrize("case", MULTISCALE_CASES, ids=_id)
def test_paper_rule_removes_a_weak_true_term(counts, case):
    """Phase II with float_ratio=10 removes a true term whose partial F is
    below 1/10 of the strongest (Duffing's -0.1 x2, Lorenz's -x2 in x2')."""
    hits = counts[case]
    report(case, hits)
    assert hits["paper"] < hits["STLSQ"]
    assert hits["paper"] == 0  # in every seed


@pytest.mark.parametrize("case", CASES, ids=_id)
def test_phase_one_recovers_support_as_often_as_stlsq(counts, case):
    hits = counts[case]
    report(case, hits)
    assert hits["Phase I only"] >= hits["STLSQ"]


def test_paper_example_stlsq_reference_count(counts):
    # The brief's reference point: STLSQ finds Van der Pol's support in 19/20
    # runs at noise variance 0.01; the paper's rule and the default in all.
    hits = counts[("van_der_pol", 0.01)]
    report(("van_der_pol", 0.01), hits)
    assert hits["STLSQ"] == 19
    assert hits["paper"] == N_SEEDS
    assert hits["default"] == N_SEEDS


# The paper's Table II (final model of its Van der Pol example): the strongest
# function in the model has partial F 5688.1, the strongest one left out
# 128.0. Phase II keeps that one out only if 128.0 < 5688.1 / float_ratio.
PAPER_STRONGEST_IN, PAPER_STRONGEST_OUT = 5688.1, 128.0
PAPER_MAX_RATIO = PAPER_STRONGEST_IN / PAPER_STRONGEST_OUT  # 44.4


def _true_model_f_ratios(system, noise, target, weak_term):
    """Per seed: strongest partial F / the weak true term's, true support fitted."""
    support = true_support(system)[target]
    ratios = []
    for seed in range(N_SEEDS):
        m = system.measure(seed, noise_variance=noise, full_state=True)
        dx = ps.SmoothedFiniteDifference()._differentiate(m.y, m.t)
        library = ps.PolynomialLibrary(degree=3).fit(m.y)
        names = library.get_feature_names()
        X = library.transform(m.y)
        cols = [j for j in np.flatnonzero(support) if names[j] != "1"]
        table = fit_anova(X, dx[:, target], cols, intercept=True)
        weak = table.partial_f[[names[j] for j in cols].index(weak_term)]
        ratios.append(table.partial_f.max() / weak)
    return np.array(ratios)


def test_no_float_ratio_serves_both_the_paper_and_lorenz():
    """Why the default cannot match STLSQ on Lorenz: a proof by numbers.

    Reproducing the paper's Table II needs float_ratio < 44.4. With the
    true Lorenz model fitted, the strongest term of x2' has a partial F
    more than 44.4 times that of the true ``-x2`` in every seed, so Phase II
    with any such ratio removes ``-x2`` from the true model (measured:
    median 223, min 195). Duffing's damping ``-0.1 x2`` needs a float_ratio
    above its ratio (median 16.9, min 12.7): compatible with the paper, not
    with the default 10.
    """
    lorenz = _true_model_f_ratios(systems.lorenz(), 0.01, 1, "x1")
    duffing = _true_model_f_ratios(systems.duffing(), 0.01, 1, "x1")
    print(
        f"\nstrongest / weak true term partial F (median over {N_SEEDS} seeds): "
        f"Lorenz x2' {np.median(lorenz):.0f} (min {lorenz.min():.0f}), "
        f"Duffing x2' {np.median(duffing):.1f} (min {duffing.min():.1f}); "
        f"paper needs float_ratio < {PAPER_MAX_RATIO:.1f}"
    )
    assert lorenz.min() > PAPER_MAX_RATIO
    assert np.all(duffing > 10.0)
    assert np.median(duffing) < PAPER_MAX_RATIO
