"""k-step-ahead prediction: how far ahead a model is good, not only how it
drifts over a whole record.

Along the record, at prediction starts ``p``, each model's state is
estimated from the ``window`` samples before ``p`` only (an output-error fit
of the state at ``p - window``: a moving-horizon estimate that sees no
sample it will be scored on), then the model runs ``k`` samples ahead of
``p``. The RMSE is pooled over every predicted sample. Starts are ``k``
apart (the predictions tile the record), at most ``max_starts`` of them,
spread evenly when the record has more: the cost is linear in the record.

A free run (:class:`LeadingWindow`) is the limit ``k -> N``; ``k = 1`` is
the one-step-ahead error a regression minimises. A model that predicts
well at short ``k`` but drifts in a free run has the right local dynamics
and a wrong slow mode (or a wrong equilibrium).
"""

from __future__ import annotations

import numbers

import numpy as np

from ..core.integrate import InputSignal
from .base import ValidationProtocol
from .runs import (
    FreeRun,
    free_run,
    measurement_function,
    record_guess,
    window_fit,
)

__all__ = ["KStepAhead"]


class KStepAhead(ValidationProtocol):
    """Predictions ``k`` samples ahead from a state fitted to the samples before.

    Parameters
    ----------
    k : int
        Samples predicted from each start (>= 1).
    records : tuple (y, t) or (y, t, u), Record, or a list of them, optional
        The validation records; None: a stretch held out of the fitting data
        (both models refitted without it, :class:`HeldOut`).
    window : int, default 20
        Samples before each start the state is fitted to.
    max_starts : int, default 200
        At most this many prediction starts per record (spread evenly).

    Examples
    --------
    >>> from pysindy_mme.protocols import KStepAhead
    >>> KStepAhead(10)
    KStepAhead(k=10, records=None, window=20, max_starts=200)
    """

    def __init__(self, k, records=None, window: int = 20, max_starts: int = 200):
        super().__init__(records, window)
        self.k = k
        self.max_starts = max_starts

    def _check(self) -> None:
        super()._check()
        for name in ("k", "max_starts"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")

    def get_params(self) -> dict:
        return {
            "k": self.k,
            "records": self._records,
            "window": self.window,
            "max_starts": self.max_starts,
        }

    def to_dict(self) -> dict:
        return {
            "protocol": "KStepAhead",
            "k": self.k,
            "window": self.window,
            "max_starts": self.max_starts,
        }

    @property
    def label(self) -> str:
        return f"{self.k}-step-ahead"

    def describe_method(self, window: int) -> str:
        return (
            f"{self.k}-step-ahead predictions: each from a state fitted to the "
            f"{window} samples before it (starts {self.k} samples apart, at "
            f"most {self.max_starts}); RMSE over the predicted samples."
        )

    def starts(self, n: int, window: int) -> np.ndarray:
        """Prediction starts in a record of ``n`` samples."""
        first = np.arange(window, n, int(self.k))
        if first.size > self.max_starts:
            pick = np.linspace(0, first.size - 1, self.max_starts)
            first = first[np.unique(np.round(pick).astype(int))]
        return first

    def score(self, study, models, features, substeps, record, window) -> dict:
        y_v, t_v, u_v = record
        y_v = np.asarray(y_v, float)
        n, k = y_v.shape[0], int(self.k)
        inputs = InputSignal(u_v, t_v, study.inputs.hold)
        measure = measurement_function(study.measurement)
        guess = record_guess(study, record)
        seen_rows = np.any(np.isfinite(y_v), axis=1)
        starts = [
            int(p)
            for p in self.starts(n, window)
            # a window with fewer than half its readings cannot place a state
            if seen_rows[p - window : p].sum() >= max(2, window // 2)
        ]
        if not starts:
            raise ValueError(
                f"KStepAhead: a record of {n} samples has no prediction start "
                f"with {window} readings before it; use a shorter window"
            )
        runs = {}
        for name, model_rhs in models.items():
            x = np.full((n, study.n_states), np.nan)
            sq = np.zeros(y_v.shape[1])
            count = np.zeros(y_v.shape[1])
            diverged, x0s = None, []
            for p in starts:
                a, b = p - window, min(p + k, n)
                x0, offsets = window_fit(
                    study,
                    model_rhs,
                    features,
                    substeps,
                    y_v[a:p],
                    t_v[a:p],
                    inputs.subset(a, p),
                    guess[a:p],
                )
                x0s.append(x0)

                def shifted(z, offsets=offsets):
                    return measure(z) + offsets

                run = free_run(
                    model_rhs,
                    x0,
                    t_v[a:b],
                    inputs.subset(a, b),
                    substeps,
                    shifted,
                    y_v[a:b],
                    window,
                    guess[a:b],
                )
                x[p:b] = run.x[window:]
                if run.diverged_at is not None:
                    diverged = diverged if diverged is not None else run.diverged_at
                    continue
                r = y_v[p:b] - shifted(run.x[window:])
                ok = np.isfinite(r)
                sq += (np.where(ok, r, 0.0) ** 2).sum(axis=0)
                count += ok.sum(axis=0)
            with np.errstate(all="ignore"):
                err = np.sqrt(sq / np.maximum(count, 1))
            if diverged is not None:
                err = np.full_like(err, np.inf)
            runs[name] = FreeRun(
                x0=x0s[0],
                x=x,
                rmse=err,
                diverged_at=diverged,
                model=model_rhs,
                window=window,
                starts=starts,
                horizon=k,
                x0s=x0s,
            )
        return runs
