"""``error_model="random_walk"``: ``d`` a continuous state, ``W`` on its rate.

``[x, d]' = [f(x, t, u) + E d, w]``: ``d`` is a random walk (in
Kalman-filter terms) and ``W`` weighs its rate,
``integral d'^T W d' dt``, so the same transcription solver estimates a
smooth model error; the measurement ignores the ``d`` block. The right
prior for a smooth model error such as a missing term of the state: it
gives a markedly better ``d`` and a better estimate of unmeasured states
on the paper's Van der Pol record (``benchmarks/bench_mme_accuracy.py``),
at about twice the cost per solve for two states.
"""

from __future__ import annotations

import numpy as np

from .base import AugmentedErrorModel

__all__ = ["RandomWalk"]


class RandomWalk(AugmentedErrorModel):
    """The model error as a random walk: ``d' = w``, ``W`` weighs ``w``."""

    name = "random_walk"
    summary = (
        "random_walk (a smooth d, W on its rate; usually better for a missing term)"
    )

    def rate(self, q: int) -> np.ndarray:
        return np.zeros((q, q))
