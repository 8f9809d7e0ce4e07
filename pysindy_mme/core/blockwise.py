"""Reductions over the rows of long arrays, without record-sized temporaries.

A solver's checks on a record of 10^6 samples (the largest defect, whether
every Jacobian is finite, how much each interval amplifies a perturbation)
written as ``np.max(np.abs(phi - x))`` make one or two temporaries the size
of the whole array. Each is fresh memory (arrays beyond glibc's mmap
threshold, 32 MiB, are mapped on allocation and unmapped when freed), and a
process touching fresh memory pays a page fault per 4 KiB page: about
2 ms per MB on the machines here, a tenth of a second for one Jacobian of two
states at 10^6 samples, at every Gauss-Newton iteration. Here the same
numbers come from blocks of ``BLOCK_ROWS`` rows, whose temporaries stay in
cache and are reused, or (one maximum per row) entry by entry over all rows:
numpy runs its inner loop over an array's last axis, and a reduction over a
row of two to four entries runs it that short.

Every function gives exactly the answer of the whole-array expression it
replaces, NaN included (a NaN anywhere makes the maximum NaN, as ``np.max``
does).
"""

from __future__ import annotations

import numpy as np

__all__ = ["BLOCK_ROWS", "all_finite", "first_true", "max_abs", "row_max_abs"]

#: rows per block: 32,768 rows of a (rows, 2, 2) array are 1 MiB
BLOCK_ROWS = 1 << 15


def _blocks(n_rows: int):
    for lo in range(0, n_rows, BLOCK_ROWS):
        yield slice(lo, min(lo + BLOCK_ROWS, n_rows))


def max_abs(a, b=None, initial: float = 0.0) -> float:
    """``max(|a - b|)`` (``max(|a|)`` without ``b``) over all entries.

    ``initial`` for an empty array, as ``np.max(..., initial=)``; NaN if any
    entry is NaN. ``a`` and ``b`` have the same shape (no broadcasting).
    """
    a = np.asarray(a)
    if b is not None:
        b = np.asarray(b)
        if b.shape != a.shape:
            raise ValueError(f"shapes differ: {a.shape} and {b.shape}")
    if a.size == 0:
        return float(initial)
    if a.ndim == 0:
        a, b = a.reshape(1), None if b is None else b.reshape(1)
    best = float(initial)
    buf = None
    for sl in _blocks(a.shape[0]):
        part = a[sl]
        if buf is None or buf.shape != part.shape:
            buf = np.empty(part.shape, dtype=np.result_type(part, float))
        if b is None:
            np.abs(part, out=buf)
        else:
            np.subtract(part, b[sl], out=buf)
            np.abs(buf, out=buf)
        m = float(buf.max())
        if m != m:  # NaN: the whole maximum is NaN
            return m
        best = max(best, m)
    return best


def row_max_abs(a) -> np.ndarray:
    """``np.abs(a).max(axis=all but the first)``: one maximum per row.

    Entry by entry over the rows (``np.maximum`` keeps a NaN, as ``max``
    does): a reduction over each row's few entries (four for a Jacobian of
    two states) runs numpy's inner loop four elements long, 5x slower.
    """
    a = np.asarray(a)
    out = np.empty(a.shape[0], dtype=np.result_type(a, float))
    if a.shape[0] == 0:
        return out
    rows = a.reshape(a.shape[0], -1)
    if rows.shape[1] == 0:
        raise ValueError("row_max_abs needs at least one entry per row")
    np.abs(rows[:, 0], out=out)
    buf = np.empty_like(out) if rows.shape[1] > 1 else None
    for j in range(1, rows.shape[1]):
        np.abs(rows[:, j], out=buf)
        np.maximum(out, buf, out=out)
    return out


def all_finite(a) -> bool:
    """``np.isfinite(a).all()``."""
    a = np.asarray(a)
    if a.ndim == 0:
        return bool(np.isfinite(a))
    return all(bool(np.isfinite(a[sl]).all()) for sl in _blocks(a.shape[0]))


def first_true(rows_test, n_rows: int) -> int:
    """The first row index where ``rows_test(slice)`` (a boolean array over
    the slice's rows) is true, or -1: the scan stops at the first block with
    one."""
    for sl in _blocks(n_rows):
        hit = np.asarray(rows_test(sl))
        if hit.any():
            return sl.start + int(np.argmax(hit))
    return -1
