"""Property-based tests (hypothesis) of ``FloatingFStepwise.fit``.

Every generated input must end either in a result that passes basic sanity
checks (right shapes, finite coefficients, zero outside the support, a step
history that replays to the support, least squares on the support against an
independent solver) or in a documented error (``ValueError`` whose message
names the argument; see ``docs/errors.md``), and only documented warnings may
be raised. Inputs: random shapes, NaN/inf placed in the library (the column
is set aside) or in the target (``ValueError``), duplicate, scaled, constant
and all-zero columns, column units over 200 orders of magnitude. The
selected terms do not depend on the order of the columns nor on their units;
scaling by powers of two changes no bit.

The hypothesis profile ("ci": derandomised, fixed example counts) is set in
``tests/conftest.py``, which also prints how many cases each entry point
received.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reliability_support import readonly, warning_types

from pysindy_mme import (
    ExcludedFeaturesWarning,
    FloatingFStepwise,
    StepwiseCycleWarning,
)
from pysindy_mme.optimizers import ConstantNotInLibraryWarning


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
    allowed = {
        ExcludedFeaturesWarning,
        StepwiseCycleWarning,
        ConstantNotInLibraryWarning,
    }
    assert warning_types(record) <= allowed, [str(w.message) for w in record]
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
    # rows whose library values or targets are all NaN are dropped first,
    # as pysindy's BaseOptimizer.fit drops them
    all_nan = np.all(np.isnan(X), axis=1) | np.all(np.isnan(Y), axis=1)
    keep = (w > 0) & ~all_nan
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


@pytest.mark.slow  # many generated cases, seconds each: CI and the full run
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
    Xr, Yr = readonly(X), readonly(Y)
    wr = None if weights is None else readonly(w)
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
    if kind == "NaN" and Y.shape[1] == 1:
        # A row whose targets are all NaN is dropped, as pysindy's
        # BaseOptimizer.fit drops it: the fit is the fit without that row.
        keep = np.arange(Y.shape[0]) != r
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                ref = FloatingFStepwise().fit(X[keep], Y[keep])
            except ValueError as exc:
                with pytest.raises(ValueError, match=re.escape(str(exc)[:20])):
                    FloatingFStepwise().fit(readonly(X), readonly(Y))
                return
            got = FloatingFStepwise().fit(readonly(X), readonly(Y))
        np.testing.assert_array_equal(got.coef_, ref.coef_)
        return
    with pytest.raises(ValueError, match=rf"y \(the target\) contains {kind}"):
        FloatingFStepwise().fit(readonly(X), readonly(Y))


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


@pytest.mark.slow  # many generated cases, seconds each: CI and the full run
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


@pytest.mark.slow  # many generated cases, seconds each: CI and the full run
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
