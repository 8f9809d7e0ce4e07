"""Record-sized scratch arrays whose memory is reused between solves.

A bordered KKT solve works in ``k + p`` columns of the record (``[b, E]``,
solved in place): at 10^6 samples of two states with three parameters,
128 MB at every Gauss-Newton step of an output-error fit. An array that
large is a fresh ``mmap`` from the C library each time (its threshold for
reusing freed memory stops at 32 MB), and numpy asks the kernel for huge
pages on it: every step then waits while the kernel finds and zeroes
2 MB pages (0.7 s of system time in a study of 10^6 samples, against none
in MME alone, whose single columns stay under that threshold).

:func:`take` hands out such arrays on memory kept from an earlier one. The
memory goes back to the pool when the last array on it dies, whatever
views of it are still alive until then (they all hold the same root array,
tracked with a weak reference), so two live arrays never share memory.
"""

from __future__ import annotations

import threading
import weakref

import numpy as np

__all__ = ["take", "release"]

#: arrays smaller than this come from numpy as usual (the C library reuses
#: their memory itself)
MIN_BYTES = 1 << 22
#: idle buffers kept (the largest): one serves the next solve of any size
#: up to its own, a second would only sit in memory
IDLE_MAX = 1

_IDLE: list = []
# arrays may die in any thread (studies run in threads by a scheduler)
_LOCK = threading.Lock()


def take(shape) -> np.ndarray:
    """An uninitialised, C-ordered float array of ``shape``.

    Large ones (at least :data:`MIN_BYTES`) lie on memory reused from a dead
    array of this module when one is idle and large enough; when none is,
    the idle ones are dropped before a new buffer is allocated (they would
    only sit beside it).
    """
    size = int(np.prod(shape))
    if size * 8 < MIN_BYTES:
        return np.empty(shape)
    with _LOCK:
        fits = [k for k, b in enumerate(_IDLE) if b.size >= size]
        if fits:
            flat = _IDLE.pop(min(fits, key=lambda k: _IDLE[k].size))
        else:
            _IDLE.clear()
            flat = None
    if flat is None:
        flat = np.empty(size)
    # a root that does not own its memory and whose base is no array: every
    # view of it keeps it (numpy collapses a view's base only through arrays
    # of the same type), so it dies with the last array on this memory
    root = np.frombuffer(memoryview(flat), dtype=float, count=size)
    weakref.finalize(root, _give_back, flat)
    return root.reshape(shape)


def _give_back(flat) -> None:
    with _LOCK:
        _IDLE.append(flat)
        while len(_IDLE) > IDLE_MAX:
            del _IDLE[min(range(len(_IDLE)), key=lambda k: _IDLE[k].size)]


def release() -> None:
    """Drop the idle buffers (their memory returns to the system)."""
    with _LOCK:
        _IDLE.clear()
