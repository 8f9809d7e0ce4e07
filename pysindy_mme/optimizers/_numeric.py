"""Small numerical helpers shared by the optimizer modules."""

from __future__ import annotations

import numpy as np
from threadpoolctl import ThreadpoolController

__all__ = [
    "EPS",
    "column_blocks",
    "one_blas_thread",
    "pow2_scale",
    "safe_ratio",
    "scaled_target",
]

EPS = np.finfo(float).eps
# Temporaries of size n_samples x block are capped at this many doubles (8 MB).
BLOCK_ELEMENTS = 1 << 20
# Blocks that several elementwise passes read should stay in a core's cache
# (2 MB of doubles) rather than be read from main memory again by each pass.
CACHE_BLOCK_ELEMENTS = 1 << 18


def safe_ratio(num, den):
    """``num / den`` with ``x / 0 = inf`` (x > 0) and ``0 / 0 = 0``, no warnings."""
    num = np.asarray(num, dtype=float)
    den = np.asarray(den, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = num / den
    out = np.where(den > 0, out, np.where(num > 0, np.inf, 0.0))
    return out[()]


def pow2_scale(max_abs):
    """Powers of two ``s`` with ``max_abs * s`` in ``[0.5, 1)``.

    1 where ``max_abs`` is 0 or not finite. Multiplying by a power of two is
    exact in floating point, so data in any units can be brought to unit
    magnitude (where sums of squares neither overflow nor underflow) without
    changing any digit.
    """
    max_abs = np.asarray(max_abs, dtype=float)
    ok = np.isfinite(max_abs) & (max_abs > 0)
    _, exponent = np.frexp(np.where(ok, max_abs, 1.0))
    return np.where(ok, np.ldexp(1.0, -exponent), 1.0)


def scaled_target(y):
    """``(y_scale, y * y_scale)``: a target in units of its largest magnitude.

    (An exact power of two: squares can then neither overflow nor underflow.)
    """
    y_scale = float(pow2_scale(np.max(np.abs(y), initial=0.0)))
    return y_scale, y * y_scale


def column_blocks(n_rows: int, n_cols: int, elements: int = BLOCK_ELEMENTS):
    """Column slices whose ``n_rows x width`` temporaries stay small."""
    width = max(1, elements // max(n_rows, 1))
    for start in range(0, n_cols, width):
        yield slice(start, min(start + width, n_cols))


def one_blas_thread():
    """Context: BLAS on one thread, for loops of many small products.

    A product over one block takes about a millisecond; splitting it over
    threads costs a synchronisation each time, and on a busy machine a thread
    that is not scheduled makes every call wait (measured: a pass of the
    screen 7x slower with two threads than with one on a loaded 2-core
    machine; a QR factorisation of 10,000 x 21 30x slower).

    The controller that finds the BLAS libraries is made once, at the first
    call (finding them took up to 0.03 s per call).
    """
    global _CONTROLLER
    if _CONTROLLER is None:
        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER.limit(limits=1, user_api="blas")


_CONTROLLER = None
