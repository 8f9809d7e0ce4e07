"""The interface every validation protocol implements.

A protocol answers "how well does each model do on data it was not fitted
to?" in two parts:

* **where**: on the validation records the user gave, or (none given) on a
  stretch of the fitting data held out, both models refitted without it
  (:class:`~pysindy_mme.protocols.HeldOut` decides the stretch);
* **how**: :meth:`ValidationProtocol.score` runs the models on one record
  (a free run from the leading window, :class:`LeadingWindow`; predictions
  k steps ahead, :class:`KStepAhead`) and returns a
  :class:`~pysindy_mme.protocols.runs.FreeRun` per model.

The study, the report, the plot, :meth:`Discovery.validate` and the command
line all go through this interface: the study calls :meth:`evaluate`, the
report and the plot print :meth:`describe_method` (saved with the result as
text), the command line builds the objects from its flags.

Adding a protocol (say, a multi-window simulation): subclass
:class:`ValidationProtocol`, implement :meth:`score` (and
:meth:`describe_method`), export it from ``protocols/__init__.py``. The
study needs no edit.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, replace

import numpy as np

from .runs import at_the_noise, pooled_runs
from .uncertainty import MissColumns

__all__ = [
    "ValidationContext",
    "ValidationOutcome",
    "ValidationProtocol",
    "check_window",
]


def check_window(window, name: str = "window") -> int:
    """``window`` as an int: the leading samples an initial state is fitted
    to (ValueError naming ``name`` unless an integer >= 2)."""
    if isinstance(window, bool) or not isinstance(window, numbers.Integral):
        raise ValueError(f"{name} must be an integer >= 2, got {window!r}")
    if window < 2:
        raise ValueError(f"{name} must be an integer >= 2, got {window!r}")
    return int(window)


@dataclass
class ValidationContext:
    """What a protocol may use of a finished study (built by the study).

    Attributes
    ----------
    study
        The checked study (read: ``validation`` / ``validation_records``,
        ``mme``, ``inputs``, ``measurement``, ``noise_cov``, ``n_states``,
        ``offsets``, ``y``, ``t``, ``u``, ``n_records``, ``record_slices``,
        ``starts``).
    models : dict
        ``{"assumed": rhs, "extended": rhs}``, ``rhs(x, t, u) -> dx/dt``, the
        models as printed.
    features : callable
        The library's columns (for the window fits).
    substeps : int
        RK4 steps per sample interval.
    in_sample_runs : dict or None
        The in-sample free runs (the assumed one may pick a held-out
        stretch).
    refit_without : callable or None
        ``refit_without(keep, window, **study_fields) -> (study, models,
        converged, draws)``: both models refitted on the samples ``keep``
        only (the structure is the study's), and ``draws`` as below for the
        refits; None where no refit is possible.
    states : ndarray (N, n) or None
        The study's state estimate of its fitting record (MME's states): the
        guess the runs on a stretch of it start from (the runs do not depend
        on it; without it, each stretch is estimated again).
    draws : dict or None
        ``{name: make}``: ``make()`` the model ``name`` at its coefficients
        moved one standard deviation along each eigenvector of their
        covariance (:func:`~.uncertainty.coefficient_draws`), made only where
        a protocol measures a run; from them it tells whether a run's miss
        is their uncertainty.
    """

    study: object
    models: dict
    features: object
    substeps: int
    in_sample_runs: dict | None = None
    refit_without: object = None
    states: object = None
    draws: dict | None = None


@dataclass
class ValidationOutcome:
    """Out-of-sample runs of both models and what they stand on."""

    runs: dict
    #: where the runs are ("the validation record", a held-out stretch ...)
    source: str
    #: the leading samples each initial state was fitted to
    window: int
    #: how the models were run and scored (a sentence, for report and plot)
    method: str
    #: the refits behind a held-out stretch settled (True without refits)
    converged: bool = True


class ValidationProtocol:
    """Base class: a way of running both models on data they were not fitted to.

    Parameters
    ----------
    records : tuple (y, t) or (y, t, u), Record, or a list of them, optional
        The validation records (checked by the study like its own data);
        None: the protocol runs on a stretch held out of the fitting data
        (:class:`~pysindy_mme.protocols.HeldOut`).
    window : int, default 50
        Leading samples of a record (or of each prediction) the initial
        state is fitted to.
    """

    #: a short name (plots, tables)
    label = "validation"

    def __init__(self, records=None, window: int = 50):
        self._records = records
        self.window = window

    # -- checks ------------------------------------------------------------
    def _check(self) -> None:
        check_window(self.window)

    @property
    def records(self):
        """The validation records this protocol carries (None: the study's
        own data, held out)."""
        return self._records

    # -- what subclasses implement ------------------------------------------
    def score(self, study, models, features, substeps, record, window) -> dict:
        """``{name: FreeRun}`` of each model on one record ``(y, t, u)``."""
        raise NotImplementedError

    def describe_method(self, window: int) -> str:
        """How the models were run and scored, as one sentence."""
        raise NotImplementedError

    def measure_uncertainty(
        self, study, runs, models, draws, features, substeps, record, *, every=False
    ) -> None:
        """Where the protocol can, set each run's ``uncertainty``: whether
        its miss of ``record`` is the uncertainty of its model's coefficients
        and start, from the coefficients' ``draws`` (:class:`ValidationContext`;
        ``every``: also for a run at the noise, one of several records' to be
        pooled). This default measures nothing: a protocol of your own need
        not (its runs then have no ``uncertainty``)."""

    # -- what the study calls --------------------------------------------------
    def evaluate(self, ctx: ValidationContext) -> ValidationOutcome | None:
        """Both models on the study's validation records (None without)."""
        study = ctx.study
        if study.validation is None:
            return None
        window = study.validation_window
        records = study.validation_records or [study.validation]
        per_record = [
            self.score(study, ctx.models, ctx.features, ctx.substeps, r, window)
            for r in records
        ]
        if len(records) == 1:
            runs, source = per_record[0], "the validation record"
            self.measure_uncertainty(
                study,
                runs,
                ctx.models,
                ctx.draws,
                ctx.features,
                ctx.substeps,
                records[0],
            )
        else:
            runs = pooled_runs(per_record, [r[0] for r in records])
            source = f"the {len(records)} validation records (RMSE pooled over them)"
            self._pooled_uncertainty(ctx, runs, per_record, records)
        window = getattr(runs["assumed"], "window", None) or window
        return ValidationOutcome(runs, source, window, self.describe_method(window))

    def _pooled_uncertainty(self, ctx, runs, per_record, records) -> None:
        """The pooled runs' ``uncertainty`` where the pool misses by more than
        the noise: every record's draws run (whatever its own run misses
        by), the draws shared by the records, each record's start its own
        (:meth:`~.uncertainty.MissColumns.stacked`)."""
        noise_sd = np.sqrt(np.diag(np.atleast_2d(ctx.study.noise_cov)))
        for name in ctx.draws or {}:
            pooled = runs.get(name)
            if pooled is None or pooled.diverged_at is not None:
                continue
            if at_the_noise(pooled.rmse, noise_sd):
                continue
            made = ctx.draws[name]()  # once for all the records
            for record_runs, record in zip(per_record, records):
                self.measure_uncertainty(
                    ctx.study,
                    record_runs,
                    ctx.models,
                    {name: lambda made=made: made},
                    ctx.features,
                    ctx.substeps,
                    record,
                    every=True,
                )
            parts = [r[name].uncertainty for r in per_record]
            if all(u is not None for u in parts):
                both = MissColumns.stacked([u.columns for u in parts])
                if both is not None:
                    pooled.uncertainty = replace(
                        both.uncertainty(pooled.rmse), columns=None
                    )
            # a result keeps the numbers, not the columns (the records' size)
            for record_runs in per_record:
                found = record_runs[name].uncertainty
                if found is not None:
                    record_runs[name].uncertainty = replace(found, columns=None)

    def __repr__(self) -> str:
        params = ", ".join(
            f"{k}={'<given>' if k == 'records' and v is not None else repr(v)}"
            for k, v in self.get_params().items()
        )
        return f"{type(self).__name__}({params})"

    def get_params(self) -> dict:
        return {"records": self._records, "window": self.window}

    def to_dict(self) -> dict:
        """The protocol as plain data (saved with a result)."""
        params = {k: v for k, v in self.get_params().items() if k != "records"}
        return {"protocol": type(self).__name__, **params}
