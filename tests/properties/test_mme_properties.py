"""Property-based tests (hypothesis) of ``MME.fit``.

Every generated input must end either in an estimate that passes basic
sanity checks (shapes, finite values, the covariance constraint met or a
warning with a flag) or in a documented error, with only documented
warnings. Inputs: random record lengths, irregular sampling, noise levels
from 1e-8 to 10, missing (NaN) samples, time shifts ``t + c`` (same
estimate), units (``y * c`` with ``noise_variance * c**2``: the estimate
scales) and missing samples padded at the ends (nothing changes).

The hypothesis profile ("ci": derandomised, fixed example counts) is set in
``tests/conftest.py``, which also prints how many cases each entry point
received.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from reliability_support import readonly, warning_types
from sklearn.exceptions import ConvergenceWarning

from pysindy_mme import MME
from pysindy_mme.exceptions import DivergenceError
from pysindy_mme.systems import duffing, lotka_volterra, van_der_pol

SYSTEMS = {s.name: s for s in (van_der_pol(), duffing(), lotka_volterra())}
# Assumed models that are linear (f(c x) = c f(x)): estimates scale with units.
LINEAR_ASSUMED = ("van_der_pol", "duffing")


@st.composite
def mme_problems(draw, systems=tuple(SYSTEMS)):
    name = draw(st.sampled_from(systems), label="system")
    system = SYSTEMS[name]
    n = draw(st.integers(8, 300), label="n_samples")
    seed = draw(st.integers(0, 2**16), label="seed")
    rng = np.random.default_rng(seed)
    if draw(st.booleans(), label="irregular sampling"):
        steps = rng.uniform(0.3, 1.7, n - 1) / system.rate_hz
        t = np.concatenate([[0.0], np.cumsum(steps)])
    else:
        t = np.arange(n) / system.rate_hz
    noise_variance = 10.0 ** draw(st.integers(-8, 1), label="log10 noise variance")
    data = system.measure(seed, noise_variance=noise_variance, t=t)
    y = data.y.copy()
    missing = draw(st.sampled_from([0.0, 0.0, 0.1, 0.4]), label="missing fraction")
    if missing:
        y[rng.random(y.shape) < missing] = np.nan
    return system, t, y, noise_variance


def _mme(system, noise_variance, **kwargs):
    return MME(
        system.assumed_model,
        system.n_states,
        measured=list(system.measured),
        noise_variance=noise_variance,
        error_states=list(system.error_states),
        **kwargs,
    )


def _run_mme(mme, y, t):
    """Fit; return (mme, warnings) or (None, documented error)."""
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        try:
            mme.fit(y, t)
        except ValueError as exc:
            # e.g. too few observed samples to see every state
            assert "measured" in str(exc) or "y (the measurements)" in str(exc), exc
            return None, exc
        except DivergenceError as exc:
            assert "assumed_model" in str(exc) or "diverged" in str(exc), exc
            return None, exc
    types = warning_types(record)
    assert types <= {ConvergenceWarning, UserWarning}, [str(w.message) for w in record]
    return mme, record


def _check_mme_result(mme, system, y, t, record):
    N, n = t.size, system.n_states
    assert mme.smoothed_x_.shape == (N, n) and mme.d_.shape == (N, n)
    assert np.all(np.isfinite(mme.smoothed_x_)) and np.all(np.isfinite(mme.d_))
    assert np.all(np.isfinite(mme.derivative_))
    others = [i for i in range(n) if i not in system.error_states]
    assert np.all(mme.d_[:, others] == 0)
    assert mme.d_intervals_.shape == (N - 1, len(system.error_states))
    # Residuals are missing exactly where the measurements are.
    np.testing.assert_array_equal(np.isnan(mme.residuals_), np.isnan(y))
    assert mme.covariance_ratio_.shape == (y.shape[1],)
    assert np.all(np.isfinite(mme.covariance_ratio_) & (mme.covariance_ratio_ >= 0))
    assert np.isfinite(mme.W_) and mme.W_ > 0
    messages = [str(w.message) for w in record]
    if not mme.converged_:
        assert any("did not converge" in m for m in messages)
    if mme.W_at_bound_:
        assert any("covariance constraint cannot be met" in m for m in messages)
    else:
        # The covariance constraint holds (to the W search's tolerance): the
        # mean over channels of mean(r_j^2) / R_jj is 1 (R is diagonal here).
        per_channel = np.nanmean(mme.residuals_**2, axis=0)
        ratio = per_channel / np.diag(mme.noise_variance_)
        np.testing.assert_allclose(ratio, mme.covariance_ratio_, rtol=1e-10)
        assert np.mean(ratio) == pytest.approx(1.0, rel=0.03)


@pytest.mark.slow  # many generated cases, seconds each: CI and the full run
@settings(max_examples=120)
@given(
    problem=mme_problems(),
    error_model=st.sampled_from(["white", "random_walk"]),
)
def test_mme_sane_or_documented_error(problem, error_model, case_counter):
    case_counter["MME.fit"] += 1
    system, t, y, noise_variance = problem
    y_ro, t_ro = readonly(y), readonly(t)
    mme, record = _run_mme(
        _mme(system, noise_variance, error_model=error_model), y_ro, t_ro
    )
    np.testing.assert_array_equal(y_ro, y)
    if mme is not None:
        _check_mme_result(mme, system, y, t, record)


@pytest.mark.slow  # many generated cases, seconds each: CI and the full run
@settings(max_examples=40)
@given(
    problem=mme_problems(),
    shift=st.one_of(st.integers(-1000, 1000), st.floats(-1e3, 1e3)),
)
def test_mme_time_shift_gives_the_same_estimate(problem, shift, case_counter):
    """The example systems are autonomous: t + c must not change the estimate."""
    case_counter["MME.fit"] += 2
    system, t, y, noise_variance = problem
    a, _ = _run_mme(_mme(system, noise_variance), y, t)
    b, _ = _run_mme(_mme(system, noise_variance), y, t + shift)
    assert (a is None) == (b is None)
    if a is None:
        return
    assert a.W_at_bound_ == b.W_at_bound_
    assert b.W_ == pytest.approx(a.W_, rel=1e-5)
    scale = np.abs(a.smoothed_x_).max()
    np.testing.assert_allclose(b.smoothed_x_, a.smoothed_x_, rtol=0, atol=1e-6 * scale)
    d_scale = max(np.abs(a.d_).max(), 1e-12)
    np.testing.assert_allclose(b.d_, a.d_, rtol=0, atol=1e-5 * d_scale)
    np.testing.assert_allclose(b.t_, a.t_ + shift)


@pytest.mark.slow  # many generated cases, seconds each: CI and the full run
@settings(max_examples=40)
@given(problem=mme_problems(LINEAR_ASSUMED), log_unit=st.integers(-6, 6))
def test_mme_units_scale_the_estimate(problem, log_unit, case_counter):
    """y * c with noise variance * c**2: states and d scale by c, W by c**-2.

    Restricted to noise variances in [1e-14, 1e14] in the new units: beyond,
    MME wrongly reports a singular problem (a defect, see
    ``tests/differentiation/test_mme_reliability.py::test_mme_units_far_from_one``).
    """
    system, t, y, noise_variance = problem
    c = 10.0**log_unit
    assume(1e-14 <= noise_variance * c**2 <= 1e14)
    case_counter["MME.fit"] += 2
    a, _ = _run_mme(_mme(system, noise_variance), y, t)
    b, _ = _run_mme(_mme(system, noise_variance * c**2), y * c, t)
    assert (a is None) == (b is None)
    if a is None:
        return
    assert a.W_at_bound_ == b.W_at_bound_
    assert b.W_ * c**2 == pytest.approx(a.W_, rel=1e-5)
    scale = np.abs(a.smoothed_x_).max()
    np.testing.assert_allclose(b.smoothed_x_ / c, a.smoothed_x_, atol=1e-6 * scale)
    d_scale = max(np.abs(a.d_).max(), 1e-12)
    np.testing.assert_allclose(b.d_ / c, a.d_, rtol=0, atol=1e-5 * d_scale)
    np.testing.assert_allclose(b.covariance_ratio_, a.covariance_ratio_, rtol=1e-6)


@settings(max_examples=40)
@given(
    problem=mme_problems(),
    lead=st.integers(0, 4),
    trail=st.integers(0, 4),
    log_w=st.integers(-2, 2),
)
def test_mme_missing_samples_at_the_ends_change_nothing(
    problem, lead, trail, log_w, case_counter
):
    """NaN measurements are missing samples: padding a record with missing
    samples before and after it leaves the estimate on the record unchanged
    (no prior on the initial state, and nothing to fit there: d = 0 and the
    states follow the model). ``W`` is fixed so that the two problems are the
    same optimisation."""
    case_counter["MME.fit"] += 2
    system, t, y, noise_variance = problem
    if lead == trail == 0:
        trail = 1
    h = float(np.mean(np.diff(t)))
    W = 10.0**log_w * h / noise_variance
    t_pad = np.concatenate(
        [t[0] - h * np.arange(lead, 0, -1), t, t[-1] + h * np.arange(1, trail + 1)]
    )
    nan_rows = np.full((1, y.shape[1]), np.nan)
    y_pad = np.vstack([np.repeat(nan_rows, lead, 0), y, np.repeat(nan_rows, trail, 0)])
    a, _ = _run_mme(_mme(system, noise_variance, W=W), y, t)
    b, _ = _run_mme(_mme(system, noise_variance, W=W), y_pad, t_pad)
    assert (a is None) == (b is None)
    if a is None:
        return
    N = t.size
    scale = np.abs(a.smoothed_x_).max()
    np.testing.assert_allclose(
        b.smoothed_x_[lead : lead + N], a.smoothed_x_, rtol=0, atol=1e-6 * scale
    )
    d_scale = max(np.abs(a.d_intervals_).max(), 1e-9 * scale / h)
    inside = b.d_intervals_[lead : lead + N - 1]
    np.testing.assert_allclose(inside, a.d_intervals_, rtol=0, atol=1e-5 * d_scale)
    outside = np.concatenate([b.d_intervals_[:lead], b.d_intervals_[lead + N - 1 :]])
    assert np.all(np.abs(outside) <= 1e-5 * d_scale)
