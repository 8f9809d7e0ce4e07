"""A library FloatingFStepwise never holds whole (issue 20, "Streamed candidates").

The streamed path reads the library block by block (``StreamedDesign``: a
callable, a pysindy polynomial library, a ``dask.array``, optionally on a
``distributed.Client``); its decisions must be those of the in-memory path.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from pysindy_mme.optimizers import FloatingFStepwise, StreamedDesign


def _fit(x, y):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the set-aside columns are listed
        return FloatingFStepwise().fit(x, y)


def _wide_problem(seed, n=400, p=600, time_ordered=False):
    rng = np.random.default_rng(seed)
    if time_ordered:  # smooth signals along a trajectory (the robust rule)
        t = np.linspace(0, 20, n)[:, None]
        X = np.sin(rng.uniform(0.2, 3.0, p) * t + rng.uniform(0, 6, p))
        X += 0.05 * rng.standard_normal((n, p))
    else:
        X = rng.standard_normal((n, p))
    true = np.sort(rng.choice(p, 6, replace=False))
    coef = rng.uniform(0.5, 2.0, 6) * rng.choice([-1.0, 1.0], 6)
    y = X[:, true] @ coef + 0.4 + 0.5 * rng.standard_normal(n)
    # awkward columns: a duplicate, a multiple, a constant, a NaN column
    X[:, 3] = X[:, 10]
    X[:, 4] = 2.0 * X[:, 11]
    X[:, 5] = 1.0
    X[:, 6] = np.nan
    return X, y


def _streamed(X, block_columns):
    n, p = X.shape
    calls = []

    def block(start, stop):
        calls.append(stop - start)
        return X[:, start:stop].copy()

    return StreamedDesign(block, n, p, block_columns=block_columns), calls


@pytest.mark.parametrize("seed", range(6))
def test_streamed_path_decides_as_the_in_memory_path(seed):
    """Same support, steps and coefficients (to 1e-10) as the dense path."""
    X, y = _wide_problem(seed, time_ordered=seed % 2 == 1)
    before = X.copy()
    dense = _fit(X, y)
    design, calls = _streamed(X, block_columns=[7, 64, 600][seed % 3])
    streamed = _fit(design, y)
    np.testing.assert_array_equal(streamed.ind_, dense.ind_)
    np.testing.assert_allclose(streamed.coef_, dense.coef_, rtol=0, atol=1e-10)
    assert [(s.action, s.feature) for s in streamed.steps_[0]] == [
        (s.action, s.feature) for s in dense.steps_[0]
    ]
    assert streamed.excluded_ == dense.excluded_
    assert streamed.rows_in_time_order_ == dense.rows_in_time_order_
    # never more than one block at a time, and the input is untouched
    assert max(calls) <= design.block_columns
    np.testing.assert_array_equal(X, before)


def test_streamed_with_weights_and_two_targets():
    X, y = _wide_problem(7)
    rng = np.random.default_rng(7)
    Y = np.column_stack([y, X[:, [20, 30]] @ [1.0, -2.0] + rng.standard_normal(400)])
    w = rng.uniform(0.0, 2.0, 400)
    w[:5] = 0.0  # rows of weight 0 are dropped, from the design as well
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dense = FloatingFStepwise().fit(X, Y, sample_weight=w)
        design, _ = _streamed(X, 50)
        streamed = FloatingFStepwise().fit(design, Y, sample_weight=w)
    np.testing.assert_array_equal(streamed.ind_, dense.ind_)
    np.testing.assert_allclose(streamed.coef_, dense.coef_, rtol=0, atol=1e-10)


def test_wide_row_major_screen_matches_column_blocks():
    """The in-memory screen by row chunks gives the column-block statistics."""
    from pysindy_mme.optimizers import screening

    X, _ = _wide_problem(3, n=300, p=500)
    sw = np.sqrt(np.random.default_rng(0).uniform(0.5, 2.0, 300))
    rows = screening.screen_columns(X, sw, float((sw**2).sum()), 1e-8)
    cols = screening.screen_columns(
        np.asfortranarray(X), sw, float((sw**2).sum()), 1e-8
    )
    assert rows.excluded == cols.excluded
    assert rows.carrier == cols.carrier
    np.testing.assert_array_equal(rows.eligible, cols.eligible)
    np.testing.assert_array_equal(rows.scale, cols.scale)
    for name in ("mean", "cn2", "un2"):
        np.testing.assert_allclose(getattr(rows, name), getattr(cols, name), 1e-12)


def test_from_library_streams_the_pysindy_columns():
    ps = pytest.importorskip("pysindy")
    rng = np.random.default_rng(0)
    x = rng.standard_normal((200, 4))
    library = ps.PolynomialLibrary(degree=3).fit(x)
    design = StreamedDesign.from_library(library, x, block_columns=9)
    full = library.transform(x)
    assert design.shape == full.shape
    assert design.names == library.get_feature_names()
    np.testing.assert_allclose(design[:, :], np.asarray(full), rtol=1e-14)
    y = 2.0 * full[:, 5] - full[:, 17] + 0.1 * rng.standard_normal(200)
    model = _fit(design, y)
    assert set(np.flatnonzero(model.coef_[0])) == {5, 17}
    assert model.feature_names_ == library.get_feature_names()


@pytest.mark.parametrize("degree, bias", [(1, True), (2, True), (3, False)])
def test_polynomial_is_pysindys_library(degree, bias):
    ps = pytest.importorskip("pysindy")
    x = np.random.default_rng(1).standard_normal((50, 4))
    library = ps.PolynomialLibrary(degree=degree, include_bias=bias).fit(x)
    design = StreamedDesign.polynomial(x, degree, include_bias=bias, block_columns=4)
    assert design.names == library.get_feature_names()
    np.testing.assert_allclose(design[:, :], library.transform(x), rtol=1e-14)


def test_bad_streamed_input_is_refused_with_the_argument_named():
    X = np.ones((10, 4))
    with pytest.raises(ValueError, match="block must be a callable"):
        StreamedDesign(X, 10, 4)
    with pytest.raises(ValueError, match="n_columns"):
        StreamedDesign(lambda a, b: X[:, a:b], 10, 0)
    with pytest.raises(ValueError, match="names has 2 entries"):
        StreamedDesign(lambda a, b: X[:, a:b], 10, 4, names=["a", "b"])
    with pytest.raises(ValueError, match="client must be"):
        StreamedDesign(lambda a, b: X[:, a:b], 10, 4, client="localhost")
    wrong = StreamedDesign(lambda a, b: X[:, a:b].T, 10, 4)
    with pytest.raises(ValueError, match=r"block\(0, 4\) returned shape"):
        FloatingFStepwise().fit(wrong, np.ones(10))
    ok = StreamedDesign(lambda a, b: X[:, a:b], 10, 4)
    with pytest.raises(ValueError, match="y has 9 rows"):
        FloatingFStepwise().fit(ok, np.ones(9))


def test_dask_array_design():
    da = pytest.importorskip("dask.array", reason="dask is an optional extra")
    X, y = _wide_problem(2)
    dense = _fit(X, y)
    lazy = _fit(da.from_array(X, chunks=(400, 128)), y)
    np.testing.assert_array_equal(lazy.ind_, dense.ind_)
    np.testing.assert_allclose(lazy.coef_, dense.coef_, rtol=0, atol=1e-10)


class _Columns:
    """Columns made from a seed (picklable: it goes to the workers)."""

    def __init__(self, n, seed):
        self.base = np.random.default_rng(seed).standard_normal((n, 60))

    def __call__(self, start, stop):
        j = np.arange(start, stop)
        return self.base[:, j % 60] * self.base[:, (j // 60) % 60] + np.sin(j)


def test_local_cluster_gives_the_serial_support():
    pytest.importorskip("dask", reason="dask is an optional extra")
    distributed = pytest.importorskip("distributed", reason="an optional extra")
    n, p = 600, 3000
    make = _Columns(n, 0)
    rng = np.random.default_rng(1)
    true = np.sort(rng.choice(p, 5, replace=False))
    y = make.base[:, true % 60] * make.base[:, (true // 60) % 60] + np.sin(true)
    y = y @ rng.uniform(1.0, 2.0, 5) + 0.3 * rng.standard_normal(n)
    serial = _fit(StreamedDesign(make, n, p, block_columns=50), y)
    with (
        distributed.LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        design = StreamedDesign(make, n, p, block_columns=50, client=client)
        remote = _fit(design, y)
    np.testing.assert_array_equal(remote.ind_, serial.ind_)
    np.testing.assert_array_equal(remote.coef_, serial.coef_)
    assert remote.excluded_ == serial.excluded_
