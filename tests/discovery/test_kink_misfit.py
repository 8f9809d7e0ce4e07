"""The misfit a smoothed kink leaves is named as such, not as a missing effect.

A plant that sticks (Coulomb friction read by a 50 nm encoder) is fitted
with ``sign(v)`` smoothed over a small width, so that the integrators and
Gauss-Newton have a derivative. The smoothed model creeps where the plant
sticks, so the extended model misses the record by thousands of times the
encoder's noise even with the right terms and sizes. The study refits with
the kinks at half the width (and twice the RK4 steps) anyway
(:func:`~pysindy_mme.discovery.steps.smoothing_check`); when the misfit
left falls to at most ``KINK_MISFIT_SHARE`` of itself there, the report
says it is the integration of the kinks, and advises a narrower width
instead of "more library functions, or a hidden state".

The rule's unit tests are here; the studies (the positioning axis at other
masses, rates and noise, and two cases whose misfit is an effect the
library lacks) are in ``test_physics_axis.py``.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from pysindy_mme.discovery.conclusion import (
    FIT_FACTOR,
    KINK_MISFIT_SHARE,
    Evidence,
    conclude,
)
from pysindy_mme.discovery.steps import _misfit_ratio


def _evidence(kink_misfit, rmse_extended=40.0):
    return Evidence(
        contradicted=True,
        consistency="chi2 = 1e17 on 16000 dof",
        terms=["sign(v) in v'", "1 in v'"],
        assumed_converged=True,
        extended_converged=True,
        rmse_assumed=np.array([7e5]),
        rmse_extended=np.array([rmse_extended]),
        noise_floor=np.array([1.0]),
        channel_names=["q"],
        out_assumed=np.array([7e5]),
        out_extended=np.array([2e3]),
        out_source="the validation record",
        kink_misfit=kink_misfit,
    )


def test_a_misfit_that_follows_the_width_is_named_the_kinks():
    found = conclude(_evidence(0.6))
    assert found.label == "partly explained"  # the fit still misses the record
    assert "integration of the smoothed kinks" in found.verdict
    assert "falls to 60 % of itself" in found.reasons[1]
    assert "not an effect the library lacks" in found.reasons[1]
    assert len(found.advice) == 1 and "PhysicsLibrary(smoothing=" in found.advice[0]
    assert "hidden state" not in found.advice[0]


@pytest.mark.parametrize("ratio", [None, 0.95, KINK_MISFIT_SHARE + 0.01])
def test_a_misfit_that_does_not_follow_the_width_is_an_effect_missed(ratio):
    found = conclude(_evidence(ratio))
    assert found.label == "partly explained"
    assert "kinks" not in found.verdict
    assert found.reasons[1].endswith("part of the effect is not in the library")
    assert "hidden state" in found.advice[0]


def test_the_share_at_the_threshold_counts():
    found = conclude(_evidence(KINK_MISFIT_SHARE))
    assert "integration of the smoothed kinks" in found.verdict


def test_a_fit_at_the_noise_is_explained_whatever_the_ratio():
    found = conclude(_evidence(0.5, rmse_extended=FIT_FACTOR * 0.9))
    assert found.label == "explained"
    assert "kinks" not in found.verdict


def _fit(cost, n=1000, dof=998, inflation=1.0):
    return SimpleNamespace(cost=cost, n_residuals=n, dof=dof, inflation=inflation)


def test_the_misfit_ratio_is_of_the_costs_beyond_the_noise():
    # cost = noise's share (inflation x dof) + misfit: 998 + 9,000 -> 998 + 2,250
    ratio = _misfit_ratio(_fit(998 + 9000.0), _fit(998 + 2250.0))
    assert ratio == pytest.approx(0.5)
    # correlated residuals: the noise's share is inflation x dof
    ratio = _misfit_ratio(
        _fit(2 * 998 + 9000.0, inflation=2.0), _fit(2 * 998 + 4000.0, inflation=2.0)
    )
    assert ratio == pytest.approx(np.sqrt(4000 / 9000))


def test_the_misfit_ratio_is_not_measured_on_a_fit_near_the_noise():
    # a misfit below the noise's own share: a ratio of noise-sized numbers
    assert _misfit_ratio(_fit(1500.0), _fit(1000.0)) is None
    assert _misfit_ratio(_fit(np.inf), _fit(1000.0)) is None
    assert _misfit_ratio(_fit(5000.0), _fit(np.nan)) is None
    # a refit at the noise (below it, by chance) leaves no misfit: 0, not NaN
    assert _misfit_ratio(_fit(5000.0), _fit(900.0)) == 0.0
