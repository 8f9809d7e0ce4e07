"""The solver's per-interval checks name the first bad interval of a long record."""

import numpy as np
import pytest

from pysindy_mme.core.blockwise import BLOCK_ROWS
from pysindy_mme.exceptions import DivergenceError
from pysindy_mme.solver.transcription import MMESmoother, _error_blocks


class _Stand:
    """What ``MMESmoother._check_flow`` reads of its solver."""

    def __init__(self, N):
        self.t = np.arange(N) * 0.5
        self.unit = np.array([1.0, 2.0])

    def scale(self, x):
        return 1.0


@pytest.mark.parametrize("bad_value", [1e7, np.nan, np.inf])
def test_check_flow_names_the_first_interval_that_blows_up(bad_value):
    N = 2 * BLOCK_ROWS + 10
    x = np.zeros((N, 2))
    phi = x[1:].copy()
    first = BLOCK_ROWS + 3  # in the second block; a later one in the third
    phi[first, 1] = bad_value
    phi[2 * BLOCK_ROWS + 1, 0] = np.nan
    with pytest.raises(DivergenceError, match=f"interval {first}, t = {first * 0.5:g}"):
        MMESmoother._check_flow(_Stand(N), phi, x)


def test_check_flow_passes_jumps_below_a_million_state_scales():
    N = BLOCK_ROWS + 5
    x = np.zeros((N, 2))
    phi = np.full((N - 1, 2), 0.99e6)
    MMESmoother._check_flow(_Stand(N), phi, x)  # no error


@pytest.mark.parametrize(
    "K, n, q", [(1000, 2, 1), (5, 3, 1), (7, 4, 1), (100, 3, 2), (0, 2, 1)]
)
def test_error_blocks_are_numpys_batched_products(K, n, q):

    rng = np.random.default_rng(K + n + q)
    G = rng.standard_normal((K, n, q))
    W = rng.standard_normal((q, q))
    W = W @ W.T + np.eye(q)
    h = rng.uniform(0.01, 0.1, K)
    GW, S = _error_blocks(G, W, h)
    expected = G @ W
    np.testing.assert_array_equal(GW, expected)
    batched = (expected @ np.swapaxes(G, 1, 2)) / h[:, None, None]
    np.testing.assert_array_equal(S, batched)
