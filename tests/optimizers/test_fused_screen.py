"""The fused one-pass screen of wide row-major arrays (issue 20).

Its centred statistics come from raw sums where cancellation is limited and
from the two-pass arithmetic elsewhere; its products ``x^T v`` replace the
first step's product with the library. These tests pin both to the
accurate two-pass values and the fits to the column-block path.
"""

import numpy as np
import pytest

from pysindy_mme.optimizers import FloatingFStepwise, screening


def _hard_library(n=400, p=300, seed=5):
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, p))
    X[:, 1] = 3.0  # exactly constant
    X[:, 2] = 1e6 + 1e-3 * rng.standard_normal(n)  # near-constant
    X[:, 3] *= 1e200  # huge
    X[:, 4] *= 1e-200  # tiny
    X[:, 5] = np.nan
    X[7, 6] = np.inf
    X[:, 7] = 0.0
    X[:, 8] = 10.0 + rng.standard_normal(n)  # mean/sd 10: beyond the raw limit
    X[:, 9] = 2.0 + rng.standard_normal(n)  # mean/sd 2: raw sums
    X[:, 10] = 2.0 * X[:, 11] + 1.0  # collinear
    X[:, 12] = X[:, 13]  # duplicate
    X[:, 14] *= 2.0**-450  # scaled before squaring
    X[:, 15] *= 2.0**450
    X[:, 16] = 1e-300 + 1e-310 * rng.standard_normal(n)  # subnormal noise
    X[:, 17] = -7.0 + 1e-9 * rng.standard_normal(n)
    X[:, 18] = 1e100 * rng.standard_normal(n)  # large, raw sums
    X[:, 20] = 7.0 + rng.standard_normal(n)  # mean/sd 7: raw sums, near the limit
    return X


def _weights(kind, n, rng):
    if kind == "unit":
        return np.ones(n)
    w = rng.uniform(0.0, 2.0, n)
    if kind == "zeros":
        w[::7] = 0.0
    return np.sqrt(w)


def _two_pass(X, sw, fused):
    """cn2 and fingerprints of every column by the two-pass arithmetic, with
    the fused pass's own means (so that only the arithmetic differs)."""
    n, p = X.shape
    G = screening._fingerprint_rows(n)
    fin = fused["finite"]
    sc = fused["scale"]
    m = fused["mean"] / sc
    top = fused["max_abs"]
    late = (top >= screening._LATE_MIN) & (top <= screening._LATE_MAX)
    unit = bool(np.all(sw == 1.0))
    with np.errstate(over="ignore", invalid="ignore"):
        cn2, fp = screening._centred_statistics(
            X, np.arange(p), fin, m, sw, unit, late, sc, G
        )
        late_sc = np.where(late, sc, 1.0)
    return cn2 * late_sc**2, fp * late_sc


@pytest.mark.parametrize("kind", ["unit", "zeros", "random"])
def test_fused_statistics_equal_the_two_pass_ones(kind, monkeypatch):
    X = _hard_library()
    n, p = X.shape
    sw = _weights(kind, n, np.random.default_rng(1))
    w = sw**2
    G = screening._fingerprint_rows(n)
    redone = []
    two_pass = screening._centred_statistics

    def record(x, cols, *args):
        redone.extend(cols.tolist())
        return two_pass(x, cols, *args)

    monkeypatch.setattr(screening, "_centred_statistics", record)
    fused = screening._row_chunk_statistics(X, w, sw, float(w.sum()), G)
    monkeypatch.setattr(screening, "_centred_statistics", two_pass)
    # the hard columns were read again, the ordinary ones were not
    for j in (1, 2, 3, 4, 5, 6, 7, 8, 14, 15, 16, 17):
        assert j in redone, j
    for j in (0, 9, 18, *range(19, p)):
        assert j not in redone, j
    cn2, fp = _two_pass(X, sw, fused)
    ok = fused["finite"]
    np.testing.assert_allclose(fused["cn2"][ok], cn2[ok], rtol=1e-12, atol=0)
    # fingerprints: in units of |g| * sqrt(cn2), the scale the screen reads them in
    unit_fp = np.linalg.norm(G, axis=1)[:, None] * np.sqrt(cn2)
    err = (
        np.abs(fused["fprint"] - fp)[:, ok] / np.where(unit_fp > 0, unit_fp, 1.0)[:, ok]
    )
    assert np.all(err <= 1e-12)
    # and the fused pass's extremes, scales and means are the column-block path's
    blocks = screening._block_statistics(np.asfortranarray(X), w, sw, float(w.sum()), G)
    for key in ("finite", "exact_const", "max_abs", "scale"):
        np.testing.assert_array_equal(fused[key], blocks[key])
    np.testing.assert_array_equal(fused["first"][ok], blocks["first"][ok])
    mean_unit = np.sqrt(np.maximum(cn2 + 0.0, 0.0) / w.sum()) + np.abs(blocks["mean"])
    assert np.all(np.abs(fused["mean"] - blocks["mean"])[ok] <= 1e-13 * mean_unit[ok])


def test_hard_library_screens_as_the_column_blocks():
    X = _hard_library()
    n = X.shape[0]
    sw = _weights("zeros", n, np.random.default_rng(2))
    n_eff = float((sw**2).sum())
    with np.errstate(all="ignore"):
        rows = screening.screen_columns(X, sw, n_eff, 1e-8)
        cols = screening.screen_columns(np.asfortranarray(X), sw, n_eff, 1e-8)
    assert rows.excluded == cols.excluded
    np.testing.assert_array_equal(rows.eligible, cols.eligible)
    np.testing.assert_array_equal(rows.scale, cols.scale)
    assert "duplicate of f12" == rows.excluded[
        13
    ] or "duplicate of f13" == rows.excluded.get(12)
    assert 10 in rows.excluded or 11 in rows.excluded


def test_fused_pass_does_not_depend_on_the_number_of_threads(monkeypatch):
    X = np.random.default_rng(3).standard_normal((300, 9000))
    sw = np.ones(300)
    G = screening._fingerprint_rows(300)
    out = []
    for workers in (1, 2, 3):
        monkeypatch.setattr(screening, "FUSED_WORKERS", workers)
        out.append(screening._row_chunk_statistics(X, sw, sw, 300.0, G, sw[None]))
    for other in out[1:]:
        for key in out[0]:
            np.testing.assert_array_equal(out[0][key], other[key])


@pytest.mark.parametrize("kind", ["unit", "zeros"])
def test_screen_products_are_the_library_products(kind):
    rng = np.random.default_rng(4)
    X = _hard_library(seed=6)
    n = X.shape[0]
    sw = _weights(kind, n, rng)
    V = rng.standard_normal((3, n))
    with np.errstate(all="ignore"):
        screen = screening.screen_columns(X, sw, float((sw**2).sum()), 1e-8, products=V)
    assert screen.products.shape == (3, X.shape[1])
    for v, got in zip(V, screen.products):
        want = screening.xt(X, v, screen.eligible)
        # relative to the size of the terms summed
        size = np.abs(v) @ np.abs(np.where(screen.eligible, X, 0.0))
        assert np.all(np.abs(got - want) <= 1e-13 * size)
        assert np.all(got[~screen.eligible] == 0.0)
    # too many vectors, or a column-major array: not computed
    assert (
        screening.screen_columns(
            X[:, 19:],
            sw,
            float((sw**2).sum()),
            1e-8,
            products=np.ones((screening.MAX_PRODUCTS + 1, n)),
        ).products
        is None
    )
    assert (
        screening.screen_columns(
            np.asfortranarray(X[:, 19:]), sw, float((sw**2).sum()), 1e-8, products=V
        ).products
        is None
    )


@pytest.mark.parametrize("weighted", [False, True])
def test_wide_fit_decides_as_the_column_block_path(weighted):
    """Row-major (fused screen, first X^T e from the screen) and column-major
    (column blocks, the product with the library) fits decide identically."""
    rng = np.random.default_rng(7)
    n, p = 400, 3000
    X = rng.standard_normal((n, p))
    X[:, 5] += 4.0  # a shifted column (two-pass statistics)
    true = [3, 5, 100, 2000]
    y = (
        X[:, true] @ np.array([1.5, -2.0, 1.0, 1.2])
        + 0.3
        + 0.5 * rng.standard_normal(n)
    )
    Y = np.column_stack([y, y[::-1] + X[:, 7]])
    sw = rng.uniform(0.0, 2.0, n) if weighted else None
    a = FloatingFStepwise(fit_intercept=True).fit(X, Y, sample_weight=sw)
    b = FloatingFStepwise(fit_intercept=True).fit(
        np.asfortranarray(X), Y, sample_weight=sw
    )
    np.testing.assert_array_equal(a.ind_, b.ind_)
    assert [[s.feature for s in steps] for steps in a.steps_] == [
        [s.feature for s in steps] for steps in b.steps_
    ]
    np.testing.assert_allclose(a.coef_, b.coef_, rtol=1e-10, atol=1e-12)
    assert set(true) <= set(np.flatnonzero(a.ind_[0]))
