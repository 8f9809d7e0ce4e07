"""The study's conclusion, derived from the evidence and stated with its reasons.

A scientist acts on the verdict, so the verdict is never more confident
than the evidence. One of five conclusions:

``"explained"``
    The data contradict the assumed model and the identified terms explain
    it. All of: every refit converged; the gains are free runs of the
    models as printed; on held-out data (the validation record, or a
    stretch of the fitting record refitted without it) the extended model
    simulates at least ``HELD_OUT_MARGIN`` (1.1) times closer to the data
    than the assumed model (noise-weighted RMSE over the channels, no
    channel worse by that factor); the extended model's free run fits its
    record within ``FIT_FACTOR`` (1.5) times the noise on every channel;
    no kept term or parameter is unidentified (an exact trade-off, a
    correlation of estimates beyond ``TRADE_OFF_CORRELATION`` (0.995) where
    one of them is imprecise, a standard error larger than the value); no
    parameter ran away (moved by more than ``RUNAWAY_FACTOR`` (10) times
    from its guess, or changed sign) or sits on a bound; the noise level is
    known.
``"partly explained"``
    As "explained", except that the extended model still misses its record
    by more than ``FIT_FACTOR`` times the noise: the misfit left is named.
    Where kinks are integrated smoothed and that misfit shrinks to at most
    ``KINK_MISFIT_SHARE`` (0.7) of itself at half the width and twice the
    RK4 steps, most of it is the integration of the kinks, not an effect
    the library lacks: the reason says so, and the advice is a narrower
    width, not more functions or a hidden state.
``"not explained"``
    The data contradict the assumed model, and either no library term
    explains it, or the terms found are worse on held-out data than the
    assumed model (by ``HELD_OUT_MARGIN``).
``"consistent"``
    The data do not contradict the assumed model (chi-square test at
    ``alpha``) and no term was kept.
``"inconclusive"``
    Anything short of the above: the reasons say what is missing and what
    to try.

Whatever the conclusion, a model whose free run crosses a level the data
never pass (:class:`Overshoot`: above the highest reading, or below the
lowest, by more than 3 noise sd, where the data sit at that extreme) adds a
reason and the advice to try a saturation or overflow there; it changes no
label.

When the assumed model's error has memory that no function of the present
states gives (:mod:`.memory`: history predicts it markedly better than the
present), a :class:`MissingState` adds a reason and, first, the advice to
add a hidden state entering that equation; without kept terms the verdict
says a state is likely missing instead of "the library lacks the effect".
It changes no label either: a static correction that fits to the noise and
holds out of sample is still an explanation.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..core.tables import sig

__all__ = [
    "CONCLUSIONS",
    "Conclusion",
    "Evidence",
    "Overshoot",
    "MissingState",
    "conclude",
    "memory_decides",
    "FIT_FACTOR",
    "HELD_OUT_MARGIN",
    "KINK_MISFIT_SHARE",
    "RUNAWAY_FACTOR",
    "TRADE_OFF_CORRELATION",
]

CONCLUSIONS = (
    "explained",
    "partly explained",
    "not explained",
    "consistent",
    "inconclusive",
)
#: the held-out gain an explanation needs: 10 % closer to the data than the
#: assumed model (smaller differences are within what refitting on a
#: shorter record and a different initial state move a free run)
HELD_OUT_MARGIN = 1.1
#: an explanation fits its record to within this factor of the noise sd
FIT_FACTOR = 1.5
#: the misfit beyond the noise left at half the kinks' smoothing width, as a
#: share of the misfit at the fit's width, at most which most of that misfit
#: is the smoothing's. The kink's part shrinks to 0.5-0.7 of itself per
#: halving (its error goes as the width to a power 0.5-1; 0.58 measured on
#: the positioning axis, where a tenth of the width gave a sixth of the
#: misfit); with a part that does not shrink beside it, adding in squares,
#: 0.7 asks the shrinking part to be nearly twice the other (a share of 0.58
#: per halving), and a kink whose error shrinks slowly is not credited
KINK_MISFIT_SHARE = 0.7
#: a parameter that moves by more than this factor from the user's guess has
#: most likely absorbed a missing effect (or the guess was a slip)
RUNAWAY_FACTOR = 10.0
#: estimates this correlated are not told apart by the data
TRADE_OFF_CORRELATION = 0.995


@dataclass(frozen=True)
class Conclusion:
    """``label`` (one of :data:`CONCLUSIONS`), the sentence, reasons, advice."""

    label: str
    verdict: str
    reasons: tuple
    advice: tuple = ()


@dataclass(frozen=True)
class MissingState:
    """Evidence that the model lacks a state entering ``equation``'.

    Attributes
    ----------
    equation : str
        The state whose equation the missing state would enter.
    evidence : str
        What the memory test measured (:meth:`.memory.MemoryEvidence.describe`).
    name : str
        A free name for the suggested hidden state.
    """

    equation: str
    evidence: str
    name: str = "z"

    def sentence(self) -> str:
        return (
            f"{self.evidence}: the model error has memory that no function of the "
            f"present states gives; a state the model does not have (or an input "
            f"it does not know) is likely, entering {self.equation}'"
        )

    def option(self) -> str:
        return f"hidden_states={{'{self.name}': '{self.equation}'}}"

    def advice(self) -> str:
        return (
            f"a hidden state entering {self.equation}': discover(..., "
            f"hidden_states={{'{self.name}': '{self.equation}'}}) (command line: "
            f"--hidden-state {self.name}:{self.equation}), with a library of the "
            f"states and {self.name}"
        )


@dataclass(frozen=True)
class Overshoot:
    """A model's free run beyond every reading of a channel: a possible limit.

    Attributes
    ----------
    model : str
        ``"extended"`` or ``"assumed"``.
    channel : str
    side : {"ceiling", "floor"}
        Above the highest reading, or below the lowest.
    reached : float
        The free run's extreme on that side.
    level : float
        The highest (lowest) reading.
    clipped : bool
        That reading is a sensor limit: the record's readings are clipped
        there.
    """

    model: str
    channel: str
    side: str
    reached: float
    level: float
    clipped: bool = False

    def sentence(self) -> str:
        above = self.side == "ceiling"
        where = "above the highest" if above else "below the lowest"
        limit = f", a sensor {self.side}" if self.clipped else ""
        tail = (
            ", or only the sensor does"
            if self.clipped
            else ", where the data level off"
        )
        return (
            f"the {self.model} model's {self.channel} reaches {sig(self.reached)}, "
            f"{where} reading ({sig(self.level)}{limit}): the plant may saturate "
            f"there (an overflow or a limit the model lacks){tail}; try "
            "PhysicsLibrary effects Overflow/Saturation at that level"
        )

    def advice(self) -> str:
        return (
            f"a limit the model lacks at {self.channel} = {sig(self.level)}: "
            "PhysicsLibrary effects Overflow or Saturation at that level"
        )


@dataclass
class Evidence:
    """What the conclusion is derived from (all numbers already measured).

    Attributes
    ----------
    contradicted : bool
        The assumed model's chi-square test rejects it at ``alpha``.
    consistency : str
        The test as text (``"chi2 = 812 on 398 dof, p = 1e-30"``).
    terms : list of str
        Kept terms (``"theta in omega'"``).
    assumed_converged, extended_converged : bool
    rmse_assumed, rmse_extended, noise_floor : ndarray (m,)
        In-sample free runs.
    out_assumed, out_extended : ndarray (m,) or None
        Out-of-sample free runs; ``out_source`` says on what.
    out_converged : bool
        The refits the out-of-sample runs come from converged.
    rivals : list of str
        Sentences naming models with other terms that fit nearly as well
        (:attr:`~.confirm.Confirmation.rivals`): the verdict names them.
    out_spread : str or None
        Where the extended model's out-of-sample run stops being determined
        by its initial state's estimate (:mod:`~pysindy_mme.protocols.spread`),
        as a sentence; None: determined throughout.
    out_uncertainty : RunUncertainty or None
        Whether the extended model's out-of-sample miss is the uncertainty
        of its coefficients and start
        (:mod:`~pysindy_mme.protocols.uncertainty`); None: not measured (the
        run at the noise, or a protocol that does not measure it).
    unidentified : list of str
        Sentences naming undetermined quantities.
    parameters : list of str
        Sentences naming runaway or bounded parameters.
    parameter_advice : str or None
        What to try for them, in the user's parameter names (bounds that
        keep each where its guess says it belongs).
    noise_doubt : str or None
        Why the noise level is not known, if it is not.
    overshoots : list of Overshoot
        Levels the data never pass that the model's free run crosses.
    gauges : list of str
        Exact trade-offs fixed by holding a parameter at its guess (a gauge):
        named among the reasons, but no doubt (every other quantity is
        determined relative to the gauge).
    kink_misfit : float or None
        The extended model's misfit beyond the noise refitted with its
        smoothed kinks at half the width (and twice the RK4 steps), as a
        share of its misfit (:class:`~.steps.SmoothingCheck`); None: not
        measured.
    vanished : list of str
        Grey-box parameters the extended fit puts at zero within a small
        standard error (the correction does the work of that part of the
        assumed model): a finding, named among the reasons.
    """

    contradicted: bool
    consistency: str
    terms: list
    assumed_converged: bool
    extended_converged: bool
    rmse_assumed: np.ndarray
    rmse_extended: np.ndarray
    noise_floor: np.ndarray
    channel_names: list
    out_assumed: np.ndarray | None = None
    out_extended: np.ndarray | None = None
    out_source: str | None = None
    out_converged: bool = True
    out_spread: str | None = None
    out_uncertainty: object = None
    rivals: list = field(default_factory=list)
    unidentified: list = field(default_factory=list)
    parameters: list = field(default_factory=list)
    parameter_advice: str | None = None
    noise_doubt: str | None = None
    overshoots: list = field(default_factory=list)
    vanished: list = field(default_factory=list)
    memory: list = field(default_factory=list)
    gauges: list = field(default_factory=list)
    kink_misfit: float | None = None


def combined(rmse, floor) -> float:
    """Noise-weighted RMSE over channels: ``sqrt(mean((rmse / floor)^2))``."""
    rmse, floor = np.asarray(rmse, float), np.asarray(floor, float)
    with np.errstate(all="ignore"):
        return float(np.sqrt(np.mean((rmse / floor) ** 2)))


def conclude(ev: Evidence) -> Conclusion:
    """The conclusion the evidence supports (module docstring)."""
    found = _with_overshoots(_with_memory(_base(ev), ev), ev.overshoots)
    extra = tuple(ev.vanished) + tuple(ev.gauges)
    if extra:
        found = replace(found, reasons=tuple(found.reasons) + extra)
    return found


def _base(ev: Evidence) -> Conclusion:
    """The conclusion before the memory test and the overshoots."""
    return _without_terms(ev) if not ev.terms else _with_terms(ev)


def memory_decides(ev: Evidence) -> bool:
    """Whether a suspected missing state in ``ev`` would be claimed (a reason
    and advice of the conclusion), not set aside by :func:`_with_memory`."""
    return bool(ev.memory) and _claims_state(_base(ev), ev)


def _claims_state(found: Conclusion, ev: Evidence) -> bool:
    """Whether the memory test's finding enters ``found`` as a likely missing
    state: not after "consistent", nor beside a model without the state that
    runs free at the noise (:func:`_runs_at_noise`)."""
    if found.label == "consistent":
        return False
    return not (found.label == "explained" and _runs_at_noise(ev))


def _with_memory(found: Conclusion, ev: Evidence) -> Conclusion:
    """A likely missing state: a reason, and its advice first (label kept).

    Not where a model without the state runs free at the noise on its record
    and on held-out data (:func:`_runs_at_noise`): that model is the
    stronger evidence. The history of MME's states reproduces MME's own
    estimation error (an error state's increment over a lag is the integral
    of ``d``), which at high sampling rates is most of ``d``: on Van der Pol
    at 40 kHz the history "explained" 63 % of a ``d`` that the present
    explained none of, and the found static terms ran free at the noise.
    The finding is then a reason, not the verdict."""
    missing = ev.memory
    if not missing or found.label == "consistent":
        return found
    if not _claims_state(found, ev):
        reasons = list(found.reasons) + [
            f"{m.evidence}, but a model without a state runs free at the noise "
            "on this record and on held-out data: no state is missing"
            for m in missing
        ]
        return replace(found, reasons=tuple(reasons))
    reasons = list(found.reasons)
    reasons[1:1] = [m.sentence() for m in missing]
    advice = [m.advice() for m in missing] + [
        a for a in found.advice if a != _TRY["library"]
    ]
    short = missing[0].option()
    if found.label == "not explained" and found.verdict.startswith(_NO_TERM):
        verdict = (
            "the data contradict the assumed model, and no library term explains "
            "it: the model error has memory no function of the present states "
            f"gives, so a state the model does not have is likely (try {short})"
        )
    elif found.label == "inconclusive":
        verdict = (
            f"inconclusive: {reasons[0]}; a state the model does not have is "
            f"likely (try {short})"
        )
    else:
        verdict = (
            f"{found.verdict}; a state the model does not have is likely (try {short})"
        )
    return replace(found, verdict=verdict, reasons=tuple(reasons), advice=tuple(advice))


def _with_overshoots(found: Conclusion, overshoots) -> Conclusion:
    """The levels a model crosses, as reasons and advice (the label stays)."""
    if not overshoots:
        return found
    advice = list(found.advice)
    for o in overshoots:
        if o.advice() not in advice:
            advice.append(o.advice())
    reasons = tuple(found.reasons) + tuple(o.sentence() for o in overshoots)
    return replace(found, reasons=reasons, advice=tuple(advice))


def _without_terms(ev: Evidence) -> Conclusion:
    reasons = [f"no library term improved the fit significantly; {ev.consistency}"]
    advice = []
    doubts = list(ev.unidentified) + list(ev.parameters)
    if not ev.assumed_converged:
        reasons.insert(0, "the output-error fit of the assumed model did not converge")
        return _inconclusive(reasons + doubts, advice + [_TRY["converge"]])
    if ev.noise_doubt:
        reasons.insert(0, ev.noise_doubt)
        return _inconclusive(reasons + doubts, [_TRY["noise"]])
    if ev.contradicted:
        verdict = (
            f"{_NO_TERM} it: the library lacks the effect (try other functions, "
            "inputs, or check the noise variance and the model's parameters)"
        )
        return Conclusion(
            "not explained", verdict, tuple(reasons + doubts), (_TRY["library"],)
        )
    verdict = "the data are consistent with the assumed model: no correction needed"
    return Conclusion("consistent", verdict, tuple(reasons + doubts))


def _with_terms(ev: Evidence) -> Conclusion:
    terms = _short(ev.terms)
    blockers, advice = [], []
    if not ev.extended_converged:
        blockers.append("the output-error refit of the extended model did not converge")
        advice.append(_TRY["converge"])
    in_a = combined(ev.rmse_assumed, ev.noise_floor)
    in_e = combined(ev.rmse_extended, ev.noise_floor)
    if not np.isfinite(in_e):
        blockers.append(
            "the extended model's free run from its fitted initial state does not "
            "stay finite over the record"
        )
    elif np.isfinite(in_a) and in_e >= in_a:
        blockers.append(
            "the extended model's free run is no closer to the record than the "
            f"assumed model's ({sig(in_e, 3)}x against {sig(in_a, 3)}x the noise)"
        )
    if ev.unidentified:
        blockers += list(ev.unidentified)
        advice.append(_TRY["identify"])
    if ev.parameters:
        blockers += list(ev.parameters)
        advice.append(ev.parameter_advice or _TRY["parameters"])
    if ev.noise_doubt:
        blockers.append(ev.noise_doubt)
        advice.append(_TRY["noise"])
    held = _held_out(ev)
    if held is None:
        blockers.append(
            "there is no held-out data to check the terms on (the record is too "
            "short to spare a stretch)"
        )
        advice.append(_TRY["validation"])
    else:
        gain, worst, text = held
        worse = gain < 1.0 / HELD_OUT_MARGIN or worst < 1.0 / HELD_OUT_MARGIN
        if ev.out_spread and (worse or gain < HELD_OUT_MARGIN):
            # A run its start's estimate spreads by more than the noise is
            # expected to miss the data even for a perfect model: "worse" or
            # "too small a gain" may then be the estimate's, not the model's
            blockers.append(f"on {text}; but {ev.out_spread}")
            advice.append(_TRY["spread"])
        elif worse:
            reasons = [f"with {terms} the model is worse on {text}"] + blockers
            verdict = (
                "the data contradict the assumed model; the terms found do not "
                f"explain it: the extended model is worse on {ev.out_source}"
            )
            return Conclusion(
                "not explained", verdict, tuple(reasons), tuple(advice + [_TRY["look"]])
            )
        elif gain < HELD_OUT_MARGIN:
            blockers.append(
                f"on {text}: less than the {HELD_OUT_MARGIN}x an explanation needs"
            )
            advice.append(_TRY["look"])
        if not ev.out_converged:
            blockers.append("the refits without the held-out stretch did not converge")
        out = ev.out_uncertainty
        if out is not None and not np.isfinite(out.expected):
            # the miss is beyond the noise and the estimates' uncertainty can
            # make the run diverge: the data cannot tell whose the miss is
            blockers.append(
                f"on {ev.out_source} it misses the data by {sig(out.observed, 3)}x "
                "the noise, and its run with a coefficient moved by one standard "
                "error diverges: whether that miss is the model's or its "
                "estimates' is not known"
            )
            advice.append(_TRY["carry"])
    if blockers:
        return _inconclusive(
            [f"the study kept {terms}, but {blockers[0]}"] + blockers[1:], advice
        )
    fit_text = _fit_text(ev)
    gain_text = (
        f"held-out gain {sig(held[0], 3)}x on {ev.out_source}"
        if np.isfinite(held[0])
        else f"on {ev.out_source} only the assumed model's free run diverges"
    )
    # why the extended model's held-out run misses the data by more than its
    # fit would suggest, where its start's estimate spreads it
    spread = (f"{ev.out_spread}",) if ev.out_spread else ()
    # whether that miss is the uncertainty of the estimates (measured where
    # the run is not at the noise)
    out = ev.out_uncertainty
    out_text = () if out is None else (f"on {ev.out_source} {out.sentence()}",)
    # other terms that fit nearly as well: the data explain the record with
    # these terms, but do not single them out
    rivals = tuple(ev.rivals)
    rival_text = (
        "; other terms fit nearly as well (see the reasons), so the data do not "
        "single these out"
        if rivals
        else ""
    )
    fits_record = bool(np.all(ev.rmse_extended <= FIT_FACTOR * ev.noise_floor))
    if fits_record and out is not None and out.beyond:
        # the terms fit the record they were chosen on and beat the assumed
        # model on data they were not, but miss those data by more than
        # their estimates' uncertainty allows: look-alikes of the effect, or
        # an effect that stretch exercises and the rest does not
        verdict = (
            "the data contradict the assumed model; the identified terms account "
            f"for its record ({terms}: {gain_text}){rival_text}, but not for data "
            f"they were not fitted to: on {ev.out_source} the extended model misses "
            f"by {sig(out.observed, 3)}x the noise where its estimates' "
            f"uncertainty allows {sig(out.expected, 3)}x"
        )
        reasons = (
            f"{held[2]}",
            *out_text,
            *rivals,
            *spread,
            f"the extended model fits its record {fit_text} (at most {FIT_FACTOR}x)",
        )
        return Conclusion("partly explained", verdict, reasons, (_TRY["carry"],))
    if fits_record:
        verdict = (
            "the data contradict the assumed model; the identified terms explain "
            f"it ({terms}: {gain_text}){rival_text}"
        )
        reasons = (
            f"{held[2]}",
            *out_text,
            *rivals,
            *spread,
            f"the extended model fits its record {fit_text} (at most {FIT_FACTOR}x)",
            "every refit converged, and no kept term or parameter is unidentified",
        )
        return Conclusion("explained", verdict, reasons)
    verdict = (
        "the data contradict the assumed model; the identified terms explain part "
        f"of it ({terms}: {gain_text}), but the extended model still misses the "
        f"data ({fit_text}){rival_text}"
    )
    if ev.kink_misfit is not None and ev.kink_misfit <= KINK_MISFIT_SHARE:
        # what is left follows a numerical choice, not the plant
        verdict += (
            ": most of that misfit is the integration of the smoothed kinks, "
            "not an effect the library lacks"
        )
        reasons = (
            f"{held[2]}",
            *out_text,
            *rivals,
            f"the extended model still misses its record {fit_text}, more than "
            f"{FIT_FACTOR}x, but refitted with its kinks smoothed over half the "
            "width (and twice the RK4 steps) that misfit falls to "
            f"{100 * ev.kink_misfit:.0f} % of itself: most of it is the "
            "integration of the smoothed kinks, not an effect the library lacks",
        )
        return Conclusion("partly explained", verdict, reasons, (_TRY["kinks"],))
    # the share a narrower smoothing left, where measured: why the misfit is
    # not put down to the kinks
    kinks = (
        ""
        if ev.kink_misfit is None
        else f" (refitted with its kinks smoothed over half the width, "
        f"{100 * ev.kink_misfit:.0f} % of that misfit stays)"
    )
    reasons = (
        f"{held[2]}",
        *out_text,
        *rivals,
        f"the extended model still misses its record {fit_text}, more than "
        f"{FIT_FACTOR}x: part of the effect is not in the library{kinks}",
    )
    return Conclusion("partly explained", verdict, reasons, (_TRY["rest"],))


def _runs_at_noise(ev: Evidence) -> bool:
    """The extended model's free runs, on its record and out of sample, are
    within ``FIT_FACTOR`` of the noise on every channel."""
    if ev.out_extended is None:
        return False
    floor = FIT_FACTOR * np.asarray(ev.noise_floor, float)
    return bool(
        np.all(np.asarray(ev.rmse_extended, float) <= floor)
        and np.all(np.asarray(ev.out_extended, float) <= floor)
    )


def _held_out(ev: Evidence):
    """``(combined gain, worst channel gain, text)`` or None."""
    if ev.out_assumed is None or ev.out_source is None:
        return None
    a = combined(ev.out_assumed, ev.noise_floor)
    e = combined(ev.out_extended, ev.noise_floor)
    if not np.isfinite(e):
        return (
            0.0,
            0.0,
            (f"{ev.out_source}, where the extended model's free run diverges"),
        )
    if not np.isfinite(a):
        return (
            np.inf,
            np.inf,
            (f"{ev.out_source}, where only the assumed model's free run diverges"),
        )
    with np.errstate(all="ignore"):
        per = np.asarray(ev.out_assumed, float) / np.asarray(ev.out_extended, float)
    per = per[np.isfinite(per)]
    worst = float(per.min()) if per.size else a / e
    gain = a / e
    text = (
        f"{ev.out_source}: RMSE {sig(a, 3)}x -> {sig(e, 3)}x the noise, a gain of "
        f"{sig(gain, 3)}x"
    )
    return gain, worst, text


def _fit_text(ev: Evidence) -> str:
    ratios = np.asarray(ev.rmse_extended, float) / np.asarray(ev.noise_floor, float)
    parts = [
        f"{name} {sig(r, 3)}x the noise" for name, r in zip(ev.channel_names, ratios)
    ]
    return "to " + ", ".join(parts)


def _short(terms, shown=4) -> str:
    terms = list(terms)
    text = ", ".join(terms[:shown])
    return text + (f" and {len(terms) - shown} more" if len(terms) > shown else "")


def _inconclusive(reasons, advice) -> Conclusion:
    first = reasons[0] if reasons else "the evidence does not settle it"
    verdict = f"inconclusive: {first}"
    if advice:
        verdict += f" (try: {advice[0]})"
    return Conclusion("inconclusive", verdict, tuple(reasons), tuple(advice))


_NO_TERM = "the data contradict the assumed model, but no library term explains"

_TRY = {
    "converge": (
        "a library without look-alike functions, a noise_variance checked against "
        "the sensor, bounds on the grey-box parameters, or a shorter stretch first"
    ),
    "noise": (
        "state noise_variance (the sensor's noise, or the accuracy the model "
        "should reach)"
    ),
    "library": "other library functions, the inputs, or a hidden state",
    "identify": (
        "fix one of the quantities that trade off (a known constant in the "
        "model), or measure the hidden state"
    ),
    "parameters": (
        "bounds on the grey-box parameters from what you know of them "
        "(parameters={name: (guess, lower, upper)}) or a library without terms "
        "that re-do them"
    ),
    "validation": "a validation record (validation=(y, t[, u]))",
    "look": (
        "a smaller library (functions only of the variables they act on, e.g. "
        "sign of the velocity, not of the input), a longer record, or one that "
        "spans the validation record's amplitudes"
    ),
    "rest": "more library functions, or a hidden state (the effect may have memory)",
    "spread": (
        "a longer window for the initial state (HeldOut(window=...), or the "
        "validation protocol's window) or predictions a few samples ahead "
        "(validation_protocol=KStepAhead(k=...)), which measure the model, not "
        "the estimate of its start"
    ),
    "carry": (
        "a validation record that exercises the effect over the range you will "
        "use the model in, a library with the effect's physical form "
        "(PhysicsLibrary), or a longer record (narrower estimates)"
    ),
    "kinks": (
        "a narrower smoothing of the kinks (PhysicsLibrary(smoothing=...), 1e-3 by "
        "default) with more RK4 steps (discover(n_substeps=...))"
    ),
}
