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
    said = "part of the effect is not in the library"
    if ratio is None:
        assert found.reasons[1].endswith(said)
    else:
        # the share the narrower smoothing left is given: why the misfit is
        # not put down to the kinks
        share = f"{100 * ratio:.0f} % of that misfit stays)"
        assert found.reasons[1].endswith(
            f"{said} (refitted with its kinks smoothed over half the width, {share}"
        )
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


class _Fit:
    """A stand-in fit: compared by value, like the solver's (no hash)."""

    __hash__ = None

    def __eq__(self, other):
        return True


def test_the_half_width_refit_of_a_fit_is_made_once(monkeypatch):
    # step 4 (smoothing artefacts) and the report (the width check) refit the
    # same fit at half the width: the second call is the first's answer;
    # another width, library or RK4 step count refits; a dead fit's entry goes
    import gc

    from pysindy_mme.discovery import steps

    calls = []

    def refit(engine, fit, library, widths):
        calls.append(widths.copy())
        return ("refit", len(calls)), [0]

    monkeypatch.setattr(steps, "_refit_at_half_width", refit)
    library = SimpleNamespace(widths_=np.array([1e-3, 0.0]))
    engine = SimpleNamespace(n_substeps=2)
    fit = _Fit()
    first = steps._half_width_refit(engine, fit, library)
    assert steps._half_width_refit(engine, fit, library) is first
    assert len(calls) == 1
    # another fit equal by value is still another fit
    other = _Fit()
    steps._half_width_refit(engine, other, library)
    assert len(calls) == 2
    library.widths_ = np.array([2e-3, 0.0])
    assert steps._half_width_refit(engine, fit, library) is not first
    assert len(calls) == 3
    steps._half_width_refit(SimpleNamespace(n_substeps=4), fit, library)
    assert len(calls) == 4
    key = id(fit)
    assert key in steps._HALF_WIDTH
    del fit, other
    gc.collect()
    assert key not in steps._HALF_WIDTH
