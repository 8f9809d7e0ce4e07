"""Issue 21: the default rule on systems it was not designed on.

Each failure pattern the issue names, with fixed seeds, through the records
``benchmarks/bench_dropin.py`` builds (full state, Gaussian noise relative to
each state's standard deviation, ``ps.SmoothedFiniteDifference()``,
``ps.PolynomialLibrary(degree)``):

* a limit cycle whose terms cancel on the cycle (Hopf normal form, one
  trajectory; Rikitake's ``x z - 5 x``): the joint restart finds the group
  and its model is kept because it is relevantly better;
* low noise with a wide library (cubic oscillator, degree 5, 0.1 %): the
  derivative's systematic error is jointly significant, but the restart's
  extra terms are not relevant, so the forward (exact) model stays;
* many rows (significance is not relevance): a term whose effect is tiny
  (Cohen's f^2 below ``MIN_EFFECT``) does not enter, however significant.
"""

from __future__ import annotations

import warnings

import numpy as np
import pysindy as ps
import pytest
from dropin_records import record as _record
from scipy.integrate import solve_ivp

from pysindy_mme import FloatingFStepwise
from pysindy_mme.optimizers.rules import MIN_EFFECT
from pysindy_mme.optimizers.selection import (
    JOINT_MIN_EFFECT,
    _next_action,
    restart_effect,
)


def _hopf(t, x, mu=0.5):
    r2 = x[0] ** 2 + x[1] ** 2
    return [mu * x[0] - x[1] - x[0] * r2, x[0] + mu * x[1] - x[1] * r2]


def _cubic(t, x):
    return [-0.1 * x[0] ** 3 + 2.0 * x[1] ** 3, -2.0 * x[0] ** 3 - 0.1 * x[1] ** 3]


def _rikitake(t, x, mu=2.0, a=5.0):
    return [-mu * x[0] + x[2] * x[1], -mu * x[1] + (x[2] - a) * x[0], 1.0 - x[0] * x[1]]


def _fit(theta, dx):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return FloatingFStepwise().fit(theta, dx)


@pytest.mark.parametrize("level", [0.001, 0.01])
def test_hopf_normal_form_one_trajectory(level):
    """mu 0.5, 10 s at dt 0.01 from (2, 0): y' = x + mu y - y (x^2 + y^2),
    whose terms nearly cancel on the cycle. Before issue 21: 0 of 4 seeds
    (forward selection took a false x y instead of y and y^3)."""
    theta, dx, support = _record(_hopf, [2.0, 0.0], 0.01, 10.0, 3, level, 0)
    opt = _fit(theta, dx)
    np.testing.assert_array_equal(opt.coef_ != 0, support)
    joint = opt.joint_tests_[1]
    assert joint["restart"] and joint["kept"]
    assert joint["effect"] >= JOINT_MIN_EFFECT


def test_rikitake_cancelling_pair():
    """y' = -2 y + x z - 5 x with z oscillating about 5: x z and x cancel."""
    theta, dx, support = _record(_rikitake, [1.0, 2.0, 3.0], 0.01, 30.0, 3, 0.01, 0)
    opt = _fit(theta, dx)
    np.testing.assert_array_equal(opt.coef_ != 0, support)
    assert opt.joint_tests_[1]["kept"]


def test_cubic_oscillator_degree_five_at_low_noise():
    """0.1 % noise, PolynomialLibrary(5): the forward model is exact; the
    derivative's systematic error is jointly significant, and the restart
    would keep two false terms of f^2 about 0.05 each, not relevant."""
    theta, dx, support = _record(_cubic, [2.0, 0.0], 0.01, 25.0, 5, 0.001, 0)
    opt = _fit(theta, dx)
    np.testing.assert_array_equal(opt.coef_ != 0, support)
    joint = opt.joint_tests_[0]
    assert joint["restart"] and not joint["kept"]
    assert joint["effect"] < JOINT_MIN_EFFECT
    assert "back to the forward model" in str(opt.summary())


# measured (10 seeds each): Hopf 10/10 at 0.1 % and 1 %, cubic 9/10, Rikitake 10/10
@pytest.mark.slow
@pytest.mark.parametrize(
    "rhs, x0, t_end, degree, level, at_least",
    [
        (_hopf, [2.0, 0.0], 10.0, 3, 0.001, 10),
        (_hopf, [2.0, 0.0], 10.0, 3, 0.01, 9),
        # measured 9/10: seed 8 keeps a forward-selected x0 x1^4 in y'
        (_cubic, [2.0, 0.0], 25.0, 5, 0.001, 9),
        # 5 % noise: 5/10 since session 29 (before: 3). The least-squares fit
        # prefers x0^5 to the weak x0^3 in seeds 0, 3, 6 and 8, so a rule
        # that chooses by fit can reach 6 at most; seed 2 misses x0^3
        (_cubic, [2.0, 0.0], 25.0, 5, 0.05, 5),
        (_rikitake, [1.0, 2.0, 3.0], 30.0, 3, 0.01, 10),
    ],
)
def test_many_seeds(rhs, x0, t_end, degree, level, at_least):
    exact = 0
    for seed in range(10):
        theta, dx, support = _record(rhs, x0, 0.01, t_end, degree, level, seed)
        exact += np.array_equal(_fit(theta, dx).coef_ != 0, support)
    print(f"\n{rhs.__name__} {level}: {exact}/10")
    assert exact >= at_least


# ------------------------------------------------- significance vs relevance
def test_significant_but_irrelevant_term_does_not_enter():
    """300,000 rows: x1's effect (f^2 = 0.02^2 / 1 = 4e-4) is significant
    (F about 120) but below MIN_EFFECT; with 3,000 rows and a ten times
    larger coefficient (f^2 0.04) it enters."""
    assert MIN_EFFECT == pytest.approx(1e-3)
    rng = np.random.default_rng(0)
    n = 300_000
    X = rng.standard_normal((n, 5))
    y = 2.0 * X[:, 0] + 0.02 * X[:, 1] + rng.standard_normal(n)
    opt = FloatingFStepwise(time_ordered=True).fit(X, y)
    assert list(np.flatnonzero(opt.coef_[0])) == [0]
    # the classic rule (significance only) admits it
    textbook = FloatingFStepwise(alpha_enter=0.01, floating=False).fit(X, y)
    assert 1 in np.flatnonzero(textbook.coef_[0])
    y_small = 2.0 * X[:3000, 0] + 0.2 * X[:3000, 1] + rng.standard_normal(3000)
    opt = FloatingFStepwise(time_ordered=True).fit(X[:3000], y_small)
    assert sorted(np.flatnonzero(opt.coef_[0])) == [0, 1]


def test_restart_effect():
    assert restart_effect(2, 10.0, 2, 5.0) == np.inf  # no larger, smaller SSE
    assert restart_effect(2, 10.0, 1, 9.0) == np.inf
    assert restart_effect(2, 10.0, 4, 10.0) == 0.0  # SSE not smaller
    assert restart_effect(2, 10.0, 4, 8.0) == pytest.approx((2.0 / 8.0) / 2)


def _lorenz(t, x):
    return [10 * (x[1] - x[0]), x[0] * (28 - x[2]) - x[1], x[0] * x[1] - 8 / 3 * x[2]]


@pytest.mark.slow
def test_a_million_rows_lorenz():
    """Issue 21: full-state Lorenz, dt 0.002, 10^6 rows, 1 % noise,
    SmoothedFiniteDifference, PolynomialLibrary(2). Before: x z and y z kept
    in x' and y z in y' (robust F 60-100, f^2 2e-5 to 7e-5)."""
    dt, n = 0.002, 1_000_000
    t = np.arange(n) * dt
    sol = solve_ivp(
        _lorenz,
        (0, t[-1]),
        [-8, 8, 27],
        t_eval=t,
        method="DOP853",
        rtol=1e-10,
        atol=1e-10,
    )
    x = sol.y.T
    y = x + 0.01 * x.std(axis=0) * np.random.default_rng(0).standard_normal(x.shape)
    dx = ps.SmoothedFiniteDifference()._differentiate(y, t)
    theta = np.asarray(ps.PolynomialLibrary(2).fit(y).transform(y))
    # 1 x y z x^2 xy xz y^2 yz z^2
    expected = np.zeros((3, 10), dtype=bool)
    expected[0, [1, 2]] = True
    expected[1, [1, 2, 6]] = True
    expected[2, [3, 5]] = True
    np.testing.assert_array_equal(_fit(theta, dx).coef_ != 0, expected)


# ----------------------------------- which of the passing candidates enters
class _StubState:
    """A model of ``k`` functions whose candidates have the given classic
    F-ratios (``-inf``: not eligible)."""

    def __init__(self, classic, k=0):
        self._classic = np.asarray(classic, float)
        self.k = k
        self.support = list(range(k))

    def candidate_f(self):
        return self._classic.copy()

    def in_model_f(self):
        return np.full(self.k + 1, 1e6)

    def exact_fit(self):
        return False


class _StubRule:
    """A rule whose statistic of entry is ``robust`` (any other test would
    do), with a fixed threshold and every candidate relevant."""

    def __init__(self, robust, threshold=10.0):
        self._robust = np.asarray(robust, float)
        self.threshold = threshold

    def thresholds(self, k):
        return self.threshold, self.threshold

    def in_model_f(self, state):
        return state.in_model_f()[1:]

    def relevant_in_model(self, state):
        return np.ones(state.k, dtype=bool)

    def candidate_f(self, state, classic):
        return self._robust.copy()

    def relevant_candidates(self, state, classic):
        return np.ones(self._robust.shape, dtype=bool)


@pytest.mark.parametrize(
    "classic, robust, expected",
    [
        # both pass the rule's test: the better fit enters, with the rule's
        # statistic recorded (before: candidate 0, the larger robust F)
        ([50.0, 80.0, 5.0], [40.0, 20.0, 3.0], ("add", 1, 20.0, 10.0)),
        # the better fit fails the rule's test: it cannot enter
        ([50.0, 80.0, 5.0], [40.0, 8.0, 3.0], ("add", 0, 40.0, 10.0)),
        # none passes
        ([50.0, 80.0], [9.0, 8.0], None),
        # not eligible stays out whatever its fit
        ([np.inf, 80.0], [-np.inf, 20.0], ("add", 1, 20.0, 10.0)),
    ],
)
def test_of_the_candidates_that_pass_the_best_fit_enters(classic, robust, expected):
    state, rule = _StubState(classic), _StubRule(robust)
    assert _next_action(state, rule, phase=1, ratio=10.0) == expected


def test_phase_two_enters_the_largest_classic_f():
    state = _StubState([50.0, 80.0, 5.0], k=0)
    assert _next_action(state, _StubRule([40.0, 20.0, 3.0]), 2, 10.0) == (
        "add",
        1,
        80.0,
        10.0,
    )


@pytest.mark.parametrize("seed", [4, 5, 16])
def test_cubic_oscillator_degree_five_weak_term_by_its_fit(seed):
    """5 % noise, PolynomialLibrary(5): after 2 y^3, x' = -0.1 x^3 + 2 y^3
    needs its weak x^3, which fits better than x^5 in these seeds (the
    residual sum of squares 3.5, 4.6 and 1.4 noise variances lower), but
    whose Newey-West F-ratio is smaller (55 against 74 in seed 4). Both pass
    the test; ranked by the robust F-ratio x^5 entered (and y^5 in y' of
    seed 4). In seeds 0, 3, 8 and 14 x^5 fits better, and enters."""
    theta, dx, support = _record(_cubic, [2.0, 0.0], 0.01, 25.0, 5, 0.05, seed)
    opt = _fit(theta, dx)
    np.testing.assert_array_equal(opt.coef_ != 0, support)
