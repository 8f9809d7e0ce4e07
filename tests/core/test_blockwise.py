"""Block-by-block reductions give exactly the whole-array expressions."""

import numpy as np
import pytest

from pysindy_mme.core import blockwise
from pysindy_mme.core.blockwise import (
    BLOCK_ROWS,
    all_finite,
    first_true,
    max_abs,
    row_max_abs,
)

# shapes below, at and beyond one block, with and without trailing axes
SHAPES = [(0, 2), (1,), (7, 2), (BLOCK_ROWS, 2, 2), (2 * BLOCK_ROWS + 5, 2, 3)]


@pytest.mark.parametrize("shape", SHAPES)
def test_max_abs_is_numpys(shape):
    rng = np.random.default_rng(len(shape) + shape[0])
    a = rng.standard_normal(shape) * 10.0 ** rng.integers(-5, 5, size=shape)
    b = rng.standard_normal(shape)
    assert max_abs(a) == np.max(np.abs(a), initial=0.0)
    assert max_abs(a, b) == np.max(np.abs(a - b), initial=0.0)
    assert max_abs(a, initial=-1.0) == np.max(np.abs(a), initial=-1.0)


def test_max_abs_of_a_strided_view_and_of_a_scalar():
    rng = np.random.default_rng(3)
    a = rng.standard_normal((3 * BLOCK_ROWS + 1, 4))
    view = a[::3, 1::2]
    assert max_abs(view) == np.max(np.abs(view))
    assert max_abs(np.float64(-2.5)) == 2.5


def test_max_abs_is_nan_when_any_entry_is_nan():
    a = np.zeros((2 * BLOCK_ROWS + 3, 2))
    a[-1, 1] = np.nan  # in the last block: every block before is read
    a[5, 0] = 1e300
    assert np.isnan(max_abs(a))
    assert np.isnan(max_abs(np.zeros_like(a), a))
    # inf is a number: the largest one
    a[-1, 1] = -np.inf
    assert max_abs(a) == np.inf


def test_max_abs_rejects_different_shapes():
    with pytest.raises(ValueError, match="shapes differ"):
        max_abs(np.zeros((3, 2)), np.zeros((3, 1)))


@pytest.mark.parametrize("shape", SHAPES)
def test_row_max_abs_is_numpys(shape):
    rng = np.random.default_rng(shape[0])
    a = rng.standard_normal(shape)
    if a.size:
        a.flat[a.size // 2] = np.nan
    axes = tuple(range(1, a.ndim))
    expected = np.abs(a).max(axis=axes) if axes else np.abs(a)
    np.testing.assert_array_equal(row_max_abs(a), expected)


def test_all_finite():
    a = np.ones((2 * BLOCK_ROWS + 1, 2, 2))
    assert all_finite(a) and all_finite(np.float64(1.0)) and all_finite(a[:0])
    for value in (np.nan, np.inf, -np.inf):
        b = a.copy()
        b[-1, 1, 0] = value
        assert not all_finite(b)
    assert not all_finite(np.float64(np.nan))


def test_first_true_stops_at_the_first_block_with_a_hit():
    n = 3 * BLOCK_ROWS
    flags = np.zeros(n, dtype=bool)
    seen = []

    def test(sl):
        seen.append(sl.start)
        return flags[sl]

    assert first_true(test, n) == -1 and len(seen) == 3
    flags[[BLOCK_ROWS + 7, 2 * BLOCK_ROWS + 1]] = True
    seen.clear()
    assert first_true(test, n) == BLOCK_ROWS + 7
    assert seen == [0, BLOCK_ROWS]
    assert first_true(test, 0) == -1


def test_blocks_cover_every_row_once():
    n = 2 * BLOCK_ROWS + 9
    rows = np.concatenate([np.arange(n)[sl] for sl in blockwise._blocks(n)])
    np.testing.assert_array_equal(rows, np.arange(n))
