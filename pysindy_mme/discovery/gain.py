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

from ..core.integrate import InputSignal, simulate_guided

__all__ = ["Gain", "FreeRun", "free_run", "rmse"]


def rmse(y, y_hat) -> np.ndarray:
    """RMSE per channel over observed samples; inf if a prediction is not finite."""
    y = np.asarray(y, dtype=float)
    y_hat = np.asarray(y_hat, dtype=float)
    observed = np.isfinite(y)
    out = np.empty(y.shape[1])
    for j in range(y.shape[1]):
        obs = observed[:, j]
        pred = y_hat[obs, j]
        out[j] = (
            np.inf
            if not np.all(np.isfinite(pred))
            else float(np.sqrt(np.mean((y[obs, j] - pred) ** 2)))
        )
    return out


@dataclass
class FreeRun:
    """A free-run simulation of one model on a validation record.

    Attributes
    ----------
    x0 : ndarray (n,)
        Initial state estimated from the leading window.
    x : ndarray (N, n)
        The simulation (NaN after a divergence).
    rmse : ndarray (m,)
        After the window; inf when the run diverged.
    diverged_at : float or None
        Time at which the run left the bound, if it did.
    model : callable
        The model that ran, ``(x, t, u) -> dx/dt`` (as printed).
    window : int or None
        Leading samples the initial state was estimated from (None for an
        in-sample run); longer than asked when readings in it were clipped
        or missing.
    """

    x0: np.ndarray
    x: np.ndarray
    rmse: np.ndarray
    diverged_at: float | None = None
    model: object = None
    window: int | None = None
    #: with several records: each record's own run (``rmse`` is pooled)
    records: list | None = None
    #: with several fitting records: each record's fitted initial state
    x0s: list | None = None


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
        }
        if self.validation_rmse_assumed is not None:
            out["validation_rmse_assumed"] = plain(self.validation_rmse_assumed)
            out["validation_rmse_extended"] = plain(self.validation_rmse_extended)
            out["validation_ratio"] = plain(self.validation_ratio)
            out["validation_window"] = self.validation_window
            out["validation_source"] = self.validation_source
        out["notes"] = list(self.notes)
        return out


def _ratio(a, b):
    """``a / b``, NaN where either is not a finite positive number."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b) & (b > 0)
    return np.where(ok, a / np.where(ok, b, 1.0), np.nan)


def free_run(model, x0, t, inputs: InputSignal, substeps, measure, y, window, guess):
    """Simulate from ``x0`` over ``t``; RMSE of ``measure(x)`` after ``window``.

    ``model(x (K, n), t (K,), u (K, m) or None) -> dx/dt``. The run is the
    exact RK4 free run from ``x0``, computed for the whole record at once
    from ``guess`` (a state estimate of the record: it only speeds Newton's
    method up, the answer does not depend on it; see
    :func:`~pysindy_mme.core.integrate.simulate_guided`). The bound is 1e6
    times the larger of the data's and the initial state's magnitude.
    """
    scale = max(float(np.nanmax(np.abs(y))), float(np.max(np.abs(x0))), 1e-300)
    sim = simulate_guided(model, x0, t, inputs, substeps, guess, bound=1e6 * scale)
    x = sim.x[0]
    at = int(sim.diverged_at[0])
    err = rmse(y[window:], measure(x)[window:])
    return FreeRun(
        x0=x0,
        x=x,
        rmse=err,
        diverged_at=None if at < 0 else float(t[at]),
        model=model,
    )
