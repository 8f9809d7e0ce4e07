"""Machines with physical effects: simulations and studies (issue 19 onwards).

Run: ``python benchmarks/bench_physics.py [--quick] [--only NAME]``

Each section is a function in ``SECTIONS`` (name -> function of the parsed
arguments) that prints its own markdown table; ``--only NAME`` runs one
(repeatable), ``--quick`` asks every section for its short version.
To add a section (study rows for the positioning axis, the cascaded tanks):
write ``def my_section(args)`` printing a table, and register it in
``SECTIONS``.

Sections:

* ``axis`` - issue 19 (1a): ``discover`` on the
  :func:`~pysindy_mme.machines.positioning_axis` with Coulomb friction 20 N
  and an offset of -3 N missing from the mass/viscous grey box (25 s at
  1 kHz, 50 nm encoder, the last fifth as the validation record), library
  ``PhysicsLibrary([Coulomb("v"), Stribeck("v", 0.02)], include_bias=True)``.
  Per seed: Coulomb and offset in newtons against the truth, mass, damping,
  other terms kept, conclusion, time; the count right (the criteria of
  ``tests/discovery/test_physics_axis.py``). ``--quick``: 3 seeds, 10 s.
* ``kinks`` - session 25: on the axis (and variants: mass, rate, noise,
  breakaway friction, a wrong fixed model), whether the misfit the extended
  model leaves is named the integration of the smoothed kinks or an effect
  the library lacks, with the share of the misfit left at half the width
  (``Discovery.kink_misfit``) and the rule's role for each row (set on it,
  run after it was set, held out). ``--quick``: the three rows it was set on.
* ``simulate_sign`` - ``ExtendedModel.simulate`` with Coulomb friction
  ``sign(v)`` on a 25,000-sample record of the positioning axis (1 kHz,
  input held between samples): LSODA at ``rtol = 1e-9`` within a budget of
  evaluations, against fixed-step RK4 with 1, 2, 4 and 8 substeps; time and
  largest error against the exact solution. The model is the machine's own
  truth (``Fs = Fc``, so the exact solution is the sticking, Filippov,
  solution of the ``sign`` model), the library with exact kinks
  (``smoothing=0``), plus rows with the library's default smoothing where it
  has one. ``--quick``: 5,000 samples.
* ``viscous_split`` - issue 19 (1c): ``discover`` on the
  :func:`~pysindy_mme.machines.asymmetric_damper` (damping 1.2 N s/m moving
  up, 0.6 moving down; multisine force held per sample; position at 100 Hz,
  noise 0.1 mm) with ``PhysicsLibrary([ViscousSplit("v"), Coulomb("v")])``;
  the assumed model's one damper ``c`` a grey-box parameter or fixed at
  0.9. Per seed: terms kept, the implied ``c_up = c - m a+`` and ``c_down =
  c - m a-`` against the truth, conclusion, time; and the count of seeds
  right (both within 5 %, no Coulomb, "explained"). ``--quick``: 3 seeds.
* ``friction_lookalikes`` - issue 19 (1d): the Coulomb-friction cases that
  offered a ``sign`` of every column (the adversarial oscillator, ``x2' =
  -x1 - 0.05 sign(x2)``, with ``1, x1, x2``; the positioning axis, grey-box
  ``M, c``, with a constant), with that ``CustomLibrary`` ("sign of all")
  and with ``PhysicsLibrary`` on the velocity only ("Coulomb(v)"). Per
  seed: terms kept, the Coulomb coefficient against the truth, look-alikes
  kept, conclusion, time; and the counts. ``--quick``: 2 seeds.
* ``tanks`` - issue 19 (1b): ``discover`` on the
  :func:`~pysindy_mme.machines.cascaded_tanks` (Torricelli outflows, the
  upper tank overflowing at 10 V, only ``h2`` measured by a clipping 12-bit
  sensor, 4096 s at 0.25 Hz) with the LINEAR assumed model (grey-box ``a1,
  b, a2, a3``) and ``PhysicsLibrary([Torricelli("h1"), Torricelli("h2"),
  Overflow("h1", [6, 8, 10, 12, 14])])`` in both equations; pump held
  (``input_hold="zoh"``), noise variance from the sensor (0.02^2 plus the
  ADC's step^2/12), clipping censored by the default ``clipped="auto"``,
  the record of seed ``1000 + s`` as the test record. Per seed: terms kept,
  the scale-free products ``c11 c21`` (truth ``-k1^2``) and ``c22`` (truth
  ``-k2`` when the linear ``a3`` absorbs nothing), conclusion, test-record
  free-run RMSE of the extended, the true (from the true initial state) and
  the assumed model, time; and the counts of seeds with the square-root law
  in both equations (signs right), saturation named (an ``over`` term or a
  "may saturate" line), and the test RMSE within 1.5x the true model's
  (the criteria of ``tests/discovery/test_physics_tanks.py``).
  ``--quick``: 3 seeds.
"""

from __future__ import annotations

import argparse
import inspect
import os
import re
import time
import warnings

import numpy as np
import pysindy as ps

from pysindy_mme import (
    MME,
    DivergenceError,
    ExtendedModel,
    PhysicsLibrary,
    StudyOptions,
    discover,
)
from pysindy_mme.core.model import simulate_model
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.feature_library import (
    Coulomb,
    Overflow,
    Stribeck,
    Torricelli,
    ViscousSplit,
)
from pysindy_mme.machines import asymmetric_damper, cascaded_tanks, positioning_axis


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


# ---------------------------------------------------------------------------
# viscous_split


def _quiet_discover(y, t, **options):
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = discover(y, t, **grouped_keywords(options))
    return res, time.perf_counter() - start


def _terms_text(res):
    kept = [
        f"{name} in {state}' = {value:+.4g}"
        for state, terms in res.terms.items()
        for name, value in terms.items()
    ]
    return ", ".join(kept) or "none"


def viscous_split(args):
    machine = asymmetric_damper()
    p = machine.true_parameters
    m, c_up, c_down = p["m"], p["c_up"], p["c_down"]
    c_fixed = 0.5 * (c_up + c_down)
    seeds = range(3 if args.quick else 10)
    for grey_box in (True, False):
        rows, right, times = [], 0, []
        for seed in seeds:
            rec = machine.record(seed)
            lib = PhysicsLibrary(
                [ViscousSplit("v"), Coulomb("v")], names=["q", "v", "u"]
            )
            options = dict(
                u=rec.u,
                n_states=2,
                measured=[0],
                noise_variance=float(rec.noise_sd[0]) ** 2,
                error_states=[1],
                feature_library=lib,
                feature_names=["q", "v", "u"],
                input_hold="zoh",
            )
            if grey_box:
                options.update(
                    assumed_model=machine.assumed_model, parameters=machine.parameters
                )
            else:
                fixed = {"k": p["k"], "c": c_fixed}
                options.update(
                    assumed_model=lambda x, t, u, fixed=fixed: machine.assumed_model(
                        x, t, u, fixed
                    )
                )
            res, sec = _quiet_discover(rec.y, rec.t, **options)
            times.append(sec)
            terms = res.terms.get("v", {})
            c = res.parameters["c"].value if grey_box else c_fixed
            up = c - m * terms.get("v+", 0.0)
            down = c - m * terms.get("v-", 0.0)
            ok = (
                res.conclusion == "explained"
                and "sign(v)" not in terms
                and bool({"v+", "v-"} & set(terms))
                and set(res.terms) <= {"v"}
                and set(terms) <= {"v+", "v-"}
                and abs(up - c_up) <= 0.05 * c_up
                and abs(down - c_down) <= 0.05 * c_down
            )
            right += ok
            rows.append(
                [
                    str(seed),
                    _terms_text(res),
                    f"{c:.4g}" + ("" if grey_box else " (fixed)"),
                    f"{up:.4g} ({100 * (up / c_up - 1):+.2f} %)",
                    f"{down:.4g} ({100 * (down / c_down - 1):+.2f} %)",
                    f"{up - down:.4g}",
                    res.conclusion,
                    f"{len(res.trade_offs)}",
                    f"{sec:.1f}",
                    "yes" if ok else "NO",
                ]
            )
        label = "grey-box c (and k)" if grey_box else f"c fixed at {c_fixed:g}, k known"
        print(
            f"\n## Direction-dependent damper, {label} (c_up = {c_up:g}, c_down = "
            f"{c_down:g} N s/m, m = {m:g} kg; 20 s at 100 Hz, noise 0.1 mm)\n"
        )
        _table(
            [
                "seed",
                "terms kept",
                "c",
                "c_up (vs truth)",
                "c_down (vs truth)",
                "c_up - c_down",
                "conclusion",
                "trade-offs named",
                "time (s)",
                "right",
            ],
            rows,
        )
        print(
            f"\nRight (c_up and c_down within 5 %, no Coulomb, 'explained'): "
            f"{right}/{len(seeds)}; time per study {np.mean(times):.1f} s (max "
            f"{np.max(times):.1f} s)."
        )


# ---------------------------------------------------------------------------
# friction_lookalikes


def _sign_of_all(bias):
    return ps.CustomLibrary(
        library_functions=[lambda s: np.sign(s)],
        function_names=[lambda s: f"sign({s})"],
        include_bias=bias,
    )


def _oscillator_case(seed, physics):
    def truth(x, t):
        return np.column_stack([x[:, 1], -x[:, 0] - 0.05 * np.sign(x[:, 1])])

    def assumed(x, t):
        return np.column_stack([x[:, 1], -x[:, 0]])

    t = np.arange(0, 30.0 + 1e-9, 1 / 20.0)
    x = simulate_model(truth, (1.0, 0.0), t, rtol=1e-10, atol=1e-12)
    rng = np.random.default_rng(seed)
    y = x[:, :1] + np.sqrt(1e-4) * rng.standard_normal((t.size, 1))
    signs = (
        PhysicsLibrary([Coulomb("x2")], names=["x1", "x2"])
        if physics
        else _sign_of_all(False)
    )
    lib = ps.GeneralizedLibrary([ps.PolynomialLibrary(degree=1), signs])
    res, sec = _quiet_discover(
        y,
        t,
        assumed_model=assumed,
        n_states=2,
        measured=[0],
        noise_variance=1e-4,
        error_states=[1],
        feature_library=lib,
        options=StudyOptions(feature_names=["x1", "x2"]),
    )
    return res, sec, ("x2", "sign(x2)", -0.05, 0.10, ())


def _axis_case(seed, physics):
    machine = positioning_axis()
    rec = machine.record(seed, duration=5.0)
    lib = (
        PhysicsLibrary([Coulomb("v")], include_bias=True, names=["q", "v", "u"])
        if physics
        else _sign_of_all(True)
    )
    res, sec = _quiet_discover(
        rec.y,
        rec.t,
        u=rec.u,
        assumed_model=machine.assumed_model,
        n_states=2,
        measured=[0],
        noise_variance=(1e-5) ** 2,
        feature_library=lib,
        options=StudyOptions(
            parameters=machine.parameters, feature_names=["q", "v", "u"]
        ),
    )
    return res, sec, ("v", "sign(v)", -20 / 95, 0.05, ("1",))


def friction_lookalikes(args):
    seeds = range(2 if args.quick else 5)
    cases = [
        ("oscillator x2' = -x1 - 0.05 sign(x2), 30 s at 20 Hz", _oscillator_case),
        ("positioning axis, grey-box M and c, 5 s at 1 kHz", _axis_case),
    ]
    for title, case in cases:
        rows, counts, times = [], {}, {}
        for physics in (False, True):
            label = "Coulomb(v)" if physics else "sign of all"
            for seed in seeds:
                res, sec, (state, name, truth, tol, allowed) = case(seed, physics)
                times.setdefault(label, []).append(sec)
                terms = res.terms.get(state, {})
                coef = terms.get(name)
                coef_ok = coef is not None and abs(coef - truth) <= tol * abs(truth)
                lookalikes = {
                    f"{k} in {s}'": v
                    for s, ts in res.terms.items()
                    for k, v in ts.items()
                    if not (s == state and (k == name or k in allowed))
                }
                n_ok, n_clean = counts.get(label, (0, 0))
                counts[label] = (n_ok + coef_ok, n_clean + (not lookalikes))
                rows.append(
                    [
                        label,
                        str(seed),
                        _terms_text(res),
                        "not kept"
                        if coef is None
                        else f"{coef:.4g} ({100 * (coef / truth - 1):+.2f} %)",
                        ", ".join(f"{k} = {v:+.3g}" for k, v in lookalikes.items())
                        or "none",
                        res.conclusion,
                        f"{sec:.1f}",
                    ]
                )
        print(f"\n## Coulomb friction and look-alikes: {title}\n")
        _table(
            [
                "library",
                "seed",
                "terms kept",
                "Coulomb coef (vs truth)",
                "look-alikes kept",
                "conclusion",
                "time (s)",
            ],
            rows,
        )
        n = len(seeds)
        for label, (n_ok, n_clean) in counts.items():
            print(
                f"\n{label}: Coulomb coefficient right in {n_ok}/{n} seeds, no "
                f"look-alike in {n_clean}/{n}; time per study "
                f"{np.mean(times[label]):.1f} s."
            )


# ---------------------------------------------------------------------------
# tanks


def _tanks_row(machine, seed):
    """One study of the linear-model tanks; returns the row's numbers."""
    rec = machine.record(seed)
    test = machine.record(1000 + seed)
    step = rec.quantisation_step or 0.0
    lib = PhysicsLibrary(
        [Torricelli("h1"), Torricelli("h2"), Overflow("h1", [6, 8, 10, 12, 14])],
        include_bias=False,
        names=["h1", "h2", "u"],
    )
    res, sec = _quiet_discover(
        rec.y,
        rec.t,
        u=rec.u,
        assumed_model=machine.assumed_model,
        n_states=2,
        measured=[1],
        noise_variance=float(rec.noise_sd[0]) ** 2 + step**2 / 12.0,
        error_states=[0, 1],
        feature_library=lib,
        validation=(test.y, test.t, test.u),
        options=StudyOptions(
            parameters=machine.parameters, feature_names=["h1", "h2", "u"]
        ),
        mme=MME(input_hold="zoh"),
    )
    # the true model's free run on the samples of the study's validation RMSE
    y_v = res.study.validation[0]
    lead, trail = res.study.validation_clipped_cut
    window = res.gain.validation_runs["extended"].window
    x_true = machine.simulate(test.t, test.u, test.x[0])[lead : test.t.size - trail]
    y = y_v[window:, 0]
    seen = np.isfinite(y)
    true = float(np.sqrt(np.mean((y[seen] - x_true[window:, 1][seen]) ** 2)))
    ext = float(res.gain.validation_rmse_extended[0])
    ass = float(res.gain.validation_rmse_assumed[0])
    h1, h2 = res.terms.get("h1", {}), res.terms.get("h2", {})
    law = (
        h1.get("sqrt(h1+)", 0.0) < 0
        and h2.get("sqrt(h1+)", 0.0) > 0
        and h2.get("sqrt(h2+)", 0.0) < 0
    )
    over = any(k.startswith("over(h1") for terms in (h1, h2) for k in terms)
    saturation = over or "may saturate" in str(res)
    clipped = next(
        (
            line[len("Clipped: ") :]
            for line in str(res).splitlines()
            if line.startswith("Clipped: h2")
        ),
        "none",
    )
    return dict(
        res=res,
        sec=sec,
        law=law,
        saturation=saturation,
        over=over,
        rmse_ok=ext <= 1.5 * true,
        ext=ext,
        true=true,
        ass=ass,
        c11c21=h1.get("sqrt(h1+)", np.nan) * h2.get("sqrt(h1+)", np.nan),
        c22=h2.get("sqrt(h2+)", np.nan),
        clipped=clipped,
    )


def tanks(args):
    machine = cascaded_tanks(assumed="linear")
    p = machine.true_parameters
    # --held-out: seeds 100-109, added after the rules were developed on 0-9
    # and reported apart (looked at only to report them, never to tune)
    first = 100 if args.held_out else 0
    seeds = range(first, first + (3 if args.quick else 10))
    rows, runs = [], []
    for seed in seeds:
        r = _tanks_row(machine, seed)
        runs.append(r)
        res = r["res"]
        params = ", ".join(f"{k} {v.value:.3g}" for k, v in res.parameters.items())
        rows.append(
            [
                str(seed),
                _terms_text(res),
                params,
                f"{r['c11c21']:.3g}",
                f"{r['c22']:.3g}",
                res.conclusion,
                f"{r['ext']:.4g}",
                f"{r['true']:.4g}",
                f"{r['ass']:.4g}",
                f"{r['ext'] / r['true']:.2f}",
                f"{r['sec']:.1f}",
                "".join(
                    mark
                    for mark, ok in (
                        ("L", r["law"]),
                        ("S", r["saturation"]),
                        ("R", r["rmse_ok"]),
                    )
                    if ok
                )
                or "-",
            ]
        )
    print(
        f"\n## Cascaded tanks{' (held-out seeds)' if args.held_out else ''}, "
        f"linear assumed model (k1 = {p['k1']:g}, k2 = "
        f"{p['k2']:g}, kp = {p['kp']:g}, rim {p['h_max']:g} V; 4096 s at 0.25 Hz, "
        f"h2 measured, noise 0.02 V, 12-bit, clipped at 0 and 10 V)\n"
    )
    _table(
        [
            "seed",
            "terms kept",
            "parameters",
            f"c11 c21 (-k1^2 = {-(p['k1'] ** 2):.3g})",
            f"c22 (-k2 = {-p['k2']:.3g})",
            "conclusion",
            "test RMSE extended",
            "true",
            "assumed",
            "ext/true",
            "time (s)",
            "right (L S R)",
        ],
        rows,
    )
    n = len(seeds)
    times = [r["sec"] for r in runs]
    print(
        f"\nSquare-root law in both equations, signs right (L): "
        f"{sum(r['law'] for r in runs)}/{n}; saturation named (S): "
        f"{sum(r['saturation'] for r in runs)}/{n} (an overflow term kept in "
        f"{sum(r['over'] for r in runs)}); test RMSE within 1.5x the true "
        f"model's (R): {sum(r['rmse_ok'] for r in runs)}/{n}. Time per study "
        f"{np.mean(times):.1f} s (max {np.max(times):.1f} s). Clipped line "
        f"(seed {seeds[0]}): {runs[0]['clipped']}"
    )


def axis(args):
    """Issue 19 (1a): Coulomb friction and an offset on the PD-controlled axis."""
    fc, f0, mass = 20.0, -3.0, 95.0
    machine = positioning_axis(F0=f0)
    names = ["q", "v", "u"]
    seeds = range(3 if args.quick else 10)
    duration = 10.0 if args.quick else 25.0
    rows, right, times = [], 0, []
    for seed in seeds:
        rec = machine.record(seed, duration=duration)
        train, test = rec.split(0.8)
        lib = PhysicsLibrary(
            [Coulomb("v"), Stribeck("v", 0.02)], include_bias=True, names=names
        )
        res, sec = _quiet_discover(
            train.y,
            train.t,
            u=train.u,
            assumed_model=machine.assumed_model,
            n_states=2,
            measured=[0],
            noise_variance=rec.quantisation_step**2 / 12.0,
            feature_library=lib,
            error_states=[1],
            validation=(test.y, test.t, test.u),
            options=StudyOptions(parameters=machine.parameters, feature_names=names),
            mme=MME(input_hold="zoh"),
        )
        times.append(sec)
        terms = res.terms.get("v", {})
        m = res.parameters["M"].value
        coulomb = -terms.get("sign(v)", np.nan) * m
        offset = terms.get("1", np.nan) * m
        others = sorted(set(terms) - {"sign(v)", "1"})
        ok = (
            abs(coulomb / fc - 1) <= 0.03
            and abs(offset / f0 - 1) <= 0.10
            and abs(m / mass - 1) <= 0.05
            and not others
            and set(res.terms) <= {"v"}
        )
        right += ok
        rows.append(
            [
                str(seed),
                f"{coulomb:.3f} ({100 * (coulomb / fc - 1):+.2f} %)",
                f"{offset:.3f} ({100 * (offset / f0 - 1):+.1f} %)",
                f"{m:.2f}",
                f"{res.parameters['c'].value:.1f}",
                ", ".join(others) or "none",
                res.conclusion,
                f"{sec:.1f}",
                "yes" if ok else "NO",
            ]
        )
    print(
        f"\n## Positioning axis: Coulomb {fc:g} N and offset {f0:g} N missing from "
        f"a mass/viscous grey box ({duration:g} s at 1 kHz, 50 nm encoder, last "
        "fifth for validation)\n"
    )
    _table(
        [
            "seed",
            "Coulomb (N)",
            "offset (N)",
            "M (kg)",
            "c (N s/m)",
            "other terms",
            "conclusion",
            "time (s)",
            "right",
        ],
        rows,
    )
    print(
        f"\nRight (Coulomb within 3 %, offset within 10 %, mass within 5 %, no other "
        f"term): {right}/{len(rows)}; median time per study {np.median(times):.1f} s."
    )


# ---------------------------------------------------------------------------
# kinks: what the misfit left on a sticking axis is


def _fixed_axis(mass, damping):
    """The axis' model with fixed constants (``K_u = 100`` N/V known)."""

    def model(x, t, u):
        return np.column_stack([x[:, 1], (100.0 * u[:, 0] - damping * x[:, 1]) / mass])

    return model


#: (case, when it was run against KINK_MISFIT_SHARE, machine, seed, fixed
#: model or None, the misfit is the kinks'): the rows of
#: tests/discovery/test_physics_axis.py (KINK_CASES) and one more held out
KINK_ROWS = [
    ("95 kg, seed 0", "set on", positioning_axis(F0=-3.0), 0, None, True),
    (
        "40 kg at 500 Hz",
        "set on",
        positioning_axis(M=40.0, c=80.0, Fc=8.0, F0=2.0, rate=500.0),
        0,
        None,
        True,
    ),
    (
        "breakaway 28 N over sliding 20 N",
        "set on",
        positioning_axis(F0=-3.0, Fs=28.0),
        0,
        None,
        False,
    ),
    ("95 kg, seed 1", "run after", positioning_axis(F0=-3.0), 1, None, True),
    (
        "60 kg, 2 um encoder noise",
        "run after",
        positioning_axis(M=60.0, c=120.0, Fc=12.0, F0=-1.5, noise_sd=2e-6),
        0,
        None,
        True,
    ),
    (
        "viscous friction fixed 5 % low",
        "run after",
        positioning_axis(F0=-3.0),
        0,
        _fixed_axis(95.0, 190.0),
        False,
    ),
    (
        "150 kg at 2 kHz, no offset",
        "run after",
        positioning_axis(M=150.0, c=300.0, Fc=35.0, F0=0.0, rate=2000.0),
        0,
        None,
        True,
    ),
    (
        "120 kg at 800 Hz",
        "held out",
        positioning_axis(M=120.0, c=250.0, Fc=30.0, F0=5.0, rate=800.0),
        7,
        None,
        True,
    ),
    (
        "mass fixed at 80 kg",
        "held out",
        positioning_axis(F0=-3.0),
        3,
        _fixed_axis(80.0, 200.0),
        False,
    ),
    (
        "80 kg at 5 kHz, seed 2",
        "held out",
        positioning_axis(M=80.0, c=160.0, Fc=15.0, F0=-2.0, rate=5000.0),
        2,
        None,
        True,
    ),
]


def _misfit_named(res) -> str:
    if "integration of the smoothed kinks" in res.verdict:
        return "the kinks"
    if any("not in the library" in reason for reason in res.reasons):
        return "the library"
    return res.conclusion


def kinks(args):
    """Session 25: the misfit a sticking axis leaves, named the smoothed kinks'
    or an effect the library lacks (``KINK_MISFIT_SHARE``)."""
    names = ["q", "v", "u"]
    rows, agree, times = [], 0, []
    for case, role, machine, seed, fixed, expected in KINK_ROWS[
        : 3 if args.quick else None
    ]:
        rec = machine.record(seed, duration=20.0)
        train, test = rec.split(0.8)
        noise = rec.quantisation_step**2 / 12.0 + float(rec.noise_sd[0]) ** 2
        res, sec = _quiet_discover(
            train.y,
            train.t,
            u=train.u,
            assumed_model=machine.assumed_model if fixed is None else fixed,
            n_states=2,
            measured=[0],
            noise_variance=noise,
            feature_library=PhysicsLibrary(
                [Coulomb("v"), Stribeck("v", 0.02)], include_bias=True, names=names
            ),
            error_states=[1],
            validation=(test.y, test.t, test.u),
            options=StudyOptions(
                parameters=machine.parameters if fixed is None else None,
                feature_names=names,
            ),
            mme=MME(input_hold="zoh"),
        )
        times.append(sec)
        named = _misfit_named(res)
        ok = named == ("the kinks" if expected else "the library")
        agree += ok
        terms = res.terms.get("v", {})
        mass = res.parameters["M"].value if "M" in res.parameters else np.nan
        found = (
            f"M {mass:.2f}, Fc {-terms['sign(v)'] * mass:.2f} N, "
            f"F0 {terms.get('1', 0.0) * mass:.3f} N"
            if fixed is None and "sign(v)" in terms
            else _terms_text(res)
        )
        share = res.kink_misfit
        excess = float(res.gain.rmse_extended[0] / res.gain.noise_floor[0])
        rows.append(
            [
                case,
                role,
                "the kinks'" if expected else "an effect missed",
                "-" if share is None else f"{100 * share:.1f} %",
                f"{excess:,.1f}x",
                named,
                found,
                f"{sec:.0f}",
                "yes" if ok else "NO",
            ]
        )
    print(
        "\n## What the misfit left on a sticking axis is (20 s records, 50 nm "
        "encoder, Coulomb + Stribeck library; the misfit is named the kinks' where "
        "at most 70 % of it stays at half the smoothing width)\n"
    )
    _table(
        [
            "axis",
            "rule",
            "the misfit is",
            "left at half width",
            "extended RMSE / noise",
            "report names",
            "found",
            "time (s)",
            "as expected",
        ],
        rows,
    )
    print(f"\nNamed as expected: {agree}/{len(rows)}; median {np.median(times):.0f} s.")


SECTIONS = {
    "axis": axis,
    "kinks": kinks,
    "simulate_sign": simulate_sign,
    "viscous_split": viscous_split,
    "friction_lookalikes": friction_lookalikes,
    "tanks": tanks,
}


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
        "--held-out",
        action="store_true",
        help="tanks: the held-out seeds 100-109 instead of the development seeds 0-9",
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
