"""Tests of the spectral-floor noise estimator (pysindy_mme.core.noise).

References: the true noise variance of simulated records; for the resonant
signal, the exact lowest level of its spectrum (closed form of an AR(2)
spectrum), which no estimator of white noise can get below; the classical
difference estimator for ``method="difference"``.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import signal

from pysindy_mme.core.noise import (
    NoiseDiagnostics,
    _spectra,
    describe_noise,
    difference_noise_variance,
    estimate_noise_variance,
    quantisation_step,
)
from pysindy_mme.exceptions import DiscoveryWarning

N = 16384


def smooth(n, rng):
    k = np.arange(n)
    f = rng.uniform(0.002, 0.02, 3)
    return 10.0 * np.sin(2 * np.pi * f[:, None] * k + rng.uniform(0, 6, (3, 1))).sum(0)


def nyquist_rich(n, rng):
    """20 sinusoids in [0.01, 0.45] fs (one at 0.45) plus a chirp 0.02-0.45 fs."""
    k = np.arange(n)
    f = np.append(rng.uniform(0.01, 0.45, 19), 0.45)
    lines = 2.0 * np.sin(2 * np.pi * f[:, None] * k + rng.uniform(0, 6, (20, 1))).sum(0)
    return lines + 6.0 * signal.chirp(k, f0=0.02, t1=n - 1, f1=0.45)


def lowpass(n, rng):
    b, a = signal.butter(4, 0.4)
    s = signal.lfilter(b, a, rng.standard_normal(n + 200))[200:]
    return 10.0 * s / s.std()


R, THETA = 0.98, 2 * np.pi * 0.1
AR2 = [1.0, -2 * R * np.cos(THETA), R * R]


def resonant(n, rng):
    s = signal.lfilter([1.0], AR2, rng.standard_normal(n + 500))[500:]
    return 10.0 * s / s.std()


def resonant_floor():
    """Exact lowest spectral level of ``resonant`` (variance 100), as a variance."""
    impulse = signal.lfilter([1.0], AR2, np.r_[1.0, np.zeros(20000)])
    _, h = signal.freqz([1.0], AR2, worN=np.linspace(0, np.pi, 4001))
    return 100.0 * np.min(np.abs(h) ** 2) / np.sum(impulse**2)


def estimate(y, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        var, diags = estimate_noise_variance(y, return_diagnostics=True, **kw)
    return var, diags, caught


# --- accuracy -----------------------------------------------------------------


def test_white_noise_alone_is_estimated_and_flagged_flat():
    """Recognised as flat in all but a few percent of records (5 of 200 measured)."""
    flagged = 0
    for seed in range(20):
        y = 0.3 * np.random.default_rng(seed).standard_normal(N)
        var, (d,), caught = estimate(y)
        assert var[0] == pytest.approx(0.09, rel=0.08)
        if "cannot be told apart from white noise" in d.reason:
            flagged += 1
            assert not d.reliable
            assert any(issubclass(w.category, DiscoveryWarning) for w in caught)
    assert flagged >= 18


@pytest.mark.parametrize("seed", range(3))
def test_smooth_signal_plus_noise(seed):
    rng = np.random.default_rng(seed)
    y = smooth(N, rng) + rng.standard_normal(N)
    var, (d,), caught = estimate(y)
    assert var[0] == pytest.approx(1.0, rel=0.08)
    assert d.reliable and d.reason == "" and not caught
    # a second method that is right for smooth signals agrees
    assert difference_noise_variance(y)[0] == pytest.approx(var[0], rel=0.1)


@pytest.mark.parametrize("seed", range(5))
def test_signal_rich_near_nyquist_within_30_percent(seed):
    """Issue 13, acceptance 4: noise is 1 % of the record's power."""
    rng = np.random.default_rng(seed)
    s = nyquist_rich(N, rng)
    y = s + rng.standard_normal(N)
    var, (d,), _ = estimate(y)
    assert abs(var[0] - 1.0) <= 0.3
    assert d.reliable
    # the floor holds the two signal-free bands, below 0.02 and above 0.45
    assert d.band[1] >= 0.49 and d.band_fraction <= 0.2
    # the 4th-difference estimator MME used takes the signal for noise
    assert difference_noise_variance(y)[0] > 20.0


@pytest.mark.parametrize("case", [lowpass, smooth])
def test_coloured_signal_with_a_free_band(case):
    rng = np.random.default_rng(11)
    y = case(N, rng) + 0.5 * rng.standard_normal(N)
    assert estimate(y)[0][0] == pytest.approx(0.25, rel=0.1)


def test_resonant_signal_estimate_is_the_spectral_floor():
    """Where the signal has power at every frequency, the estimate is noise plus
    the signal's lowest spectral level (closed form), never the noise alone."""
    ideal = 1.0 + resonant_floor()
    assert ideal == pytest.approx(1.2135, abs=1e-3)
    ratios = []
    for seed in range(4):
        rng = np.random.default_rng(seed)
        ratios.append(estimate(resonant(65536, rng) + rng.standard_normal(65536))[0][0])
    assert np.mean(ratios) == pytest.approx(ideal, rel=0.08)
    assert np.mean(ratios) >= ideal * 0.97  # an upper bound on the noise


def test_white_signal_is_flagged_and_estimate_is_an_upper_bound():
    rng = np.random.default_rng(3)
    y = 3.0 * rng.standard_normal(N) + rng.standard_normal(N)
    var, (d,), caught = estimate(y)
    assert var[0] == pytest.approx(10.0, rel=0.08)
    assert not d.reliable and "upper bound" in d.reason and caught


def test_spectrum_still_falling_at_its_floor_is_flagged():
    """Like the Silverbox output: no white plateau before Nyquist."""
    rng = np.random.default_rng(4)
    e = rng.standard_normal(N + 1)
    y = 0.5 * (e[1:] + e[:-1])  # spectrum cos^2(pi f), zero at Nyquist; no noise
    var, (d,), caught = estimate(y)
    assert not d.reliable and "still falls or rises" in d.reason
    assert var[0] < 1e-2 * y.var()
    assert "y channel 0" in str(caught[0].message)


def test_slow_drift_below_the_analysed_bins_is_not_called_white():
    """A trend is signal even though no analysed band shows it."""
    rng = np.random.default_rng(5)
    y = np.linspace(0.0, 50.0, N) + rng.standard_normal(N)
    var, (d,), _ = estimate(y)
    assert var[0] == pytest.approx(1.0, rel=0.08)
    assert d.reliable


def test_real_and_imaginary_parts_are_uncorrelated_exactly():
    """The cross-fit rests on this: with the symmetric window and detrending,
    the real parts (picking the floor) and the imaginary parts (reading it)
    of white noise are uncorrelated at every pair of bins, with equal
    variances. Checked on the exact linear map from samples to transforms."""
    n = 128
    A = np.vstack([_spectra(np.eye(n)[i], [(0, n)], n)[0] for i in range(n)]).T
    np.testing.assert_allclose(A.real @ A.imag.T, 0.0, atol=1e-12)
    np.testing.assert_allclose(np.sum(A.real**2, axis=1), 0.5, rtol=2e-3)
    np.testing.assert_allclose(np.sum(A.imag**2, axis=1), 0.5, rtol=2e-3)


def test_estimate_scales_with_the_square_of_the_data():
    rng = np.random.default_rng(6)
    y = nyquist_rich(4096, rng) + rng.standard_normal(4096)
    v1 = estimate_noise_variance(y, warn=False)[0]
    v2 = estimate_noise_variance(1e-3 * y, warn=False)[0]
    assert v2 == pytest.approx(1e-6 * v1, rel=1e-9)


# --- missing data, channels, time, fallback -------------------------------------


def test_nan_tolerant_and_input_not_modified():
    rng = np.random.default_rng(7)
    y = smooth(N, rng) + 0.1 * rng.standard_normal(N)
    y[rng.random(N) < 0.01] = np.nan  # scattered
    y[5000:5600] = np.nan  # a gap
    before = y.copy()
    var, (d,), _ = estimate(y)
    np.testing.assert_array_equal(y, before)
    assert d.method == "spectral"
    assert var[0] == pytest.approx(0.01, rel=0.1)


def test_heavily_fragmented_record_falls_back_to_differences():
    rng = np.random.default_rng(8)
    y = smooth(4000, rng) + 0.1 * rng.standard_normal(4000)
    y[rng.random(4000) < 0.3] = np.nan
    var, (d,), _ = estimate(y)
    assert d.method == "difference" and d.band is None
    assert d.reliable and d.fallback.startswith("fewer than 4 NaN-free stretches")
    assert var[0] == pytest.approx(0.01, rel=0.15)
    with pytest.raises(
        ValueError, match="method='spectral' cannot be used on y channel 0"
    ):
        estimate_noise_variance(y, method="spectral")


def test_short_record_fallback_is_flagged():
    rng = np.random.default_rng(9)
    y = nyquist_rich(300, rng) + rng.standard_normal(300)
    var, (d,), caught = estimate(y)
    assert d.method == "difference" and not d.reliable
    assert "fewer than 4 NaN-free stretches of 128" in d.fallback
    # too short to resolve the free band: it looks white, or the orders disagree
    assert "upper bound" in d.reason
    assert var[0] > 10.0
    assert "differences were used" in str(caught[0].message)


def test_channels_are_estimated_separately():
    rng = np.random.default_rng(10)
    y = np.column_stack(
        [
            smooth(N, rng) + 0.1 * rng.standard_normal(N),
            lowpass(N, rng) + rng.standard_normal(N),
        ]
    )
    var, diags, _ = estimate(y)
    assert var.shape == (2,) and [d.channel for d in diags] == [0, 1]
    np.testing.assert_allclose(var, [0.01, 1.0], rtol=0.1)
    assert all(isinstance(d, NoiseDiagnostics) for d in diags)


def test_time_gives_hertz_and_non_uniform_time_falls_back():
    rng = np.random.default_rng(12)
    y = nyquist_rich(8192, rng) + rng.standard_normal(8192)
    fs = 610.35
    var_hz, (d_hz,), _ = estimate(y, t=1.0 / fs)
    var_1, (d_1,), _ = estimate(y)
    assert var_hz[0] == var_1[0]
    assert d_hz.unit == "Hz" and d_1.unit == "cycles/sample"
    assert d_hz.band == pytest.approx((d_1.band[0] * fs, d_1.band[1] * fs))
    t = np.cumsum(rng.uniform(0.5, 1.5, 8192))
    _, (d,), _ = estimate(y, t=t)
    assert d.method == "difference" and d.fallback == "t is not uniformly spaced"
    with pytest.raises(ValueError, match="t is not uniformly spaced"):
        estimate_noise_variance(y, t=t, method="spectral")


def test_difference_method_matches_the_classical_estimator():
    rng = np.random.default_rng(13)
    y = smooth(3000, rng)[:, None] + rng.standard_normal((3000, 2))
    for order in (2, 4):
        ours = estimate_noise_variance(y, method="difference", order=order, warn=False)
        np.testing.assert_allclose(
            ours, difference_noise_variance(y, order), rtol=1e-12
        )


def test_relative_se_matches_the_scatter_over_seeds():
    est, ses = [], []
    for seed in range(60):
        rng = np.random.default_rng(100 + seed)
        v, (d,), _ = estimate(rng.standard_normal(4096))
        est.append(v[0])
        ses.append(d.relative_se)
    assert np.std(est) == pytest.approx(np.mean(ses), rel=0.35)


@pytest.mark.parametrize("n", [200, 2000])
def test_constant_channel_gives_zero_flagged(n):
    var, (d,), caught = estimate(np.full(n, 3.0))
    assert var[0] == 0.0 and not d.reliable and "constant" in d.reason
    assert [w.category for w in caught] == [DiscoveryWarning]  # no RuntimeWarning


def test_no_warning_when_warn_is_false_and_plain_array_by_default():
    rng = np.random.default_rng(14)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = estimate_noise_variance(rng.standard_normal(2048), warn=False)
    assert isinstance(out, np.ndarray) and out.shape == (1,)


# --- many seeds ------------------------------------------------------------------


@pytest.mark.slow
def test_unbiased_for_white_noise_over_many_seeds():
    ratios = []
    for seed in range(300):
        x = np.random.default_rng(seed).standard_normal(10000)
        ratios.append(estimate_noise_variance(x, warn=False)[0] / x.var())
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.005)


@pytest.mark.slow
def test_nyquist_rich_many_seeds_and_lengths():
    """Within the bound at every seed once the free band holds enough data;
    on shorter records unbiased on average, with a spread the reported
    relative_se announces (the band above 0.45 fs is 10 % of the axis)."""
    for n, tol in ((4000, None), (16384, 0.3), (65536, 0.15)):
        ratios, ses = [], []
        for seed in range(24):
            rng = np.random.default_rng(seed)
            y = nyquist_rich(n, rng) + rng.standard_normal(n)
            v, (d,) = estimate_noise_variance(y, warn=False, return_diagnostics=True)
            ratios.append(v[0])
            ses.append(d.relative_se)
        ratios = np.array(ratios)
        assert abs(ratios.mean() - 1.0) <= 0.07, (n, ratios.mean())
        assert np.std(ratios) == pytest.approx(np.mean(ses), rel=0.5), n
        if tol is not None:
            assert np.all(np.abs(ratios - 1.0) <= tol), (n, ratios.min(), ratios.max())


# --- bad input -------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, exc, match",
    [
        ({"y": np.zeros((4, 4, 4))}, ValueError, "y must be a non-empty 1-D or 2-D"),
        ({"y": []}, ValueError, "y must be a non-empty"),
        ({"y": [1.0, np.inf] * 50}, ValueError, "y contains inf"),
        ({"y": ["a", "b"]}, TypeError, "y must be a numeric array"),
        ({"y": np.arange(5.0)}, ValueError, "y channel 0 has 5 observed samples"),
        ({"y": np.full(100, np.nan)}, ValueError, "y channel 0 has 0 observed"),
        ({"method": "welch"}, ValueError, "method must be one of"),
        ({"order": 0}, ValueError, "order must be at least 1"),
        ({"order": 2.5}, TypeError, "order must be an integer"),
        ({"segment_length": 64}, ValueError, "segment_length must be at least 128"),
        ({"segment_length": True}, TypeError, "segment_length must be an integer"),
        ({"n_bands": 2}, ValueError, "n_bands must be at least 4"),
        ({"t": np.arange(10.0)}, ValueError, "t has 10 entries"),
        ({"t": -1.0}, ValueError, "t must be finite and > 0"),
        ({"y": np.ones(200), "method": "spectral"}, ValueError, "cannot be used"),
    ],
)
def test_bad_input_names_the_argument(kwargs, exc, match):
    args = {"y": np.random.default_rng(0).standard_normal(1000), **kwargs}
    with pytest.raises(exc, match=match):
        estimate_noise_variance(**args)


# --- quantised sensors -----------------------------------------------------------
# An encoder with a 50 nm step on a positioning axis: a smooth position trace
# (25 s at 1 kHz, spanning ~3e7 steps) rounded to the grid, as np.round(x / q) * q
# gives it (values carry float representation error).

STEP = 5e-8
T_ENC = np.arange(25000) / 1000.0
POSITION = 0.1 * np.sin(2 * np.pi * 0.5 * T_ENC) + 0.05 * T_ENC


def encoder(noise_sd, seed=0, step=STEP):
    rng = np.random.default_rng(seed)
    return (
        np.round((POSITION + noise_sd * rng.standard_normal(POSITION.size)) / step)
        * step
    )


def test_quantised_channel_with_noise_above_the_step_is_determined():
    var, (d,), caught = estimate(encoder(1e-5), t=T_ENC)
    assert var[0] == pytest.approx(1e-10, rel=0.2)
    assert d.quantisation_step == pytest.approx(STEP, rel=1e-3)
    assert d.determined and d.reliable and not caught


def test_quantised_channel_without_noise_is_not_determined():
    var, (d,), caught = estimate(encoder(0.0), t=T_ENC)
    assert d.quantisation_step == pytest.approx(STEP, rel=1e-3)
    assert not d.determined and not d.reliable
    assert var[0] >= STEP**2 / 12 * (1 - 1e-12) and var[0] == d.variance
    assert "5e-08" in d.reason and "cannot be told from the quantisation" in d.reason
    assert "noise variance" in d.reason  # tells the user to state it
    assert [w.category for w in caught] == [DiscoveryWarning]
    assert "5e-08" in str(caught[0].message)


def test_noise_of_half_a_step_is_the_boundary():
    """Factor 2 on step/sqrt(12): noise up to about half a step is undetermined."""
    below = estimate(encoder(0.4 * STEP, seed=3), t=T_ENC)[1][0]
    above = estimate(encoder(0.7 * STEP, seed=3), t=T_ENC)[1][0]
    assert not below.determined and above.determined
    assert above.quantisation_step == pytest.approx(STEP, rel=1e-3)


def test_continuous_channels_are_not_quantised():
    rng = np.random.default_rng(5)
    noisy = POSITION + 1e-5 * rng.standard_normal(POSITION.size)
    assert np.isnan(quantisation_step(noisy))
    assert np.isnan(quantisation_step(POSITION))
    assert np.isnan(quantisation_step(rng.standard_normal(200000)))
    _, (d,), _ = estimate(noisy, t=T_ENC)
    assert np.isnan(d.quantisation_step) and d.determined


def test_few_random_values_are_not_called_a_grid():
    rng = np.random.default_rng(6)
    for n in (5, 6, 8, 12, 20, 50):
        for _ in range(100):
            assert np.isnan(quantisation_step(rng.uniform(0.0, 1.0, n)))


def test_nan_holding_channel():
    y = encoder(1e-5)
    y[::7] = np.nan
    y[1000:1500] = np.nan
    assert quantisation_step(y) == pytest.approx(STEP, rel=1e-3)
    var, (d,), _ = estimate(y, t=T_ENC)
    assert d.quantisation_step == pytest.approx(STEP, rel=1e-3) and d.determined
    assert var[0] == pytest.approx(1e-10, rel=0.2)


@pytest.mark.parametrize(
    "values, step",
    [
        # values ~0.1..0.5 m (float representation error), spanning 1.6e6 steps
        (lambda k: np.round((0.3 + 0.2 * np.sin(k / 3000)) / 5e-8) * 5e-8, 5e-8),
        # step 1e-3 on values ~1e3
        (lambda k: 1e3 + np.round(2.0 * np.sin(k / 500) / 1e-3) * 1e-3, 1e-3),
        # an ADC: 0..10 V with a step of 0.01 V
        (lambda k: np.round((5 + 5 * np.sin(k / 700)) / 0.01) * 0.01, 0.01),
        # signal spanning only 10^2 steps, with an offset off the grid's zero
        (lambda k: 0.123 + np.round(50 * np.sin(k / 300)) * 0.25, 0.25),
        # 10^7 steps spanned, few of the levels occur
        (lambda k: np.round(5e6 * np.sin(k / 2000)) * 1e-7, 1e-7),
    ],
)
def test_step_is_found_across_magnitudes(values, step):
    y = values(np.arange(20000.0))
    assert quantisation_step(y) == pytest.approx(step, rel=1e-6)


def test_step_of_a_sparse_ramp_is_the_gcd_of_its_spacings():
    """A ramp of 400.3 steps per sample: spacings of 400 and 401 steps only."""
    y = np.round((0.123 + np.arange(25000) * 400.3 * STEP) / STEP) * STEP
    assert quantisation_step(y) == pytest.approx(STEP, rel=1e-6)


def test_few_distinct_values():
    assert np.isnan(quantisation_step(np.full(1000, 3.0)))  # constant
    assert np.isnan(quantisation_step([0.0, 1.0] * 50))  # two levels: no grid seen
    # three levels whose step needs a reduction: too little evidence
    assert np.isnan(quantisation_step([0.0, 3.0, 5.0] * 30))
    assert np.isnan(quantisation_step([np.nan] * 10))
    assert quantisation_step(np.tile(np.arange(10) * 0.1, 20)) == pytest.approx(0.1)


def test_a_few_glitches_are_allowed_but_not_many():
    rng = np.random.default_rng(8)
    y = encoder(1e-5)
    glitched = y.copy()
    idx = rng.choice(y.size, 20, replace=False)  # 0.08 %
    glitched[idx] += rng.uniform(0.0, STEP, idx.size)
    assert quantisation_step(glitched) == pytest.approx(STEP, rel=1e-3)
    idx = rng.choice(y.size, 50, replace=False)  # 0.2 %
    y[idx] += rng.uniform(0.0, STEP, idx.size)
    assert np.isnan(quantisation_step(y))


def test_channels_are_checked_for_quantisation_separately():
    rng = np.random.default_rng(9)
    y = np.column_stack([encoder(0.0), POSITION + 1e-5 * rng.standard_normal(25000)])
    var, diags, _ = estimate(y, t=T_ENC)
    assert not diags[0].determined and diags[1].determined
    assert np.isnan(diags[1].quantisation_step)
    assert var[1] == pytest.approx(1e-10, rel=0.2)


def test_describe_noise():
    var, diags, _ = estimate(encoder(1e-5), t=T_ENC)
    text = describe_noise(var, diags)
    assert text.startswith("estimated from the data") and "spectral floor" in text
    assert "Hz" in text and "step 5e-08" in text and "\n" not in text
    var, diags, _ = estimate(encoder(0.0), t=T_ENC)
    assert "NOT determined" in describe_noise(var, diags)
    assert "step 5e-08" in describe_noise(var, diags)
    rng = np.random.default_rng(10)
    y = np.column_stack([encoder(1e-5), POSITION + 1e-5 * rng.standard_normal(25000)])
    var, diags, _ = estimate(y, t=T_ENC)
    text = describe_noise(var, diags)
    assert "channel 0" in text and "channel 1" in text
    assert text.count("quantised") == 1
    assert describe_noise(np.diag([1e-6, 4e-6]), None) == "stated: sd 0.001, 0.002"


def test_a_channels_quantisation_step_is_computed_once_and_kept_by_content(
    monkeypatch,
):
    # a study asks for each channel's step twice (clipping check, noise
    # estimate): the second answer is the kept one, for the same values
    # only (NaN and inf ignored, as the step ignores them), and only a few
    # channels are kept
    from pysindy_mme.core import noise

    rng = np.random.default_rng(7)
    grid = np.round(rng.normal(size=2000) / 0.01) * 0.01
    calls = []
    inner = noise._quantisation_step
    monkeypatch.setattr(
        noise, "_quantisation_step", lambda x: calls.append(x.size) or inner(x)
    )
    noise._STEPS.clear()
    first = quantisation_step(grid)
    with_nan = grid.copy()
    with_nan[[5, 50]] = np.nan
    assert first == pytest.approx(0.01, rel=1e-9)
    assert quantisation_step(grid.copy()) == first
    assert len(calls) == 1
    # other values: computed (a continuous channel: no grid)
    assert np.isnan(quantisation_step(grid + 1e-5 * rng.normal(size=2000)))
    assert quantisation_step(with_nan) == pytest.approx(0.01, rel=1e-9)
    assert len(calls) == 3
    for k in range(noise._STEPS_KEPT + 2):
        quantisation_step(grid * (k + 2))
    assert len(noise._STEPS) == noise._STEPS_KEPT
