"""Machines with physical effects: simulations and studies (issue 19 onwards).

Run: ``python benchmarks/bench_physics.py [--quick] [--only NAME]``

Each section is a function in ``SECTIONS`` (name -> function of the parsed
arguments) that prints its own markdown table; ``--only NAME`` runs one
(repeatable), ``--quick`` asks every section for its short version.
To add a section (study rows for the positioning axis, the cascaded tanks):
write ``def my_section(args)`` printing a table, and register it in
``SECTIONS``.

Sections:

* ``simulate_sign`` - ``ExtendedModel.simulate`` with Coulomb friction
  ``sign(v)`` on a 25,000-sample record of the positioning axis (1 kHz,
  input held between samples): LSODA at ``rtol = 1e-9`` within a budget of
  evaluations, against fixed-step RK4 with 1, 2, 4 and 8 substeps; time and
  largest error against the exact solution. The model is the machine's own
  truth (``Fs = Fc``, so the exact solution is the sticking, Filippov,
  solution of the ``sign`` model), the library with exact kinks
  (``smoothing=0``), plus rows with the library's default smoothing where it
  has one. ``--quick``: 5,000 samples.
"""

from __future__ import annotations

import argparse
import inspect
import os
import re
import time
import warnings

import numpy as np

from pysindy_mme import DivergenceError, ExtendedModel, PhysicsLibrary
from pysindy_mme.feature_library import Coulomb
from pysindy_mme.machines import positioning_axis


def _table(header, rows):
    print("| " + " | ".join(header) + " |")
    print("|" + "|".join("---" if i == 0 else "---:" for i in range(len(header))) + "|")
    for row in rows:
        print("| " + " | ".join(row) + " |", flush=True)


# ---------------------------------------------------------------------------
# simulate_sign


def _axis_model(rec, machine, **library_options):
    """The axis' true model as an ExtendedModel: ``q' = v``,
    ``v' = (K_u u - c v)/M`` assumed, ``-Fc/M sign(v) + F0/M`` the correction."""
    p = machine.true_parameters
    M, c, K_u = p["M"], p["c"], p["K_u"]

    def assumed(x, t, u):
        return np.column_stack([x[:, 1], (K_u * u[:, 0] - c * x[:, 1]) / M])

    z = np.hstack([rec.x, rec.u])
    lib = PhysicsLibrary([Coulomb("v")], names=["q", "v", "u"], **library_options)
    return ExtendedModel(
        assumed,
        lib.fit(z),
        [[0.0], [-p["Fc"] / M]],
        ["q", "v"],
        ["u"],
        intercept=[0.0, p["F0"] / M],
        z_reference=z[:: max(1, z.shape[0] // 500)],
    )


def simulate_sign(args):
    n = 5_000 if args.quick else 25_000
    machine = positioning_axis(duration=n / 1000.0)
    rec = machine.record()
    exact = machine.simulate(rec.t, rec.u, rec.x[0])
    x0, t, u = rec.x[0], rec.t, rec.u
    budget = args.budget * t.size
    smoothing = "smoothing" in inspect.signature(PhysicsLibrary).parameters
    models = [
        (
            "exact sign",
            _axis_model(rec, machine, **({"smoothing": 0.0} if smoothing else {})),
        )
    ]
    if smoothing:
        default = inspect.signature(PhysicsLibrary).parameters["smoothing"].default
        models.append((f"smoothing={default:g}", _axis_model(rec, machine)))
    runs = []
    for label, em in models:
        runs.append((label, em, "LSODA", None))
        for substeps in (1, 2, 4, 8) if label == "exact sign" else (4,):
            runs.append((label, em, "rk4", substeps))
    rows = []
    for label, em, method, substeps in runs:
        options = dict(method=method, input_hold="zoh")
        if method == "rk4":
            options["substeps"] = substeps
            evaluations = f"{4 * substeps * (t.size - 1):,}"
        else:
            options["max_evaluations"] = budget
            evaluations = f"<= {budget:,}"
        start = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                x = em.simulate(x0, t, u, **options)
        except DivergenceError as exc:
            sec = time.perf_counter() - start
            stalled = re.search(r"model evaluations by t = (\S+)", str(exc))
            note = (
                f"did not finish in budget: reached t = {stalled.group(1)} of "
                f"{t[-1]:.4g} s"
                if stalled
                else f"diverged: {exc}"
            )
            rows.append([label, method, "", evaluations, f"{sec:.2f}", note, ""])
            continue
        sec = time.perf_counter() - start
        err = np.max(np.abs(x - exact), axis=0)
        rows.append(
            [
                label,
                method,
                "" if substeps is None else str(substeps),
                evaluations,
                f"{sec:.2f}",
                f"{err[0]:.2e}",
                f"{err[1]:.2e}",
            ]
        )
    print(
        f"\n## ExtendedModel.simulate with sign(v), {t.size:,} samples "
        f"(positioning axis, 1 kHz, u held; {os.cpu_count()} cores)\n"
    )
    _table(
        [
            "library",
            "method",
            "substeps",
            "model evaluations",
            "time (s)",
            "max error q (m)",
            "max error v (m/s)",
        ],
        rows,
    )
    print(
        f"\nErrors against the exact (sticking) solution; q spans "
        f"{np.ptp(exact[:, 0]):.3f} m, |v| reaches {np.max(np.abs(exact[:, 1])):.3f} "
        f"m/s. LSODA: rtol 1e-9, budget {args.budget} evaluations per sample."
    )


SECTIONS = {"simulate_sign": simulate_sign}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="short versions")
    parser.add_argument(
        "--only",
        action="append",
        choices=sorted(SECTIONS),
        metavar="NAME",
        help=f"run only this section (repeatable): {', '.join(SECTIONS)}",
    )
    parser.add_argument(
        "--budget",
        type=int,
        default=40,
        help="LSODA's budget of model evaluations per sample (default 40)",
    )
    args = parser.parse_args(argv)
    for name in args.only or list(SECTIONS):
        SECTIONS[name](args)


if __name__ == "__main__":
    main()
