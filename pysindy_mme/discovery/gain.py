"""Step 5: the gain - how much closer to the measurements the fix simulates.

Every number is a **free run** of the model as printed, from its fitted
initial state, against the data:

* **in-sample** (the fitting record): each model run free over the whole
  record from the initial state (and parameters) of its output-error fit.
  A fit that did not converge still gets a true simulation here (never the
  RMSE of fitted trajectory pieces that do not join), and is marked as not
  converged wherever its numbers appear. The extended model's terms were
  chosen on this record: in-sample numbers flatter it.
* **out-of-sample**: a validation record when given, else a stretch held
  out of the fitting record (both models refitted without it), by the
  protocol the system-identification benchmarks use: the initial state is
  estimated from a short leading window only (``validation_window``
  samples: an output-error fit of the initial state on the window), then
  the model runs free over the whole record, and the RMSE is taken over the
  samples after the window. A model whose free run leaves the finite range
  (or a bound of 1e6 times the data's scale) has no RMSE: the gain says
  where it diverged instead of averaging over the rows that stayed finite.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Gain"]


@dataclass
class Gain:
    """How much closer to the measurements the extended model simulates.

    RMSE per measured channel of the simulated measurement against the data,
    every one a free run (module docstring): in-sample on the fitting record
    (from each fit's initial state), and out-of-sample on the validation
    record or a held-out stretch (``validation_source``; initial state from
    the leading ``validation_window`` samples, then free simulation; RMSE
    after the window). ``noise_floor = sqrt(R_jj)`` is what a perfect model
    reaches.
    """

    channel_names: list
    rmse_assumed: np.ndarray
    rmse_extended: np.ndarray
    noise_floor: np.ndarray
    validation_rmse_assumed: np.ndarray | None = None
    validation_rmse_extended: np.ndarray | None = None
    validation_window: int | None = None
    notes: list = field(default_factory=list)
    #: the validation free runs, ``{"assumed": FreeRun, "extended": FreeRun}``
    validation_runs: dict | None = None
    #: the in-sample free runs, ``{"assumed": FreeRun, "extended": FreeRun}``
    in_sample_runs: dict | None = None
    #: whether each model's fit to the record converged
    converged: dict = field(default_factory=dict)
    #: where the out-of-sample numbers come from ("the validation record" or
    #: a held-out stretch of the fitting record, described)
    validation_source: str | None = None
    #: whether the refits without the held-out stretch converged
    held_out_converged: bool = True
    #: how the models were run and scored out of sample (the protocol's
    #: sentence, :mod:`pysindy_mme.protocols`)
    validation_method: str | None = None
    #: ``{model: time}`` for each model whose in-sample run is set by
    #: rounding from that time on (:mod:`.run_sensitivity`): its RMSE and a
    #: gain over it are one run's among many, not the model's
    rounding_set: dict = field(default_factory=dict)

    @property
    def ratio(self) -> np.ndarray:
        return _ratio(self.rmse_assumed, self.rmse_extended)

    @property
    def validation_ratio(self) -> np.ndarray | None:
        if self.validation_rmse_assumed is None:
            return None
        return _ratio(self.validation_rmse_assumed, self.validation_rmse_extended)

    def to_dict(self) -> dict:
        def plain(a):
            return [None if not np.isfinite(v) else float(v) for v in a]

        out = {
            "channels": list(self.channel_names),
            "rmse_assumed": plain(self.rmse_assumed),
            "rmse_extended": plain(self.rmse_extended),
            "ratio": plain(self.ratio),
            "noise_floor": plain(self.noise_floor),
            "in_sample": True,
            "free_run": True,
            "converged": dict(self.converged),
            "rounding_set": {k: float(v) for k, v in self.rounding_set.items()},
        }
        if self.validation_rmse_assumed is not None:
            out["validation_rmse_assumed"] = plain(self.validation_rmse_assumed)
            out["validation_rmse_extended"] = plain(self.validation_rmse_extended)
            out["validation_ratio"] = plain(self.validation_ratio)
            out["validation_window"] = self.validation_window
            out["validation_source"] = self.validation_source
            out["validation_method"] = self.validation_method
        out["notes"] = list(self.notes)
        return out


def _ratio(a, b):
    """``a / b``, NaN where either is not a finite positive number."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b) & (b > 0)
    return np.where(ok, a / np.where(ok, b, 1.0), np.nan)
