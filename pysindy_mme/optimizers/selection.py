"""The Phase I / Phase II selection machine (pure logic over the QR state).

Phase I (Draper & Smith's stepwise regression): in each iteration, if a
function in the model has a partial F-ratio (eq. 20) below the removal
threshold, the weakest one leaves; otherwise, of the candidates whose partial
F-ratio of entry reaches the entry threshold, the one that lowers the
residual sum of squares most (the largest classic F-ratio, eq. 19) enters.
Which F-ratios decide (classic or Newey-West robust) and which thresholds is
the rule's business (:mod:`.rules`); with classic ones the candidate that
enters is the one with the largest F-ratio, as in the paper.

Phase II (the paper's floating threshold): the threshold becomes the largest
partial F-ratio in the model divided by ``float_ratio``; the weakest function
below it leaves (one per iteration, all partial F-ratios and the threshold are
then recomputed); when none is below it, candidates must reach ``max(entry
threshold, floating threshold)`` to enter.

Jointly significant groups (the default rule only): forward selection
misses terms that matter only together, such as ``mu y - y (x^2 + y^2)``
in a Hopf normal form, whose parts nearly cancel on the limit cycle, or
``x z - 5 x`` in Rikitake's dynamo (z oscillates about 5), so that none
enters alone and a false proxy may enter instead. When Phase I stops, the
candidates left out are tested together (one F-test at level ``alpha``,
Newey-West robust like the single-term tests); if they are jointly
significant, every one is added, the weakest are removed by the same rule
until all that remain pass (a backward elimination, removals only), and
Phase I continues. Significance is not relevance: with thousands of rows,
the systematic error of a derivative estimate (Rossler's z' bursts, Chen,
a degree-5 library at 0.1 % noise) is jointly significant too, and the
restart then keeps false terms that improve the fit by a few per cent. So
the restarted model is kept only where the forward model left most of the
target unexplained (R^2 < ``JOINT_MAX_R2``: it misses dynamics, the case
the restart was made for), or where it is relevantly better than the
forward one: no more terms and a smaller residual, or each extra term
reduces the residual sum of squares by at least ``JOINT_MIN_EFFECT`` times
the restarted model's (Cohen's f^2 per extra term). Otherwise the
selection returns to the forward model. Only for libraries of at most
``JOINT_MAX_CANDIDATES`` columns, and with ten observations per column:
beyond, the test costs more than the fit.

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
from scipy import stats

__all__ = [
    "AUTO_LAG1",
    "JOINT_MAX_CANDIDATES",
    "JOINT_MAX_R2",
    "JOINT_MIN_EFFECT",
    "Selection",
    "Step",
    "engage_phase_two",
    "joint_test",
    "history_row",
    "select",
    "select_target",
]

# floating="auto" engages Phase II when the Phase I residual's lag-1
# autocorrelation exceeds this. Smoothed finite-difference derivatives leave
# at most 0.66 (every record of the drop-in benchmark); MME's d(t) on the
# paper's Van der Pol record 0.94-0.98.
AUTO_LAG1 = 0.9
# The joint test of the left-out candidates costs O(n q^2): up to this many.
JOINT_MAX_CANDIDATES = 100
# The restarted model is kept where the forward model explains less than this
# share of the target's variance: terms that cancel along the data leave
# their target poorly explained (Hopf's y' from two trajectories at 5 %
# noise: R^2 0.52-0.54 before the restart) ...
JOINT_MAX_R2 = 0.8
# ... and elsewhere only if each term it has beyond the forward model reduces
# the residual sum of squares by at least this multiple of the restarted
# model's (Cohen's f^2 per extra term; 0.15 is his "medium" effect), or if it
# has no more terms and a smaller residual. Measured on the drop-in
# benchmark's records (3 seeds, old and development systems): restarts that
# found a cancelling group the forward model missed gained f^2 of 0.13 to 21
# per extra term (Hopf normal form at 1 % and 0.1 %, Brusselator at 5 %) or
# were no larger (Rikitake at 1 %); restarts that only added false terms
# fitted to the derivative's systematic error 0.001 to 0.056 (Rossler,
# Lorenz, Chen, Rikitake at 5 %, the degree-5 cubic oscillator at 0.1 %).
JOINT_MIN_EFFECT = 0.15


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
        The threshold it was compared with. (A Phase I removal whose
        ``partial_f`` is above it was for relevance: the function's Cohen's
        f^2 fell below the default rule's ``rules.MIN_EFFECT``.)
    n_terms : int
        Number of functions in the model after the step (constant excluded).
    joint : bool
        Added by the joint restart: ``partial_f`` and ``threshold`` are then
        the joint F-ratio of all the functions added together and its
        critical value at ``alpha``. (A step with ``threshold`` 1 exchanged
        the model for a smaller one with a smaller corrected residual sum of
        squares, ``partial_f`` their ratio:
        :func:`~.errors_in_variables.corrected_or_as_given`.)
    """

    iteration: int
    phase: int
    action: str
    feature: int
    name: str
    partial_f: float
    threshold: float
    n_terms: int
    joint: bool = False


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
    joint : dict or None
        ``{"n", "f", "p", "restart"}`` of the joint test of the candidates
        left out by Phase I (None when it was not run).
    """

    steps: list = field(default_factory=list)
    converged: bool = True
    cycle: dict | None = None
    phase_two: bool = False
    phase_one_lag1: float = 0.0
    joint: dict | None = None


class _CycleGuard:
    """Remembers the (phase, model) states visited and resolves a cycle.

    At the first repeat it picks the state of the cycle with the largest
    overall F-ratio; the selection then replays the cycle (decisions depend
    only on the state) until it reaches that state.
    """

    def __init__(self, start=(1, frozenset()), start_f: float = 0.0):
        self.visited = {start}
        self.trail = [start]  # states in the order visited
        self.trail_f = [start_f]  # their overall F-ratios
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


def _next_action(state, rule, phase: int, ratio: float, backward: bool = False):
    """``(kind, column, partial F, threshold)`` of the next step, or None.

    Phase I compares the rule's statistics with its thresholds; Phase II the
    classic F-ratios with ``max(rule threshold, strongest F / ratio)``.
    ``backward``: removals only (the elimination after a joint restart).
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
    # Phase I: a function must also be relevant (the default rule's f^2 floor,
    # see rules.MIN_EFFECT); an irrelevant one leaves, weakest first.
    weak = f_in < remove_thr
    if phase == 1 and k:
        weak = weak | ~rule.relevant_in_model(state)
    if k and np.any(weak):
        i = int(np.argmin(np.where(weak, f_in, np.inf)))
        return ("remove", state.support[i], float(f_in[i]), remove_thr)
    if backward or state.exact_fit():
        return None
    classic = state.candidate_f()
    f_cand = rule.candidate_f(state, classic) if phase == 1 else classic
    if f_cand.size:
        if phase == 1:
            relevant = rule.relevant_candidates(state, classic)
            f_cand = np.where(relevant, f_cand, -np.inf)
        # -inf marks "not eligible"; +inf (exact improvement) may enter.
        passing = (f_cand > -np.inf) & (f_cand >= enter_thr)
        if np.any(passing):
            # The rule's statistic decides which candidates may enter; of
            # those, the one that lowers the residual sum of squares most
            # (the classic F-ratio, eq. 19) enters. A robust F-ratio divides
            # by each candidate's own long-run variance: it calibrates the
            # test, but ranking by it prefers a worse-fitting look-alike whose
            # score happens to be less autocorrelated (x0^5 for a weak x0^3 in
            # a degree-5 cubic oscillator at 5 % noise). With classic
            # F-ratios (Phase II, ClassicRule) this is the largest one.
            best = int(np.argmax(np.where(passing, classic, -np.inf)))
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
    return state.residual_lag1() > threshold


def joint_test(state, rule):
    """Joint F-test of every eligible candidate outside the model.

    Returns ``(columns, F, p, critical F)`` or None when the test does not
    apply (fewer than two candidates, more than ``JOINT_MAX_CANDIDATES``, or
    fewer than ten observations per column of the full model). Under a robust rule the
    F-ratio is the Newey-West Wald statistic over ``q``
    (:func:`~.robust.robust_joint_f`), as the single-term tests are robust.
    """
    if state.sst <= 0:
        return None
    f_cand = state.candidate_f()
    cols = np.flatnonzero(f_cand > -np.inf)
    q, k = cols.size, state.k
    dof = state.n_eff - k - q - 1
    if q < 2 or q > JOINT_MAX_CANDIDATES or dof < 10 * (k + q + 1):
        return None
    f = state.joint_f(cols, rule.lags if rule.robust else None)
    p = float(stats.f.sf(f, q, dof))
    return cols, float(f), p, float(stats.f.isf(rule.joint_alpha, q, dof))


def _restart_from_all(state, cols, f, critical, iteration, name) -> list:
    """Add every column of ``cols`` (those still eligible as they come)."""
    steps = []
    for column in cols:
        if state.candidate_f()[column] == -np.inf:
            continue  # collinear with the columns already added
        state.add(int(column))
        steps.append(
            Step(
                iteration=iteration + len(steps),
                phase=1,
                action="add",
                feature=int(column),
                name=name(int(column)),
                partial_f=float(f),
                threshold=critical,
                n_terms=state.k,
                joint=True,
            )
        )
    return steps


def restart_effect(forward_k: int, forward_sse: float, k: int, sse: float) -> float:
    """Cohen's f^2 per extra term of the restarted model over the forward one.

    ``inf`` when the restarted model has no more terms and a smaller
    residual (it is better on both counts); 0 when its residual is not
    smaller.
    """
    if sse >= forward_sse:
        return 0.0
    if k <= forward_k:
        return np.inf
    if sse <= 0.0:
        return np.inf
    return (forward_sse - sse) / sse / (k - forward_k)


def _return_to(state, support, iteration: int, name, f, critical) -> list:
    """Steps that take ``state`` back to the model ``support`` (joint=True)."""
    steps = []
    for column in [c for c in state.support if c not in support]:
        state.remove(int(column))
        steps.append(
            Step(
                iteration + len(steps),
                1,
                "remove",
                int(column),
                name(int(column)),
                float(f),
                critical,
                state.k,
                joint=True,
            )
        )
    for column in [c for c in support if c not in state.support]:
        state.add(int(column))
        steps.append(
            Step(
                iteration + len(steps),
                1,
                "add",
                int(column),
                name(int(column)),
                float(f),
                critical,
                state.k,
                joint=True,
            )
        )
    return steps


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
    joint_alpha = getattr(rule, "joint_alpha", None)
    backward = False  # after a joint restart: removals only, then stepwise again
    forward = None  # (support, SSE, F, critical) of the model before the restart
    while True:
        action = _next_action(state, rule, phase, float_ratio, backward)
        if action is None and backward:
            backward = False
            continue
        if action is None and phase == 1 and forward is not None:
            # Significance is not relevance: keep the restarted model only if
            # it is relevantly better than the forward one.
            support, sse, f, critical = forward
            forward = None
            effect = restart_effect(len(support), sse, state.k, state.sse())
            explained = 1.0 - sse / state.sst if state.sst > 0 else 1.0
            kept = bool(explained < JOINT_MAX_R2 or effect >= JOINT_MIN_EFFECT)
            out.joint.update(effect=float(effect), kept=kept)
            if not kept:
                back = _return_to(state, support, len(out.steps) + 1, name, f, critical)
                out.steps += back
                if on_step is not None and back:
                    on_step(state)
            continue
        if action is None and phase == 1 and joint_alpha and out.joint is None:
            test = None if state.exact_fit() else joint_test(state, rule)
            if test is not None:
                cols, f, p, critical = test
                restart = p < joint_alpha and len(out.steps) + cols.size <= max_iter
                out.joint = dict(n=int(cols.size), f=f, p=p, restart=restart)
                if restart:
                    forward = (list(state.support), state.sse(), f, critical)
                    added = _restart_from_all(
                        state, cols, f, critical, len(out.steps) + 1, name
                    )
                    out.steps += added
                    if on_step is not None and added:
                        on_step(state)
                    # A fresh guard: coming back to the forward model is the
                    # restart finding nothing, not a cycle.
                    guard = _CycleGuard(
                        (1, frozenset(state.support)), state.overall_f()
                    )
                    backward = True
                    continue
        if action is None:
            if phase == 1:
                out.phase_one_lag1 = state.residual_lag1()
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


def history_row(coef, target: int, state) -> np.ndarray:
    """A copy of ``coef`` with ``state``'s coefficients as row ``target``
    (pysindy's ``history_``: ``coef_`` after each step)."""
    row = coef.copy()
    row[target] = state.coefficient_row()
    return row


def select_target(
    make_state,
    rule,
    coef,
    target: int,
    *,
    floating,
    float_ratio,
    max_iter,
    name,
    time_ordered,
):
    """Phases I and II of one target: ``(state, Selection, history rows, rule)``.

    ``make_state()``: a fresh selection state; ``coef``: the coefficients of
    the targets so far (each step's history row is a copy with this
    target's row); ``time_ordered``: whether the rows are in time order.

    Under the default rule with ``floating="auto"``, a Phase I residual
    with lag-1 autocorrelation above ``AUTO_LAG1`` means the regime the
    paper's rule was designed for (a smooth model-error estimate), where
    Newey-West's few lags cannot capture the correlation: the selection is
    then run again with the paper's rule (``F* = 10``, Phase II on).
    """
    from .rules import PAPER_F, ClassicRule

    history = []

    def record(state):
        history.append(history_row(coef, target, state))

    def run(state, rule, floating):
        return select(
            state, rule, floating, float_ratio, max_iter, name, on_step=record
        )

    state = make_state()
    if floating == "auto" and not time_ordered and not isinstance(rule, ClassicRule):
        # Rows not in time order: the lag-1 autocorrelation "auto" reads
        # means nothing, and the F-ratios' scale is not calibrated.
        floating = True
    if not (floating == "auto" and rule.robust):
        return state, run(state, rule, floating), history, rule
    result = run(state, rule, False)
    if not engage_phase_two(state, "auto"):
        return state, result, history, rule
    lag1 = result.phase_one_lag1
    history.clear()
    state = make_state()
    # the paper's Phase I rule, for a strongly autocorrelated residual
    rule = ClassicRule(PAPER_F, PAPER_F, None, None, rule.n_eff)
    result = run(state, rule, True)
    result.phase_one_lag1 = lag1
    result.phase_two = True
    return state, result, history, rule
