"""Issue 11's claims about the default, as slow many-seed studies.

* A subset of ``benchmarks/bench_dropin.py`` (same records, same counts).
* The README's drop-in claim: full-state Lorenz, dt 0.002, 10 time units,
  1% noise: ``ps.SINDy(optimizer=FloatingFStepwise())`` prints the exact
  Lorenz model in at least 9 of 10 seeds.
* The paper's Van der Pol study through ``ps.SINDy(differentiation_method=
  MME(...), optimizer=FloatingFStepwise())`` finds the three true terms in
  all 20 seeds, as the paper's rule does.
"""

from __future__ import annotations

import importlib.util
import sys
import warnings
from pathlib import Path

import numpy as np
import pysindy as ps
import pytest
from scipy.integrate import solve_ivp

from pysindy_mme import MME
from pysindy_mme.optimizers import FloatingFStepwise
from pysindy_mme.systems import van_der_pol

pytestmark = pytest.mark.slow

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_dropin.py"


@pytest.fixture(scope="module")
def bench():
    if not BENCH.exists():
        pytest.skip(f"{BENCH} not found (the benchmarks folder is not installed)")
    spec = importlib.util.spec_from_file_location("bench_dropin", BENCH)
    module = importlib.util.module_from_spec(spec)
    # Registered before running it: its dataclasses look their module up.
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def _row(bench, name, level, labels, seeds=range(20)):
    index = [s.name for s in bench.SYSTEMS].index(name)
    hits = dict.fromkeys(labels, 0)
    for seed in seeds:
        theta, dx, coef = bench._record(index, level, seed)
        for label in labels:
            hits[label] += bench.evaluate(label, theta, dx, coef)[0]
    print(f"\n{name} {100 * level:g}%: {hits}")
    return hits


# Counts of the full benchmark run (python benchmarks/bench_dropin.py).
@pytest.mark.parametrize(
    "name, level, ours, stlsq",
    [
        ("Duffing", 0.01, 20, 6),
        ("cubic oscillator", 0.001, 20, 0),
        ("Hopf (2 traj.)", 0.01, 20, 19),
        ("Lorenz", 0.01, 19, 20),
        # the cancelling group mu y - y r^2, found by the joint restart
        ("Hopf (2 traj.)", 0.05, 20, 13),
        ("Rossler", 0.01, 19, 20),
    ],
)
def test_benchmark_rows(bench, name, level, ours, stlsq):
    hits = _row(bench, name, level, ["ours", "STLSQ"])
    assert hits["STLSQ"] == stlsq
    assert hits["ours"] >= ours - 1
    assert hits["ours"] >= hits["STLSQ"] - 1


def test_rossler_at_five_per_cent_is_the_librarys_noise(bench):
    """Rossler at 5 % noise, the one row of the nine where the default was
    behind STLSQ() (11 vs 14 before session 23): the noise of the measured
    library made false terms fit better than the true ones; corrected for it
    (``errors_in_variables="auto"``) the default is exact in every seed.
    Recorded so that a change in either count is seen."""
    hits = _row(bench, "Rossler", 0.05, ["ours", "ours floating=False", "STLSQ"])
    assert hits["STLSQ"] == 14
    assert hits["ours"] >= 19  # measured: 20
    index = [s.name for s in bench.SYSTEMS].index("Rossler")
    plain = 0
    for seed in range(20):
        theta, dx, coef = bench._record(index, 0.05, seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            opt = FloatingFStepwise(errors_in_variables=False).fit(theta, dx)
        plain += bool(np.array_equal(opt.coef_ != 0, coef != 0))
    assert 9 <= plain <= 13  # measured: 11


def test_benchmark_wide_library(bench):
    """5,000 columns: the Bonferroni level keeps every noise column out."""
    hits = _row(bench, "Van der Pol + 4,990 random columns", 0.01, ["ours"])
    assert hits["ours"] >= 18  # measured: 19


def _lorenz(t, x):
    return [10 * (x[1] - x[0]), x[0] * (28 - x[2]) - x[1], x[0] * x[1] - 8 / 3 * x[2]]


def test_readme_lorenz_claim(capsys):
    t = np.arange(0, 10 + 1e-9, 0.002)
    sol = solve_ivp(
        _lorenz, (0, 10), [-8, 8, 27], t_eval=t, method="DOP853", rtol=1e-11, atol=1e-12
    )
    x = sol.y.T
    expected = [{"x", "y"}, {"x", "y", "x z"}, {"z", "x y"}]
    exact = 0
    for seed in range(10):
        rng = np.random.default_rng(seed)
        noisy = x + 0.01 * x.std(axis=0) * rng.standard_normal(x.shape)
        model = ps.SINDy(
            optimizer=FloatingFStepwise(),
            feature_library=ps.PolynomialLibrary(degree=3),
            differentiation_method=ps.SmoothedFiniteDifference(),
        )
        model.fit(noisy, t=t, feature_names=["x", "y", "z"])
        model.print()
        lines = capsys.readouterr().out.splitlines()
        printed = [
            {term.strip().split(" ", 1)[1] for term in line.split("=")[1].split(" + ")}
            for line in lines
        ]
        exact += printed == expected
    print(f"\nexact Lorenz model printed in {exact}/10 seeds")
    assert exact >= 9


def test_mme_sindy_route_finds_the_paper_terms_in_every_seed():
    system = van_der_pol()
    found = 0
    for seed in range(20):
        m = system.measure(seed)
        mme = MME(
            system.assumed_model,
            2,
            measured=[0],
            noise_variance=0.01,
            error_states=[1],
        )
        sindy = ps.SINDy(
            differentiation_method=mme,
            optimizer=FloatingFStepwise(),
            feature_library=ps.PolynomialLibrary(degree=3),
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sindy.fit(m.y, t=m.t, feature_names=["x1", "x2"])
        names = np.array(sindy.get_feature_names())
        coef = sindy.coefficients()
        terms = set(names[np.flatnonzero(coef[1])])
        found += terms == {"x1", "x2", "x1^2 x2"} and not np.any(coef[0])
        # d(t) is smooth: the default applies the paper's rule to it.
        assert sindy.optimizer.phase_two_[1]
    print(f"\nthree true terms in {found}/20 seeds")
    assert found == 20
