"""``error_model="white"`` (the paper): ``W`` weighs the model error itself.

``J = sum_k r_k^T R^-1 r_k + integral d^T W d dt`` with ``d`` held constant
between samples: the problem the transcription solver solves as stated. In
Kalman-filter terms ``d`` is white noise of intensity ``W^-1``; its
estimate is as rough as the data allow (for a measured position and an
error in its acceleration, ``d`` is the second derivative of a cubic
smoothing spline).
"""

from __future__ import annotations

import numpy as np

from .base import ErrorModel, ErrorReading, SolverInputs

__all__ = ["WhiteNoise"]


class WhiteNoise(ErrorModel):
    """The model error as white noise, held on each sample interval."""

    name = "white"
    summary = "white (the paper: d rough, W on d itself)"

    def smoother(self, inputs: SolverInputs):
        return inputs.base

    def read(self, smoother, result, n_states: int) -> ErrorReading:
        # d at a sample: the mean of the two adjacent intervals' values (the
        # one interval's at each record's ends)
        d_int = result.d
        d = np.empty((smoother.N, smoother.q))
        d[1:-1] = 0.5 * (d_int[1:] + d_int[:-1])
        d[0] = d_int[0]
        d[-1] = d_int[-1]
        for k in smoother.breaks:
            d[k] = d_int[k - 1]
            d[k + 1] = d_int[k + 1]
        return ErrorReading(d=d, d_intervals=d_int, model=smoother.model)
