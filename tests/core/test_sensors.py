"""Clipped readings (issue 19, "sensors as they come"): what is found, what not.

A sensor that reads at most 10 V reports 10 V above it. ``clipped_samples``
must find such readings (exact counts on a clipped sine, at a ceiling and a
floor, continuous or quantised), raise no alarm on quantised data that is not
clipped (a 12-bit ADC repeats values by design), ignore short runs, and
treat NaN as a missing sample.
"""

from __future__ import annotations

import numpy as np
import pytest

from pysindy_mme.core.sensors import (
    CEILING,
    FLOOR,
    check_ranges,
    clipped_at,
    clipped_samples,
)
from pysindy_mme.machines import cascaded_tanks

ADC_STEP = 10.0 / 4096  # a 12-bit ADC over 10 V


def noisy_sine(seed=0, n=1000, sd=0.05, periods=5.0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, periods * 2 * np.pi, n)
    return np.sin(t) + sd * rng.standard_normal(n)


def test_a_clipped_sine_at_a_ceiling_exact_count():
    raw = noisy_sine()
    y = np.minimum(raw, 0.8)
    found = clipped_samples(y)
    assert len(found) == 1
    (c,) = found
    assert (c.channel, c.side, c.level) == (0, CEILING, 0.8)
    assert c.count == int(np.sum(raw >= 0.8)) == found.count
    np.testing.assert_array_equal(c.mask, raw >= 0.8)
    assert c.longest_run >= 3 and c.n_observed == y.size
    assert c.share == pytest.approx(c.count / y.size)


def test_a_clipped_sine_at_a_floor_exact_count():
    raw = noisy_sine(seed=1)
    y = np.maximum(raw, -0.7)
    (c,) = clipped_samples(y)
    assert (c.side, c.level) == (FLOOR, -0.7)
    assert c.count == int(np.sum(raw <= -0.7))


def test_both_sides_and_two_channels_combined_mask():
    a = np.clip(noisy_sine(seed=2), -0.6, 0.9)
    b = noisy_sine(seed=3)  # not clipped
    found = clipped_samples(np.column_stack([a, b]))
    assert [(c.channel, c.side) for c in found] == [(0, CEILING), (0, FLOOR)]
    assert found.mask.shape == (a.size, 2)
    assert not found.mask[:, 1].any()
    np.testing.assert_array_equal(found.mask[:, 0], (a == 0.9) | (a == -0.6))
    assert found.ranges() == [(-0.6, 0.9), (None, None)]
    assert found.on(0, FLOOR).level == -0.6 and found.on(1, CEILING) is None


def test_a_quantised_clipped_record_the_tanks_ceiling():
    rec = cascaded_tanks().record(0)
    found = clipped_samples(rec.y)
    ceiling = found.on(0, CEILING)
    assert ceiling is not None and ceiling.level == 10.0
    assert ceiling.count == int(np.sum(rec.y == 10.0)) > 50


@pytest.mark.parametrize("sd_in_steps", [0.0, 0.3, 1.0, 8.0])
def test_quantised_but_unclipped_data_raise_no_alarm(sd_in_steps):
    # a 12-bit ADC on a slow sine: without noise the readings sit on the top
    # level for tens of samples at every peak, and still it is no ceiling
    rng = np.random.default_rng(4)
    t = np.linspace(0.0, 6 * 2 * np.pi, 4000)
    x = 5.0 + 4.0 * np.sin(t) * np.exp(-0.02 * t)
    y = ADC_STEP * np.round(
        (x + sd_in_steps * ADC_STEP * rng.standard_normal(t.size)) / ADC_STEP
    )
    assert np.max(np.unique(y, return_counts=True)[1]) >= 3  # values repeat
    assert not clipped_samples(y)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_tanks_sensor_with_a_wide_range_raises_no_alarm(seed):
    rec = cascaded_tanks().record(seed, sensor_range=(-100.0, 100.0))
    assert not clipped_samples(rec.y)


def test_a_noise_free_plateau_on_the_extreme_is_taken_for_a_limit():
    # the limitation the module names: without noise, an empty tank reads
    # exactly 0 for a while, which the data cannot tell from a sensor floor
    rec = cascaded_tanks().record(0, sensor_range=(-100.0, 100.0), noise_sd=0.0)
    (c,) = clipped_samples(rec.y)
    assert (c.side, c.level) == (FLOOR, 0.0)
    assert np.all(rec.x[c.mask, 1] < ADC_STEP / 2)  # the tank is empty


def test_the_same_sine_clipped_on_the_adc_is_found():
    t = np.linspace(0.0, 6 * 2 * np.pi, 4000)
    x = 5.0 + 4.0 * np.sin(t)
    y = ADC_STEP * np.round(x / ADC_STEP)
    level = ADC_STEP * np.round(8.0 / ADC_STEP)
    clipped = np.minimum(y, level)
    (c,) = clipped_samples(clipped)
    assert c.level == level and c.count == int(np.sum(y >= level))


def test_nan_is_a_missing_sample():
    raw = noisy_sine(seed=5)
    y = np.minimum(raw, 0.8)
    y[::7] = np.nan
    (c,) = clipped_samples(y)
    assert not c.mask[::7].any()
    assert c.count == int(np.sum(y == 0.8))
    assert c.n_observed == int(np.isfinite(y).sum())
    assert not clipped_samples(np.full(50, np.nan))
    # NaN breaks runs: readings at the maximum never 3 in a row
    z = noisy_sine(seed=6, n=200)
    top = np.max(z) + 1.0
    z[[10, 11, 13, 14, 16, 17]] = top
    z[[12, 15]] = np.nan
    assert not clipped_samples(z)
    z[[12, 15]] = top
    assert clipped_samples(z).count == 8


def test_short_runs_are_ignored():
    z = noisy_sine(seed=7, n=300)
    top = np.max(z) + 0.5
    z[[20, 21, 90, 91, 200, 201]] = top  # six readings on the maximum, runs of 2
    assert not clipped_samples(z)
    (c,) = clipped_samples(z, min_run=2)
    assert c.count == 6 and c.longest_run == 2
    z[22] = top  # one run of 3
    assert clipped_samples(z).count == 7


def test_a_genuine_maximum_reached_once_is_not_clipping():
    z = noisy_sine(seed=8)
    assert not clipped_samples(z)
    assert not clipped_samples(np.full(100, 2.0))  # a constant channel


def test_the_input_is_not_modified_and_censor_copies():
    y = np.minimum(noisy_sine(seed=9), 0.8)[:, None]
    before = y.copy()
    found = clipped_samples(y)
    censored = found.censor(y)
    np.testing.assert_array_equal(y, before)
    assert np.isnan(censored[found.mask]).all()
    np.testing.assert_array_equal(censored[~found.mask], y[~found.mask])


def test_known_limits():
    raw = noisy_sine(seed=10)
    y = np.minimum(raw, 0.8)
    (c,) = clipped_at(y, (None, 0.8))
    assert c.given and c.count == int(np.sum(raw >= 0.8))
    both = clipped_at(np.column_stack([y, y]), [None, (-0.5, 0.8)])
    assert [(c.channel, c.side) for c in both] == [(1, CEILING), (1, FLOOR)]
    exact = clipped_at(np.r_[y, 0.9], (None, 0.8), beyond=False)
    assert exact.count == c.count  # 0.9 is beyond, not on, the level
    assert not clipped_at(y, (None, np.inf))


@pytest.mark.parametrize(
    "ranges, error",
    [
        ((1.0, 0.0), ValueError),
        ((0.0, float("nan")), ValueError),
        (("a", 1.0), TypeError),
        ([(0, 1), (0, 1), (0, 1)], ValueError),
        (5.0, TypeError),
        ([(0, 1, 2), (0, 1)], TypeError),
    ],
)
def test_bad_ranges(ranges, error):
    with pytest.raises(error, match="clipped"):
        check_ranges(ranges, 2)


def test_bad_min_run():
    with pytest.raises(ValueError, match="min_run"):
        clipped_samples(np.zeros(10), min_run=1)
    with pytest.raises(TypeError, match="min_run"):
        clipped_samples(np.zeros(10), min_run=2.5)
