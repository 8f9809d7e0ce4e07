"""A stretch of the fitting data held out: the out-of-sample numbers when
the user has no validation record.

Both models are refitted without the stretch (their structure, the kept
terms, is the study's: the stretch only ever scores), then run on it by a
record protocol (:class:`LeadingWindow` by default, :class:`KStepAhead` if
asked). Which stretch: ``fraction`` of a single record at one of its ends,
the end where the assumed model misses the data more (a decaying transient
shows its effect at the start, not at the end; the choice reads the
assumed model only); with several records, the last record whole.
"""

from __future__ import annotations

import numbers
from fractions import Fraction

import numpy as np

from ..core.tables import sig
from .base import ValidationContext, ValidationOutcome, ValidationProtocol
from .leading_window import LeadingWindow
from .runs import measurement_function

__all__ = ["HeldOut", "held_out_split"]

#: fewest samples of a held-out stretch beyond the initial-state window
MIN_HELD_OUT = 30


class HeldOut(ValidationProtocol):
    """Refit without a stretch of the fitting data, then score on it.

    Parameters
    ----------
    fraction : float, default 0.2
        Share of a single record held out (at least ``window`` plus 30
        samples; none when the rest would be under four times the stretch).
    window : int, default 50
        Leading samples of the stretch the initial states are fitted to (at
        most a fifth of the stretch).
    method : ValidationProtocol, optional
        How the models run on the stretch (default: a free run from the
        leading window, :class:`LeadingWindow`).

    Examples
    --------
    >>> from pysindy_mme.protocols import HeldOut, KStepAhead
    >>> HeldOut(fraction=0.25, method=KStepAhead(5)).label
    '5-step-ahead'
    """

    def __init__(self, fraction: float = 0.2, window: int = 50, method=None):
        super().__init__(None, window)
        self.fraction = fraction
        self.method = method

    @property
    def label(self) -> str:
        return self._method.label

    @property
    def _method(self) -> ValidationProtocol:
        return self.method if self.method is not None else LeadingWindow()

    def _check(self) -> None:
        super()._check()
        f = self.fraction
        if (
            isinstance(f, bool)
            or not isinstance(f, numbers.Real)
            or not 0.0 < float(f) < 0.5
        ):
            raise ValueError(f"fraction must be a number in (0, 0.5), got {f!r}")
        if self.method is not None:
            if not isinstance(self.method, ValidationProtocol) or isinstance(
                self.method, HeldOut
            ):
                raise TypeError(
                    "method must be a record protocol (LeadingWindow() or "
                    f"KStepAhead(k)), got {self.method!r}"
                )
            self.method._check()

    def get_params(self) -> dict:
        return {"fraction": self.fraction, "window": self.window, "method": self.method}

    def to_dict(self) -> dict:
        return {
            "protocol": "HeldOut",
            "fraction": self.fraction,
            "window": self.window,
            "method": self._method.to_dict(),
        }

    def score(self, study, models, features, substeps, record, window) -> dict:
        return self._method.score(study, models, features, substeps, record, window)

    def measure_uncertainty(
        self, study, runs, models, draws, features, substeps, record, *, every=False
    ) -> None:
        self._method.measure_uncertainty(
            study, runs, models, draws, features, substeps, record, every=every
        )

    def describe_method(self, window: int) -> str:
        return self._method.describe_method(window)

    def evaluate(self, ctx: ValidationContext) -> ValidationOutcome | None:
        """Both models refitted without the stretch, then scored on it (None
        when the data cannot spare one)."""
        study = ctx.study
        if ctx.refit_without is None:
            return None
        if study.n_records > 1:
            return self._last_record(ctx)
        split = held_out_split(
            study,
            self.fraction,
            self.window,
            None if ctx.in_sample_runs is None else ctx.in_sample_runs["assumed"],
        )
        if split is None:
            return None
        start, stop = split
        n = study.t.size
        keep = slice(stop, n) if start == 0 else slice(0, start)
        window = min(self.window, max(2, (stop - start) // 5))
        where = "first" if start == 0 else "last"
        source = (
            f"a held-out stretch (t = {sig(study.t[start])} .. "
            f"{sig(study.t[stop - 1])}, the {where} {stop - start} samples; both "
            "models refitted without it)"
        )
        return self._scored(ctx, keep, slice(start, stop), window, source)

    def _last_record(self, ctx: ValidationContext) -> ValidationOutcome | None:
        study = ctx.study
        last = study.record_slices[-1]
        size = last.stop - last.start
        window = min(self.window, max(2, size // 5))
        if size - window < MIN_HELD_OUT:
            return None
        source = (
            f"the last record held out whole ({size} samples, t = "
            f"{sig(study.t[last.start])} .. {sig(study.t[last.stop - 1])}; both "
            "models refitted on the other records)"
        )
        return self._scored(
            ctx,
            slice(0, last.start),
            last,
            window,
            source,
            starts=np.asarray(study.starts[:-1], dtype=int),
        )

    def _scored(self, ctx, keep, held, window, source, **rest) -> ValidationOutcome:
        """Both models refitted on the samples ``keep``, then scored on the
        samples ``held``; ``rest``: further fields of the reduced study."""
        study = ctx.study
        if ctx.states is not None:
            rest.setdefault("states_guess", np.asarray(ctx.states)[held])
        if ctx.in_sample_runs is not None:
            # A limit cycle's free run over 750 periods from MME's states
            # (the data's phase) took Newton eight block solves, two of them
            # failed; from the same model's own run it joins in one (0.57 s
            # against 0.31 s at 2 x 10^5 samples)
            rest.setdefault(
                "run_guesses",
                {name: run.x[held] for name, run in ctx.in_sample_runs.items()},
            )
        refitted, models, converged, draws = ctx.refit_without(keep, window, **rest)
        u = study.u
        record = (study.y[held], study.t[held], None if u is None else u[held])
        runs = self.score(refitted, models, ctx.features, ctx.substeps, record, window)
        self.measure_uncertainty(
            refitted, runs, models, draws, ctx.features, ctx.substeps, record
        )
        window = getattr(runs["assumed"], "window", None) or window
        return ValidationOutcome(
            runs, source, window, self.describe_method(window), bool(converged)
        )


def held_out_split(study, fraction=0.2, window=50, assumed_run=None):
    """``(start, stop)`` of the stretch to hold out, or None.

    ``fraction`` of the record (at least the window plus ``MIN_HELD_OUT``
    samples) at one of its ends, when what is left for fitting keeps at
    least ``(1 - fraction) / fraction`` times as many samples (four times at
    the default 0.2). Which end: the one where the assumed
    model's free run (``assumed_run``) misses the data more; the end stretch
    is the default.
    """
    n = study.t.size
    window = min(window, max(2, n // 20))
    size = max(int(round(fraction * n)), window + MIN_HELD_OUT)
    # what is left must be (1 - fraction) / fraction times the stretch (four
    # times at 0.2): compared in exact rationals, so that the rule does not
    # move by a rounding of the fraction
    share = Fraction(fraction).limit_denominator(10**6)
    if (n - size) * share < (1 - share) * size or size - window < MIN_HELD_OUT:
        return None
    if assumed_run is not None:
        measure = measurement_function(study.measurement)
        r = np.asarray(study.y, float) - measure(assumed_run.x)
        w = np.diag(np.linalg.inv(study.noise_cov))
        with np.errstate(all="ignore"):
            first = np.nanmean(r[:size] ** 2 * w)
            last = np.nanmean(r[-size:] ** 2 * w)
        if np.isfinite(first) and np.isfinite(last) and first > last:
            return 0, size
    return n - size, n
