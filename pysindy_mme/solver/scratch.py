"""Record-sized buffers whose memory is reused between solves.

A factorisation's band and a bordered KKT solve's ``k + p`` columns of the
record (``[b, E]``, solved in place: at 10^6 samples of two states with
three parameters, 128 MB at every Gauss-Newton step of an output-error fit)
are arrays larger than the C library's threshold for reusing freed memory
(32 MB): each new one is a fresh mapping, on which numpy asks the kernel
for huge pages, so every step waited while the kernel found and zeroed 2 MB
pages (0.7 s of system time in a study of 10^6 samples, against none in MME
alone, whose single columns stay under that threshold).

:class:`BufferPool` keeps the memory of dead buffers for the next one that
fits (the band pool of :mod:`.kkt` is one); :func:`take` hands out arrays on
such memory and takes it back when the last array on it dies, whatever
views of it are alive until then (they all hold the same root array, tracked
with a weak reference), so two live arrays never share memory.
"""

from __future__ import annotations

import threading
import weakref

import numpy as np

__all__ = ["BufferPool", "release", "take"]

#: arrays smaller than this come from numpy as usual (the C library reuses
#: their memory itself)
MIN_BYTES = 1 << 22


class BufferPool:
    """Idle flat float buffers, for the next request they can hold.

    At most ``max_idle`` are kept (the largest: they serve any smaller
    request too). A request no idle buffer holds drops the idle ones before
    a new buffer is allocated: they would only sit beside it.
    """

    def __init__(self, max_idle: int = 1):
        self.max_idle = max_idle
        self.idle: list = []
        # buffers come back in any thread (studies run in threads)
        self._lock = threading.Lock()

    def take(self, size: int) -> np.ndarray:
        """A flat buffer of at least ``size`` floats: the smallest idle one
        that holds it, or a new one of exactly ``size``."""
        with self._lock:
            fits = [k for k, b in enumerate(self.idle) if b.size >= size]
            if fits:
                return self.idle.pop(min(fits, key=lambda k: self.idle[k].size))
            self.idle.clear()
        return np.empty(size)

    def give_back(self, flat: np.ndarray) -> None:
        """Keep ``flat`` (no array may use it any more) for a later request."""
        with self._lock:
            self.idle.append(flat)
            while len(self.idle) > self.max_idle:
                smallest = min(range(len(self.idle)), key=lambda k: self.idle[k].size)
                del self.idle[smallest]

    def clear(self) -> None:
        """Drop the idle buffers (their memory returns to the system)."""
        with self._lock:
            self.idle.clear()


#: the pool of :func:`take`: one idle buffer serves the next solve of any
#: size up to its own, a second would only sit in memory
_SCRATCH = BufferPool(max_idle=1)
_IDLE = _SCRATCH.idle  # (for tests)


def take(shape) -> np.ndarray:
    """An uninitialised, C-ordered float array of ``shape``.

    Large ones (at least :data:`MIN_BYTES`) lie on memory reused from a dead
    array of this module when one is idle and large enough.
    """
    size = int(np.prod(shape))
    if size * 8 < MIN_BYTES:
        return np.empty(shape)
    flat = _SCRATCH.take(size)
    # a root that does not own its memory and whose base is no array: every
    # view of it keeps it (numpy collapses a view's base only through arrays
    # of the same type), so it dies with the last array on this memory
    root = np.frombuffer(memoryview(flat), dtype=float, count=size)
    weakref.finalize(root, _SCRATCH.give_back, flat)
    return root.reshape(shape)


def release() -> None:
    """Drop the idle buffers of :func:`take`."""
    _SCRATCH.clear()
