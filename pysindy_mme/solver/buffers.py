"""Record-sized buffers whose memory is reused: the factorisations' bands.

A band at 10^6 samples of two states is 320 MB, above the C library's
threshold for reusing freed memory (32 MB): a fresh one per Gauss-Newton
step would be a fresh mapping the kernel must fill with zeroed pages, which
costs more than the factorisation itself. :class:`BufferPool` keeps the
buffer of a dead band for the next (the band pool of :mod:`.kkt`).

(Session 26 tried the same for the bordered solves' ``k + p`` columns, 128
MB at every step of a fit with three parameters, whose fresh pages cost 0.7-
1.1 s of system time in a study of 10^6 samples: pooled and kept between
solves, the study's peak rose to 1.51-1.58 kB per sample, over the 1.5 it
must stay under; pooled within a solve only, or mapped on ordinary pages
instead of huge ones, the system time and the study's time stayed what
they were. They are numpy's arrays.)
"""

from __future__ import annotations

import threading

import numpy as np

__all__ = ["BufferPool"]


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
