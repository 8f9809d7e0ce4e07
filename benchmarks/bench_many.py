"""Many studies at once: serial discover calls vs discover_many's engines.

Run: ``python benchmarks/bench_many.py [--records 50] [--workers 2] [--t-end 10]``

The paper's Van der Pol case (x1 at 40 Hz for ``t_end`` s, the hidden term
``x1^2 x2``), one record per seed, studied four ways: ``discover`` in a
loop; ``discover_many(n_jobs=1)`` (this process); ``discover_many(n_jobs=
workers)`` (local processes, joblib); and ``discover_many(client=...)`` on
a ``LocalCluster`` of ``workers`` worker processes on the loopback
interface. The engines that start processes run twice: "cold" includes
starting them and importing the package in each (the cluster's own
start-up is timed apart), "warm" reuses them (joblib keeps its
processes; the cluster stays up). Prints a markdown table: wall time,
speed-up over the loop, and whether every result is identical to the
loop's (terms, coefficients, standard errors, gains, simulations, summary
and report text, to the last bit). The assumed model is defined in
``__main__``, so it travels to the workers by value (cloudpickle).
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import numpy as np
import pysindy as ps

from pysindy_mme import discover, discover_many
from pysindy_mme.systems import van_der_pol


def vdp_assumed(x, t):
    """The paper's ignorance model ``x1' = x2, x2' = 0``."""
    return np.column_stack([x[:, 1], np.zeros(len(x))])


def keywords() -> dict:
    return dict(
        assumed_model=vdp_assumed,
        n_states=2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
        feature_library=ps.PolynomialLibrary(degree=3),
        options={"feature_names": ["x1", "x2"]},
    )


def identical(a, b) -> bool:
    """Two Discovery objects agree to the last bit."""
    return (
        a.to_dict() == b.to_dict()
        and a.param_names == b.param_names
        and np.array_equal(a.params, b.params)
        and np.array_equal(a.bse, b.bse, equal_nan=True)
        and a.gain.to_dict() == b.gain.to_dict()
        and np.array_equal(a.extended_simulation, b.extended_simulation)
        and str(a.summary()) == str(b.summary())
        and str(a) == str(b)
    )


def timed(run):
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = run()
    return out, time.perf_counter() - start


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--records", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--t-end", type=float, default=10.0)
    args = parser.parse_args(argv)
    system = van_der_pol()
    grid = system.time(t_end=args.t_end)
    records = [
        (d.y, d.t) for d in (system.measure(s, t=grid) for s in range(args.records))
    ]
    serial, t_serial = timed(lambda: [discover(y, t, **keywords()) for y, t in records])
    rows = [("`discover` in a loop", "", t_serial, True)]
    many = dict(progress=False, **keywords())
    out, seconds = timed(lambda: discover_many(records, n_jobs=1, **many))
    rows.append(("`discover_many(n_jobs=1)`", "", seconds, out))
    for warm in ("cold", "warm"):
        out, seconds = timed(
            lambda: discover_many(records, n_jobs=args.workers, **many)
        )
        rows.append(
            (f"`discover_many(n_jobs={args.workers})`, {warm}", "", seconds, out)
        )
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        print("(no LocalCluster row: pip install pysindy-mme[distributed])")
    else:
        start = time.perf_counter()
        with (
            LocalCluster(
                n_workers=args.workers,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address=None,
            ) as cluster,
            Client(cluster) as client,
        ):
            started = f"{time.perf_counter() - start:.1f}"
            for warm in ("cold", "warm"):
                out, seconds = timed(
                    lambda: discover_many(records, client=client, **many)
                )
                name = f"`discover_many(client=)`, LocalCluster of {args.workers}"
                rows.append((f"{name}, {warm}", started, seconds, out))
                started = ""
    exact = sum(set(r.terms.get("x2", {})) == {"x1", "x2", "x1^2 x2"} for r in serial)
    print(
        f"\n{args.records} records of the paper's Van der Pol case "
        f"({grid.size} samples each); exact terms in {exact}/{args.records}; "
        f"{os.cpu_count()} cores, load average {os.getloadavg()[1]:.1f} over "
        "the last 5 minutes (other work on the machine slows the parallel rows "
        "most)\n"
    )
    print(
        "| engine | cluster start-up (s) | time (s) | per study (ms) | speed-up "
        "| identical |"
    )
    print("|---|---|---|---|---|---|")
    for name, started, seconds, out in rows:
        same = out is True or all(identical(a, b) for a, b in zip(serial, out))
        print(
            f"| {name} | {started or '-'} | {seconds:.1f} | "
            f"{1000 * seconds / args.records:.0f} | {t_serial / seconds:.2f}x | "
            f"{'yes' if same else 'NO'} |"
        )


if __name__ == "__main__":
    main()
