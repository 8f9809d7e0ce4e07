"""Step 4 on a long record: search on a part of it, check on all of it.

The confirmation's search (:mod:`.confirm`) fits many candidate models, each
a Gauss-Newton loop over every sample interval, and their number grows with
the record: at 10^6 samples more look-alikes are significant at first, so
there are more refits, each ten times longer than at 10^5 (issue 20: the
search was 78 % of a study and 23x its cost at 10^5 samples). Its decisions
do not need all of it: at 10^5 samples of white noise the tests already
tell a term of the plant from a look-alike.

So, on a record of more than :data:`SEARCH_SAMPLES` intervals (one record,
no breaks), the search runs on a part of it (:func:`search_part`): every
``s``-th sample, at a stride where the model still needs no more RK4 steps
per interval than at the record's own rate (a denser record loses nothing
the integration needs: 10 s at 100 kHz is searched at 10 kHz), and, if that
is still longer, its leading :data:`SEARCH_SAMPLES` intervals (25,000 s at
40 Hz is searched at every 7th sample over its first 17,500 s). Every test there
is a valid test: a subset of samples with white noise of the same
covariance.

Then the whole record has the last word (:func:`check_on_whole_record`):
the terms found are fitted on all of it (from MME's states: one fit), each
must be significant there (the backward step, Wald-ranked and confirmed by
the fit without it, as in the search), and no library function may pass
the score test that would make the search add it (one pass for all). When
both hold, the search on the whole record would stop where it starts, on
the same terms: its result is the part's, with every number of the whole
record. Otherwise the whole record is searched as a record of any length
is, and the log says why.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy import stats

from ..core.integrate import RK4_H_RHO, InputSignal
from .confirm import (
    POLISH_ITER,
    Confirmation,
    _Search,
    _verdict,
    best_score,
    confirm_terms,
    term_alpha,
)

__all__ = ["SEARCH_SAMPLES", "SearchPart", "confirm_long_record", "search_part"]

#: sample intervals the search runs on at most; a longer record is searched on
#: a part of it and checked on all of it
SEARCH_SAMPLES = 100_000


@dataclass(frozen=True)
class SearchPart:
    """The samples of a long record the search runs on.

    Attributes
    ----------
    keep : ndarray of int
        Their indices, increasing: ``range(0, stride * len(keep), stride)``.
    stride : int
        Every ``stride``-th sample.
    n_samples : int
        Samples of the whole record.
    """

    keep: np.ndarray
    stride: int
    n_samples: int

    @property
    def whole_span(self) -> bool:
        """Whether the part reaches the end of the record."""
        return int(self.keep[-1]) + self.stride >= self.n_samples

    def describe(self, t) -> str:
        which = (
            "every sample" if self.stride == 1 else f"every {_nth(self.stride)} sample"
        )
        text = f"searched on {which} ({self.keep.size:,} of {self.n_samples:,})"
        if not self.whole_span:
            span, whole = t[self.keep[-1]] - t[0], t[-1] - t[0]
            text += f" over the first {span:.6g} of {whole:.6g} time units"
        return text


def _nth(k: int) -> str:
    """``2nd``, ``3rd``, ``11th``, ``21st``: the ordinal of ``k``."""
    if 10 <= k % 100 <= 20:
        return f"{k}th"
    return f"{k}{ {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th') }"


def search_part(study, substeps: int, radius) -> SearchPart | None:
    """The part of ``study``'s record the search runs on (None: all of it).

    ``substeps``: RK4 steps per interval of the study's fits; ``radius``:
    the spectral radius of the model's Jacobian along the record (its
    fastest time scale is ``1 / radius``), or a callable that computes it
    (called only for a record long enough to need it). The stride is the
    largest at which ``substeps`` steps still keep ``h * radius`` within
    RK4's accuracy (:data:`~pysindy_mme.core.integrate.RK4_H_RHO`), at most
    what brings the record down to :data:`SEARCH_SAMPLES` intervals; a record
    still longer is cut to its leading :data:`SEARCH_SAMPLES` thinned
    intervals.
    """
    n = int(study.t.size)
    limit = SEARCH_SAMPLES  # read at the call: tests set a smaller one
    # counted in intervals: 10^6 + 1 samples at every 10th are 10^5 intervals
    if n - 1 <= limit or len(study.starts):
        return None
    dt = float(np.max(np.diff(study.t)))
    cap = int(np.ceil((n - 1) / limit))
    free = cap
    if callable(radius):
        radius = float(radius())
    if radius > 0 and np.isfinite(radius):
        # (a hair over the ratio: 0.5 / (0.025 * 10) is 1.9999999999999998)
        free = int(np.floor(substeps * RK4_H_RHO / (dt * radius) * (1 + 1e-9)))
    stride = max(1, min(cap, free))
    keep = np.arange(0, n, stride)[: limit + 1]
    return SearchPart(keep, stride, n)


def reduced_study(study, part: SearchPart):
    """``study`` on the samples of ``part``.

    Inputs given as samples are read between the kept samples as the whole
    record reads them (through its own hold): a thinned grid that
    interpolated its own samples would change the input the model sees.
    """
    keep = part.keep
    t = study.t[keep]
    inputs = study.inputs
    if part.stride == 1:
        signal = inputs.subset(0, int(keep[-1]) + 1)
    elif inputs.is_none or callable(inputs.u):
        signal = InputSignal(inputs.u, t, inputs.hold)
    else:
        signal = InputSignal(inputs.at, t, inputs.hold)
    readings = getattr(study, "readings", None)
    return replace(
        study,
        y=study.y[keep],
        t=t,
        u=None if study.u is None else study.u[keep],
        inputs=signal,
        x_init=study.x_init[keep],
        readings=None if readings is None else readings[keep],
    )


def confirm_long_record(
    study, engine, part_engine, assumed, estimate, part: SearchPart, settings, steps_of
) -> Confirmation:
    """The search on ``part`` of the record, checked on all of it.

    ``engine`` / ``part_engine``: output-error fits of the whole record and
    of the part; ``assumed``: the assumed model's fit on the whole record;
    ``settings``: the keyword arguments of :func:`~.confirm.confirm_terms`
    but the record's (``proposals``, ``start_values``, ``alpha``,
    ``describe``, ``library_candidates``, ``progress``, ``min_effect``);
    ``steps_of(study) -> (fit -> int)``: the RK4 steps a fit's model needs
    on the record of ``study`` (the part's or the whole).
    """
    keep = part.keep
    progress = settings.get("progress") or (lambda msg: None)
    what = part.describe(study.t)
    progress(f"  {what}")
    part_assumed = part_engine.fit((), assumed.theta, assumed.x[keep])
    found = confirm_terms(
        part_engine,
        part_assumed,
        x_start=estimate.x[keep],
        mme_start=(estimate.x[keep], estimate.d[keep], estimate.physical),
        steps_of=steps_of(reduced_study(study, part)),
        **settings,
    )
    power = _part_power(part, found.fit or part_assumed, settings)
    checked, why = check_on_whole_record(
        engine, assumed, found, estimate, settings, power
    )
    if checked is not None:
        checked.log[:0] = [f"{what}, then checked on the whole record: {why}"]
        return checked
    progress(f"  the whole record did not confirm it ({why}): searched all of it")
    whole = confirm_terms(
        engine,
        assumed,
        x_start=estimate.x,
        mme_start=(estimate.x, estimate.d, estimate.physical),
        steps_of=steps_of(study),
        **settings,
    )
    whole.log[:0] = [
        f"{what} first; the whole record did not confirm what it found ({why}), "
        "so the whole record was searched"
    ]
    return whole


#: power the part's score tests must have for a term at ``min_effect`` before
#: the whole record's score pass is left out (see :func:`_part_power`)
PART_POWER = 0.999


def _part_power(part: SearchPart, fit, settings) -> float:
    """The power of the part's last score test for a term that removes
    ``min_effect`` of the misfit (0: not known, or no such threshold).

    A term enters when its score test is significant and it removes at least
    ``min_effect`` of the misfit (:func:`~.confirm.best_score`); that share
    is a property of the record, not of its length. A part that spans the
    whole record (every ``s``-th sample) sees every regime in it, so a term
    that removes ``min_effect`` of the whole record's misfit removes about
    as much of the part's; when the part's test finds such a term with
    power :data:`PART_POWER` (the noncentral F distribution),
    the whole record's score pass (the check's costliest step) would add
    nothing the part did not: it is left out, and the log says so.
    """
    share = float(settings.get("min_effect", 0.0))
    if not (part.whole_span and share > 0 and fit is not None and fit.ok):
        return 0.0
    pool = list(settings["library_candidates"])
    alpha_term = term_alpha(settings["alpha"], pool, settings["proposals"])
    # independent residuals (fewer than the samples when they are correlated)
    den = max(fit.n_residuals - fit.n_free - 1, 1) / fit.inflation
    lam = share / (1.0 - share) * den  # the noncentrality of such a term's F
    critical = stats.f.isf(alpha_term, 1, den)
    return float(stats.ncf.sf(critical, 1, den, lam))


def check_on_whole_record(engine, assumed, found, estimate, settings, power=0.0):
    """``(the confirmation on the whole record, what the check found)``, or
    ``(None, why not)`` when the whole record's search would not stop on
    ``found``'s terms (see the module docstring). ``power``: of the part's
    score tests at ``min_effect`` (:func:`_part_power`); at least
    :data:`PART_POWER`, the whole record's score pass is left out."""
    pool = list(settings["library_candidates"])
    alpha_term = term_alpha(settings["alpha"], pool, settings["proposals"])
    search = _Search(
        engine,
        assumed,
        alpha_term,
        settings["describe"],
        pool,
        settings.get("progress"),
        settings.get("min_effect", 0.0),
    )
    said = []
    if found.slots:
        slots = list(found.slots)
        fit = engine.fit(
            slots, found.fit.theta, estimate.x, max_iter=POLISH_ITER, tol=1e-9
        )
        fit = search._from_the_clamp(slots, fit, True)
        search.progress(
            f"  the whole record: {len(slots)} term(s) fitted, cost {fit.cost:.6g}, "
            f"{fit.n_iter} it."
        )
        if not (fit.ok and fit.joined):
            return None, f"the fit of its terms does not join ({fit.message})"
        _, _, removed = search.backward(slots, fit)
        if removed:
            names = ", ".join(search.describe(s) for s, _, _ in removed)
            return None, f"{names} not significant there"
        search.slots, search.fit = slots, fit
        pvals = fit.coefficient_p_values()[fit.n_physical : fit.n_physical + len(slots)]
        said.append(
            f"no term leaves in the backward step (largest Wald p = "
            f"{np.max(pvals):.2g})"
        )
    candidates = [c for c in pool if c not in search.slots]
    if candidates and power >= PART_POWER:
        said.append(
            "no library function would enter (the part spans the record, and "
            f"its score tests find a term that removes {100 * search.min_effect:.2g}"
            f" % of the misfit with power {power:.4f}; they found none)"
        )
    elif candidates:
        best, p, share, _, enters = best_score(search, candidates)
        if enters:
            name = search.describe(candidates[best])
            return None, f"the score test would add {name} (p = {p:.2g})"
        said.append(f"no library function would enter (smallest score p = {p:.2g})")
    search.rejected = list(found.rejected)
    search.log = list(found.log)
    out = _verdict(search, assumed, settings["alpha"], search.min_effect)
    out.notes = list(found.notes)
    return out, "; ".join(said) or "nothing to add"
