"""MME speed and memory against the number of samples, and two baselines.

The paper's Van der Pol case (ignorance model x1' = x2, x2' = d, only x1
measured, noise variance 0.01, 40 Hz) on records of 10^3 ... 10^6 samples,
with W tuned by the covariance constraint (``W="auto"``, the default).
One long trajectory is simulated once and its prefixes are used, so every
size sees the same kind of data.

Baselines on the same data: pysindy's ``SmoothedFiniteDifference``
(Savitzky-Golay, window 11, order 3) and the ``derivative`` package's Kalman
smoother through ``ps.SINDyDerivative(kind="kalman", alpha=R * W_)`` -- the
continuous-time twin of MME with the same weight. Both estimate x2 as the
derivative of their smoothed x1. ``derivative``'s Kalman builds and solves a
dense 2N x 2N system (O(N^3) time, O(N^2) memory), so it is run only where
that is affordable.

Run: ``python benchmarks/bench_mme.py`` (about two minutes, most of it the
10^6-sample simulation). Targets: 10^5 samples in < 3 s; time and memory
linear (10x samples within 12x time).
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np
import pysindy as ps

from pysindy_mme import MME
from pysindy_mme.systems import van_der_pol

R = 0.01
RATE = 40.0


def ignorance_model(x, t):
    return np.column_stack([x[:, 1], np.zeros(len(x))])


def make_data(n_max: int, seed: int = 0):
    system = van_der_pol()
    t = np.arange(n_max) / RATE
    x = system.simulate(t)
    rng = np.random.default_rng(seed)
    y = x[:, :1] + np.sqrt(R) * rng.standard_normal((n_max, 1))
    return t, x, y


def run_mme(t, y):
    mme = MME(ignorance_model, 2, measured=[0], noise_variance=R, error_states=[1])
    start = time.perf_counter()
    mme.fit(y, t)
    return mme, time.perf_counter() - start


def peak_memory(fn):
    """Peak bytes allocated (numpy arrays included) while ``fn`` runs."""
    tracemalloc.start()
    tracemalloc.reset_peak()
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak


def timed(fn, repeat=1):
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return out, best


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--sizes",
        type=int,
        nargs="+",
        default=[1_000, 10_000, 100_000, 1_000_000],
    )
    parser.add_argument("--kalman-max", type=int, default=2_000)
    args = parser.parse_args(argv)
    sizes = sorted(args.sizes)

    t0 = time.perf_counter()
    t_all, x_all, y_all = make_data(sizes[-1])
    print(f"simulated {sizes[-1]} samples in {time.perf_counter() - t0:.1f} s\n")

    rows, base_rows = [], []
    for n in sizes:
        t, x, y = t_all[:n], x_all[:n], y_all[:n]
        run_mme(t, y)  # warm-up (imports, first-touch memory)
        results = [run_mme(t, y) for _ in range(3 if n <= 100_000 else 1)]
        mme = results[0][0]
        sec = min(r[1] for r in results)
        mem = peak_memory(lambda t=t, y=y: run_mme(t, y))
        e = mme.smoothed_x_ - x
        rows.append(
            dict(
                n=n,
                sec=sec,
                mem=mem,
                it=mme.n_iter_total_,
                nW=len(mme.W_history_),
                W=mme.W_,
                ratio=mme.covariance_ratio_[0],
                x1=np.var(e[:, 0]),
                x2=np.var(e[:, 1]),
            )
        )

        sfd = ps.SmoothedFiniteDifference()
        xdot, s_sfd = timed(lambda y=y, t=t, sfd=sfd: sfd._differentiate(y, t))
        base_rows.append(
            dict(
                n=n,
                method="SmoothedFiniteDifference",
                sec=s_sfd,
                x1=np.var(sfd.smoothed_x_[:, 0] - x[:, 0]),
                x2=np.var(xdot[:, 0] - x[:, 1]),
            )
        )
        if n <= args.kalman_max:
            kal = ps.SINDyDerivative(kind="kalman", alpha=R * mme.W_)
            xdot, s_kal = timed(lambda y=y, t=t, kal=kal: kal._differentiate(y, t))
            base_rows.append(
                dict(
                    n=n,
                    method=f"derivative Kalman (alpha = R W_ = {R * mme.W_:.3g})",
                    sec=s_kal,
                    x1=np.var(kal.smoothed_x_[:, 0] - x[:, 0]),
                    x2=np.var(xdot[:, 0] - x[:, 1]),
                )
            )
        else:
            base_rows.append(
                dict(
                    n=n,
                    method="derivative Kalman: not run (dense 2N x 2N solve, "
                    f"{(2 * n) ** 2 * 8 / 1e9:.1f} GB)",
                    sec=np.nan,
                    x1=np.nan,
                    x2=np.nan,
                )
            )
        r = rows[-1]
        print(
            f"n = {n}: {r['sec']:.3f} s, peak {r['mem'] / 1e6:.1f} MB, "
            f"{r['it']} Gauss-Newton iterations over {r['nW']} W values",
            flush=True,
        )

    print("\n## MME (W='auto'), Van der Pol, 40 Hz, x1 measured\n")
    print(
        "| samples | time (s) | us/sample | peak memory (MB) | bytes/sample "
        "| GN iterations | W evaluations | W | cov. ratio | var x1 err "
        "| var x2 err |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['n']:,} | {r['sec']:.3f} | {1e6 * r['sec'] / r['n']:.2f} "
            f"| {r['mem'] / 1e6:.1f} | {r['mem'] / r['n']:.0f} | {r['it']} "
            f"| {r['nW']} | {r['W']:.3g} | {r['ratio']:.4f} | {r['x1']:.2e} "
            f"| {r['x2']:.2e} |"
        )
    print("\n## Baselines on the same data\n")
    print("| samples | method | time (s) | var x1 err | var x2 err |")
    print("|---:|---|---:|---:|---:|")
    for r in base_rows:
        sec = "-" if np.isnan(r["sec"]) else f"{r['sec']:.3f}"
        x1 = "-" if np.isnan(r["x1"]) else f"{r['x1']:.2e}"
        x2 = "-" if np.isnan(r["x2"]) else f"{r['x2']:.2e}"
        print(f"| {r['n']:,} | {r['method']} | {sec} | {x1} | {x2} |")

    print("\n## Targets\n")
    by_n = {r["n"]: r for r in rows}
    if 100_000 in by_n:
        sec = by_n[100_000]["sec"]
        print(
            f"- 10^5 samples in {sec:.2f} s (target < 3 s): "
            f"{'met' if sec < 3 else 'MISSED'}"
        )
    for a, b in zip(rows[:-1], rows[1:], strict=True):
        grow = b["sec"] / a["sec"]
        mem = b["mem"] / a["mem"]
        ok = "met" if grow <= 12 * b["n"] / a["n"] / 10 else "MISSED"
        print(
            f"- {a['n']:,} -> {b['n']:,} samples: time x{grow:.1f}, memory "
            f"x{mem:.1f} (linear: time within 12x per 10x samples): {ok}"
        )


if __name__ == "__main__":
    main()
