"""Issue 19 (1b): the cascaded tanks with a linear assumed model.

The machine (:func:`~pysindy_mme.machines.cascaded_tanks`, defaults): two
tanks in series fed by a held pump, Torricelli outflows and an overflow of
the upper tank at its rim::

    h1' = -k1 sqrt(h1) + kp u                       (h1 < 10, or not filling)
    h2' =  k1 sqrt(h1) - k2 sqrt(h2) + overflow

Only the lower level ``h2`` is measured (noise sd 0.02 V, 12-bit ADC,
clipped to 0..10 V), 4096 s at 0.25 Hz. The user's model is linear,
``h1' = -a1 h1 + b u``, ``h2' = a2 h1 - a3 h2``, with the four coefficients
grey-box parameters. The study offers ``PhysicsLibrary([Torricelli("h1"),
Torricelli("h2"), Overflow("h1", levels)])`` in both equations.

What is identifiable, and so what the checks ask for.

* The scale of the hidden level. With ``h1`` never measured, ``z = s h1``
  (``s > 0``) is the same model with ``b -> s b``, ``a2 -> a2 / s`` and the
  square-root coefficients ``c11 -> sqrt(s) c11`` (in ``h1'``), ``c21 ->
  c21 / sqrt(s)`` (in ``h2'``); only ``b a2``, ``c11 c21`` and ``b c21^2``
  are determined. No other change of the hidden state keeps ``h1'`` linear
  in ``u`` with a constant gain, so this scale is the only exact trade-off.
  The checks never compare a coefficient of ``h1`` with ``k1`` or ``kp``.
* The linear terms of the assumed model can absorb part of each outflow
  (over 1..10 V a line follows a square root closely), so the square-root
  coefficients need not equal ``-k1``, ``k1``, ``-k2``. What a line cannot
  absorb is the curvature: the flow ``-a1 h1 + c11 sqrt(h1+)`` is concave
  (an orifice) exactly when ``c11 < 0``, whatever ``a1`` is, and the sign
  survives the scaling (``s > 0``). "The square-root outflow named in both
  equations with the right signs" is therefore: ``sqrt(h1+)`` kept in
  ``h1'`` with a negative coefficient, ``sqrt(h1+)`` kept in ``h2'`` with a
  positive one, ``sqrt(h2+)`` kept in ``h2'`` with a negative one.
* The overflow level is in units of ``h1``, whose scale is not determined
  until an overflow term pins it; the library offers several candidate
  rims around the lower tank's 10 V (the user's guess that both tanks are
  alike), 6..14 V. Saturation counts as named when an ``over(h1, L)`` term
  is kept in either equation, or when the report says the plant "may
  saturate" (a free run above the sensor's ceiling).

The gain is measured on a test record from another seed (``1000 + seed``),
given as ``validation=``: the study estimates each model's initial state
from the record's first ``validation_window`` samples and runs it free; the
true model runs free from the record's true initial state (the machine's
own simulator). Both RMSEs are over the same samples: after the window,
clipped readings left out (the study censors them, ``clipped="auto"``).

Requirements over seeds 0..9 (fixed before any of these studies was run):
the law named (all three square-root terms, signs right), saturation named,
and the extended model's test RMSE within 1.5x the true model's, each in at
least 9 of the 10 seeds.
"""

from __future__ import annotations

import time
import warnings

import numpy as np
import pytest
from tanks_case import tanks_arguments

from pysindy_mme import Discovery, PhysicsLibrary, discover
from pysindy_mme.feature_library import Overflow, Torricelli
from pysindy_mme.machines import cascaded_tanks
from pysindy_mme.solver.output_error import WALL_DECAY

MACHINE = cascaded_tanks(assumed="linear")
RIMS = [6.0, 8.0, 10.0, 12.0, 14.0]  # candidate overflow levels of h1 (V)
VALIDATION_SEED = 1000  # the test record of seed s is MACHINE.record(1000 + s)
RMSE_FACTOR = 1.5
SEEDS = range(10)
NEEDED = 9


def tanks_study(seed):
    """``discover`` on record ``seed``; returns ``(result, test record, seconds)``."""
    rec = MACHINE.record(seed)
    test = MACHINE.record(VALIDATION_SEED + seed)
    lib = PhysicsLibrary(
        [Torricelli("h1"), Torricelli("h2"), Overflow("h1", RIMS)],
        include_bias=False,
        names=["h1", "h2", "u"],
    )
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = discover(**tanks_arguments(MACHINE, rec, lib, validation=test))
    return res, test, time.perf_counter() - start


def rmse_on_test_record(res, test) -> dict:
    """Free-run RMSE of ``h2`` on the test record, over the samples the
    study's validation RMSE uses: ``{"extended", "true", "assumed"}``."""
    y_v, t_v, _ = res.study.validation  # clipped readings are NaN here
    lead, trail = res.study.validation_clipped_cut
    run = res.gain.validation_runs["extended"]
    window = run.window
    x_true = MACHINE.simulate(test.t, test.u, test.x[0])[lead : test.t.size - trail]
    assert x_true.shape[0] == t_v.size
    y = y_v[window:, 0]
    seen = np.isfinite(y)
    true = float(np.sqrt(np.mean((y[seen] - x_true[window:, 1][seen]) ** 2)))
    return {
        "extended": float(res.gain.validation_rmse_extended[0]),
        "true": true,
        "assumed": float(res.gain.validation_rmse_assumed[0]),
    }


def tanks_failures(res, test) -> dict:
    """What the study got wrong, per requirement (empty dict: all right)."""
    out = {}
    h1, h2 = res.terms.get("h1", {}), res.terms.get("h2", {})
    law = []
    for state, terms, name, sign in (
        ("h1", h1, "sqrt(h1+)", -1),
        ("h2", h2, "sqrt(h1+)", +1),
        ("h2", h2, "sqrt(h2+)", -1),
    ):
        if name not in terms:
            law.append(f"{name} not kept in {state}'")
        elif np.sign(terms[name]) != sign:
            law.append(f"{name} in {state}' = {terms[name]:+.4g} (wrong sign)")
    if law:
        out["law"] = law
    overflow = any(k.startswith("over(h1") for terms in (h1, h2) for k in terms)
    if not (overflow or "may saturate" in str(res)):
        out["saturation"] = "no overflow term kept and no 'may saturate' line"
    rmse = rmse_on_test_record(res, test)
    if not rmse["extended"] <= RMSE_FACTOR * rmse["true"]:
        out["rmse"] = (
            f"test RMSE extended {rmse['extended']:.4g} > {RMSE_FACTOR} x true "
            f"{rmse['true']:.4g}"
        )
    return out


def _describe(res) -> str:
    return f"terms {res.terms}; {res.conclusion}; {res.reasons}"


# Met since session 13 (benchmarks/bench_physics.py --only tanks, criteria
# fixed before the runs): the law 9/10, saturation named 10/10, test RMSE
# within 1.5x the true model's 9/10 (seed 0 misses both, 3.4x: see
# test_tanks_seed0); seeds 1-9 all end on the true structure, the wall
# over(h1, 14) with 71-74 % of the excess routed into h2. Held out (seeds
# 100..109, --held-out): 10/10, 10/10, 9/10 (seed 102, 2.1x: a soft wall at
# level 12). Before: 10/10, 10/10, 2/10 (held out 10, 10, 6). What changed:
# overflow terms of states are solved exactly around each RK4 step
# (core/relaxation.py), so a wall of any stiffness joins its trajectory; a
# wall's coefficient is bounded at -WALL_DECAY/dt (a clamp as far as the
# data can tell: held there, at_wall); the search tries each wall from the
# clamp as well as from where it was, and moves an overflow's level in
# every equation at once.


@pytest.fixture(scope="module")
def seed0():
    return tanks_study(0)


@pytest.mark.slow  # a whole study: keeps the edit loop under 2 minutes
def test_report_names_the_clipping_seed0(seed0):
    """The 10 V ceiling is found and censored by the default ``clipped="auto"``."""
    res, _, _ = seed0
    text = str(res)
    assert "Clipped: h2:" in text
    assert "sensor's ceiling 10: treated as censored" in text
    # every reading on the 10 V ceiling is censored (seed 0: none cut at the ends)
    assert res.study.clipped_cut == (0, 0)
    ceiling = res.clipped.on(0, "ceiling")
    assert ceiling.level == 10.0
    assert ceiling.count == int(np.sum(MACHINE.record(0).y >= 10.0))


@pytest.mark.slow  # a whole study: keeps the edit loop under 2 minutes
@pytest.mark.xfail(
    strict=True,
    reason="seed 0 is the dev seed the study gets wrong since session 13: the "
    "regression's first proposal in h1' is over(h1, 6) (a look-alike of the "
    "square-root outflow), after which sqrt(h1+) does not join and constants "
    "and ramps take its place (3.4x the true model's test RMSE); seeds 1-9 meet "
    "all three requirements",
)
def test_tanks_seed0(seed0):
    res, test, _ = seed0
    failures = tanks_failures(res, test)
    assert failures == {}, f"{failures}; {_describe(res)}"


@pytest.mark.slow
def test_tanks_over_ten_seeds():
    failed = {"law": [], "saturation": [], "rmse": []}
    details = {}
    for seed in SEEDS:
        res, test, _ = tanks_study(seed)
        failures = tanks_failures(res, test)
        for key in failures:
            failed[key].append(seed)
        if failures:
            details[seed] = failures
    counts = {k: len(SEEDS) - len(v) for k, v in failed.items()}
    print(
        f"\ncascaded tanks (linear assumed): right per requirement {counts} of "
        f"{len(SEEDS)}; {details}"
    )
    assert all(n >= NEEDED for n in counts.values()), details


@pytest.mark.slow  # one study, 10-30 s
def test_overflow_kept_as_a_wall_seed6(tmp_path):
    """Seed 6: the law, and the overflow out of h1' and into h2' as a wall
    (its coefficient on the wall limit -WALL_DECAY/dt, held: the data say only that
    the excess is gone within a sample) with the route taking the machine's
    share of the excess, predicting the test record as well as the true
    model does; the report names the wall and the share."""
    res, test, _ = tanks_study(6)
    assert tanks_failures(res, test) == {}, _describe(res)
    out = res.terms["h1"]["over(h1, 14)"]
    into = res.terms["h2"]["over(h1, 14)"]
    assert out == pytest.approx(-WALL_DECAY / 4.0)  # the wall limit at 0.25 Hz
    # the share is the hidden level's scale: b is held at its guess 0.05, the
    # truth is kp = 0.036, so h1 is in units 0.05 / 0.036 = 1.39 times the
    # lower tank's, and the water h1 loses arrives in h2 divided by that
    (wall,) = res.walls
    assert wall["state"] == "h1" and wall["level"] == 14.0
    assert wall["routes"]["h2"] == pytest.approx(0.036 / 0.05, rel=0.05)
    assert into == pytest.approx(-out * wall["routes"]["h2"])
    text = str(res)
    assert "Wall: h1 stays at or below 14" in text
    assert "of the excess flows into h2" in text
    # a saved result names its walls when loaded (the library's declaration
    # of its overflow columns is saved with the column names)
    res.save(tmp_path / "tanks.json")
    back = Discovery.load(tmp_path / "tanks.json", assumed_model=MACHINE.assumed_model)
    assert back.walls == res.walls
    assert [w for w in str(back).splitlines() if w.startswith("Wall:")] == [
        w for w in text.splitlines() if w.startswith("Wall:")
    ]
