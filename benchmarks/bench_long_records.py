"""The study at the length of real measurements (issue 9).

The paper's Van der Pol case (x1 measured, noise variance 0.01, ignorance
model, ``PolynomialLibrary(3)``) at 40 Hz over 10, 100, 1,000 and 10,000 s
(401 to 400,001 samples; and 2,500 s: 100,001 samples), and over 10 s at
40 Hz to 40 kHz. For every record
length: the whole ``discover`` time and, on the same data in the same run,
MME alone; peak memory of one study (``tracemalloc``: numpy allocations);
exact terms (seeds: 20 up to 4,001 samples, 5 beyond); the median largest
coefficient error over the exact seeds.

Run: ``python benchmarks/bench_long_records.py`` (about 15 minutes on 2
cores; ``--quick`` for the first three rows only). Prints a markdown table
and the targets of issue 9.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc
import warnings

import numpy as np
import pysindy as ps

from pysindy_mme import MME, StudyOptions, discover
from pysindy_mme.systems import van_der_pol

TRUE = {"x1": -1.0, "x2": 1.0, "x1^2 x2": -1.0}
CASES = [  # (seconds, Hz)
    (10, 40),
    (100, 40),
    (10, 400),
    (1_000, 40),
    (10, 4_000),
    (2_500, 40),
    (10_000, 40),
    (10, 40_000),
]


def study(y, t, system):
    return discover(
        y,
        t,
        assumed_model=system.assumed_model,
        n_states=2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
        feature_library=ps.PolynomialLibrary(degree=3),
        options=StudyOptions(feature_names=["x1", "x2"]),
    )


def mme_alone(y, t, system):
    return MME(
        system.assumed_model, 2, measured=[0], noise_variance=0.01, error_states=[1]
    ).fit(y, t)


def timed(fn):
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start


def run_case(seconds, rate, n_seeds):
    system = van_der_pol()
    t = system.time(seconds, rate)
    exact, errors, t_study, t_mme = 0, [], [], []
    for seed in range(n_seeds):
        data = system.measure(seed, t=t)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res, sec = timed(lambda data=data: study(data.y, data.t, system))
            _, sec_mme = timed(lambda data=data: mme_alone(data.y, data.t, system))
        t_study.append(sec)
        t_mme.append(sec_mme)
        found = res.terms["x2"]
        if set(found) == set(TRUE):
            exact += 1
            errors.append(max(abs(found[k] - v) for k, v in TRUE.items()))
    data = system.measure(0, t=t)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tracemalloc.start()
        study(data.y, data.t, system)
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    return {
        "seconds": seconds,
        "rate": rate,
        "n": t.size,
        "seeds": n_seeds,
        "exact": exact,
        "error": float(np.median(errors)) if errors else float("nan"),
        "time": float(np.median(t_study)),
        "mme": float(np.median(t_mme)),
        "peak": peak,
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="first three rows")
    args = parser.parse_args(argv)
    cases = CASES[:3] if args.quick else CASES
    rows = []
    for seconds, rate in cases:
        n = int(round(seconds * rate)) + 1
        row = run_case(seconds, rate, 20 if n <= 4_001 else 5)
        rows.append(row)
        print(
            f"{row['n']:>8} samples: {row['time']:.2f} s/study, MME {row['mme']:.2f} s,"
            f" exact {row['exact']}/{row['seeds']}",
            flush=True,
        )
    print(
        "\n| record | samples | exact terms | median largest coef. error | s / study "
        "| MME alone (s) | study / MME | peak MB |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['seconds']:,} s at {r['rate']:,} Hz | {r['n']:,} | "
            f"{r['exact']}/{r['seeds']} | {r['error']:.4f} | {r['time']:.2f} | "
            f"{r['mme']:.2f} | {r['time'] / r['mme']:.1f} | {r['peak']:.0f} |"
        )
    by_n = {r["n"]: r for r in rows}
    print("\nTargets (issue 9):")
    print(f"- exact terms in every seed: {all(r['exact'] == r['seeds'] for r in rows)}")
    if 40_001 in by_n:
        print(
            "- coefficient error at 40,001 samples (<= 0.01): "
            f"{by_n[40_001]['error']:.4f}"
        )
    growth = [
        (a["n"], b["n"], b["time"] / a["time"])
        for a in rows
        for b in rows
        if a["rate"] == b["rate"] == 40
        and b["n"] == 10 * a["n"] - 9
        and a["n"] >= 4_001
    ]
    for a, b, g in growth:
        print(f"- time growth {a:,} -> {b:,} samples: x{g:.1f} (target <= 12)")
    if 100_001 in by_n:
        r = by_n[100_001]
        print(
            f"- 100,001 samples: {r['time']:.1f} s (<= 15), "
            f"{r['time'] / r['mme']:.1f}x MME (<= 15)"
        )


if __name__ == "__main__":
    main()
