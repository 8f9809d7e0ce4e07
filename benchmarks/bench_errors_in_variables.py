"""What misleads the selection at 5 % noise: the library, not the derivative.

On the drop-in benchmark's records (``bench_dropin.py``: full state, noise
relative to each state's standard deviation, ``SmoothedFiniteDifference``,
``PolynomialLibrary``), the default rule without the errors-in-variables
correction (``FloatingFStepwise(errors_in_variables=False)``) is given

* the benchmark's record: the library of the measured states and their
  smoothed derivatives;
* the library of the noise-free states, the same smoothed derivatives (the
  derivative's own error kept, the library's removed);
* the library of the measured states, the exact derivatives (the library's
  error kept, the derivative's removed);

and the default (``errors_in_variables="auto"``) the benchmark's record.
Cells count seeds with exactly the true support in every equation.

Run: ``python benchmarks/bench_errors_in_variables.py`` (about a minute;
``--seeds N``, ``--noise 0.05``).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pysindy as ps

sys.path.insert(0, str(Path(__file__).parent))
import bench_dropin as B  # noqa: E402

ROWS = ["Lorenz", "Rossler", "Chen", "Rikitake"]


def _exact(coef, truth) -> bool:
    return bool(np.array_equal(np.asarray(coef) != 0, truth != 0))


def run(names, level: float, seeds: int):
    from pysindy_mme.optimizers import FloatingFStepwise

    rows = []
    for name in names:
        index = [s.name for s in B.SYSTEMS].index(name)
        system = B.SYSTEMS[index]
        t, trajectories = B.simulate(system)
        truth = B.true_coefficients(system)
        counts = dict(measured=0, clean_library=0, exact_derivative=0, corrected=0)
        for seed in range(seeds):
            rng = np.random.default_rng([seed, int(level * 1e6)])
            parts = {key: ([], []) for key in counts}
            for x in trajectories:
                y = x + level * x.std(axis=0) * rng.standard_normal(x.shape)
                lib = ps.PolynomialLibrary(system.degree)
                measured = np.asarray(lib.fit(y).transform(y))
                clean = np.asarray(lib.fit(x).transform(x))
                smoothed = ps.SmoothedFiniteDifference()._differentiate(y, t)
                exact = clean @ truth.T  # the right-hand side at the true states
                for key, pair in dict(
                    measured=(measured, smoothed),
                    clean_library=(clean, smoothed),
                    exact_derivative=(measured, exact),
                    corrected=(measured, smoothed),
                ).items():
                    parts[key][0].append(pair[0])
                    parts[key][1].append(pair[1])
            for key, (thetas, dxs) in parts.items():
                mode = "auto" if key == "corrected" else False
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    opt = FloatingFStepwise(errors_in_variables=mode)
                    opt.fit(np.vstack(thetas), np.vstack(dxs))
                counts[key] += _exact(opt.coef_, truth)
        rows.append((name, counts))
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--noise", type=float, default=0.05)
    parser.add_argument("--systems", default=",".join(ROWS))
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    rows = run(args.systems.split(","), args.noise, args.seeds)
    print(
        f"noise {100 * args.noise:g} %, {args.seeds} seeds; exact supports "
        "(FloatingFStepwise(errors_in_variables=False) unless corrected)\n"
    )
    print(
        "| system | measured library, smoothed derivative (the benchmark) "
        "| noise-free library, smoothed derivative "
        "| measured library, exact derivative | corrected (the default) |"
    )
    print("|---|---:|---:|---:|---:|")
    for name, c in rows:
        print(
            f"| {name} | {c['measured']} | {c['clean_library']} | "
            f"{c['exact_derivative']} | {c['corrected']} |"
        )
    print(f"\n{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
