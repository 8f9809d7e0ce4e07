"""Property-based tests (hypothesis) of the public entry points.

Every generated input must end either in a result that passes basic sanity
checks (right shapes, finite where promised, coefficients zero outside the
support, ...) or in one of the documented errors (``ValueError`` /
``TypeError`` whose message names the argument; see ``docs/errors.md``), and
only documented warnings may be raised. On top of that, the invariances a user
relies on:

* ``FloatingFStepwise.fit``: random shapes, NaN/inf placed in the library (the
  column is set aside) or in the target (``ValueError``), duplicate, scaled,
  constant and all-zero columns, column units over 200 orders of magnitude.
  The selected terms do not depend on the order of the columns nor on their
  units; scaling by powers of two changes no bit.
* ``MME``: random record lengths, irregular sampling, noise levels from
  1e-8 to 10, missing (NaN) samples, time shifts ``t + c`` (same estimate)
  and units (``y * c`` with ``noise_variance * c**2``: the estimate scales).
* ``discover``: a few short records (each runs MME, a regression and refits).
* ``PowerLibrary.transform``: any float input, against a direct evaluation of
  every column from its signs and exponents.

The hypothesis profile ("ci": derandomised, fixed example counts) is set in
``conftest.py``, which also prints how many cases each entry point received.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pysindy as ps
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from sklearn.exceptions import ConvergenceWarning

from pysindy_mme import (
    MME,
    ExcludedFeaturesWarning,
    FloatingFStepwise,
    PowerLibrary,
    StepwiseCycleWarning,
    discover,
)
from pysindy_mme.discovery import DiscoveryWarning
from pysindy_mme.smoother import DivergenceError
from pysindy_mme.systems import duffing, lotka_volterra, van_der_pol

SYSTEMS = {s.name: s for s in (van_der_pol(), duffing(), lotka_volterra())}
# Assumed models that are linear (f(c x) = c f(x)): estimates scale with units.
LINEAR_ASSUMED = ("van_der_pol", "duffing")


def _readonly(arr):
    arr = np.array(arr, dtype=float)
    arr.setflags(write=False)
    return arr


def _warning_types(record):
    return {type(w.message) for w in record}


# --------------------------------------------------------------------------- #
# FloatingFStepwise.fit


@st.composite
def regression_problems(draw, nonfinite=True, max_p=12):
    """A library ``X`` (units 1) with special columns and a target ``Y``.

    Returns ``(X, Y, info)``; ``Y`` is a sparse combination of columns plus
    noise (possibly none: an exact fit), with each term of order one.
    """
    n = draw(st.integers(2, 60), label="n_samples")
    p = draw(st.integers(1, max_p), label="n_columns")
    n_targets = draw(st.integers(1, 3), label="n_targets")
    seed = draw(st.integers(0, 2**32 - 1), label="seed")
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, p))
    kinds = draw(
        st.lists(
            st.sampled_from(
                ["plain"] * 4 + ["duplicate", "scaled copy", "constant", "zero", "few"]
            ),
            min_size=p,
            max_size=p,
        ),
        label="column kinds",
    )
    for j, kind in enumerate(kinds):
        if kind in ("duplicate", "scaled copy") and j > 0:
            i = draw(st.integers(0, j - 1))
            factor = 1.0 if kind == "duplicate" else rng.choice([-3.0, 0.5, 7.0])
            X[:, j] = factor * X[:, i]
        elif kind == "constant":
            X[:, j] = rng.choice([1.0, -2.5, 1e3])
        elif kind == "zero":
            X[:, j] = 0.0
        elif kind == "few":  # few distinct values: ties and accidental collinearity
            X[:, j] = rng.integers(0, 3, n)
    Y = np.zeros((n, n_targets))
    for t in range(n_targets):
        size = draw(st.integers(0, min(3, p)))
        support = rng.choice(p, size, replace=False)
        Y[:, t] = X[:, support] @ (
            rng.uniform(0.5, 2.0, size) * rng.choice([-1, 1], size)
        )
    noise_exp = draw(st.one_of(st.none(), st.integers(-10, 0)), label="log10 noise")
    if noise_exp is not None:
        Y += 10.0**noise_exp * rng.standard_normal(Y.shape)
    bad = []
    if nonfinite:
        for _ in range(draw(st.integers(0, 3), label="non-finite cells")):
            r, c = draw(st.integers(0, n - 1)), draw(st.integers(0, p - 1))
            value = draw(st.sampled_from([np.nan, np.inf, -np.inf]))
            X[r, c] = value
            bad.append((r, c, value))
    return X, Y, dict(kinds=kinds, noise_exp=noise_exp, bad=bad)


def _fit(X, Y, sample_weight=None, **params):
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        opt = FloatingFStepwise(**params).fit(X, Y, sample_weight=sample_weight)
    allowed = {ExcludedFeaturesWarning, StepwiseCycleWarning}
    assert _warning_types(record) <= allowed, [str(w.message) for w in record]
    return opt


def _support(opt, t):
    return set(np.flatnonzero(opt.coef_[t])) - {opt.constant_feature_}


def _check_stepwise_result(opt, X, Y, w):
    n, p = X.shape
    T = Y.shape[1]
    assert opt.coef_.shape == (T, p) and opt.intercept_.shape == (T,)
    assert np.all(np.isfinite(opt.coef_)) and np.all(np.isfinite(opt.intercept_))
    np.testing.assert_array_equal(opt.ind_, opt.coef_ != 0)
    assert opt.converged_ is True
    # Non-finite columns are set aside (rows of weight 0 are ignored), and
    # set-aside columns are never selected.
    keep = w > 0
    nonfinite = np.flatnonzero(~np.all(np.isfinite(X[keep]), axis=0)).tolist()
    assert set(nonfinite) <= set(opt.excluded_)
    used = set(np.flatnonzero(np.any(opt.coef_ != 0, axis=0)).tolist())
    assert not used & set(opt.excluded_)
    for t in range(T):
        support = _support(opt, t)
        assert support == set(opt.anova_[t].features)
        # The history replays to the final support; every step obeys its rule.
        replay = set()
        for step in opt.steps_[t]:
            if step.action == "add":
                assert step.feature not in replay
                assert step.partial_f >= step.threshold * (1 - 1e-9)
                replay.add(step.feature)
            else:
                assert step.feature in replay
                assert step.partial_f < step.threshold
                replay.remove(step.feature)
        assert replay == support
        assert opt.n_iter_[t] == len(opt.steps_[t])
        if opt.intercept_dropped_[t]:
            assert opt.intercept_[t] == 0
        # Least squares on the support: fitted values against an independent
        # weighted lstsq (on columns scaled to unit size, as SVD needs).
        cols = sorted(support)
        A = X[keep][:, cols]
        colmax = np.maximum(np.abs(A).max(axis=0), 1e-300) if cols else np.ones(0)
        if not opt.intercept_dropped_[t]:
            A = np.column_stack([np.ones(keep.sum()), A / colmax])
        else:
            A = A / colmax
        sw = np.sqrt(w[keep])
        ymax = max(np.abs(Y[keep, t]).max(), 1e-300)
        yt = Y[keep, t] / ymax
        if A.shape[1]:
            beta = np.linalg.lstsq(A * sw[:, None], yt * sw, rcond=None)[0]
            ref = A @ beta
        else:
            ref = np.zeros(keep.sum())
        got = opt.predict(X[keep])[:, t] / ymax
        np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-6)
    with np.errstate(invalid="ignore"):  # NaN in rows of weight 0
        pred = opt.predict(X)
    assert pred.shape == (n, T) and np.all(np.isfinite(pred[keep]))


@settings(max_examples=300)
@given(problem=regression_problems(), data=st.data())
def test_stepwise_fit_sane_or_documented_error(problem, data, case_counter):
    case_counter["FloatingFStepwise.fit"] += 1
    X, Y, info = problem
    n = X.shape[0]
    weights = data.draw(
        st.one_of(st.none(), st.lists(st.integers(0, 3), min_size=n, max_size=n)),
        label="sample_weight",
    )
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=float)
    Xr, Yr = _readonly(X), _readonly(Y)
    wr = None if weights is None else _readonly(w)
    if w.sum() < 2:
        with pytest.raises(ValueError, match="need at least 2 observations"):
            FloatingFStepwise().fit(Xr, Yr, sample_weight=wr)
        return
    opt = _fit(Xr, Yr, sample_weight=wr)
    np.testing.assert_array_equal(Xr, X)  # inputs untouched
    np.testing.assert_array_equal(Yr, Y)
    _check_stepwise_result(opt, X, Y, w)


@settings(max_examples=60)
@given(problem=regression_problems(), data=st.data())
def test_stepwise_nonfinite_target_is_a_documented_error(problem, data, case_counter):
    case_counter["FloatingFStepwise.fit"] += 1
    X, Y, _ = problem
    r = data.draw(st.integers(0, Y.shape[0] - 1))
    c = data.draw(st.integers(0, Y.shape[1] - 1))
    value = data.draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    Y = Y.copy()
    Y[r, c] = value
    kind = "NaN" if np.isnan(value) else "inf"
    with pytest.raises(ValueError, match=rf"y \(the target\) contains {kind}"):
        FloatingFStepwise().fit(_readonly(X), _readonly(Y))


def _column_groups(X):
    """Equivalence classes of columns the optimizer cannot tell apart.

    Collinear columns (after centring, duplicates and scaled copies included)
    share a class, all constant non-zero columns share one, and so do all-zero
    columns; a column with a non-finite value is its own class.
    """
    n, p = X.shape
    group = list(range(p))
    finite = np.all(np.isfinite(X), axis=0)
    Z = np.where(finite, X, 0.0)
    Z = Z / np.maximum(np.abs(Z).max(axis=0), 1e-300)
    C = Z - Z.mean(axis=0)
    norm = np.linalg.norm(C, axis=0)
    for j in range(p):
        if not finite[j]:
            continue
        for i in range(j):
            if not finite[i] or group[i] != i:
                continue
            if norm[i] == 0 and norm[j] == 0:
                if (np.all(Z[:, i] == 0)) == (np.all(Z[:, j] == 0)):
                    group[j] = i
                    break
            elif norm[i] > 0 and norm[j] > 0:
                cos = abs(C[:, i] @ C[:, j]) / (norm[i] * norm[j])
                if cos > 1 - 1e-12:
                    group[j] = i
                    break
    return group


@settings(max_examples=200)
@given(problem=regression_problems(), data=st.data())
def test_stepwise_selection_does_not_depend_on_column_order(
    problem, data, case_counter
):
    case_counter["FloatingFStepwise.fit"] += 2
    X, Y, _ = problem
    p = X.shape[1]
    perm = np.asarray(data.draw(st.permutations(range(p)), label="permutation"))
    group = _column_groups(X)
    a = _fit(X, Y)
    b = _fit(X[:, perm], Y)
    for t in range(Y.shape[1]):
        selected_a = {group[j] for j in np.flatnonzero(a.coef_[t])}
        selected_b = {group[perm[j]] for j in np.flatnonzero(b.coef_[t])}
        assert selected_a == selected_b
        np.testing.assert_allclose(
            b.predict(X[:, perm])[:, t],
            a.predict(X)[:, t],
            rtol=1e-7,
            atol=1e-9 * max(np.abs(Y[:, t]).max(), 1e-300),
        )


@settings(max_examples=200)
@given(problem=regression_problems(), data=st.data())
def test_stepwise_selection_does_not_depend_on_units(problem, data, case_counter):
    case_counter["FloatingFStepwise.fit"] += 2
    X, Y, _ = problem
    p, T = X.shape[1], Y.shape[1]
    col_exp = np.asarray(
        data.draw(st.lists(st.integers(-100, 100), min_size=p, max_size=p)),
        dtype=float,
    )
    y_exp = np.asarray(
        data.draw(st.lists(st.integers(-100, 100), min_size=T, max_size=T)),
        dtype=float,
    )
    a = _fit(X, Y)
    b = _fit(X * 10.0**col_exp, Y * 10.0**y_exp)
    assert set(a.excluded_) == set(b.excluded_)
    for t in range(T):
        assert _support(a, t) == _support(b, t)
    np.testing.assert_array_equal(b.coef_ != 0, a.coef_ != 0)
    # The fitted values convert with the units (to rounding and conditioning).
    np.testing.assert_allclose(
        b.predict(X * 10.0**col_exp) / 10.0**y_exp,
        a.predict(X),
        rtol=1e-6,
        atol=1e-8 * max(np.abs(Y).max(), 1e-300),
    )


@settings(max_examples=100)
@given(problem=regression_problems(), data=st.data())
def test_stepwise_power_of_two_units_change_no_bit(problem, data, case_counter):
    """Units that are powers of two: every step and coefficient is bit-identical."""
    case_counter["FloatingFStepwise.fit"] += 2
    X, Y, _ = problem
    p, T = X.shape[1], Y.shape[1]
    col_exp = data.draw(st.lists(st.integers(-600, 600), min_size=p, max_size=p))
    y_exp = data.draw(st.lists(st.integers(-600, 600), min_size=T, max_size=T))
    col_unit = np.ldexp(1.0, col_exp)
    y_unit = np.ldexp(1.0, y_exp)
    a = _fit(X, Y)
    b = _fit(X * col_unit, Y * y_unit)
    np.testing.assert_array_equal(b.coef_, a.coef_ * y_unit[:, None] / col_unit)
    np.testing.assert_array_equal(b.intercept_, a.intercept_ * y_unit)
    assert [
        [(s.action, s.feature, s.partial_f) for s in steps] for steps in b.steps_
    ] == [[(s.action, s.feature, s.partial_f) for s in steps] for steps in a.steps_]


# --------------------------------------------------------------------------- #
# MME


@st.composite
def mme_problems(draw, systems=tuple(SYSTEMS)):
    name = draw(st.sampled_from(systems), label="system")
    system = SYSTEMS[name]
    n = draw(st.integers(8, 300), label="n_samples")
    seed = draw(st.integers(0, 2**16), label="seed")
    rng = np.random.default_rng(seed)
    if draw(st.booleans(), label="irregular sampling"):
        steps = rng.uniform(0.3, 1.7, n - 1) / system.rate_hz
        t = np.concatenate([[0.0], np.cumsum(steps)])
    else:
        t = np.arange(n) / system.rate_hz
    noise_variance = 10.0 ** draw(st.integers(-8, 1), label="log10 noise variance")
    data = system.measure(seed, noise_variance=noise_variance, t=t)
    y = data.y.copy()
    missing = draw(st.sampled_from([0.0, 0.0, 0.1, 0.4]), label="missing fraction")
    if missing:
        y[rng.random(y.shape) < missing] = np.nan
    return system, t, y, noise_variance


def _mme(system, noise_variance, **kwargs):
    return MME(
        system.assumed_model,
        system.n_states,
        measured=list(system.measured),
        noise_variance=noise_variance,
        error_states=list(system.error_states),
        **kwargs,
    )


def _run_mme(mme, y, t):
    """Fit; return (mme, warnings) or (None, documented error)."""
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        try:
            mme.fit(y, t)
        except ValueError as exc:
            # e.g. too few observed samples to see every state
            assert "measured" in str(exc) or "y (the measurements)" in str(exc), exc
            return None, exc
        except DivergenceError as exc:
            assert "assumed_model" in str(exc) or "diverged" in str(exc), exc
            return None, exc
    types = _warning_types(record)
    assert types <= {ConvergenceWarning, UserWarning}, [str(w.message) for w in record]
    return mme, record


def _check_mme_result(mme, system, y, t, record):
    N, n = t.size, system.n_states
    assert mme.smoothed_x_.shape == (N, n) and mme.d_.shape == (N, n)
    assert np.all(np.isfinite(mme.smoothed_x_)) and np.all(np.isfinite(mme.d_))
    assert np.all(np.isfinite(mme.derivative_))
    others = [i for i in range(n) if i not in system.error_states]
    assert np.all(mme.d_[:, others] == 0)
    assert mme.d_intervals_.shape == (N - 1, len(system.error_states))
    # Residuals are missing exactly where the measurements are.
    np.testing.assert_array_equal(np.isnan(mme.residuals_), np.isnan(y))
    assert mme.covariance_ratio_.shape == (y.shape[1],)
    assert np.all(np.isfinite(mme.covariance_ratio_) & (mme.covariance_ratio_ >= 0))
    assert np.isfinite(mme.W_) and mme.W_ > 0
    messages = [str(w.message) for w in record]
    if not mme.converged_:
        assert any("did not converge" in m for m in messages)
    if mme.W_at_bound_:
        assert any("covariance constraint cannot be met" in m for m in messages)
    else:
        # The covariance constraint holds (to the W search's tolerance): the
        # mean over channels of mean(r_j^2) / R_jj is 1 (R is diagonal here).
        per_channel = np.nanmean(mme.residuals_**2, axis=0)
        ratio = per_channel / np.diag(mme.noise_variance_)
        np.testing.assert_allclose(ratio, mme.covariance_ratio_, rtol=1e-10)
        assert np.mean(ratio) == pytest.approx(1.0, rel=0.03)


@settings(max_examples=120)
@given(
    problem=mme_problems(),
    error_model=st.sampled_from(["white", "random_walk"]),
)
def test_mme_sane_or_documented_error(problem, error_model, case_counter):
    case_counter["MME.fit"] += 1
    system, t, y, noise_variance = problem
    y_ro, t_ro = _readonly(y), _readonly(t)
    mme, record = _run_mme(
        _mme(system, noise_variance, error_model=error_model), y_ro, t_ro
    )
    np.testing.assert_array_equal(y_ro, y)
    if mme is not None:
        _check_mme_result(mme, system, y, t, record)


@settings(max_examples=40)
@given(
    problem=mme_problems(),
    shift=st.one_of(st.integers(-1000, 1000), st.floats(-1e3, 1e3)),
)
def test_mme_time_shift_gives_the_same_estimate(problem, shift, case_counter):
    """The example systems are autonomous: t + c must not change the estimate."""
    case_counter["MME.fit"] += 2
    system, t, y, noise_variance = problem
    a, _ = _run_mme(_mme(system, noise_variance), y, t)
    b, _ = _run_mme(_mme(system, noise_variance), y, t + shift)
    assert (a is None) == (b is None)
    if a is None:
        return
    assert a.W_at_bound_ == b.W_at_bound_
    assert b.W_ == pytest.approx(a.W_, rel=1e-5)
    scale = np.abs(a.smoothed_x_).max()
    np.testing.assert_allclose(b.smoothed_x_, a.smoothed_x_, rtol=0, atol=1e-6 * scale)
    d_scale = max(np.abs(a.d_).max(), 1e-12)
    np.testing.assert_allclose(b.d_, a.d_, rtol=0, atol=1e-5 * d_scale)
    np.testing.assert_allclose(b.t_, a.t_ + shift)


@settings(max_examples=40)
@given(problem=mme_problems(LINEAR_ASSUMED), log_unit=st.integers(-6, 6))
def test_mme_units_scale_the_estimate(problem, log_unit, case_counter):
    """y * c with noise variance * c**2: states and d scale by c, W by c**-2.

    Restricted to noise variances in [1e-14, 1e14] in the new units: beyond,
    MME wrongly reports a singular problem (a defect, see
    ``test_reliability.py::test_mme_units_far_from_one``).
    """
    system, t, y, noise_variance = problem
    c = 10.0**log_unit
    assume(1e-14 <= noise_variance * c**2 <= 1e14)
    case_counter["MME.fit"] += 2
    a, _ = _run_mme(_mme(system, noise_variance), y, t)
    b, _ = _run_mme(_mme(system, noise_variance * c**2), y * c, t)
    assert (a is None) == (b is None)
    if a is None:
        return
    assert a.W_at_bound_ == b.W_at_bound_
    assert b.W_ * c**2 == pytest.approx(a.W_, rel=1e-5)
    scale = np.abs(a.smoothed_x_).max()
    np.testing.assert_allclose(b.smoothed_x_ / c, a.smoothed_x_, atol=1e-6 * scale)
    d_scale = max(np.abs(a.d_).max(), 1e-12)
    np.testing.assert_allclose(b.d_ / c, a.d_, rtol=0, atol=1e-5 * d_scale)
    np.testing.assert_allclose(b.covariance_ratio_, a.covariance_ratio_, rtol=1e-6)


@settings(max_examples=40)
@given(
    problem=mme_problems(),
    lead=st.integers(0, 4),
    trail=st.integers(0, 4),
    log_w=st.integers(-2, 2),
)
def test_mme_missing_samples_at_the_ends_change_nothing(
    problem, lead, trail, log_w, case_counter
):
    """NaN measurements are missing samples: padding a record with missing
    samples before and after it leaves the estimate on the record unchanged
    (no prior on the initial state, and nothing to fit there: d = 0 and the
    states follow the model). ``W`` is fixed so that the two problems are the
    same optimisation."""
    case_counter["MME.fit"] += 2
    system, t, y, noise_variance = problem
    if lead == trail == 0:
        trail = 1
    h = float(np.mean(np.diff(t)))
    W = 10.0**log_w * h / noise_variance
    t_pad = np.concatenate(
        [t[0] - h * np.arange(lead, 0, -1), t, t[-1] + h * np.arange(1, trail + 1)]
    )
    nan_rows = np.full((1, y.shape[1]), np.nan)
    y_pad = np.vstack([np.repeat(nan_rows, lead, 0), y, np.repeat(nan_rows, trail, 0)])
    a, _ = _run_mme(_mme(system, noise_variance, W=W), y, t)
    b, _ = _run_mme(_mme(system, noise_variance, W=W), y_pad, t_pad)
    assert (a is None) == (b is None)
    if a is None:
        return
    N = t.size
    scale = np.abs(a.smoothed_x_).max()
    np.testing.assert_allclose(
        b.smoothed_x_[lead : lead + N], a.smoothed_x_, rtol=0, atol=1e-6 * scale
    )
    d_scale = max(np.abs(a.d_intervals_).max(), 1e-9 * scale / h)
    inside = b.d_intervals_[lead : lead + N - 1]
    np.testing.assert_allclose(inside, a.d_intervals_, rtol=0, atol=1e-5 * d_scale)
    outside = np.concatenate([b.d_intervals_[:lead], b.d_intervals_[lead + N - 1 :]])
    assert np.all(np.abs(outside) <= 1e-5 * d_scale)


# --------------------------------------------------------------------------- #
# discover


_DISCOVERY_LIBRARIES = {
    "poly2": lambda: ps.PolynomialLibrary(degree=2),
    "poly3": lambda: ps.PolynomialLibrary(degree=3),
    "power": lambda: PowerLibrary(powers=(-1, 1, 2), abs_powers=(1,)),
}


def _discovery_problem(t_end, seed, noise_variance, missing, library):
    """A short Van der Pol record (20 Hz), x1 measured, as in the paper."""
    system = van_der_pol()
    t = system.time(t_end, 20.0)
    y = system.measure(seed, noise_variance=noise_variance, t=t).y.copy()
    if missing:
        y[np.random.default_rng(seed).random(y.shape) < 0.1] = np.nan
    return system, t, y, noise_variance, _DISCOVERY_LIBRARIES[library]()


discovery_problems = st.builds(
    _discovery_problem,
    t_end=st.sampled_from([2.0, 5.0]),
    seed=st.integers(0, 1000),
    noise_variance=st.sampled_from([1e-4, 1e-2]),
    missing=st.booleans(),
    library=st.sampled_from(sorted(_DISCOVERY_LIBRARIES)),
)


@settings(max_examples=4)
@given(problem=discovery_problems)
# Cases the search must always include: the paper's library kind (Table I,
# with singular negative powers) and a record too short for a cubic library.
@example(problem=_discovery_problem(5.0, 7, 1e-2, True, "power"))
@example(problem=_discovery_problem(0.35, 3, 1e-2, False, "poly3"))
def test_discover_sane_or_documented_error(problem, case_counter):
    case_counter["discover"] += 1
    system, t, y, noise_variance, library = problem
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        try:
            result = discover(
                _readonly(y),
                _readonly(t),
                assumed_model=system.assumed_model,
                n_states=2,
                measured=[0],
                noise_variance=noise_variance,
                error_states=[1],
                feature_library=library,
                feature_names=["x1", "x2"],
            )
        except ValueError as exc:
            assert "samples are needed" in str(exc), exc  # record too short
            return
    allowed = {
        DiscoveryWarning,
        ExcludedFeaturesWarning,
        StepwiseCycleWarning,
        ConvergenceWarning,
        UserWarning,
    }
    assert _warning_types(record) <= allowed, [str(w.message) for w in record]
    assert set(result.terms) == {"x2"}
    names = set(result.library_feature_names) | {"1"}
    for feature, coefficient in result.terms["x2"].items():
        assert feature in names and np.isfinite(coefficient)
    x_hat = result.mme.smoothed_x_
    rhs = result.extended_model.predict(x_hat)
    assert rhs.shape == x_hat.shape and np.all(np.isfinite(rhs))
    for rmse in (result.gain.rmse_assumed, result.gain.rmse_extended):
        assert rmse.shape == (1,) and np.all(np.isfinite(rmse) & (rmse > 0))
    if result.found_correction:
        assert result.gain.rmse_extended[0] <= result.gain.rmse_assumed[0]
    assert "x2" in str(result)
    json.dumps(result.to_dict())


# --------------------------------------------------------------------------- #
# PowerLibrary.transform

_SPECIAL = [0.0, -0.0, 1.0, -1.0, 1e-200, -1e-200, 1e200, np.nan, np.inf, -np.inf]


def _reference_columns(lib, x):
    """Every column straight from ``signs_`` and ``exponents_``."""
    out = np.ones((x.shape[0], lib.n_output_features_))
    with np.errstate(all="ignore"):
        for c, (s_row, k_row) in enumerate(zip(lib.signs_, lib.exponents_)):
            col = None
            for v in range(x.shape[1]):
                s, k = int(s_row[v]), int(k_row[v])
                if s == 0 and k == 0:
                    continue
                factor = np.power(np.abs(x[:, v]), float(k))
                if s:
                    factor = np.copysign(factor, x[:, v])
                col = factor if col is None else col * factor
            if col is not None:
                out[:, c] = col
    return out


@settings(max_examples=250)
@given(
    n_features=st.integers(1, 3),
    powers=st.lists(
        st.sampled_from([-3, -2, -1, 1, 2, 3]), min_size=1, max_size=4, unique=True
    ),
    abs_powers=st.lists(st.sampled_from([-3, -1, 1, 3]), max_size=3, unique=True),
    flags=st.tuples(st.booleans(), st.booleans(), st.booleans(), st.booleans()),
    nonfinite=st.sampled_from(["keep", "nan", "zero"]),
    data=st.data(),
)
def test_power_library_transform(
    n_features, powers, abs_powers, flags, nonfinite, data, case_counter
):
    case_counter["PowerLibrary.transform"] += 1
    cross, signed_abs, power_products, constant = flags
    x = data.draw(
        hnp.arrays(
            float,
            st.tuples(st.integers(0, 6), st.just(n_features)),
            elements=st.one_of(
                st.floats(-1e3, 1e3), st.sampled_from(_SPECIAL), st.floats()
            ),
        ),
        label="x",
    )
    lib = PowerLibrary(
        powers=powers,
        abs_powers=abs_powers,
        cross_products=cross,
        signed_abs_products=signed_abs,
        power_products=power_products,
        include_constant=constant,
        nonfinite=nonfinite,
    ).fit(np.ones((1, n_features)))
    names = lib.get_feature_names()
    assert len(names) == len(set(names)) == lib.n_output_features_
    x_ro = _readonly(x)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the library never warns
        if nonfinite == "zero" and not np.all(np.isfinite(x)):
            with pytest.raises(ValueError, match="nonfinite='zero'"):
                lib.transform(x_ro)
            return
        out = np.asarray(lib.transform(x_ro))
    np.testing.assert_array_equal(x_ro, x)
    assert out.shape == (x.shape[0], lib.n_output_features_)
    ref = _reference_columns(lib, x)
    if nonfinite == "nan":
        ref = np.where(np.isfinite(ref), ref, np.nan)
    elif nonfinite == "zero":
        ref = np.where(np.isfinite(ref), ref, 0.0)
        assert np.all(np.isfinite(out))
    # Same non-finite values at the same places; finite values to a few ulp
    # (numpy's vectorised power may round differently from the scalar loop).
    finite = np.isfinite(ref)
    np.testing.assert_array_equal(np.isfinite(out), finite)
    np.testing.assert_array_equal(out[~finite], ref[~finite])
    np.testing.assert_allclose(out[finite], ref[finite], rtol=1e-14, atol=1e-300)
