"""FloatingFStepwise against pysindy's STLSQ on a tall, narrow library.

Run: ``python benchmarks/bench_tall.py`` (``--rows 100000 1000000``,
``--repeats 3``, ``--threads 1`` to pin BLAS threads). Prints a markdown
table.

Full-state Lorenz (dt 0.002, one trajectory from (-8, 8, 27)), 1 % noise
(of each state's standard deviation), ``ps.SmoothedFiniteDifference()``,
``ps.PolynomialLibrary(2)`` (10 columns): the whole ``ps.SINDy(...).fit``
with ``FloatingFStepwise()`` and with ``STLSQ()``, timed in the same run
(interleaved repeats, best of each, so the machine's load cancels).
Target (issue 20): ``FloatingFStepwise`` within 3x ``STLSQ`` at 10^6
samples. From 20,000 rows such a library is selected from its moments
(``pysindy_mme/optimizers/moments.py``): two passes over the data, then
nothing per step that grows with the number of rows.

``--direct`` adds a column timing ``FloatingFStepwise`` with the moments
switched off (the selection on the data, as below 20,000 rows).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
import pysindy as ps
from scipy.integrate import solve_ivp

from pysindy_mme.optimizers import FloatingFStepwise

DT = 0.002
NOISE = 0.01
X0 = (-8.0, 8.0, 27.0)


def lorenz(t, x, sigma=10.0, rho=28.0, beta=8.0 / 3.0):
    return [
        sigma * (x[1] - x[0]),
        x[0] * (rho - x[2]) - x[1],
        x[0] * x[1] - beta * x[2],
    ]


def simulate(n: int) -> np.ndarray:
    t = np.arange(n) * DT
    sol = solve_ivp(
        lorenz, (0.0, t[-1]), X0, t_eval=t, method="DOP853", rtol=1e-11, atol=1e-12
    )
    if not sol.success:  # pragma: no cover - Lorenz is benign
        raise RuntimeError(sol.message)
    return sol.y.T


def true_support() -> np.ndarray:
    """The true terms in PolynomialLibrary(2), by exact least squares."""
    points = np.random.default_rng(0).standard_normal((400, 3)) * 3
    library = ps.PolynomialLibrary(degree=2).fit(points)
    rhs = np.array([lorenz(0.0, p) for p in points])
    coef = np.linalg.lstsq(library.transform(points), rhs, rcond=None)[0].T
    return np.abs(coef) > 1e-9


def sindy_fit(optimizer, x):
    model = ps.SINDy(
        optimizer=optimizer,
        feature_library=ps.PolynomialLibrary(degree=2),
        differentiation_method=ps.SmoothedFiniteDifference(),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.fit(x, t=DT)
    return model


def describe(model) -> str:
    """``x0' = x0 + x1; ...`` (the selected terms, not their coefficients)."""
    names = model.get_feature_names()
    out = []
    for i, row in enumerate(model.coefficients()):
        terms = " + ".join(names[j] for j in np.flatnonzero(row)) or "0"
        out.append(f"x{i}' = {terms}")
    return "; ".join(out)


def _direct():
    """FloatingFStepwise with the moments switched off (selection on the data)."""
    # Imported here so that the script also times versions without moments.
    from pysindy_mme.optimizers import moments as _moments

    class _Direct(FloatingFStepwise):
        def fit(self, x_, y, **kwargs):
            saved = _moments.MIN_ROWS
            _moments.MIN_ROWS = np.iinfo(np.int64).max
            try:
                return super().fit(x_, y, **kwargs)
            finally:
                _moments.MIN_ROWS = saved

    return _Direct()


def run(rows, repeats: int, direct: bool):
    truth = true_support()
    full = simulate(max(rows))
    results = []
    for n in rows:
        x = full[:n]
        rng = np.random.default_rng(n)
        x = x + NOISE * x.std(axis=0) * rng.standard_normal(x.shape)
        makers = {"stepwise": FloatingFStepwise, "stlsq": ps.STLSQ}
        if direct:
            makers["direct"] = _direct
        best = dict.fromkeys(makers, np.inf)
        models = {}
        for _ in range(repeats):  # interleaved: the machine's load cancels
            for label, make in makers.items():
                t0 = time.perf_counter()
                models[label] = sindy_fit(make(), x)
                best[label] = min(best[label], time.perf_counter() - t0)
        row = dict(rows=n, **best)
        for label, model in models.items():
            row[f"{label}_support"] = describe(model)
            row[f"{label}_exact"] = bool(
                np.array_equal(model.coefficients() != 0, truth)
            )
        results.append(row)
    return results


def print_table(results, direct: bool):
    head = "| rows | FloatingFStepwise (s) | STLSQ (s) | ratio |"
    rule = "| ---: | ---: | ---: | ---: |"
    if direct:
        head += " on the data (s) |"
        rule += " ---: |"
    print(head + " exact (ours / STLSQ) |")
    print(rule + " :---: |")
    for r in results:
        line = (
            f"| {r['rows']:,} | {r['stepwise']:.2f} | {r['stlsq']:.2f} | "
            f"{r['stepwise'] / r['stlsq']:.2f} |"
        )
        if direct:
            line += f" {r['direct']:.2f} |"
        exact = f"{'yes' if r['stepwise_exact'] else 'no'} / "
        exact += "yes" if r["stlsq_exact"] else "no"
        print(line + f" {exact} |")
    print()
    for r in results:
        print(f"- {r['rows']:,} rows, FloatingFStepwise: {r['stepwise_support']}")
        print(f"- {r['rows']:,} rows, STLSQ: {r['stlsq_support']}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--direct", action="store_true")
    parser.add_argument(
        "--threads", type=int, default=None, help="BLAS threads (default: as set)"
    )
    args = parser.parse_args(argv)
    if args.threads is not None:
        from threadpoolctl import threadpool_limits

        threadpool_limits(args.threads)
    print_table(run(args.rows, args.repeats, args.direct), args.direct)


if __name__ == "__main__":
    main()
