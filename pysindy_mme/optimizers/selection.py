"""The Phase I / Phase II selection machine (pure logic over the QR state).

Phase I (Draper & Smith's stepwise regression): in each iteration, if a
function in the model has a partial F-ratio (eq. 20) below the removal
threshold, the weakest one leaves; otherwise the candidate with the largest
partial F-ratio of entry (eq. 19) enters if it reaches the entry threshold.
Which F-ratios (classic or Newey-West robust) and which thresholds is the
rule's business (:mod:`.rules`).

Phase II (the paper's floating threshold): the threshold becomes the largest
partial F-ratio in the model divided by ``float_ratio``; the weakest function
below it leaves (one per iteration, all partial F-ratios and the threshold are
then recomputed); when none is below it, candidates must reach ``max(entry
threshold, floating threshold)`` to enter.

Cycles: the floating threshold can send the selection round a loop (removing
a term lowers the strongest partial F-ratio, hence the threshold, and the
term re-enters). Decisions depend only on (phase, model), so a repeated state
is a true cycle: the selection stops at the model of the cycle with the
largest overall F-ratio, which the paper reads as the better representation.

This module decides and records; it warns about nothing. The estimator turns
:attr:`Selection.converged` and :attr:`Selection.cycle` into warnings.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .robust import lag1_autocorrelation

__all__ = ["AUTO_LAG1", "Selection", "Step", "engage_phase_two", "select"]

# floating="auto" engages Phase II when the Phase I residual's lag-1
# autocorrelation exceeds this. Smoothed finite-difference derivatives leave
# at most 0.66 (every record of the drop-in benchmark); MME's d(t) on the
# paper's Van der Pol record 0.94-0.98.
AUTO_LAG1 = 0.9


@dataclass(frozen=True)
class Step:
    """One addition or removal made by :class:`FloatingFStepwise`.

    Attributes
    ----------
    iteration : int
        1-based iteration number (per target).
    phase : int
        1 (fixed thresholds) or 2 (floating threshold).
    action : str
        ``"add"`` or ``"remove"``.
    feature : int
        Library column index.
    name : str
        Its name (``feature_names`` given to ``fit``, else ``"f<index>"``).
    partial_f : float
        The function's partial F-ratio that triggered the step (of entry for
        an addition, eq. 19; in the model for a removal, eq. 20).
    threshold : float
        The threshold it was compared with.
    n_terms : int
        Number of functions in the model after the step (constant excluded).
    """

    iteration: int
    phase: int
    action: str
    feature: int
    name: str
    partial_f: float
    threshold: float
    n_terms: int


@dataclass
class Selection:
    """What the selection of one target did.

    Attributes
    ----------
    steps : list of Step
    converged : bool
        False if ``max_iter`` steps were taken before the rules settled.
    cycle : dict or None
        ``{"phase", "iteration", "length"}`` of the cycle that stopped the
        selection (the phase and iteration at which a state repeated).
    phase_two : bool
        Whether Phase II ran.
    phase_one_lag1 : float
        Lag-1 autocorrelation of the residual at the end of Phase I (what
        ``floating="auto"`` decides on).
    """

    steps: list = field(default_factory=list)
    converged: bool = True
    cycle: dict | None = None
    phase_two: bool = False
    phase_one_lag1: float = 0.0


class _CycleGuard:
    """Remembers the (phase, model) states visited and resolves a cycle.

    At the first repeat it picks the state of the cycle with the largest
    overall F-ratio; the selection then replays the cycle (decisions depend
    only on the state) until it reaches that state.
    """

    def __init__(self):
        start = (1, frozenset())
        self.visited = {start}
        self.trail = [start]  # states in the order visited
        self.trail_f = [0.0]  # their overall F-ratios
        self.goal = None
        self.replay_left = 0
        self.cycle = None

    def record(self, key, overall_f: float) -> None:
        self.visited.add(key)
        self.trail.append(key)
        self.trail_f.append(overall_f)

    def stop_after(self, key, overall_f: float, iteration: int) -> bool:
        """Whether to stop after a step that reached ``key``."""
        if self.goal is not None:
            self.replay_left -= 1
            return key == self.goal or self.replay_left <= 0
        if key not in self.visited:
            self.record(key, overall_f)
            return False
        first = self.trail.index(key)
        cycle, cycle_f = self.trail[first:], self.trail_f[first:]
        self.goal = cycle[int(np.argmax(cycle_f))]
        self.cycle = dict(phase=key[0], iteration=iteration, length=len(cycle))
        if self.goal == key:
            return True
        self.replay_left = len(cycle)
        return False


def _next_action(state, rule, phase: int, ratio: float):
    """``(kind, column, partial F, threshold)`` of the next step, or None.

    Phase I compares the rule's statistics with its thresholds; Phase II the
    classic F-ratios with ``max(rule threshold, strongest F / ratio)``.
    """
    enter_thr, remove_thr = rule.thresholds(state.k)
    k = state.k
    if phase == 1:
        f_in = rule.in_model_f(state) if k else np.zeros(0)
    else:
        f_in = state.in_model_f()[1:] if k else np.zeros(0)
    # At an exact fit (noise-free target) every partial F-ratio is infinite
    # in principle; rounding-level values cannot be ranked, so the floating
    # threshold does not apply.
    if phase == 2 and k and not state.exact_fit():
        floating = float(np.max(f_in)) / ratio
        enter_thr = max(enter_thr, floating)
        remove_thr = max(remove_thr, floating)
    if k and float(np.min(f_in)) < remove_thr:
        i = int(np.argmin(f_in))
        return ("remove", state.support[i], float(f_in[i]), remove_thr)
    if state.exact_fit():
        return None
    f_cand = rule.candidate_f(state) if phase == 1 else state.candidate_f()
    if f_cand.size:
        best = int(np.argmax(f_cand))
        # -inf marks "not eligible"; +inf (exact improvement) may enter.
        if f_cand[best] > -np.inf and f_cand[best] >= enter_thr:
            return ("add", best, float(f_cand[best]), enter_thr)
    return None


def engage_phase_two(state, floating, threshold: float = AUTO_LAG1) -> bool:
    """Whether Phase II runs after Phase I.

    ``floating`` True or False decides; ``"auto"`` engages it when the Phase I
    residual's lag-1 autocorrelation exceeds ``threshold`` (smooth residuals
    such as MME's model-error estimate, the case the floating threshold was
    designed for) and the fit is not exact.
    """
    if floating != "auto":
        return bool(floating)
    if not state.k or state.exact_fit():
        return False
    return lag1_autocorrelation(state.e) > threshold


def _take(state, rule, action, phase: int, iteration: int, name) -> Step:
    kind, column, fval, thr = action
    if kind == "add":
        state.add(column)
        # Same value as the F of entry, but free of the cancellation in
        # SSE_old - reduction when the new term explains nearly all.
        f_in = rule.in_model_f(state) if phase == 1 else state.in_model_f()[1:]
        fval = float(f_in[-1])
    else:
        state.remove(column)
    column = int(column)
    return Step(
        iteration=iteration,
        phase=phase,
        action=kind,
        feature=column,
        name=name(column),
        partial_f=fval,
        threshold=float(thr),
        n_terms=state.k,
    )


def select(
    state,
    rule,
    floating,
    float_ratio: float,
    max_iter: int,
    name,
    on_step=None,
):
    """Run Phases I and II on ``state`` (an :class:`~.incremental_qr.IncrementalQR`).

    Parameters
    ----------
    state : IncrementalQR
        Starts at the constant-only model; modified in place.
    rule : ClassicRule or FamilywiseRule
        Statistics and thresholds of Phase I (see :mod:`.rules`).
    floating : bool or "auto"
        Run Phase II after Phase I (see :func:`engage_phase_two`).
    float_ratio : float
        Phase II threshold = strongest partial F in the model / this.
    max_iter : int
        Maximum number of steps.
    name : callable
        ``name(column) -> str`` for the steps.
    on_step : callable, optional
        Called as ``on_step(state)`` after every step (e.g. to record the
        coefficients; nothing is kept here, so wide libraries cost no memory).

    Returns
    -------
    Selection
    """
    out = Selection()
    phase = 1
    guard = _CycleGuard()
    while True:
        action = _next_action(state, rule, phase, float_ratio)
        if action is None:
            if phase == 1:
                out.phase_one_lag1 = lag1_autocorrelation(state.e)
                if engage_phase_two(state, floating):
                    phase = 2
                    out.phase_two = True
                    guard.record((2, frozenset(state.support)), state.overall_f())
                    continue
            break
        if len(out.steps) >= max_iter:
            out.converged = False
            break
        out.steps.append(_take(state, rule, action, phase, len(out.steps) + 1, name))
        if on_step is not None:
            on_step(state)
        key = (phase, frozenset(state.support))
        if guard.stop_after(key, state.overall_f(), len(out.steps)):
            break
    out.cycle = guard.cycle
    return out
