"""The band pool's buffers (issue 20), and a factor's solve for a few rows
of the record against a dense reference."""

import numpy as np

from pysindy_mme.solver import kkt
from pysindy_mme.solver.buffers import BufferPool
from pysindy_mme.solver.kkt import BandedKKT


def test_the_pool_hands_out_the_smallest_idle_buffer_that_fits():
    pool = BufferPool(max_idle=2)
    small, large = np.empty(10), np.empty(100)
    pool.give_back(small)
    pool.give_back(large)
    assert pool.take(5) is small
    assert pool.take(50) is large
    fresh = pool.take(20)  # none idle
    assert fresh.size == 20 and fresh is not small and fresh is not large


def test_the_pool_keeps_the_largest_and_drops_the_idle_for_a_larger_request():
    pool = BufferPool(max_idle=1)
    pool.give_back(np.empty(10))
    large = np.empty(100)
    pool.give_back(large)
    assert pool.idle == [large]  # the smaller one went
    bigger = pool.take(200)
    assert bigger.size == 200 and not pool.idle
    pool.give_back(bigger)
    pool.clear()
    assert not pool.idle


def test_solves_and_their_rows_match_a_dense_reference():
    # a factor's solve (no border) for all samples and for a few (the
    # initial state's covariance needs sample 0 only: no copy of the rest),
    # against numpy's dense solve of the matrix the kkt docstring writes
    N, n = 40, 2
    rng = np.random.default_rng(0)
    M = rng.standard_normal((N, n, n))
    Q = np.einsum("kij,klj->kil", M, M) + np.eye(n)
    A = np.eye(n) + 0.1 * rng.standard_normal((N - 1, n, n))
    fac = BandedKKT(N, n).factor(Q, A, None)
    b = rng.standard_normal((N, 2 * n, n))
    dense = np.zeros((N * 2 * n, N * 2 * n))
    for k in range(N):
        i = 2 * n * k
        dense[i : i + n, i : i + n] = Q[k]
        if k < N - 1:
            dense[i : i + n, i + n : i + 2 * n] = A[k].T
            dense[i + n : i + 2 * n, i : i + n] = A[k]
            dense[i + n : i + 2 * n, i + 2 * n : i + 3 * n] = -np.eye(n)
            dense[i + 2 * n : i + 3 * n, i + n : i + 2 * n] = -np.eye(n)
        else:
            dense[i + n : i + 2 * n, i + n : i + 2 * n] = np.eye(n)
    ref = np.linalg.solve(dense, b.reshape(N * 2 * n, n)).reshape(b.shape)
    np.testing.assert_allclose(fac.solve(b), ref, atol=1e-10)
    np.testing.assert_allclose(fac.solve(b, rows=slice(3, 7)), ref[3:7], atol=1e-10)
    part = kkt.solve_reduced(fac, None, np.zeros((0, 0)), b, None, rows=slice(0, 1))
    np.testing.assert_allclose(part.z, ref[:1], atol=1e-10)
    assert part.z.shape == (1, 2 * n, n)
