"""Step 4: confirm and complete the correction terms against the measurements.

The stepwise regression of the MME model error proposes terms, but its
F-ratios are computed on ``d(t)``, an estimate that is smooth (strongly
autocorrelated) and shrunk toward zero: they overstate significance, and
functions that look alike on the estimated trajectory (``x2`` and
``x2 |x2|``) cannot be told apart there. The measurements, on the other
hand, carry white noise of known variance, so F-tests on output-error
residuals are valid. The selection is therefore finished in output-error
space (:mod:`.output_error`):

1. start: the proposed terms refitted together (initial state and all
   coefficients, from the MME state estimate), or, when there are many or
   the joint fit fails, added one at a time in the order the regression
   chose them, each kept only if it improves the fit significantly; the
   start is completed by forward steps (4.) before it is pruned;
   then the proposals that failed alone are fitted as one group on top of
   what was kept (terms that matter only together: a hysteretic law
   ``z' = a v - b |v| z`` does nothing with either term alone), pruned
   backward, and kept if the group improves the fit significantly (a
   group the backward step has just removed from a fit of exactly the
   kept terms plus that group, the joint start's false proposals, is not
   fitted again);
2. swap: each term is taken out and the look-alike library functions of its
   equation (most correlated along the current trajectory) put in instead;
   a pair of terms of one equation may be merged into the single function
   most like their fitted combination (``x2 |x2|`` and ``x2^3`` together
   imitate ``x2``). Swaps and merges are pruned backward and kept when they
   lower the BIC;
3. backward: terms whose coefficient is not significant (Wald) leave,
   weakest first;
4. forward over the whole library: a score test (the partial F each library
   function of each error state would have, from the fitted KKT system)
   ranks the candidates; the best enters if it is significant after a
   Bonferroni correction, confirmed by an actual fit;
5. repeat 2-4 until nothing changes; if a model visited on the way (its
   fit joined) beats the one the search ended on, the search returns to it
   (:func:`_best_visited`: the steps are local, and a chain of BIC swaps and
   redundancies can end far from the best); finally the extended model is
   F-tested against the assumed one.

Every term is tested at the Bonferroni level ``alpha / n_candidates`` (it
was picked from the whole library), so that the chance of reporting any
false term when the assumed model is right stays about ``alpha``. A trial
whose model blows up or cannot be fitted is rejected with that reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

from ..solver.output_error import OutputErrorFit, OutputErrorModel, bic_of
from ..solver.statistics import better_bic, partial_f_p_value

__all__ = ["Confirmation", "confirm_terms", "partial_f_p_value"]

#: proposals fitted jointly at the start (then pruned backward) when there
#: are at most this many (a joint fit of many terms on a long record costs
#: more than fitting them one by one)
JOINT_START_MAX = 6
#: proposals that failed alone fitted together as one group (at most)
GROUP_MAX = 6
#: rounds of swap/backward/forward passes
MAX_ROUNDS = 4
#: Gauss-Newton iterations allowed to a trial fit (the chosen model is
#: polished with the full budget)
TRIAL_ITER = 12
#: iterations a trial gets before it must show it can compete
TRIAL_FIRST = 4
#: a trial fit stops at this relative predicted decrease (it is judged by a
#: cost difference of many units when it matters)
TRIAL_TOL = 1e-6
#: look-alike functions tried in place of each term
N_LOOK_ALIKES = 2
#: a model with other terms whose BIC is less than this above the kept model's
#: is named as a rival: Kass and Raftery's (1995) scale calls a BIC
#: difference of 2-6 "positive" evidence and 6-10 "strong"; below 6 the data
#: do not tell the two models apart strongly
RIVAL_BIC = 6.0
#: Gauss-Newton iterations of a polish (the chosen model's fit)
POLISH_ITER = 50
#: further polishes of a fit that has not joined when its budget ran out
POLISH_ROUNDS = 2
#: why a term whose polished fit does not join is not taken
_NOT_JOINED = (
    "its fit does not follow the model (the trajectory does not join), so its "
    "cost is no model's cost"
)


@dataclass
class Confirmation:
    """Outcome of :func:`confirm_terms`.

    Attributes
    ----------
    slots : list of (state, column)
        Terms kept.
    fit : OutputErrorFit or None
        Final fit (None when no term is kept).
    rejected : list of (slot, reason)
        Proposed or tried terms not kept, with the reason.
    correction_p_value : float
        F-test of the extended against the assumed model (NaN if no term).
    log : list of str
        One line per decision.
    notes : list of str
        What the report must say about the kept terms (a flow kept as a
        wall whose rate the data do not fix).
    rivals : list of (slots, float)
        Models the search fitted that neither contain the kept terms nor
        are contained in them, with a BIC less than :data:`RIVAL_BIC` above
        the kept model's (that difference, smallest first): other terms the
        data tell from the kept ones only weakly.
    """

    slots: list
    fit: OutputErrorFit | None
    rejected: list = field(default_factory=list)
    correction_p_value: float = float("nan")
    log: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    rivals: list = field(default_factory=list)


class _Search:
    """The state of the selection: current terms, fit, log and rejections."""

    def __init__(
        self,
        engine: OutputErrorModel,
        assumed: OutputErrorFit,
        alpha_term,
        describe,
        pool,
        progress,
        min_effect=0.0,
    ):
        self.min_effect = float(min_effect)
        self.engine, self.assumed = engine, assumed
        self.alpha_term, self.describe, self.pool = alpha_term, describe, list(pool)
        self.progress = progress or (lambda msg: None)
        self.slots, self.fit = [], assumed
        self.log, self.rejected = [], []
        self.tried = set()
        self.mme = None  # (x, d, physical): MME's estimate, see mme_trial
        # (terms fitted together, terms the backward step left of them): a
        # group that was fitted as a whole and pruned is not refitted
        self.pruned = []
        self.steps_of = None  # fit -> RK4 steps its model needs, see accept
        # term sets for which no fit that joins was found (_joined_without)
        self.unjoined = set()
        # every current model whose fit joined: (slots, fit), see _best_visited
        self.visited = []
        # models a swap tried and did not keep (slots, fit), see _rivals
        self.tried_swaps = []

    # ------------------------------------------------------------ MME start
    def mme_fit(self) -> OutputErrorFit:
        """A placeholder fit at MME's trajectory and parameters (a start)."""
        x, _, physical = self.mme
        return self.placeholder(x, physical)

    def placeholder(self, x, physical) -> OutputErrorFit:
        """A fit of no terms at trajectory ``x`` and ``physical`` (with the
        assumed fit's offsets): where a trial starts, not a result."""
        return OutputErrorFit(
            slots=(),
            theta=np.concatenate([physical, self.assumed.offsets]),
            x=x,
            cost=np.nan,
            n_residuals=0,
            n_free=0,
            converged=False,
            message="",
            rank_deficient=False,
            n_iter=0,
            n_physical=self.assumed.n_physical,
            n_offsets=self.assumed.n_offsets,
        )

    def mme_coefficients(self, slots) -> np.ndarray:
        """Least-squares coefficients of ``slots`` on MME's ``d(t)``, per
        equation, along MME's states (zeros where it cannot be solved)."""
        x, d, _ = self.mme
        u = self.engine.inputs.grid()
        z = x if u is None else np.hstack([x, u])
        coefs = np.zeros(len(slots))
        with np.errstate(all="ignore"):
            cols = self.engine.features(z, [c for _, c in slots])
        for i in {s[0] for s in slots}:
            rows = [k for k, s in enumerate(slots) if s[0] == i]
            a = cols[:, rows]
            ok = np.all(np.isfinite(a), axis=1) & np.isfinite(d[:, i])
            if np.count_nonzero(ok) > len(rows):
                coefs[rows] = np.linalg.lstsq(a[ok], d[ok, i], rcond=None)[0]
        return coefs

    def mme_trial(self, slots, best: OutputErrorFit | None) -> OutputErrorFit | None:
        """``slots`` fitted from MME's states instead of the current fit; the
        better of this and ``best``.

        Why: MME's states follow the data whatever the model, while a fit of
        fewer terms follows its own model. When the terms feed back through
        a state (a hysteretic law), adding one term to a wrong fit starts in
        the wrong basin; from MME's trajectory, with the coefficients that
        best explain ``d(t)`` there, the same terms reach the right one.
        """
        if self.mme is None:
            return best
        trial = self.refit(slots, self.mme_coefficients(slots), self.mme_fit())
        if trial.ok and (best is None or not best.ok or trial.cost < best.cost):
            return trial
        return best

    # -------------------------------------------------------------- fitting
    def theta(self, fit, coefs):
        """``[physical, coefs, offsets]`` taking ``fit``'s physical and offsets."""
        return np.concatenate([fit.physical, np.asarray(coefs, float), fit.offsets])

    def refit(self, slots, coefs, start: OutputErrorFit, polish=False):
        """Fit ``slots`` from ``start``'s trajectory with coefficients ``coefs``.

        A trial (not ``polish``) first gets ``TRIAL_FIRST`` iterations; it is
        carried on to ``TRIAL_ITER`` only if it is then within reach of the
        current model (a trial that is still far worse after a few
        Gauss-Newton steps from a warm start is not going to win, and on a
        long record every iteration counts).
        """
        theta = self.theta(start, coefs)
        if polish and _continues(start, slots, theta, self.engine):
            # the polish of a trial goes on from where the trial stopped
            # (its solver and linearisation), not from a fresh solver that
            # would linearise the same point again
            fit = self.engine.resume(start, max_iter=POLISH_ITER, tol=1e-9)
        elif polish:
            fit = self.engine.fit(slots, theta, start.x, max_iter=POLISH_ITER, tol=1e-9)
        else:
            fit = self.engine.fit(
                slots, theta, start.x, max_iter=TRIAL_FIRST, tol=TRIAL_TOL
            )
            reach = (
                self.fit.cost * 1.05 + 10.0 if np.isfinite(self.fit.cost) else np.inf
            )
            if not fit.converged and fit.ok and fit.cost <= reach:
                more = self.engine.resume(
                    fit, max_iter=TRIAL_ITER - fit.n_iter, tol=TRIAL_TOL
                )
                more.n_iter += fit.n_iter
                fit = more if more.ok else fit
        fit = self._from_the_clamp(slots, fit, polish)
        self.progress(
            f"  fit {len(slots)} term(s): cost {fit.cost:.6g}, {fit.n_iter} it."
            + ("" if fit.converged else f" ({fit.message})")
        )
        return fit

    def _from_the_clamp(self, slots, fit, polish):
        """``fit``, or the same terms fitted from the clamp if that fits better.

        A wall (an overflow term of a state in its own equation with a
        negative coefficient, :mod:`~pysindy_mme.solver.output_error`) that a
        rim makes ever stiffer is approached along a curved valley: the
        routes' coefficients must grow with the wall's to keep the fraction
        of the excess they take, and Gauss-Newton crawls along it (tanks
        seed 2: -0.9 to -3.1 in 150 iterations, the trajectory still not
        joined). From the clamp (the wall on its limit, each route at the
        fraction of it that it has now) the same terms converge in a few
        iterations. Both are fitted; the lower joined cost wins, so a soft
        weir that the data call soft stays soft.
        """
        positions = getattr(self.engine, "wall_positions", None)
        if not callable(positions) or not fit.ok:
            return fit
        coefs = np.array(fit.coefficients, dtype=float)
        walls = [k for k in positions(slots) if coefs[k] < 0 and not fit.at_wall[k]]
        if not walls:
            return fit
        limit = self.engine.wall_limit
        for k in walls:
            i, c = slots[k]
            stretch = limit / abs(coefs[k])
            for m, (j, cc) in enumerate(slots):
                if cc == c and j != i:
                    coefs[m] *= stretch  # the same fraction of the excess
            coefs[k] = -limit
        iters = POLISH_ITER if polish else TRIAL_ITER
        tol = 1e-9 if polish else TRIAL_TOL
        clamp = self.engine.fit(
            slots, self.theta(fit, coefs), fit.x, max_iter=iters, tol=tol
        )
        clamp.n_iter += fit.n_iter
        if not clamp.ok or (fit.joined and not clamp.joined):
            return fit
        if clamp.cost < fit.cost or (clamp.joined and not fit.joined):
            return clamp
        return fit

    def improves(self, small, big, n_added=1) -> tuple:
        """``(p, relative cost reduction, ok)`` of ``big`` over ``small``."""
        p = partial_f_p_value(small, big, n_added)
        gain = (small.cost - big.cost) / small.cost if small.cost > 0 else 0.0
        return p, gain, p <= self.alpha_term and gain >= self.min_effect * n_added

    def note(self, text):
        self.log.append(text)
        self.progress(text)

    def reject(self, slot, reason):
        self.rejected.append((slot, reason))

    def replaced(self, before, kept, why):
        """``before``'s terms not in ``kept`` rejected with ``why``; ``kept``'s
        earlier rejections withdrawn (they are in the model now)."""
        for slot in before:
            if slot not in kept:
                self.reject(slot, why)
        self.rejected = [(s, r) for s, r in self.rejected if s not in kept]

    # ------------------------------------------------------------- backward
    def effects(self, fit) -> np.ndarray:
        """Each coefficient's share of the misfit it removes (linearised).

        Removing a term raises the cost by about ``t_raw^2`` residual
        variances (``t_raw`` its Wald statistic before the correlation
        correction), i.e. by ``t_raw^2 / (n - p)`` of the whole cost.
        """
        a = fit.n_physical
        se = fit.std_errors[a : a + len(fit.slots)]
        with np.errstate(divide="ignore", invalid="ignore"):
            t2 = (fit.coefficients / se) ** 2 * fit.inflation
        raw = max(fit.n_residuals - fit.n_free, 1)
        return np.where(np.isfinite(t2), t2 / raw, 0.0)

    def backward(self, slots, fit):
        """Drop terms that are not significant or too small, weakest first.

        The Wald statistics of the joint fit rank the candidates for removal;
        each removal is then confirmed by the fit without the term (the
        change in cost, a likelihood-ratio F-test). Why both: in a model whose
        terms feed back through the states (a hysteretic law) the Wald
        linearisation can call a term worthless whose removal multiplies the
        misfit; the refit is the test the forward steps use too.
        """
        removed = []
        while slots:
            pvals = fit.coefficient_p_values()
            effects = self.effects(fit)
            failing = (pvals > self.alpha_term) | (effects < self.min_effect)
            if not np.any(failing):
                break
            order = np.argsort(-np.where(failing, pvals - effects, -np.inf))
            dropped = False
            for worst in order[: int(np.count_nonzero(failing))]:
                worst = int(worst)
                keep = [k for k in range(len(slots)) if k != worst]
                smaller = [slots[k] for k in keep]
                without = (
                    self.refit(smaller, fit.coefficients[keep], fit)
                    if smaller
                    else self.assumed
                )
                if not without.ok:
                    # from this fit's trajectory the smaller model may not be
                    # fittable; MME's states follow the data whatever the model
                    without = self.mme_trial(smaller, without)
                if not without.ok:
                    # A Wald p of 1 is also what an undefined standard error
                    # gives: with no fit without the term there is no evidence
                    # that it does not matter (a true term whose removal made
                    # the fit diverge was dropped at 10^6 samples)
                    continue
                if fit.joined and not without.joined:
                    without = self._joined_without(smaller, without)
                    if without is None:
                        # Its cost is no model's cost (an overflow taken out of
                        # one tank only, its coefficient walking to 1e12 with
                        # the defects open, "fitted" below the cost of the
                        # joined pair it came from): no evidence either
                        continue
                p, gain, needed = self.improves(without, fit)
                if needed:
                    continue  # the refit says it matters: keep it
                removed.append(
                    (slots[worst], float(pvals[worst]), float(effects[worst]))
                )
                slots = smaller
                if not slots:
                    return [], self.assumed, removed
                fit = without
                dropped = True
                break
            if not dropped:
                break
        return slots, fit, removed

    def _joined_without(self, smaller, without):
        """A fit of ``smaller`` whose trajectory joins, or None.

        ``without`` (a trial that did not join) polished with the full
        budget, then from MME's states; None if neither joins.
        """
        key = frozenset(smaller)
        if key in self.unjoined:
            return None  # tried before in this search: the same two fits
        polished = self.refit(smaller, without.coefficients, without, True)
        if polished.ok and polished.joined:
            return polished
        retry = self.mme_trial(smaller, None)
        if retry is not None and retry.ok and retry.joined:
            return retry
        self.unjoined.add(key)
        return None

    def accept(self, slots, fit, force=False) -> bool:
        """Make ``slots`` the current terms, their fit polished; False (and
        the new terms rejected) when the polished fit does not join (after
        up to ``POLISH_ROUNDS`` more polishes while it was still closing its
        defects when its iterations ran out).

        A trajectory that does not follow its model (defects left open: a
        coefficient walked to 1e70 on a column that is zero along the fit,
        the line search stuck) has a transcription cost that is no model's
        cost, often far below any model's: judged by it, it would replace a
        model that does follow its trajectory. ``force``: take it anyway
        (a term removed for weakness stays removed).
        """
        polished = self.refit(slots, fit.coefficients, fit, True)
        for _ in range(POLISH_ROUNDS):
            # still closing its defects when the budget ran out: carry on
            if polished.joined or polished.n_iter < POLISH_ITER or not polished.ok:
                break
            polished = self.refit(slots, polished.coefficients, polished, True)
        if not (
            force
            or polished.joined
            or not self.fit.joined
            or self.joins_when_finer(polished)
            or self.improves_as_a_model(polished)
        ):
            new = [slot for slot in slots if slot not in self.slots]
            for slot in new:
                self.reject(slot, _NOT_JOINED)
            if new:
                names = ", ".join(self.describe(slot) for slot in new)
                self.note(f"refused {names}: {_NOT_JOINED}")
            return False
        self.slots, self.fit = list(slots), polished
        if polished.joined:
            self.visited.append((list(slots), polished))
        return True

    def joins_when_finer(self, fit) -> bool:
        """Whether a fit that does not join at the search's RK4 steps joins
        at the steps its own model needs (``steps_of``).

        A model faster than the search's discretisation (a hysteretic law
        whose decay rate grows with ``|v|``) cannot follow its trajectory at
        too few steps: that is the step size, not a trajectory that is no
        model's. The search keeps comparing fits at its own steps (every
        F-test on one discretisation); the confirmed model is polished with
        the steps it needs afterwards.
        """
        if self.steps_of is None or not fit.ok:
            return False
        needed = int(self.steps_of(fit))
        if needed <= self.engine.n_substeps:
            return False
        finer = self.engine.with_substeps(needed)
        check = finer.fit(fit.slots, fit.theta, fit.x, max_iter=POLISH_ITER, tol=1e-9)
        if check.ok and check.joined:
            self.note(
                f"the fit with {', '.join(self.describe(s) for s in fit.slots)} "
                f"joins at the {needed} RK4 steps per interval its terms need "
                f"(not at {self.engine.n_substeps}): taken"
            )
            return True
        return False

    def improves_as_a_model(self, fit) -> bool:
        """Whether the model of a fit that does not join, run as a model (its
        parameters held, only its initial state fitted: a trajectory that
        follows it), still improves significantly on the current fit.

        Then the open defects were the line search's, not a sign that the
        cost is no model's: the terms are taken (with the polished fit, whose
        trajectory is within its defects of the model's). A pathological fit
        (a coefficient walked to 1e70 on a column that is zero along the
        fit) fails this: run as a model it blows up or gains nothing.
        """
        new = [s for s in fit.slots if s not in self.slots]
        if not new:
            return False
        held = self.engine.fit_held(fit.slots, fit.theta, fit.x)
        if not (held.ok and held.joined):
            return False
        held = replace(held, n_free=fit.n_free)  # the fit's own parameters
        p, _, ok = self.improves(self.fit, held, n_added=len(new))
        if ok:
            self.note(
                f"the fit with {', '.join(self.describe(s) for s in new)} does "
                f"not join, but its model, run as a model, improves on the "
                f"current one (p = {p:.2g}): taken"
            )
        return ok

    # ---------------------------------------------------------------- start
    def start(self, proposals, values, x_start):
        start_fit = (
            self.mme_fit()
            if self.mme is not None
            else self.placeholder(x_start, self.assumed.physical)
        )
        if 0 < len(proposals) <= JOINT_START_MAX:
            joint = self.refit(proposals, values, start_fit, polish=True)
            p = partial_f_p_value(self.assumed, joint, n_added=len(proposals))
            if joint.ok and joint.joined and p <= self.alpha_term:
                self.slots, self.fit = list(proposals), joint
                self.note(f"joint fit of {len(proposals)} proposals (p = {p:.2g})")
                return
        # terms may only work together (Van der Pol's x2 and -x1^2 x2), so
        # one at a time, in the regression's order, each by an actual fit
        for slot, value in zip(proposals, values):
            self._try_proposal(slot, value, self.fit if self.slots else start_fit)

    def _try_proposal(self, slot, value, current):
        trial = self.refit(
            self.slots + [slot], [*self.fit.coefficients, value], current
        )
        if not trial.ok or trial.cost >= self.fit.cost:
            # the regression value may start in a poor basin (a d(t) estimate
            # that is poor where the model is non-smooth gives huge, opposed
            # coefficients to look-alike terms); from 0 on the current fit's
            # own trajectory the new term starts as a small perturbation of
            # the current model, at a point that already follows it
            retry = self.refit(
                self.slots + [slot], [*self.fit.coefficients, 0.0], self.fit
            )
            trial = retry if retry.cost < trial.cost else trial
        if not (trial.ok and self.improves(self.fit, trial)[2]):
            trial = self.mme_trial(self.slots + [slot], trial)
        if not trial.ok:
            self.reject(slot, f"its extended model cannot be fitted ({trial.message})")
            return
        p, gain, ok = self.improves(self.fit, trial)
        if ok:
            if self.accept(self.slots + [slot], trial):
                self.note(f"kept {self.describe(slot)} (p = {p:.2g})")
        else:
            why = _too_weak(p, gain, self.min_effect)
            self.reject(slot, why)
            self.note(f"rejected {self.describe(slot)}: {why}")


def _continues(start: OutputErrorFit, slots, theta, engine) -> bool:
    """Whether a fit of ``slots`` from ``theta`` is ``start`` carried on."""
    return (
        start._state is not None
        and start._engine is engine
        and start.ok
        and tuple(start.slots) == tuple(tuple(s) for s in slots)
        and np.array_equal(start.theta, theta)
    )


def _most_alike(features, z, ref, pool, n_best):
    """The ``n_best`` slots of ``pool`` most correlated with ``ref`` along ``z``.

    Returns ``[(slot, ratio)]``, ``ratio`` the least-squares multiple of the
    candidate that best matches ``ref`` (to start its coefficient). Only
    candidates with correlation above 0.8.
    """
    if not pool or not np.all(np.isfinite(ref)) or np.std(ref) == 0:
        return []
    with np.errstate(all="ignore"):
        others = features(z, [c[1] for c in pool])
    ok = np.all(np.isfinite(others), axis=0) & (np.std(others, axis=0) > 0)
    if not np.any(ok):
        return []
    rc = ref - ref.mean()
    oc = others - others.mean(axis=0)
    with np.errstate(all="ignore"):
        corr = np.abs(oc.T @ rc) / (np.linalg.norm(oc, axis=0) * np.linalg.norm(rc))
        ratio = (others.T @ ref) / np.einsum("ij,ij->j", others, others)
    corr[~ok] = -1.0
    order = np.argsort(corr)[::-1][:n_best]
    return [(pool[k], float(ratio[k])) for k in order if corr[k] > 0.8]


def _swap_round(search: _Search, checked) -> bool:
    """Try look-alikes in place of each term; keep a swap that lowers the BIC."""
    changed = False
    features = search.engine.features
    for slot in list(search.slots):
        if slot not in search.slots or slot in checked:
            continue
        checked.add(slot)
        z = _library_inputs(search.engine, search.fit)
        pool = [c for c in search.pool if c[0] == slot[0] and c not in search.slots]
        with np.errstate(all="ignore"):
            ref = features(z, [slot[1]])[:, 0]
        best = None
        for alt, ratio in _most_alike(features, z, ref, pool, N_LOOK_ALIKES):
            k = search.slots.index(slot)
            slots = search.slots[:k] + [alt] + search.slots[k + 1 :]
            coefs = search.fit.coefficients.copy()
            coefs[k] *= ratio
            trial = search.refit(slots, coefs, search.fit)
            if not trial.ok:
                continue
            slots, trial, _ = search.backward(slots, trial)
            if trial.ok and trial.joined:
                search.tried_swaps.append((list(slots), _Scored.of(trial)))
            if better_bic(trial, search.fit) and (
                best is None or better_bic(trial, best[1])
            ):
                best = (slots, trial, alt)
        if best is not None:
            new_slots, trial, alt = best
            before = list(search.slots)
            search.tried.add(alt)
            if not search.accept(new_slots, trial):
                continue
            search.note(f"swapped {search.describe(slot)} for {search.describe(alt)}")
            for gone in before:
                if gone not in new_slots:
                    why = (
                        f"replaced by {search.describe(alt)}, which fits better"
                        if gone == slot
                        else f"redundant once {search.describe(alt)} is in"
                    )
                    search.reject(gone, why)
            changed = True
    return changed


def _level_round(search: _Search, checked) -> bool:
    """Move each kept overflow column to another of the library's levels.

    An overflow of a state is one mechanism acting in several equations (a
    wall in its own, the routes of the excess in the others): a swap of one
    slot at a time cannot move its level, since half a wall at one level and
    half at another fits worse than either. Each other level of the same
    variable (among the columns the search may add) replaces the column in
    every equation at once; the lowest cost wins (the same number of terms,
    so the cost decides). The regression of ``d(t)`` picks the level from
    MME's states, where a hidden tank's rim is blurred (tanks seed 4: 12
    where the rim is at 13.9).
    """
    overflows = getattr(search.engine.features, "overflow_columns", None)
    columns = overflows() if callable(overflows) else {}
    n = search.engine.n_states
    kept = sorted({c for _, c in search.slots if c in columns and columns[c][0] < n})
    changed = False
    for c in kept:
        if (
            c not in {cc for _, cc in search.slots}
            or (c, tuple(search.slots)) in checked
        ):
            continue
        checked.add((c, tuple(search.slots)))
        var = columns[c][0]
        states = {i for i, cc in search.slots if cc == c}
        others = [
            o
            for o in sorted(columns)
            if o != c
            and columns[o][0] == var
            and all((i, o) in search.pool or (i, o) in search.slots for i in states)
        ]
        best = None
        for o in others:
            slots = [(i, o if cc == c else cc) for i, cc in search.slots]
            if len(set(slots)) < len(slots):
                continue  # the other level is already there
            trial = search.refit(slots, search.fit.coefficients, search.fit)
            if not trial.ok:
                continue
            # a fit that does not join (Gauss-Newton stalls on the kink a
            # wall puts in the flow) is judged by its model, run as a model
            judged = trial if trial.joined else _run_as_a_model(search, trial)
            if not (judged.ok and judged.joined) or judged.cost >= search.fit.cost:
                continue
            if best is None or judged.cost < best[0]:
                best = (judged.cost, slots, trial, o)
        if best is None:
            continue
        _, slots, trial, o = best
        before, cost = list(search.slots), search.fit.cost
        if not search.accept(slots, trial):
            continue
        search.note(
            f"moved {search.describe((var, c)).split(': ')[-1]} to "
            f"{search.describe((var, o)).split(': ')[-1]} in every equation "
            f"(cost {cost:.6g} -> {search.fit.cost:.6g})"
        )
        search.replaced(before, slots, f"its level moved to {columns[o][1]:g}")
        changed = True
    return changed


def _merge_round(search: _Search, z) -> bool:
    """Can one library function do the job of two look-alike terms?"""
    slots, fit = search.slots, search.fit
    features = search.engine.features
    with np.errstate(all="ignore"):
        cols = features(z, [s[1] for s in slots])
    coefs = fit.coefficients
    for i in range(len(slots)):
        for j in range(i + 1, len(slots)):
            if slots[i][0] != slots[j][0]:
                continue
            combo = coefs[i] * cols[:, i] + coefs[j] * cols[:, j]
            pool = [c for c in search.pool if c[0] == slots[i][0] and c not in slots]
            for cand, ratio in _most_alike(features, z, combo, pool, 1):
                keep = [k for k in range(len(slots)) if k not in (i, j)]
                trial_slots = [slots[k] for k in keep] + [cand]
                trial = search.refit(trial_slots, [*coefs[keep], ratio], fit)
                if not trial.ok:
                    continue
                trial_slots, trial, _ = search.backward(trial_slots, trial)
                if better_bic(trial, fit):
                    search.tried.add(cand)
                    if not search.accept(trial_slots, trial):
                        continue
                    pair = (
                        f"{search.describe(slots[i])} and {search.describe(slots[j])}"
                    )
                    search.note(f"merged {pair} into {search.describe(cand)}")
                    for gone in (slots[i], slots[j]):
                        search.reject(
                            gone,
                            f"{pair} together replaced by "
                            f"{search.describe(cand)}, fewer terms, as good a fit",
                        )
                    # the merged fit's backward step may drop other terms too
                    # (half of a flow whose other half was merged away): said
                    for gone in slots:
                        if gone not in trial_slots and gone not in (slots[i], slots[j]):
                            why = f"redundant once {pair} were merged"
                            search.reject(gone, why)
                            search.note(f"removed {search.describe(gone)}: {why}")
                    return True
    return False


def best_score(search: _Search, pool) -> tuple:
    """The library candidate of ``pool`` the score test ranks first against
    the current fit: ``(index, p, share of the misfit, its Gauss-Newton step,
    whether it would enter)`` (one pass over the record for all of them)."""
    f_vals, steps = search.engine.scores(search.fit, pool)
    best = int(np.argmax(f_vals))
    p_best = float(stats.f.sf(f_vals[best], 1, max(search.fit.dof - 1, 1)))
    # the score's share of the misfit (f = dssr / (ssr - dssr) * dof / inflation)
    raw = max(search.fit.n_residuals - search.fit.n_free - 1, 1)
    share = f_vals[best] * search.fit.inflation / raw
    share = share / (1.0 + share)
    enters = p_best <= search.alpha_term and share >= search.min_effect
    return best, p_best, share, steps[best], bool(enters)


def _forward_step(search: _Search) -> bool:
    """Score every library candidate; add the best if it is significant."""
    pool = [c for c in search.pool if c not in search.slots and c not in search.tried]
    if not pool:
        return False
    best, _, _, step, enters = best_score(search, pool)
    if not enters:
        return False
    slot = pool[best]
    search.tried.add(slot)
    trial = search.refit(
        search.slots + [slot], [*search.fit.coefficients, step], search.fit
    )
    if not (trial.ok and search.improves(search.fit, trial)[2]):
        trial = search.mme_trial(search.slots + [slot], trial)
    if not trial.ok:
        search.reject(slot, f"its extended model cannot be fitted ({trial.message})")
        return False
    p, gain, ok = search.improves(search.fit, trial)
    if ok:
        if not search.accept(search.slots + [slot], trial):
            return False
        search.note(f"added {search.describe(slot)} from the library (p = {p:.2g})")
        return True
    search.reject(
        slot,
        "score test suggested it, the fit did not confirm: "
        + _too_weak(p, gain, search.min_effect),
    )
    return False


def _group_step(search: _Search, proposals, values) -> bool:
    """The proposals that failed alone, fitted together on the kept terms.

    The regression of ``d(t)`` chose its proposals jointly; one-at-a-time
    fits cannot see terms whose effect only exists together (each alone is
    absorbed by a parameter, or cancels). The group starts from the current
    fit with its coefficients at 0 and at the regression's values (the
    better fit is used), is pruned backward (every term significant at the
    Bonferroni level in the joint fit), and is kept if the terms it adds
    improve the fit significantly (F-test on the number added) or, when
    it also removes kept terms, if it lowers the BIC.
    """
    group = [
        (slot, value)
        for slot, value in zip(proposals, values)
        if slot not in search.slots
    ][:GROUP_MAX]
    if len(group) < 2:  # one term alone was already tried alone
        return False
    slots = search.slots + [slot for slot, _ in group]
    if (frozenset(slots), frozenset(search.slots)) in search.pruned:
        # this very group was fitted together with the current terms (the
        # joint start) and the backward step removed it from that fit: the
        # group fit would be the same fit, pruned by the same step (on a long
        # record, a third of the confirmation's time)
        return False
    current = list(search.fit.coefficients)
    starts = [current + [0.0] * len(group), current + [value for _, value in group]]
    return _try_together(
        search,
        slots,
        starts,
        lambda names, p: (
            f"kept {names} together (they fail alone; p = {p:.2g} for the group)"
        ),
        "redundant once the group of proposals is in",
    )


def _flow_step(search: _Search, proposals, values) -> bool:
    """Each function proposed in several equations, tried in all of them at once.

    One function acting on two states is how a flow between them appears:
    the outflow of a tank is the inflow of the next, the water over a weir
    leaves one tank and fills another, heat leaves one body for another.
    Each half alone can be the wrong model (an overflow taken out of the
    upper tank only is best fitted as a hard wall with the water lost, a
    coefficient walking off to 1e12), so that the other half is then not
    significant on top of it, while the two together fit to the noise with
    a moderate coefficient. So, for every column proposed in two or more
    equations and not kept in all of them: the current terms without that
    column, plus the column in every equation it was proposed for,
    started at the regression's values and at 0; pruned backward; kept as
    :func:`_group_step` keeps a group.
    """
    changed = False
    columns = []
    for _, c in proposals:
        if c not in columns:
            columns.append(c)
    for c in columns:
        ours = [(slot, v) for slot, v in zip(proposals, values) if slot[1] == c]
        if len({slot[0] for slot, _ in ours}) < 2:
            continue
        if all(slot in search.slots for slot, _ in ours):
            continue
        keep = [k for k, slot in enumerate(search.slots) if slot[1] != c]
        slots = [search.slots[k] for k in keep] + [slot for slot, _ in ours]
        if (frozenset(slots), frozenset(search.slots)) in search.pruned:
            continue
        base = [float(search.fit.coefficients[k]) for k in keep]
        starts = [base + [v for _, v in ours], base + [0.0] * len(ours)]
        changed |= _try_together(
            search,
            slots,
            starts,
            lambda names, p: (
                f"kept {names} together (one function in several "
                f"equations: a flow between states; p = {p:.2g} for the terms added)"
            ),
            "replaced by the same function in all the equations it was proposed for",
        )
    return changed


def _try_together(search: _Search, slots, starts, kept_note, dropped_why) -> bool:
    """Fit ``slots`` from each coefficient vector in ``starts`` (from the
    current fit's trajectory; from MME's states when that fails), prune
    backward, and make the result current if the terms it adds improve the
    fit significantly (F-test on their number) or, when it adds none, if it
    lowers the BIC. ``kept_note(names, p) -> str`` for the log,
    ``dropped_why`` the reason recorded for a current term it drops."""
    best = None
    for start in starts:
        trial = search.refit(slots, start, search.fit)
        if trial.ok and (best is None or trial.cost < best.cost):
            best = trial
    best = search.mme_trial(slots, best)
    if best is None or not best.ok:
        return False
    kept, trial, _ = search.backward(list(slots), best)
    added = [slot for slot in kept if slot not in search.slots]
    if not added or not trial.ok:
        return False
    n_added = len(kept) - len(search.slots)
    if n_added > 0:
        p, _, ok = search.improves(search.fit, trial, n_added=n_added)
    else:
        p, ok = float("nan"), better_bic(trial, search.fit)
    if not ok:
        return False
    before = list(search.slots)
    if not search.accept(kept, trial):
        return False
    search.replaced(before, kept, dropped_why)
    names = ", ".join(search.describe(slot) for slot in added)
    search.note(
        kept_note(names, p)
        if n_added > 0
        else f"kept {names} together in place of weaker terms (lower BIC)"
    )
    return True


def _too_weak(p, gain, min_effect) -> str:
    if gain < min_effect:
        return (
            f"removes only {100 * gain:.2g}% of the misfit (at least "
            f"{100 * min_effect:.2g}% asked, min_effect)"
        )
    return f"does not improve the fit significantly (p = {p:.2g})"


def term_alpha(alpha, library_candidates, proposals) -> float:
    """The level each term is tested at: every term was picked from the
    whole library, so each must pass at the Bonferroni level, and the chance
    of any false term stays about ``alpha``."""
    return alpha / max(1, len(library_candidates), len(proposals))


def confirm_terms(
    engine: OutputErrorModel,
    assumed: OutputErrorFit,
    proposals,
    start_values,
    x_start,
    alpha: float,
    describe,
    library_candidates=(),
    progress=None,
    min_effect: float = 0.0,
    mme_start=None,
    steps_of=None,
) -> Confirmation:
    """Select correction terms by output-error tests (see module docstring).

    Parameters
    ----------
    engine : OutputErrorModel
        Fits of the record for any set of terms.
    assumed : OutputErrorFit
        Fit of the assumed model (no correction term).
    proposals : list of (state, column), in the order to try them
    start_values : list of float
        Regression coefficient of each proposal (the starting value).
    x_start : ndarray (N, n)
        Starting trajectory of the first fit (the MME estimate).
    describe : callable ``slot -> str`` for the log.
    library_candidates : list of (state, column)
        Every library function the forward search may add.
    progress : callable ``str -> None``, optional
    min_effect : float
        Every kept term must remove at least this share of the misfit of
        the model without it (practical significance: on a long record even
        a negligible term is statistically significant).
    mme_start : tuple (x, d, physical), optional
        MME's states and model error and the parameters it ran with: trial
        fits that fail from the current fit are tried again from there
        (:meth:`_Search.mme_trial`), and the joint start begins there.
    steps_of : callable ``fit -> int``, optional
        RK4 steps per interval the model of a fit needs: a fit that does not
        join is taken if it joins at those steps (:meth:`_Search.accept`).
    """
    alpha_term = term_alpha(alpha, library_candidates, proposals)
    search = _Search(
        engine, assumed, alpha_term, describe, library_candidates, progress, min_effect
    )
    search.steps_of = steps_of
    if mme_start is not None:
        x, d, physical = mme_start
        search.mme = (np.asarray(x, float), np.asarray(d, float), np.asarray(physical))
    proposals = [(int(i), int(c)) for i, c in proposals]
    search.start(proposals, list(start_values), x_start)
    # Complete the start before pruning it: a group that only works together
    # loses its members one by one to the backward step when one member is
    # missing (the regression of d(t) proposed z and |v| z of a hysteretic
    # law but not v |z|; without it, v and z are not significant).
    for _ in range(MAX_ROUNDS if search.slots else 0):
        if not _forward_step(search):
            break
    _prune(search, alpha_term, min_effect)  # a joint start may hold many
    _group_step(search, proposals, list(start_values))
    _flow_step(search, proposals, list(start_values))
    search.tried = set(search.slots)
    swap_checked, level_checked = set(), set()
    for _ in range(MAX_ROUNDS):
        changed = False
        if search.slots and search.pool:
            changed |= _swap_round(search, swap_checked)
            changed |= _level_round(search, level_checked)
            if len(search.slots) > 1 and _merge_round(
                search, _library_inputs(engine, search.fit)
            ):
                swap_checked.clear()  # the context changed: look again
                changed = True
        changed |= _prune(search, alpha_term, min_effect)
        if search.pool and _forward_step(search):
            changed = True
        if not changed:
            break
    _best_visited(search)
    return _verdict(search, assumed, alpha, min_effect)


def _run_as_a_model(search: _Search, fit) -> OutputErrorFit:
    """``fit``'s model with its parameters held (only the initial state
    fitted), at the search's RK4 steps or, if its trajectory does not join
    there, at the steps its terms need (``search.steps_of``)."""
    held = search.engine.fit_held(fit.slots, fit.theta, fit.x)
    if (held.ok and held.joined) or search.steps_of is None:
        return held
    needed = int(search.steps_of(fit))
    if needed <= search.engine.n_substeps:
        return held
    return search.engine.with_substeps(needed).fit_held(fit.slots, fit.theta, fit.x)


def _best_visited(search: _Search) -> bool:
    """Return to a model the search visited that beats where it ended.

    The search's steps are local and some compare fits by BIC (swaps, merged
    terms, groups in place of weaker terms) or drop terms made redundant by
    others; a chain of them can end on a model that an earlier one beats
    outright (tanks seed 5: the square-root law, then constants and ramps in
    its place, then a wall alone, with 100x the misfit). A visited model
    (its fit joined) beats the final one if it fits better with no more
    terms, or if its extra terms would pass the search's own test of an
    addition (:meth:`_Search.improves`); of those, the lowest BIC is taken.
    A final fit that does not join is judged by its model run as a model;
    one whose model cannot even be run (its trajectory does not join with
    only the initial state fitted, at the RK4 steps its terms need) is
    beaten by every visited model.
    """
    final = search.fit
    if not search.slots or not search.visited:
        return False
    runnable = final.joined
    if not final.joined:
        # its transcription cost is no model's: judge its model run as a
        # model (only the initial state fitted), as accept() does, at the
        # RK4 steps its terms need if the search's are too few (a wall)
        held = _run_as_a_model(search, final)
        runnable = held.ok and held.joined
        final = replace(held, n_free=final.n_free)
    better = []
    for slots, fit in search.visited:
        if set(slots) == set(search.slots):
            continue
        extra = len(slots) - len(search.slots)
        if not runnable or (
            fit.cost < final.cost
            and (extra <= 0 or search.improves(final, fit, n_added=extra)[2])
        ):
            better.append((slots, fit))
    if not better:
        return False
    slots, fit = better[0]
    for other in better[1:]:
        if better_bic(other[1], fit):
            slots, fit = other
    extra = len(slots) - len(search.slots)
    if not runnable:
        how = "its model cannot be run as a model"
    elif extra > 0:  # a test of the terms it adds; otherwise no test is needed
        how = f"p = {partial_f_p_value(final, fit, extra):.2g} for its {extra} more"
    else:
        how = "no more terms"
    search.replaced(
        search.slots, slots, "the search ended on a model an earlier one beats"
    )
    names = ", ".join(search.describe(slot) for slot in slots)
    search.note(
        f"returned to {names}: a model visited earlier that beats the one the "
        f"search ended on (cost {fit.cost:.6g} against {final.cost:.6g}; {how})"
    )
    search.slots, search.fit = list(slots), fit
    return True


def _prune(search: _Search, alpha_term, min_effect) -> bool:
    """Backward elimination of the current terms; whether any left."""
    before = frozenset(search.slots)
    slots, fit, removed = search.backward(search.slots, search.fit)
    for slot, p_val, effect in removed:
        why = (
            f"not significant in the joint fit (p = {p_val:.2g})"
            if p_val > alpha_term
            else _too_weak(p_val, effect, min_effect)
        )
        search.reject(slot, why)
        search.note(f"removed {search.describe(slot)}: {why}")
    if removed:
        if slots:
            search.accept(slots, fit, force=True)
        else:
            search.slots, search.fit = [], search.assumed
        search.pruned.append((before, frozenset(search.slots)))
    return bool(removed)


def _library_inputs(engine: OutputErrorModel, fit: OutputErrorFit):
    """Library input ``z`` (states, then inputs) along the fitted trajectory."""
    u = engine.inputs.grid()
    return fit.x if u is None else np.hstack([fit.x, u])


def _verdict(search: _Search, assumed: OutputErrorFit, alpha, min_effect):
    """The extended model against the assumed one: keep the terms or none."""
    if not search.slots:
        return Confirmation([], None, search.rejected, float("nan"), search.log)
    fit = search.fit
    p_total = partial_f_p_value(assumed, fit, n_added=len(search.slots))
    gain = (assumed.cost - fit.cost) / assumed.cost if assumed.cost > 0 else 0.0
    if p_total > alpha or gain < min_effect:
        why = (
            f"extended model not significant (p = {p_total:.2g})"
            if p_total > alpha
            else f"the extended model removes only {100 * gain:.2g}% of the misfit"
        )
        search.rejected.extend((s, why) for s in search.slots)
        return Confirmation([], None, search.rejected, p_total, search.log)
    return Confirmation(
        list(search.slots),
        fit,
        search.rejected,
        p_total,
        search.log,
        rivals=_rivals(search),
    )


@dataclass(frozen=True)
class _Scored:
    """What :func:`_rivals` reads of a fit the search tried and did not keep:
    its BIC's parts, not the fit (whose trajectory and linearisation a
    search of many swaps on a long record would otherwise hold)."""

    slots: tuple
    cost: float
    n_residuals: int
    inflation: float
    ok: bool = True
    joined: bool = True

    @classmethod
    def of(cls, fit) -> _Scored:
        return cls(
            tuple(fit.slots),
            float(fit.cost),
            int(fit.n_residuals),
            float(fit.inflation),
        )

    def bic(self, inflation: float | None = None) -> float:
        """As :meth:`~pysindy_mme.solver.output_error.OutputErrorFit.bic`."""
        inflation = self.inflation if inflation is None else inflation
        return bic_of(self.cost, self.n_residuals, len(self.slots), inflation)


def _rivals(search: _Search) -> list:
    """``[(slots, BIC difference)]``: the models fitted on the way (kept or
    tried as swaps) with other terms, not nested with the kept ones, whose
    BIC is within :data:`RIVAL_BIC` of the kept model's; the best fit of
    each set of terms, smallest difference first. Nested models are the
    tests' business (a term's own p-value), not a rival's."""
    final = search.fit
    if not (final.ok and final.joined):
        return []
    kept = set(search.slots)
    best = {}
    for slots, fit in search.visited + search.tried_swaps:
        terms = frozenset(slots)
        if not (fit.ok and fit.joined) or terms <= kept or terms >= kept:
            continue
        c = min(fit.inflation, final.inflation)
        delta = float(fit.bic(c) - final.bic(c))
        if delta < RIVAL_BIC and (terms not in best or delta < best[terms][1]):
            best[terms] = (list(slots), delta)
    return sorted(best.values(), key=lambda item: item[1])
