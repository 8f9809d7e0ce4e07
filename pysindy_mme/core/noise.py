"""Measurement-noise variance that does not take fast signal for noise.

For ``y_k = s(t_k) + v_k`` with white noise ``v`` of variance ``sigma^2``
independent of the signal ``s``, the spectrum of ``y`` is the signal's
spectrum plus a flat floor at ``sigma^2``. Where the signal has no power the
spectrum *is* the noise; everywhere else it lies above it. This module finds
that floor, wherever it lies on the frequency axis:

1. Each channel's NaN-free stretches are cut into non-overlapping segments
   (length: the power of two nearest ``n / 8``, 128 to 4096); each loses its
   mean and trend, is Hann windowed and transformed. Ordinates are scaled so
   that white noise gives ``sigma^2`` in every bin; bins 0-2 and N/2-1 are
   left out.
2. The axis is cut into 16 bands. The floor is the band with the lowest
   median ordinate, pooled with every band within 3 standard errors of it;
   a half-band significantly above the pooled level (the edge of a signal
   band) is dropped. Medians ignore the few bins that spectral lines occupy.
3. The level is *cross-fitted*: the floor is picked on the real parts of the
   transforms and read on the imaginary parts, and the other way round. For
   Gaussian white noise the two are independent (the window and the
   detrending are symmetric), so the reading is not biased low by having
   picked the lowest bands, yet both see the same segments of a changing
   signal. Each reading is divided by the median of ``chi2(K) / K`` (``K``
   segments), which makes it unbiased for white noise.

The floor is an upper bound on ``sigma^2`` (up to sampling error): signal
power only adds to it. It equals ``sigma^2`` when some band is free of
signal. What cannot be resolved is flagged (``reliable=False`` and a
:class:`~pysindy_mme.DiscoveryWarning`), not guessed: a *flat* record (no
band above the floor: pure noise, or a signal whose spectrum is flat to the
Nyquist frequency; no spectral method can separate those), a floor region of
fewer than 8 bins (within window leakage of the signal), and a *sloped* floor
(the spectrum still falls or rises where it is lowest: no white plateau).

Evidence (``python benchmarks/bench_noise.py``: noise sd 1, 16384 samples,
8 seeds, estimated / true variance, mean [range]). A signal of 20 sinusoids
up to 0.45 fs plus a chirp 0.02-0.45 fs, rms 10: the 4th-difference
estimator MME used, 48 [43, 60]; differences of orders 1-8, 42-56; a
Savitzky-Golay residual (cubic, 9 samples, dof-corrected), 55; the median
of a Welch periodogram over all frequencies, 20; its 10 % quantile, 1.56;
the floor, 0.97 [0.92, 1.02]. Smooth, low-pass and random-walk signals:
the floor 0.98-1.03; 4th differences 0.98-2.3. A resonance whose spectrum
never falls below 0.21 of the noise level: the floor 1.26 against the ideal
1.21. White noise: unbiased within 0.5 % over 300 records and recognised as
flat in 299 (``tests/core/test_noise.py``, slow). The Silverbox record
(output V2; arrow and multisine parts): 4th differences 2.4 mV (sd); the
floor 0.0034-0.0040 mV, flagged *sloped*: the spectrum falls by two decades
from 200 Hz to the Nyquist frequency, so the white measurement noise is at
most that; the multisines' unexcited (even) lines show 0.02-0.5 mV in band,
coloured by the resonance: disturbances and even distortion, not sensor
noise.

Limits: the noise must be white (noise low-pass filtered before sampling has
its floor near Nyquist, and the estimate is then too low for the in-band
noise) and the sampling uniform within 1 %. Records without 4 NaN-free
stretches of 128 samples fall back to the order-4 difference estimator,
checked against order 8 and against the record's variance (flagged when they
disagree or when the record looks white).

Quantised sensors (an encoder with a 50 nm step, an ADC): rounding to a grid
of step ``q`` adds a white error of variance ``q^2 / 12`` when the signal
crosses many steps, so the floor of such a record cannot fall below that,
however small the sensor's own noise. :func:`quantisation_step` finds the
grid; where the estimate is at its level (sd at most ``2 q / sqrt(12)``) the
noise is *not determined* by the data (``determined=False``): the variance
``q^2 / 12`` of the quantisation is returned, a lower bound on the
measurement error, and the user has to state the noise.
"""

from __future__ import annotations

import hashlib
import threading
import warnings
from dataclasses import dataclass, replace
from math import comb

import numpy as np
from scipy import stats

from ..exceptions import DiscoveryWarning
from .tables import sig
from .validation import as_float_array, check_positive_number, check_time

__all__ = [
    "NoiseDiagnostics",
    "describe_noise",
    "estimate_noise_variance",
    "quantisation_step",
    "difference_noise_variance",
    "noise_covariance",
]

_METHODS = ("auto", "spectral", "difference")
_MIN_SEGMENT = 128  # shortest segment: 60 usable bins, 10 bands of 6
_MIN_SEGMENTS = 4  # fewest segments averaged (8 degrees of freedom per bin)
_TARGET_SEGMENTS = 8  # segment length: the power of two nearest n / 8
_MIN_FLOOR_BINS = 8  # a narrower floor is within Hann leakage of the signal
_MAX_SEGMENT = 4096
_FIRST_BIN = 3  # bins 0-2 carry the detrended mean/slope and window leakage
_Z = 3.0  # band medians within _Z standard errors count as the same level
_ALPHA = 0.01  # false-alarm rate of each test on the spectrum
# The cross-fitted level (see _cross_fitted_level) picks its floor more
# strictly: there, leaving out a band costs precision but no bias.
_Z_PICK = 2.0
_Z_TRIM = 1.645
# Hann windows correlate neighbouring bins; the variance of a mean over many
# bins grows by 1 + 2 (4/9 + 1/36) = 1.944 compared with independent bins.
_HANN_VARIANCE_INFLATION = 1.0 + 2.0 * (4.0 / 9.0 + 1.0 / 36.0)

# Quantisation (see quantisation_step).
# The noise counts as undetermined while its estimated sd is at most this
# multiple of the quantisation sd q / sqrt(12): the estimate is then at most
# q^2 / 3 = q^2 / 12 + (q / 2)^2, i.e. the noise beyond the rounding error is
# at most half a step. Below about half a step the rounding error is not the
# white, signal-independent error of variance q^2 / 12 (Widrow's quantisation
# theorem needs noise of about that size to dither it), so the data cannot
# separate the sensor noise from the rounding.
_QUANTISATION_FACTOR = 2.0
# A value is on the grid when within this fraction of a step of it (plus the
# float rounding of values of its magnitude).
_GRID_TOL = 1e-6
# Share of the samples that must lie on the grid: a few glitches are allowed.
_ON_GRID_SHARE = 0.999
# Distinct levels that must lie on the grid beyond those the step was built
# from: a continuous value is within _GRID_TOL of a given grid with
# probability ~2e-6, so three such leave a false alarm of ~1e-17.
_MIN_CHECKS = 3
# Grids finer than 1e-10 of the range are not looked for: there the float
# rounding of the values approaches _GRID_TOL of the step, and every float64
# record lies on the grid of its own least significant bit.
_MAX_LEVELS = 1e10
# A step candidate whose rounding error exceeds this share of it cannot be
# reduced further (its multiples no longer tell integers apart).
_MAX_STEP_ERROR = 1e-3
# Spacings tried as the first step candidate when some values are off the
# grid (glitches make the smallest spacings).
_N_CANDIDATES = 4
_EPS = float(np.finfo(float).eps)


_FLAT = (
    "the record cannot be told apart from white noise (pure noise, or a signal "
    "whose spectrum is flat up to the Nyquist frequency): nothing in it rises "
    "above its noise floor; the estimate is the record's variance, an upper "
    "bound on the noise"
)


@dataclass(frozen=True)
class NoiseDiagnostics:
    """How the noise variance of one channel was estimated.

    Attributes
    ----------
    channel : int
        Column of ``y``.
    variance : float
        The estimate.
    method : str
        ``"spectral"`` (the spectral floor) or ``"difference"``.
    band : tuple of float or None
        Lowest and highest frequency of the floor region (in ``unit``);
        ``None`` for the difference method.
    band_fraction : float
        Share of the analysed frequency axis that the floor region covers
        (``nan`` for the difference method).
    unit : str
        ``"Hz"`` when ``t`` was given, else ``"cycles/sample"``.
    segment_length, n_segments : int
        Segment length and number of segments averaged (0 for the
        difference method).
    relative_se : float
        Relative standard error of the estimate from the sampling of the noise
        alone (Gaussian white noise in the bins used); signal power in the
        floor adds a bias that this does not include.
    reliable : bool
        False when the estimate is only an upper bound (or zero), or when the
        noise is not determined (``determined=False``).
    reason : str
        Why it is not reliable; empty when it is.
    fallback : str
        Why ``method="auto"`` used differences; empty otherwise.
    quantisation_step : float
        Step of the grid the channel's values lie on
        (:func:`quantisation_step`); ``nan`` when they lie on none. The
        estimate includes the rounding error (variance ``step^2 / 12``), which
        is part of the measurement error.
    determined : bool
        False when the channel is quantised and the estimate is at the
        quantisation level (sd at most ``2 step / sqrt(12)``): the sensor noise
        cannot be told from the rounding, and ``variance`` is then
        ``max(estimate, step^2 / 12)``, the rounding error alone, a lower bound
        on the measurement error. The noise has to be stated.
    """

    channel: int
    variance: float
    method: str
    band: tuple | None
    band_fraction: float
    unit: str
    segment_length: int
    n_segments: int
    relative_se: float
    reliable: bool
    reason: str
    fallback: str = ""
    quantisation_step: float = float("nan")
    determined: bool = True


def estimate_noise_variance(
    y,
    t=None,
    method: str = "auto",
    *,
    order: int = 4,
    segment_length: int | None = None,
    n_bands: int = 16,
    warn: bool = True,
    return_diagnostics: bool = False,
):
    """Variance of the white measurement noise in each column of ``y``.

    Parameters
    ----------
    y : array-like (n_samples,) or (n_samples, n_channels)
        Uniformly sampled measurements; NaN marks a missing value.
    t : float, array-like (n_samples,) or None
        Sample step or sample times; used to check uniform sampling (within
        1 %) and to report the floor band in Hz. ``None``: unit step.
    method : {"auto", "spectral", "difference"}
        ``"spectral"``: the spectral floor (module docstring).
        ``"difference"``: mean square of ``order``-th differences within
        NaN-free stretches divided by ``C(2 order, order)``; right only for
        signals smooth on the sampling scale. ``"auto"``: spectral where the
        channel allows it (uniform sampling, at least 4 NaN-free stretches of
        128 samples), else difference.
    order : int
        Difference order for ``method="difference"`` and the fallback.
    segment_length : int or None
        Segment length of the spectral method (at least 128). ``None``: the
        power of two nearest ``n / 8``, between 128 and 4096, halved while
        fewer than 4 NaN-free segments fit.
    n_bands : int
        Bands the frequency axis is cut into (at least 4; fewer are used when
        a band would hold fewer than 6 bins).
    warn : bool
        Issue a :class:`~pysindy_mme.DiscoveryWarning` for each channel whose
        estimate is not reliable.
    return_diagnostics : bool
        Also return a list of :class:`NoiseDiagnostics`, one per channel.

    Returns
    -------
    variance : ndarray (n_channels,)
        For a quantised channel whose estimate is at the quantisation level
        (``NoiseDiagnostics.determined`` False): ``step^2 / 12``, the variance
        of the rounding, unless the estimate is larger.
    diagnostics : list of NoiseDiagnostics
        Only with ``return_diagnostics=True``.

    Raises
    ------
    ValueError, TypeError
        Naming the argument: ``y`` not 1-D/2-D, empty, holding inf, or a
        channel with ``order + 5`` or fewer observed samples; ``t`` not
        matching ``y``; an unknown ``method``; bad ``order``,
        ``segment_length``, ``n_bands``; ``method="spectral"`` where the
        channel does not allow it.
    """
    Y, dt = _check_inputs(y, t, method, order, segment_length, n_bands)
    sampling = (
        None if dt is None else (1.0 / dt, "cycles/sample" if t is None else "Hz")
    )
    results = []
    for j in range(Y.shape[1]):
        diag = _estimate_channel(
            Y[:, j], j, method, order, segment_length, n_bands, sampling
        )
        diag = _with_quantisation(diag, Y[:, j])
        if warn and not diag.reliable:
            used = f" (differences were used: {diag.fallback})" if diag.fallback else ""
            warnings.warn(
                f"noise variance of y channel {j} ({diag.variance:.4g}, sd "
                f"{np.sqrt(diag.variance):.4g}) is not reliable: {diag.reason}{used}",
                DiscoveryWarning,
                stacklevel=2,
            )
        results.append(diag)
    variance = np.array([d.variance for d in results])
    return (variance, results) if return_diagnostics else variance


def quantisation_step(col) -> float:
    """Step of the uniform grid that a channel's values lie on, or ``nan``.

    A channel is quantised when its finite values are ``offset + k * step``
    for integers ``k`` (an encoder, an ADC, values printed with a fixed number
    of decimals), each within ``1e-6`` of the step plus the float rounding of
    values of its magnitude, for at least 99.9 % of the samples (a few
    glitches are allowed). Only a few of the levels need to occur: the step is
    the largest one that divides every spacing between the sorted distinct
    values (found by Euclid's algorithm on the spacings, with their rounding
    errors carried along), refined by a least-squares fit of the values on
    their level numbers. Cost ``O(n log n)``.

    Parameters
    ----------
    col : array-like
        The values of one channel (flattened); NaN and inf are ignored.

    Returns
    -------
    float
        The step (positive), or ``nan`` when the values lie on no grid: a
        continuous channel; fewer than 5 distinct values, or no 3 distinct
        values beyond those the step was built from (too little to tell a grid
        from chance; a constant channel in particular); a grid finer than
        ``1e-10`` of the range (float rounding).
    """
    x = np.asarray(col, dtype=float).ravel()
    x = x[np.isfinite(x)]
    if x.size == 0:
        return float("nan")
    # A study asks twice for each channel (the clipping check and the noise
    # estimate), an O(n log n) sort each time: 0.15 s per channel at 10^6
    # samples. The answer is kept for the last few channels, by content.
    key = (x.size, hashlib.blake2b(x.tobytes(), digest_size=16).digest())
    with _STEP_LOCK:
        if key in _STEPS:
            return _STEPS[key]
    step = _quantisation_step(x)
    with _STEP_LOCK:
        _STEPS[key] = step
        while len(_STEPS) > _STEPS_KEPT:
            del _STEPS[next(iter(_STEPS))]  # the oldest
    return step


#: channels whose quantisation step is kept (see :func:`quantisation_step`)
_STEPS_KEPT = 8
_STEPS: dict = {}
_STEP_LOCK = threading.Lock()


def _quantisation_step(x) -> float:
    """:func:`quantisation_step` of the finite values ``x`` (not kept)."""
    u, counts = np.unique(x, return_counts=True)
    scale = float(np.max(np.abs(u)))
    tau = 8.0 * _EPS * scale  # rounding error of a difference of two values
    if u.size > 1:  # one level written two ways (differing in the last bits)
        new = np.r_[True, np.diff(u) > tau]
        counts = np.bincount(np.cumsum(new) - 1, weights=counts)
        u = u[new]
    if u.size < 2 + _MIN_CHECKS:
        return float("nan")
    d = np.diff(u)
    # First every value on the grid, from the smallest spacing; then allowing
    # glitches, from small spacings that recur (a glitch makes a spacing that
    # does not).
    for allowed_off, candidates in (
        (0.0, [int(np.argmin(d))]),
        (1.0 - _ON_GRID_SHARE, _recurring_spacings(d, tau)),
    ):
        for i in candidates:
            found = _euclid_step(d, counts, i, tau, allowed_off)
            if found is None:
                continue
            g, err, good, n_used = found
            # reference level: an end of the best-populated spacing on the grid
            weight = np.where(good, counts[:-1] + counts[1:], -1.0)
            ref = float(u[int(np.argmax(weight))])
            step = _fit_grid(u, counts, g, err, ref, tau, n_used)
            if np.isfinite(step):
                return step
    return float("nan")


def _recurring_spacings(d, tau):
    """Indices of the smallest spacings that occur at least 3 times.

    Spacings equal within rounding form a group; the first index of each of
    the ``_N_CANDIDATES`` smallest groups of 3 or more is returned.
    """
    order = np.argsort(d, kind="stable")
    ds = d[order]
    new = np.r_[True, np.diff(ds) > tau + _GRID_TOL * ds[1:]]
    size = np.bincount(np.cumsum(new) - 1)
    return order[new][size >= 3][:_N_CANDIDATES].tolist()


def _euclid_step(d, counts, i, tau, allowed_off):
    """Largest step dividing the spacings ``d``, starting from ``d[i]``.

    Euclid's algorithm: while some spacing is no integer multiple of the
    candidate ``g``, its remainder modulo ``g`` (a multiple of the true step,
    at most ``g / 2``) becomes the candidate, and the earlier candidates must
    be multiples of it too. Rounding errors are carried along (``err``; a
    multiple ``q g`` has error ``q err``). Spacings next to values holding at
    most ``allowed_off`` of the samples may stay off the grid (glitches).

    Returns ``(g, err, good, n_used)`` (``good``: the spacings on the grid;
    ``n_used``: distinct values the candidate was built from) or None when
    the candidate becomes finer than ``_MAX_LEVELS`` of the range or too
    imprecise.
    """
    span = float(d.sum())
    total = float(counts.sum())
    g, err = float(d[i]), tau
    earlier = []  # (candidate, its error): the step must divide them too
    n_used = 2
    while True:
        if span / g > _MAX_LEVELS or err > _MAX_STEP_ERROR * g:
            return None
        q = np.round(d / g)
        bad = np.abs(d / g - q) > _GRID_TOL + (tau + q * err) / g
        bad_earlier = [
            (v, e)
            for v, e in earlier
            if abs(v / g - round(v / g)) > _GRID_TOL + (e + round(v / g) * err) / g
        ]
        if not bad_earlier:
            # A glitch spoils both spacings next to it: half the smaller
            # counts at the ends of the spoilt spacings estimates its samples.
            off = np.minimum(counts[:-1], counts[1:])[bad].sum() / 2.0
            if off <= allowed_off * total:
                return g, err, ~bad, n_used
        values = np.r_[d[bad], [v for v, _ in bad_earlier]]
        errors = np.r_[np.full(int(bad.sum()), tau), [e for _, e in bad_earlier]]
        multiple = np.round(values / g)
        rem = np.abs(values - multiple * g)
        rem_err = errors + multiple * err
        precise = (rem > 0.0) & (rem_err <= _MAX_STEP_ERROR * rem)
        if not precise.any():
            return None
        j = np.flatnonzero(precise)[np.argmin(rem[precise])]
        earlier.append((g, err))
        g, err = float(rem[j]), float(rem_err[j])
        n_used += 1


def _fit_grid(u, counts, g, err, ref, tau, n_used):
    """The step refined on all levels, or ``nan`` if they do not fit a grid.

    Level numbers ``k = round((u - ref) / step)`` are only certain where
    ``|k|`` times the step's relative error stays small; the fit of
    ``u = offset + step * k`` on those makes the step more precise, which
    makes more levels certain, until all are. The result is accepted when
    at least ``_ON_GRID_SHARE`` of the samples and ``_MIN_CHECKS`` distinct
    levels beyond the ``n_used`` it was built from lie on the grid.
    """
    step, offset, rel = g, ref, err / g
    while True:
        k = np.round((u - offset) / step)
        certain = np.abs(k) * rel <= 0.05
        res = u - (offset + step * k)
        tol = _GRID_TOL * step + 8.0 * _EPS * (np.abs(u) + abs(offset))
        fit = certain & (np.abs(res) <= tol + 2.0 * np.abs(k) * rel * step)
        kf, uf = k[fit], u[fit]
        if kf.size < 2 or kf.max() == kf.min():
            return float("nan")
        kc = kf - kf.mean()
        step = float(kc @ (uf - uf.mean()) / (kc @ kc))
        offset = float(uf.mean() - step * kf.mean())
        if certain.all():
            break
        # a fit over a span of K levels pins the step to ~ tau / K
        new_rel = 2.0 * tau / (step * (kf.max() - kf.min()))
        if not step > 0.0 or new_rel >= 0.5 * rel:
            return float("nan")
        rel = new_rel
    k = np.round((u - offset) / step)
    tol = _GRID_TOL * step + 8.0 * _EPS * (np.abs(u) + abs(offset))
    on = np.abs(u - (offset + step * k)) <= tol
    if (
        not step > 0.0
        or counts[on].sum() < _ON_GRID_SHARE * counts.sum()
        or int(on.sum()) - n_used < _MIN_CHECKS
    ):
        return float("nan")
    return step


def _with_quantisation(diag, col):
    """``diag`` with the channel's quantisation step, and its consequence.

    When the estimate is at the quantisation level (sd at most
    ``_QUANTISATION_FACTOR * step / sqrt(12)``) the noise is not determined:
    the variance becomes at least ``step^2 / 12``, the rounding error, which
    is part of the measurement error whatever the sensor's noise.
    """
    step = quantisation_step(col)
    if not np.isfinite(step):
        return diag
    floor = step**2 / 12.0
    if diag.variance > _QUANTISATION_FACTOR**2 * floor:
        return replace(diag, quantisation_step=step)
    reason = (
        f"the channel is quantised with step {sig(step)} and its estimated noise "
        f"(sd {sig(np.sqrt(diag.variance))}) is at the quantisation level (sd of "
        f"the rounding: step/sqrt(12) = {sig(np.sqrt(floor))}): the sensor noise "
        "cannot be told from the quantisation, so the noise is not determined by "
        "the data; the rounding's variance step^2/12 is used, a lower bound. "
        "State the noise variance (the sensor's specified noise, or the accuracy "
        "the model is expected to reach)"
    )
    if diag.reason:
        reason += f"; besides, {diag.reason}"
    return replace(
        diag,
        variance=float(max(diag.variance, floor)),
        quantisation_step=step,
        determined=False,
        reliable=False,
        reason=reason,
    )


def describe_noise(variance, diagnostics) -> str:
    """One line for a report: how the noise variance of each channel was found.

    Parameters
    ----------
    variance : float or array-like (m,) or (m, m)
        The variances used (the diagonal of a covariance matrix).
    diagnostics : list of NoiseDiagnostics or None
        From :func:`estimate_noise_variance`; None when the noise was stated.

    Returns
    -------
    str
        E.g. ``"estimated from the data: sd 1e-05 (spectral floor 120-500 Hz;
        quantised, step 5e-08)"``; several channels as ``"channel 0 sd ...;
        channel 1 sd ..."``; ``"stated: sd 0.001"`` when stated.
    """
    var = np.asarray(variance, dtype=float)
    var = np.diag(var) if var.ndim == 2 else np.atleast_1d(var)
    sds = np.sqrt(np.abs(var))
    if diagnostics is None:
        return "stated: sd " + ", ".join(sig(v) for v in sds)
    items = []
    for d, sd in zip(diagnostics, sds):
        if d.band is not None:
            how = f"spectral floor {sig(d.band[0], 3)}-{sig(d.band[1], 3)} {d.unit}"
        else:
            how = "differences"
        if not d.determined:
            how += (
                f"; NOT determined: quantised, step {sig(d.quantisation_step)}, "
                "at the quantisation level"
            )
        elif np.isfinite(d.quantisation_step):
            how += f"; quantised, step {sig(d.quantisation_step)}"
        if d.determined and not d.reliable:
            how += "; not reliable"
        items.append((d.channel, f"sd {sig(sd)} ({how})"))
    if len(items) == 1:
        return "estimated from the data: " + items[0][1]
    return "estimated from the data: " + "; ".join(f"channel {j} {t}" for j, t in items)


def _check_inputs(y, t, method, order, segment_length, n_bands):
    """Validated copy of ``y`` as 2-D, the sample step and uniformity."""
    if not isinstance(method, str) or method not in _METHODS:
        raise ValueError(f"method must be one of {_METHODS}, got {method!r}")
    for name, value, low in (
        ("order", order, 1),
        ("n_bands", n_bands, 4),
        ("segment_length", segment_length, _MIN_SEGMENT),
    ):
        if value is None and name == "segment_length":
            continue
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name} must be an integer, got {value!r}")
        if value < low:
            raise ValueError(f"{name} must be at least {low}, got {value}")
    try:
        Y = np.array(y, dtype=float, copy=True)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"y must be a numeric array: {exc}") from None
    if Y.ndim not in (1, 2) or Y.size == 0:
        raise ValueError(f"y must be a non-empty 1-D or 2-D array, got shape {Y.shape}")
    if np.any(np.isinf(Y)):
        raise ValueError("y contains inf; mark missing values with NaN")
    Y = Y[:, None] if Y.ndim == 1 else Y
    if t is None or Y.shape[0] < 2:
        return Y, 1.0
    steps = np.diff(check_time(t, Y.shape[0], "t"))
    dt = float(np.median(steps))
    return Y, (dt if np.max(np.abs(steps - dt)) <= 0.01 * dt else None)


def _estimate_channel(col, j, method, order, segment_length, n_bands, sampling):
    """Diagnostics of one channel.

    ``sampling`` is (sampling rate, unit) or None when the sampling is not
    uniform (then only differences apply).
    """
    runs = _nan_free_runs(col)
    n_obs = sum(b - a for a, b in runs)
    if n_obs <= order + 5:
        raise ValueError(
            f"y channel {j} has {n_obs} observed samples; the noise "
            f"variance needs more than {order + 5}"
        )
    nperseg = None
    if method != "difference" and sampling is not None:
        nperseg = _choose_segment_length(runs, segment_length)
        if nperseg is not None:
            return _spectral_channel(col, runs, j, nperseg, n_bands, *sampling)
    if sampling is None:
        why = "t is not uniformly spaced"
    else:
        why = (
            f"fewer than {_MIN_SEGMENTS} NaN-free stretches of "
            f"{segment_length or _MIN_SEGMENT} samples"
        )
    if method == "spectral":
        raise ValueError(f"method='spectral' cannot be used on y channel {j}: {why}")
    unit = "Hz" if sampling is None else sampling[1]  # None: t was given
    fallback = "" if method == "difference" else why
    return _difference_channel(col, runs, j, order, unit, fallback)


def _nan_free_runs(col):
    """(start, stop) of every maximal NaN-free stretch of ``col``."""
    ok = np.concatenate(([False], ~np.isnan(col), [False]))
    edges = np.flatnonzero(np.diff(ok.astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _choose_segment_length(runs, requested):
    """Segment length (module constants) giving _MIN_SEGMENTS segments, or None."""

    def count(n):
        return sum((b - a) // n for a, b in runs)

    if requested is not None:
        return int(requested) if count(requested) >= _MIN_SEGMENTS else None
    n_obs = sum(b - a for a, b in runs)
    n = 2 ** int(np.round(np.log2(max(n_obs / _TARGET_SEGMENTS, 1.0))))
    n = int(min(max(n, _MIN_SEGMENT), _MAX_SEGMENT))
    while n >= _MIN_SEGMENT:
        if count(n) >= _MIN_SEGMENTS:
            return n
        n //= 2
    return None


def _spectra(col, runs, nperseg):
    """Windowed DFT of every segment, bins 3 .. N/2-2, shape (K, bins).

    Scaled so that for white noise of variance s2, ``2 Re^2`` and ``2 Im^2``
    both have expectation s2 in every returned bin (so does ``|X|^2``). Each
    segment loses its mean and its trend against ``s(n) = n - N/2`` (with
    ``s(0) = 0``): both regressors, like the periodic Hann window, are
    symmetric or antisymmetric under ``n -> N - n``, so the real parts (cosine
    sums) and imaginary parts (sine sums) of white noise stay uncorrelated
    across all bins, hence independent when the noise is Gaussian.
    """
    starts = [a + i * nperseg for a, b in runs for i in range((b - a) // nperseg)]
    seg = col[np.asarray(starts)[:, None] + np.arange(nperseg)]
    n = np.arange(nperseg)
    slope = np.where(n == 0, 0.0, n - nperseg / 2.0)
    seg = seg - seg.mean(axis=1, keepdims=True)
    seg = seg - np.outer(seg @ slope / (slope @ slope), slope)
    window = 0.5 - 0.5 * np.cos(2.0 * np.pi * n / nperseg)
    # Bin N/2-1 is left out: there Re and Im have unequal variances.
    spec = np.fft.rfft(seg * window, axis=1)[:, _FIRST_BIN : nperseg // 2 - 1]
    return spec / np.sqrt(np.sum(window**2))


def _spectral_channel(col, runs, j, nperseg, n_bands, fs, unit):
    """The spectral-floor estimate of one channel (module docstring)."""
    spec = _spectra(col, runs, nperseg)
    K = spec.shape[0]
    P = np.mean(spec.real**2 + spec.imag**2, axis=0)
    kept, bands_flat = _floor(P, 2 * K, n_bands)
    variance, rel_se = _cross_fitted_level(spec, n_bands)
    freq = (kept + _FIRST_BIN) * fs / nperseg
    band = (float(freq.min()), float(freq.max()))
    observed = np.concatenate([col[a:b] for a, b in runs])
    # Signal below the analysed bins (slow drifts, trends) shows in the
    # record's variance though not in the band medians.
    se_total = np.sqrt(_median_se(2 * K, kept.size) ** 2 + 2.0 / observed.size)
    quiet = observed.var() <= variance * (1.0 + 4.0 * se_total)
    reason = ""
    if variance == 0.0:
        reason = "the channel is constant on every segment"
    elif bands_flat and quiet:
        reason = _FLAT
    elif kept.size < _MIN_FLOOR_BINS:
        reason = (
            f"the floor region ({band[0]:.4g}-{band[1]:.4g} {unit}) holds only "
            f"{kept.size} frequency bins, too few to exclude leakage from the "
            "signal next to it (a longer record resolves it); the estimate is an "
            "upper bound on the noise"
        )
    elif _sloped(P[kept], 2 * K):
        reason = (
            f"the spectrum still falls or rises within its floor region "
            f"({band[0]:.4g}-{band[1]:.4g} {unit}): no white-noise plateau was "
            "reached, so the estimate is an upper bound on the noise"
        )
    return NoiseDiagnostics(
        channel=j,
        variance=float(variance),
        method="spectral",
        band=band,
        band_fraction=kept.size / P.size,
        unit=unit,
        segment_length=nperseg,
        n_segments=K,
        relative_se=rel_se,
        reliable=not reason,
        reason=reason,
    )


def _cross_fitted_level(spec, n_bands):
    """Level of the floor (and its relative se), free of the bias of picking it.

    Choosing the floor as the lowest part of a noisy spectrum and reading its
    level from the same ordinates biases the level low: bands that hold some
    signal join the floor when their noise happens to be low (measured: 9 %
    low at 8 segments on the signal rich near Nyquist). So the floor is
    chosen on the real parts and read on the imaginary parts, and the other
    way round, and the two readings are averaged. For Gaussian white noise the
    two are independent (see :func:`_spectra`), so each reading is unbiased
    once divided by the median of ``chi2(K) / K``; yet both see the same
    segments, so a signal that changes over the record (a chirp) looks alike
    in both, which a split of the segments in time would not give. The pick
    is stricter than the reported floor (``_Z_PICK``, ``_Z_TRIM``): leaving a
    band out here costs precision, taking in a band with signal costs bias.
    """
    K = spec.shape[0]
    parts = (np.mean(2.0 * spec.real**2, axis=0), np.mean(2.0 * spec.imag**2, axis=0))
    correction = stats.chi2.median(K) / K
    levels, ses = [], []
    for pick, read in (parts, parts[::-1]):
        kept = _floor(pick, K, n_bands, _Z_PICK, _Z_TRIM)[0]
        levels.append(np.median(read[kept]) / correction)
        ses.append(_median_se(K, kept.size))
    return float(np.mean(levels)), float(np.hypot(*ses) / 2.0)


def _floor(P, dof, n_bands, z_band=None, z_half=None):
    """Bins of the floor region and whether all bands agree.

    ``P`` holds averaged ordinates with ``dof`` degrees of freedom each. Bands
    whose median is within ``_Z`` standard errors of the lowest one form the
    floor. Each floor band is then halved and a half whose median lies
    significantly above the pooled level (one-sided, Bonferroni ``_ALPHA``) is
    dropped: the edge of a signal band that reaches into a floor band.
    """
    bands = np.array_split(np.arange(P.size), min(n_bands, P.size // 6))
    med = np.array([np.median(P[b]) for b in bands])
    se = np.array([_median_se(dof, b.size) for b in bands])
    low = int(np.argmin(med))
    z_band = _Z if z_band is None else z_band
    in_floor = med <= med[low] * (1.0 + z_band * np.sqrt(se**2 + se[low] ** 2))
    if med[low] > 0.0:  # compared on a log scale, where a band median is ~normal
        flat = np.log(med.max() / med[low]) <= _flat_range(len(bands)) * se.max()
    else:
        flat = med.max() == 0.0
    halves = [h for b, f in zip(bands, in_floor) if f for h in np.array_split(b, 2)]
    pooled = np.median(P[np.concatenate(halves)])
    z = stats.norm.isf(_ALPHA / len(halves)) if z_half is None else z_half
    h_med = np.array([np.median(P[h]) for h in halves])
    h_se = np.array([_median_se(dof, h.size) for h in halves])
    keep = h_med <= pooled * (1.0 + z * h_se)
    keep[np.argmin(h_med)] = True
    return np.concatenate([h for h, k in zip(halves, keep) if k]), bool(flat)


def _flat_range(n_bands):
    """Upper ``_ALPHA`` quantile of the range of ``n_bands`` standard normals.

    The band medians of white noise scatter like independent normals with the
    standard errors of :func:`_median_se`; a spread beyond this quantile means
    that some band holds more than noise.
    """
    return float(stats.studentized_range.ppf(1.0 - _ALPHA, n_bands, np.inf))


def _median_se(dof, n_bins):
    """Relative standard error of the median of ``n_bins`` averaged ordinates.

    Each ordinate (``chi2(dof) / dof`` times the level) has relative sd
    ``sqrt(2 / dof)``; the sample median of ``m`` values has ``sqrt(pi / 2)``
    times the sd of their mean, which the Hann window's neighbour correlation
    inflates by ``sqrt(1.944)``.
    """
    return np.sqrt(np.pi * _HANN_VARIANCE_INFLATION / (dof * n_bins))


def _sloped(ordinates, dof):
    """True when the lower- and upper-frequency halves differ in level.

    Ordinates in frequency order; medians (robust to spectral lines) of the
    two halves are compared at the two-sided ``_ALPHA`` level.
    """
    lo, hi = np.array_split(ordinates, 2)
    level = np.median(ordinates)
    if lo.size < 3 or level == 0.0:
        return False
    se = np.sqrt(_median_se(dof, lo.size) ** 2 + _median_se(dof, hi.size) ** 2)
    return abs(np.median(lo) - np.median(hi)) > stats.norm.isf(_ALPHA / 2) * se * level


def _difference_variance(col, runs, order):
    """Mean square ``order``-th difference within runs over C(2 order, order).

    Returns (estimate, relative standard error for Gaussian white noise) or
    (None, None) when no run is longer than ``order``. The differenced noise
    has autocorrelation ``(-1)^l C(2k, k+l) / C(2k, k)`` at lag ``l``, so the
    mean of its ``m`` squares has relative variance ``2 sum_l rho_l^2 / m``.
    """
    total, count = 0.0, 0
    for a, b in runs:
        if b - a > order:
            d = np.diff(col[a:b], n=order)
            total += float(d @ d)
            count += d.size
    if not count:
        return None, None
    c = comb(2 * order, order)
    rho2 = sum(
        (comb(2 * order, order + lag) / c) ** 2 for lag in range(-order, order + 1)
    )
    return total / count / c, float(np.sqrt(2.0 * rho2 / count))


def _difference_channel(col, runs, j, order, unit, fallback):
    """Difference estimate of one channel, checked against twice the order.

    For white noise the estimates of orders ``order`` and ``2 order`` agree
    within a known scatter (:func:`_ratio_sd`); a signal that the order does
    not suppress shifts them apart (a smooth signal inflates lower orders
    more, so ``order / 2`` is not compared). A disagreement beyond the
    two-sided ``_ALPHA`` level marks the estimate unreliable; so does an
    estimate as large as the record's variance (nothing but noise seen).
    """
    variance, rel_se = _difference_variance(col, runs, order)
    if variance is None:
        raise ValueError(
            f"y channel {j} has no NaN-free stretch longer than order={order} samples"
        )
    n_terms = sum(b - a - 2 * order for a, b in runs if b - a > 2 * order)
    others = {}
    if n_terms > 0:
        others[2 * order] = _difference_variance(col, runs, 2 * order)[0]
    z = stats.norm.isf(_ALPHA / 2)
    off = {
        o: v
        for o, v in others.items()
        if variance > 0 and abs(v / variance - 1.0) > z * _ratio_sd(o, order, n_terms)
    }
    observed = np.concatenate([col[a:b] for a, b in runs])
    reason = ""
    if variance == 0.0:
        reason = "the channel is constant"
    elif variance >= observed.var() * (1.0 - 3.0 * rel_se):
        reason = _FLAT
    elif off:
        listed = ", ".join(
            f"order {o}: {v:.4g}"
            for o, v in sorted({**others, order: variance}.items())
        )
        reason = (
            f"difference estimators disagree ({listed}): the signal is not smooth "
            "on the sampling scale and inflates them; the estimate is an upper "
            "bound on the noise"
        )
    return NoiseDiagnostics(
        channel=j,
        variance=float(variance),
        method="difference",
        band=None,
        band_fraction=float("nan"),
        unit=unit,
        segment_length=0,
        n_segments=0,
        relative_se=rel_se,
        reliable=not reason,
        reason=reason,
        fallback=fallback,
    )


def _ratio_sd(a, b, m):
    """sd of the ratio of the order-``a`` and order-``b`` estimates, white noise.

    From the auto- and cross-correlations of the two difference filters
    (binomial coefficients with alternating signs) over ``m`` terms, by the
    delta method: ``2 / m * sum_l (r_aa^2 + r_bb^2 - 2 r_ab^2)``.
    """
    ca, cb = (
        np.array([(-1) ** (k - i) * comb(k, i) for i in range(k + 1)]) for k in (a, b)
    )
    na, nb = ca @ ca, cb @ cb
    raa = np.correlate(ca, ca, "full") / na
    rbb = np.correlate(cb, cb, "full") / nb
    rab = np.correlate(ca, cb, "full") / np.sqrt(na * nb)
    total = np.sum(raa**2) + np.sum(rbb**2) - 2.0 * np.sum(rab**2)
    return float(np.sqrt(2.0 * total / m))


# --------------------------------------------------------------------------
# what the user gives as the noise, and the classical difference estimate
# (one noise module: the spectral floor above, these two below)


def difference_noise_variance(y, order: int = 4) -> np.ndarray:
    """Noise variance of each column of ``y`` from its ``order``-th differences.

    For ``y_k = s(t_k) + v_k`` with white noise ``v`` and a signal ``s``
    that is smooth on the scale of the sampling, the ``order``-th difference
    is dominated by the noise, whose variance it multiplies by
    ``sum_j C(order, j)^2 = C(2 order, order)`` (70 for order 4). This is the
    classical difference-based variance estimator; it overestimates the noise
    when the signal is not well resolved by the sampling. Missing values
    (NaN) are skipped.

    Returns
    -------
    ndarray (n_columns,)
    """
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    out = np.empty(y.shape[1])
    for j in range(y.shape[1]):
        col = y[~np.isnan(y[:, j]), j]
        if col.size <= order + 5:
            raise ValueError(
                f"noise_variance='auto' needs more than {order + 5} observed "
                f"samples in measured channel {j}; got {col.size}. Give "
                "noise_variance explicitly."
            )
        out[j] = np.mean(np.diff(col, n=order) ** 2) / comb(2 * order, order)
    return out


def noise_covariance(noise_variance, m: int) -> np.ndarray:
    """The (m, m) noise covariance R from a variance, one per channel, or R.

    Raises ``ValueError`` naming ``noise_variance`` when it is not finite and
    positive (definite), or does not match the ``m`` measured channels.
    """
    arr = as_float_array(noise_variance, "noise_variance", ndim=(0, 1, 2))
    if arr.ndim == 0:
        check_positive_number(float(arr), "noise_variance")
        return float(arr) * np.eye(m)
    if arr.ndim == 1:
        if arr.size != m:
            raise ValueError(
                f"noise_variance has {arr.size} entries but there are {m} "
                "measured channels"
            )
        if np.any(arr <= 0):
            raise ValueError(f"noise_variance must be positive, got {arr.tolist()}")
        return np.diag(arr)
    if arr.shape != (m, m):
        raise ValueError(
            f"noise_variance must be ({m}, {m}) for {m} measured channels, "
            f"got shape {arr.shape}"
        )
    if not np.allclose(arr, arr.T):
        raise ValueError("noise_variance (covariance R) must be symmetric")
    try:
        np.linalg.cholesky(arr)
    except np.linalg.LinAlgError:
        raise ValueError(
            "noise_variance (covariance R) must be positive definite"
        ) from None
    return arr
