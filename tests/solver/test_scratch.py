"""Scratch memory reused between bordered solves (issue 20): an array's
memory is handed out again only once no array on it is alive, and the
solves that use it give the numbers a fresh array gives."""

import gc

import numpy as np

from pysindy_mme.solver import kkt, scratch
from pysindy_mme.solver.kkt import BandedKKT

BIG = (3, scratch.MIN_BYTES // 8)  # large enough to be pooled


def _pooled():
    scratch.release()
    first = scratch.take(BIG)
    first[:] = 1.0
    return first


def test_the_memory_of_a_dead_array_is_reused():
    first = _pooled()
    address = first.__array_interface__["data"][0]
    del first
    gc.collect()
    second = scratch.take(BIG)
    assert second.__array_interface__["data"][0] == address
    assert second.shape == BIG and second.flags.c_contiguous


def test_a_live_view_keeps_the_memory_from_being_handed_out():
    first = _pooled()
    # a transposed slice: the kind of view a kept border holds
    view = first[1:].T
    del first
    gc.collect()
    second = scratch.take(BIG)
    assert not np.shares_memory(second, view)
    second[:] = 2.0
    assert np.all(view == 1.0)
    del view
    gc.collect()
    third = scratch.take(BIG)  # now the first buffer is idle again
    assert not np.shares_memory(third, second)


def test_small_arrays_are_not_pooled_and_release_empties_the_pool():
    first = _pooled()
    del first
    gc.collect()
    assert len(scratch._IDLE) == 1
    small = scratch.take((10, 10))
    assert small.base is None  # numpy's own
    assert len(scratch._IDLE) == 1
    scratch.release()
    assert not scratch._IDLE


def test_a_larger_request_drops_the_idle_buffer_before_allocating():
    first = _pooled()
    del first
    gc.collect()
    bigger = scratch.take((5, BIG[1]))
    assert not scratch._IDLE
    assert bigger.shape == (5, BIG[1])


def test_solves_on_reused_memory_and_their_rows_match_a_dense_reference():
    # a factor's solve (no border) for all samples and for a few, on memory
    # a dead solve left: the numbers of numpy's dense solve
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
    part = kkt.solve_reduced(fac, None, np.zeros((0, 0)), b, None, rows=slice(0, 1))
    np.testing.assert_allclose(part.z, ref[:1], atol=1e-10)
    assert part.z.shape == (1, 2 * n, n)
