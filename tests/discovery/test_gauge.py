"""Gauges: a grey-box parameter in an exact trade-off is held at its guess.

The case here is built to check the rule on a system it was not tuned on
(the rule was developed on the cascaded tanks, ``test_physics_tanks.py``):
two states in series, only the second measured, the first driven by the
input through a gain ``b`` and leaving through ``c`` into the second. The
scale of the hidden state ``x1`` is not determined (``z = s x1``: ``b -> s
b``, ``c -> c / s``, and a cubic damping of ``x1`` ``e -> e / s^2``); only
``b c``, ``e b^2`` and the rates are. The truth has the cubic damping
``-e x1^3`` that the user's linear model lacks::

    x1' = -a x1 - e x1^3 + b u,     x2' = c x1 - d x2,     y = x2 + noise

The requirements were fixed before the first run: the study holds one of
``b``, ``c`` (and only one parameter) as a gauge and names it; the assumed
model's fit converges without running away (no parameter moved more than
tenfold from its guess); the cubic is kept in ``x1'`` with a negative
coefficient and no other term is kept; the determined combinations ``b
c``, ``e b^2``, ``a`` and ``d`` of the extended fit are within 10 % of the
truth.
"""

from __future__ import annotations

import warnings

import numpy as np
import pysindy as ps
import pytest
from scipy.integrate import solve_ivp

from pysindy_mme import MME, StudyOptions, discover

TRUTH = {"a": 0.2, "e": 0.01, "b": 0.5, "c": 0.3, "d": 0.1}
GUESSES = {"a": 0.15, "b": 0.4, "c": 0.25, "d": 0.12}
NOISE_SD = 0.01


def _chain(x, t, u, p):
    """The user's model: two first-order lags in series (grey box)."""
    return np.column_stack(
        [-p["a"] * x[:, 0] + p["b"] * u[:, 0], p["c"] * x[:, 0] - p["d"] * x[:, 1]]
    )


def record(seed, n=1000, dt=1.0):
    """The true system under a held random multi-level input, ``(y, t, u, x)``."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    u = np.empty(n)
    k = 0
    while k < n:
        m = int(rng.integers(20, 61))
        u[k : k + m] = rng.uniform(-2.0, 2.0)
        k += m
    p = TRUTH

    def rhs(s, x):
        uu = u[min(int(s // dt), n - 1)]  # zero-order hold
        return [
            -p["a"] * x[0] - p["e"] * x[0] ** 3 + p["b"] * uu,
            p["c"] * x[0] - p["d"] * x[1],
        ]

    x = np.empty((n, 2))
    x[0] = 0.0
    for i in range(n - 1):
        sol = solve_ivp(
            rhs, (t[i], t[i + 1]), x[i], rtol=1e-10, atol=1e-12, method="DOP853"
        )
        x[i + 1] = sol.y[:, -1]
    y = x[:, [1]] + NOISE_SD * rng.standard_normal((n, 1))
    return y, t, u[:, None], x


def chain_study(seed):
    y, t, u, _ = record(seed)
    yv, tv, uv, _ = record(1000 + seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return discover(
            y,
            t,
            u=u,
            assumed_model=_chain,
            n_states=2,
            measured=[1],
            noise_variance=NOISE_SD**2,
            feature_library=ps.PolynomialLibrary(degree=3, include_bias=False),
            validation=(yv, tv, uv),
            options=StudyOptions(
                parameters=dict(GUESSES), feature_names=["x1", "x2", "u"]
            ),
            mme=MME(input_hold="zoh"),
        )


def chain_failures(res) -> dict:
    out = {}
    gauges = [name for name, pe in res.parameters.items() if pe.gauge]
    if len(gauges) != 1 or gauges[0] not in ("b", "c"):
        out["gauge"] = f"held {gauges}"
    if not res.assumed.fit.converged:
        out["assumed"] = "the assumed model's fit did not converge"
    runaway = [
        name
        for name, pe in res.parameters.items()
        if not 0.1 < pe.assumed_fit / pe.initial < 10.0
    ]
    if runaway:
        out["runaway"] = runaway
    x1 = res.terms.get("x1", {})
    others = {s: t for s, t in res.terms.items() for k in t if (s, k) != ("x1", "x1^3")}
    if not x1.get("x1^3", 0.0) < 0:
        out["cubic"] = f"x1' terms {x1}"
    if others:
        out["others"] = others
    p = {name: pe.value for name, pe in res.parameters.items()}
    e = -x1.get("x1^3", np.nan)
    checks = {
        "b*c": (p["b"] * p["c"], TRUTH["b"] * TRUTH["c"]),
        "e*b^2": (e * p["b"] ** 2, TRUTH["e"] * TRUTH["b"] ** 2),
        "a": (p["a"], TRUTH["a"]),
        "d": (p["d"], TRUTH["d"]),
    }
    off = {k: v / w for k, (v, w) in checks.items() if not abs(v / w - 1) <= 0.1}
    if off:
        out["determined"] = off
    return out


@pytest.fixture(scope="module")
def seed0():
    return chain_study(0)


def test_gauge_on_an_untuned_hidden_scale_case(seed0):
    res = seed0
    assert chain_failures(res) == {}, (res.terms, res.parameters, res.reasons)
    text = str(res)
    assert "Gauge:" in text and "is held at its guess" in text
    assert any("held at its guess" in r for r in res.reasons)
    assert not any(pe.at_bound for pe in res.parameters.values())
    # a gauge is no doubt: the trade-off it fixes is not called undetermined
    assert not any("not determined by the data (no standard" in w for w in res.warnings)


def test_a_saved_study_keeps_its_gauge(seed0, tmp_path):
    from pysindy_mme import Discovery

    path = tmp_path / "chain.npz"
    seed0.save(path)
    again = Discovery.load(path)
    assert [t.gauge for t in again.study.gauges] == [
        t.gauge for t in seed0.study.gauges
    ]
    assert {n: pe.gauge for n, pe in again.parameters.items()} == {
        n: pe.gauge for n, pe in seed0.parameters.items()
    }
    assert "Gauge:" in str(again)


def test_no_gauge_without_a_trade_off():
    """Both states measured: the scale is determined, nothing is held."""
    y, t, u, x = record(0, n=300)
    rng = np.random.default_rng(1)
    both = x + NOISE_SD * rng.standard_normal(x.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = discover(
            both,
            t,
            u=u,
            assumed_model=_chain,
            n_states=2,
            noise_variance=NOISE_SD**2,
            feature_library=ps.PolynomialLibrary(degree=3, include_bias=False),
            options=StudyOptions(
                parameters=dict(GUESSES), feature_names=["x1", "x2", "u"]
            ),
            mme=MME(input_hold="zoh"),
        )
    assert res.study.gauges == []
    assert not any(pe.gauge for pe in res.parameters.values())
    assert "Gauge:" not in str(res)


@pytest.mark.slow
def test_gauge_on_an_untuned_hidden_scale_case_over_seeds():
    failed = {}
    for seed in range(5):
        failures = chain_failures(chain_study(seed))
        if failures:
            failed[seed] = failures
    assert len(failed) <= 1, failed
