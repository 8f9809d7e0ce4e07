"""Noise-variance estimators on signals that are smooth, coloured, rich near Nyquist.

Compares the 4th-difference estimator MME used until now
(``difference_noise_variance``), differences of other orders, a
Savitzky-Golay residual, two periodogram statistics over the whole frequency
axis, and :func:`pysindy_mme.core.noise.estimate_noise_variance` (the spectral
floor). Synthetic cases: white noise of sd 1 added to a signal; each cell is
the estimated / true variance, mean over seeds [min, max]. Then the Silverbox
record (``../shared/data/silverbox``, Wigren and Schoukens 2013), arrow and
multisine parts of the output V2, as noise sd in mV.

Run: ``nice -n 10 python benchmarks/bench_noise.py [--seeds 8] [--n 16384]``
"""

from __future__ import annotations

import argparse
import time
import warnings
from math import comb
from pathlib import Path

import numpy as np
from scipy import signal, stats

from pysindy_mme.core.noise import estimate_noise_variance

SILVERBOX = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "silverbox"


# --- signals (sd-1 white noise is added by the caller) -----------------------


def white(n, rng):
    """No signal at all."""
    return np.zeros(n)


def smooth(n, rng):
    """Three slow sinusoids, rms about 12 (frequencies below 0.02 fs)."""
    k = np.arange(n)
    f = rng.uniform(0.002, 0.02, 3)
    ph = rng.uniform(0, 2 * np.pi, 3)
    return 10.0 * np.sin(2 * np.pi * f[:, None] * k + ph[:, None]).sum(axis=0)


def nyquist_rich(n, rng):
    """20 sinusoids in [0.01, 0.45] fs (one at 0.45) and a chirp 0.02-0.45 fs.

    Signal rms about 10: the noise is 1 % of the record's power.
    """
    k = np.arange(n)
    f = np.append(rng.uniform(0.01, 0.45, 19), 0.45)
    ph = rng.uniform(0, 2 * np.pi, 20)
    lines = 2.0 * np.sin(2 * np.pi * f[:, None] * k + ph[:, None]).sum(axis=0)
    chirp = 6.0 * signal.chirp(k, f0=0.02, t1=n - 1, f1=0.45, phi=rng.uniform(0, 360))
    return lines + chirp


def resonant(n, rng):
    """AR(2) resonance at 0.1 fs (pole radius 0.98), rms 10: coloured to Nyquist."""
    r, theta = 0.98, 2 * np.pi * 0.1
    s = signal.lfilter(
        [1.0], [1.0, -2 * r * np.cos(theta), r * r], rng.standard_normal(n)
    )
    return 10.0 * s / s.std()


def lowpass(n, rng):
    """White noise through a 4th-order Butterworth low-pass at 0.2 fs, rms 10."""
    b, a = signal.butter(4, 0.4)
    s = signal.lfilter(b, a, rng.standard_normal(n + 200))[200:]
    return 10.0 * s / s.std()


def random_walk(n, rng):
    """Brownian motion with step sd 0.3: spectrum falling as 1/f^2 to Nyquist."""
    return np.cumsum(0.3 * rng.standard_normal(n))


def white_signal(n, rng):
    """A signal that is itself white (sd 3): indistinguishable from noise."""
    return 3.0 * rng.standard_normal(n)


CASES = [white, smooth, nyquist_rich, resonant, lowpass, random_walk, white_signal]


def _resonant_floor():
    """Lowest spectral level of the resonant signal (variance 100) over frequency."""
    r, theta = 0.98, 2 * np.pi * 0.1
    a = [1.0, -2 * r * np.cos(theta), r * r]
    impulse = signal.lfilter([1.0], a, np.r_[1.0, np.zeros(20000)])
    _, h = signal.freqz([1.0], a, worN=np.linspace(0, np.pi, 4001))
    return 100.0 * np.min(np.abs(h) ** 2) / np.sum(impulse**2)


# The best any estimator of white noise can do: 1 + the signal's lowest spectral
# level (relative to the noise's), for an infinitely long record.
IDEAL = {
    "white": 1.0,
    "smooth": 1.0,
    "nyquist_rich": 1.0,
    "resonant": 1.0 + _resonant_floor(),
    "lowpass": 1.0,  # the Butterworth filter has a zero at Nyquist
    "random_walk": 1.0 + 0.09 / 4.0,  # step variance / |1 - e^{i pi}|^2
    "white_signal": 10.0,
}


# --- estimators ---------------------------------------------------------------


def difference(order):
    def est(y):
        return np.mean(np.diff(y, n=order) ** 2) / comb(2 * order, order)

    est.__name__ = f"diff{order}"
    return est


def savgol(y, window=9, degree=3):
    """Residual of a local cubic over 9 samples, divided by its dof factor 1 - h0."""
    h = signal.savgol_coeffs(window, degree)
    r = y[window // 2 : -(window // 2)] - np.convolve(y, h[::-1], mode="valid")
    return np.mean(r**2) / (1.0 - h[window // 2])


def _ordinates(y, nperseg):
    f, p = signal.welch(y, nperseg=nperseg, noverlap=0, window="hann", detrend="linear")
    return p[3:-1] / 2.0, len(y) // nperseg  # one-sided density -> variance level


def welch_median(y, nperseg=512):
    """Median over all frequencies of the averaged periodogram, chi2-corrected."""
    p, k = _ordinates(y, nperseg)
    return np.median(p) / (stats.chi2.median(2 * k) / (2 * k))


def welch_q10(y, nperseg=512):
    """10 % quantile over all frequencies, chi2-corrected."""
    p, k = _ordinates(y, nperseg)
    return np.quantile(p, 0.1) / (stats.chi2.ppf(0.1, 2 * k) / (2 * k))


def floor(y):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return float(estimate_noise_variance(y)[0])


ESTIMATORS = [difference(1), difference(2), difference(4), difference(8)]
ESTIMATORS += [savgol, welch_median, welch_q10, floor]


def synthetic_table(n, seeds):
    names = [e.__name__ for e in ESTIMATORS]
    print(f"estimated / true noise variance, n = {n}, {seeds} seeds: mean [min, max]")
    head = f"{'case':<13}{'ideal':>6}" + "".join(f"{m:>20}" for m in names)
    print(head + f"{'flagged':>9}")
    for case in CASES:
        ratios = np.empty((seeds, len(ESTIMATORS)))
        flagged = 0
        for s in range(seeds):
            rng = np.random.default_rng(1000 + s)
            y = case(n, rng) + rng.standard_normal(n)
            ratios[s] = [e(y) for e in ESTIMATORS]
            _, diag = estimate_noise_variance(y, warn=False, return_diagnostics=True)
            flagged += not diag[0].reliable
        cells = "".join(
            f"{m:>8.3g} [{lo:.3g}, {hi:.3g}]".rjust(20)
            for m, lo, hi in zip(ratios.mean(0), ratios.min(0), ratios.max(0))
        )
        ideal = IDEAL[case.__name__]
        print(f"{case.__name__:<13}{ideal:>6.3g}{cells}{flagged:>6}/{seeds}")
    print(
        "ideal: 1 + the signal's lowest spectral level relative to the noise's, "
        "what a perfect\nfloor estimate gives; flagged: runs of the new estimator "
        "marked not reliable"
    )


def silverbox_table():
    csv = SILVERBOX / "SNLS80mV.csv"
    if not csv.exists():
        print(f"\nSilverbox: {csv} not found, skipped")
        return
    data = np.loadtxt(csv, delimiter=",", skiprows=1, usecols=(0, 1))
    y = data[:, 1] - data[:, 1].mean()
    fs = 610.35
    parts = {
        "arrow [100, 40575)": slice(100, 40575),
        "multisine [40650, 127400)": slice(40650, 127400),
        "train [40650, 105712)": slice(40650, 105712),
    }
    print("\nSilverbox output V2, noise sd in mV (sqrt of the variance estimate)")
    names = [e.__name__ for e in ESTIMATORS]
    print(f"{'part':<27}" + "".join(f"{m:>13}" for m in names))
    for name, sl in parts.items():
        seg = y[sl]
        cells = "".join(f"{1e3 * np.sqrt(e(seg)):>13.4g}" for e in ESTIMATORS)
        print(f"{name:<27}{cells}")
    multisine_even_lines(data[:, 0] - data[:, 0].mean(), y, fs)
    print("\nspectral floor per part:")
    for name, sl in parts.items():
        _, (d,) = estimate_noise_variance(
            y[sl], 1.0 / fs, warn=False, return_diagnostics=True
        )
        print(
            f"  floor on {name}: sd {1e3 * np.sqrt(d.variance):.4g} mV, band "
            f"{d.band[0]:.1f}-{d.band[1]:.1f} Hz ({100 * d.band_fraction:.0f} % of the "
            f"axis), {d.n_segments} segments of {d.segment_length}, reliable="
            f"{d.reliable}: {d.reason or '-'}"
        )


def multisine_even_lines(u, y, fs):
    """A second look at the Silverbox noise, from the structure of its input.

    The estimation block holds 10 random-phase odd multisines of 8192 samples,
    each after 460 transient samples (record layout: 100 + 40400 samples
    before the first block of 460 + 8192 + 40). In steady state each
    realisation's output DFT holds the excited odd lines; the even lines
    hold only noise and even-order distortion. Printed: their level as the sd
    of a white noise with the same power, per band, median over realisations.
    """
    n = 8192
    rows = []
    for r in range(10):
        s = 100 + 40400 + r * (460 + n + 40) + 460
        U = np.fft.rfft(u[s : s + n])
        Y = np.fft.rfft(y[s : s + n])
        k = np.arange(U.size)
        excited = k[np.abs(U) ** 2 > 1e-2 * np.median(np.abs(U[1:2684:2]) ** 2)]
        band_top = excited.max()
        even = (k % 2 == 0) & (k > 2) & (k < band_top)
        odd_even = np.mean(np.abs(U[1:band_top:2]) ** 2) / np.mean(np.abs(U[even]) ** 2)
        edges = [3, 700, 1400, 2100, band_top, n // 2]
        levels = [
            np.sqrt(np.mean(np.abs(Y[(k >= a) & (k < b) & (k % 2 == 0)]) ** 2 / n))
            for a, b in zip(edges[:-1], edges[1:])
        ]
        rows.append([odd_even, band_top * fs / n, *levels])
    rows = np.median(np.array(rows), axis=0)
    edges_hz = [3, 700, 1400, 2100]
    labels = [
        f"{a * fs / n:.0f}-{b * fs / n:.0f} Hz" for a, b in zip(edges_hz, edges_hz[1:])
    ]
    labels += [
        f"{2100 * fs / n:.0f}-{rows[1]:.0f} Hz",
        f"{rows[1]:.0f}-{fs / 2:.0f} Hz",
    ]
    print(
        f"\nSilverbox multisines: input power odd/even lines {rows[0]:.3g} (alignment "
        f"check), excited up to {rows[1]:.1f} Hz;\nlevel of the output's even "
        "lines (noise + even distortion) as a white-noise sd in mV:"
    )
    print(
        "  " + "   ".join(f"{lab}: {1e3 * v:.3g}" for lab, v in zip(labels, rows[2:]))
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--n", type=int, default=16384)
    args = parser.parse_args()
    start = time.perf_counter()
    synthetic_table(args.n, args.seeds)
    silverbox_table()
    print(f"\n{time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
