"""Confirm and complete the correction terms against the measurements.

The stepwise regression of the MME model error proposes terms, but its
F-ratios are computed on ``d(t)``, an estimate that is smooth (strongly
autocorrelated) and shrunk toward zero: they overstate significance, and
functions that look alike on the estimated trajectory (``x2`` and
``x2 |x2|``) cannot be told apart there. The measurements, on the other
hand, carry white noise of known variance, so F-tests on *simulation*
residuals (output error) are valid. This module therefore finishes the
selection in output-error space:

1. start: the proposed terms refitted together (initial state and all
   coefficients), or, when there are many or the joint refit fails, added one
   at a time in the order the regression chose them, each kept only if it
   improves the fit significantly (partial F-test);
2. swap: each term is taken out and the look-alike library functions of
   its equation (most correlated along the current simulation) are put in
   instead (the regression cannot tell ``x2`` from ``x2 |x2|``; the
   measurements can). Likewise a pair of terms of one equation may be merged
   into the single library function most like their fitted combination
   (``x2 |x2|`` and ``x2^3`` together imitate ``x2``). Swaps and merges are
   pruned backward and kept when they lower the BIC (fit and size together);
3. backward: terms whose refitted coefficient is not significant (Wald test)
   leave, weakest first;
4. forward over the whole library: a linearised score test (output
   sensitivities from the variational equations along the current
   simulation) ranks every library function of every error state by the
   partial F it would have; the best enters if it is significant after a
   Bonferroni correction for the number of candidates, and is confirmed by an
   actual refit;
5. repeat 2-4 until nothing changes; finally the extended model is F-tested
   against the assumed model.

Every term is tested at the Bonferroni level ``alpha / n_candidates`` (the
regression picked it from the whole library), so that the chance of reporting
any false term when the assumed model is right stays about ``alpha``. The
refit also removes the shrinkage bias of the regression coefficients.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from ._output_error import OutputErrorProblem, OutputErrorResult
from .core.model import rowwise_jacobian

__all__ = ["confirm_terms", "Confirmation", "make_problem_factory", "add_scores"]

#: proposals refitted jointly at the start when there are at most this many
JOINT_START_MAX = 6
#: rounds of backward/swap/forward passes
MAX_ROUNDS = 4
#: function evaluations allowed to a trial refit
TRIAL_NFEV = 20


@dataclass
class Confirmation:
    """Outcome of :func:`confirm_terms`.

    Attributes
    ----------
    slots : list of (state, column) pairs kept
    fit : OutputErrorResult or None
        Final refit (None when no term is kept).
    rejected : list of (slot, reason) for proposed or tried terms not kept
    correction_p_value : float
        F-test of the extended against the assumed model (NaN if no term).
    log : list of str
        One line per decision.
    """

    slots: list
    fit: OutputErrorResult | None
    rejected: list = field(default_factory=list)
    correction_p_value: float = float("nan")
    log: list = field(default_factory=list)


def _p_add(cost_small, cost_big, n_res, n_params_big, n_added=1) -> float:
    """p-value of the partial F-test for ``n_added`` extra parameters."""
    if not np.isfinite(cost_big):
        return 1.0
    if cost_big <= 0:
        return 0.0
    dof = max(n_res - n_params_big, 1)
    f_stat = ((cost_small - cost_big) / n_added) / (cost_big / dof)
    return float(stats.f.sf(f_stat, n_added, dof)) if f_stat > 0 else 1.0


def _bic(fit: OutputErrorResult, n_states: int) -> float:
    """Bayesian information criterion of an output-error fit (up to a constant)."""
    return fit.cost + (fit.params.size - n_states) * np.log(max(fit.n_residuals, 2))


def _wald_p(fit: OutputErrorResult, n_states: int) -> np.ndarray:
    coefs = fit.params[n_states:]
    se = fit.std_errors[n_states:]
    dof = max(fit.n_residuals - fit.params.size, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = 2 * stats.t.sf(np.abs(coefs / se), dof)
    return np.where(np.isfinite(p), p, 1.0)


def add_scores(problem: OutputErrorProblem, fit: OutputErrorResult, candidates, f_rows):
    """Linearised partial F (and a step) for adding each candidate slot.

    The sensitivity of the simulated measurements to a new coefficient
    ``beta_c`` (at 0) solves ``S' = A(t) S + e_state theta_c(x(t))`` along the
    current simulation, ``A`` the Jacobian of the current model; it is
    integrated for all candidates at once with RK4 on the sample grid. With
    the current residual ``r`` and Jacobian ``J``, the reduction of the
    residual sum of squares from fitting ``beta_c`` jointly with the current
    parameters is ``(s_perp . r)^2 / |s_perp|^2``, ``s_perp`` the whitened
    sensitivity with the span of ``J`` projected out (a score test).

    Returns
    -------
    f_values : ndarray (n_candidates,)
    steps : ndarray (n_candidates,)
        Gauss-Newton estimate of each new coefficient.
    """
    n = problem.n_states
    k_c = len(candidates)
    zeros = np.zeros(k_c)
    if fit is None or fit.jacobian is None or not k_c:
        return zeros, zeros
    x = problem._simulate(fit.params[None])[0]
    if not np.all(np.isfinite(x)):
        return zeros, zeros
    t, u = problem.t, problem.u
    coef = fit.params[n:]

    def rhs_rows(xx):
        out = np.array(f_rows(xx, t, u), dtype=float)
        if problem.slots:
            zz = xx if u is None else np.hstack([xx, u])
            theta = problem.features(zz, problem.used)
            for j, (state, pos) in enumerate(problem._state_pos):
                out[:, state] += coef[j] * theta[:, pos]
        return out

    jac = rowwise_jacobian(rhs_rows, x, rel_step=1e-6)
    z = x if u is None else np.hstack([x, u])
    cols = sorted({c for _, c in candidates})
    pos = {c: k for k, c in enumerate(cols)}
    with np.errstate(all="ignore"):
        theta = problem.features(z, cols)
    forcing = np.zeros((x.shape[0], n, k_c))
    for k, (state, col) in enumerate(candidates):
        forcing[:, state, k] = theta[:, pos[col]]
    usable = np.all(np.isfinite(forcing), axis=(0, 1)) & np.all(np.isfinite(jac))
    forcing[:, :, ~usable] = 0.0
    jac[~np.isfinite(jac)] = 0.0

    sens = np.zeros((x.shape[0], n, k_c))
    s_k = np.zeros((n, k_c))
    for k in range(x.shape[0] - 1):
        dt = t[k + 1] - t[k]
        a0, a1 = jac[k], jac[k + 1]
        am = 0.5 * (a0 + a1)
        g0, g1 = forcing[k], forcing[k + 1]
        gm = 0.5 * (g0 + g1)
        k1 = a0 @ s_k + g0
        k2 = am @ (s_k + 0.5 * dt * k1) + gm
        k3 = am @ (s_k + 0.5 * dt * k2) + gm
        k4 = a1 @ (s_k + dt * k3) + g1
        s_k = s_k + (dt / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
        sens[k + 1] = s_k
    y_sens = problem.measure(sens.transpose(0, 2, 1)) @ problem.whiten.T  # (N,K,m)
    y_sens = y_sens.transpose(1, 0, 2)  # (K, N, m)
    mask = np.broadcast_to(problem.mask, y_sens.shape)
    s_mat = y_sens[mask].reshape(k_c, -1).T  # (n_res, K)
    if not np.all(np.isfinite(s_mat)):
        bad = ~np.all(np.isfinite(s_mat), axis=0)
        s_mat[:, bad] = 0.0
        usable &= ~bad
    q, _ = np.linalg.qr(fit.jacobian)
    s_perp = s_mat - q @ (q.T @ s_mat)
    r = fit.residuals
    num = s_perp.T @ r
    den = np.einsum("ij,ij->j", s_perp, s_perp)
    ssr = float(r @ r)
    dof = max(r.size - fit.params.size - 1, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        dssr = np.where(den > 1e-12 * max(ssr, 1e-300), num**2 / den, 0.0)
        f_values = dssr / np.maximum(ssr - dssr, 1e-300) * dof
        step = np.where(den > 0, num / den, 0.0)
    f_values[~usable] = 0.0
    return np.nan_to_num(f_values), np.nan_to_num(step)


#: look-alike functions tried in place of each term
N_LOOK_ALIKES = 2


def _simulated_inputs(problem, fit):
    """Library input ``z`` (states, then inputs) along the current simulation."""
    x = problem._simulate(fit.params[None])[0]
    if not np.all(np.isfinite(x)):
        return None
    return x if problem.u is None else np.hstack([x, problem.u])


def _most_alike(problem, z, ref, pool, n_best):
    """The ``n_best`` columns of ``pool`` most correlated with ``ref`` along ``z``.

    Returns ``[(candidate slot, coefficient ratio)]``, the ratio being the
    least-squares multiple of the candidate that best matches ``ref`` (to
    start its coefficient). Only candidates with correlation above 0.8.
    """
    if not pool or not np.all(np.isfinite(ref)) or np.std(ref) == 0:
        return []
    with np.errstate(all="ignore"):
        others = problem.features(z, [c[1] for c in pool])
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


def _look_alikes(problem, fit, slot, library_candidates, slots):
    """The library functions of ``slot``'s equation most like it."""
    z = _simulated_inputs(problem, fit)
    if z is None:
        return []
    pool = [c for c in library_candidates if c[0] == slot[0] and c not in slots]
    with np.errstate(all="ignore"):
        ref = problem.features(z, [slot[1]])[:, 0]
    return _most_alike(problem, z, ref, pool, N_LOOK_ALIKES)


def _merges(problem, fit, slots, library_candidates, n_states):
    """Pairs of terms of one equation that a single library function may replace.

    Two look-alike terms can share one job (``x2 |x2|`` and ``x2^3`` together
    imitate ``x2``). For every pair, the function most like their fitted
    combination along the current simulation. Yields
    ``(i, j, candidate slot, coefficient)``.
    """
    z = _simulated_inputs(problem, fit)
    if z is None:
        return []
    with np.errstate(all="ignore"):
        cols = problem.features(z, [s[1] for s in slots])
    coefs = fit.params[n_states:]
    out = []
    for i in range(len(slots)):
        for j in range(i + 1, len(slots)):
            if slots[i][0] != slots[j][0]:
                continue
            combo = coefs[i] * cols[:, i] + coefs[j] * cols[:, j]
            pool = [
                c for c in library_candidates if c[0] == slots[i][0] and c not in slots
            ]
            for cand, ratio in _most_alike(problem, z, combo, pool, 1):
                out.append((i, j, cand, ratio))
    return out


def confirm_terms(
    make_problem,
    proposals,
    start_values,
    assumed_fit: OutputErrorResult,
    n_states: int,
    alpha: float,
    describe,
    library_candidates=(),
    f_rows=None,
    x0_start=None,
) -> Confirmation:
    """Select correction terms by output-error tests (see module docstring).

    Parameters
    ----------
    make_problem : callable ``slots -> OutputErrorProblem``
    proposals : list of (state, column) slots, in the order to try them
    start_values : list of float
        Regression coefficient of each proposal (the starting value).
    assumed_fit : OutputErrorResult
        Fit of the assumed model (initial state only).
    describe : callable ``slot -> str`` for the log.
    library_candidates : list of (state, column) slots
        Every library function the forward search may add.
    f_rows : callable ``(x, t, u) -> dx/dt``, row-wise assumed model
        Needed for the forward search over the library.
    x0_start : ndarray (n_states,), optional
        Initial state to start the first refit from (the MME estimate). The
        assumed model's own best-fit initial state can be far off, because it
        bends the initial state to make up for the missing terms.
    """
    log, rejected = [], []
    x0_start = assumed_fit.params if x0_start is None else np.asarray(x0_start)
    # Every term was picked from the whole library: each one must pass at the
    # Bonferroni level, so that the chance of any false term stays ~alpha.
    alpha_term = alpha / max(1, len(library_candidates), len(proposals))

    def polish(slots, params0):
        return make_problem(slots).fit(np.asarray(params0, dtype=float))

    def backward(slots, fit, fitter):
        """Drop terms whose coefficient is not significant, weakest first."""
        removed = []
        while slots:
            pvals = _wald_p(fit, n_states)
            worst = int(np.argmax(pvals))
            if pvals[worst] <= alpha_term:
                break
            removed.append((slots[worst], float(pvals[worst])))
            keep = [k for k in range(len(slots)) if k != worst]
            slots = [slots[k] for k in keep]
            if not slots:
                return [], assumed_fit, removed
            fit = fitter(
                slots,
                np.concatenate([fit.params[:n_states], fit.params[n_states:][keep]]),
            )
        return slots, fit, removed

    def refit(slots, params0):
        # trial refits stop early; the chosen model is polished at the end
        return make_problem(slots).fit(
            np.asarray(params0, dtype=float), max_nfev=TRIAL_NFEV, tol=1e-6
        )

    # ---- 1. start ----
    slots, current = [], assumed_fit
    joint = None
    if 0 < len(proposals) <= JOINT_START_MAX:
        joint = polish(list(proposals), np.concatenate([x0_start, start_values]))
        p_joint = _p_add(
            assumed_fit.cost,
            joint.cost,
            joint.n_residuals,
            joint.params.size,
            n_added=len(proposals),
        )
        if np.isfinite(joint.cost) and p_joint <= alpha_term:
            slots, current = list(proposals), joint
            log.append(f"joint refit of {len(proposals)} proposals (p = {p_joint:.2g})")
        else:
            joint = None
    if joint is None:
        for slot, value in zip(proposals, start_values):
            trial_slots = slots + [slot]
            x0 = x0_start if not slots else current.params[:n_states]
            trial = refit(
                trial_slots,
                np.concatenate([x0, current.params[n_states:], [value]]),
            )
            # the regression value may start the refit in a poor basin; from 0
            # the new term starts as a small perturbation of the current model
            if not np.isfinite(trial.cost) or trial.cost >= current.cost:
                retry = refit(trial_slots, np.concatenate([current.params, [0.0]]))
                if retry.cost < trial.cost:
                    trial = retry
            p = _p_add(current.cost, trial.cost, trial.n_residuals, trial.params.size)
            if p <= alpha_term:
                slots, current = trial_slots, polish(trial_slots, trial.params)
                log.append(f"kept {describe(slot)} (p = {p:.2g})")
            else:
                rejected.append((slot, f"does not improve the fit (p = {p:.2g})"))
                log.append(f"rejected {describe(slot)} (p = {p:.2g})")

    tried = set(slots)
    swap_checked = set()
    for _ in range(MAX_ROUNDS):
        changed = False
        search = f_rows is not None and bool(library_candidates)
        # ---- 2. swap: could a look-alike library function do a term's job
        # better? (The regression of d cannot tell x2 from x2 |x2|; the
        # measurements can.) Look-alikes: the functions of the same equation
        # most correlated with the term along the current simulation. A swap
        # may make other terms redundant, so each trial is pruned backward and
        # the models are compared by BIC (fit and size together).
        for slot in list(slots) if search else []:
            if slot not in slots or slot in swap_checked:
                continue
            swap_checked.add(slot)
            best = None
            for alt, ratio in _look_alikes(
                make_problem(slots), current, slot, library_candidates, slots
            ):
                k = slots.index(slot)
                trial_slots = slots[:k] + [alt] + slots[k + 1 :]
                params0 = current.params.copy()
                params0[n_states + k] *= ratio
                trial = refit(trial_slots, params0)
                trial_slots, trial, _ = backward(trial_slots, trial, refit)
                if _bic(trial, n_states) < _bic(current, n_states) and (
                    best is None or _bic(trial, n_states) < _bic(best[1], n_states)
                ):
                    best = (trial_slots, trial, alt)
            if best is not None:
                new_slots, trial, alt = best
                log.append(f"swapped {describe(slot)} for {describe(alt)}")
                for gone in slots:
                    if gone not in new_slots:
                        why = (
                            f"replaced by {describe(alt)}, which fits the data better"
                            if gone == slot
                            else f"redundant once {describe(alt)} is in"
                        )
                        rejected.append((gone, why))
                slots, current = new_slots, polish(new_slots, trial.params)
                tried.add(alt)
                changed = True
        # ---- 2b. merge: can one function do the job of two look-alikes?
        for i, j, cand, coef in (
            _merges(make_problem(slots), current, slots, library_candidates, n_states)
            if search and len(slots) > 1
            else []
        ):
            keep = [k for k in range(len(slots)) if k not in (i, j)]
            trial_slots = [slots[k] for k in keep] + [cand]
            params0 = np.concatenate(
                [current.params[:n_states], current.params[n_states:][keep], [coef]]
            )
            trial = refit(trial_slots, params0)
            trial_slots, trial, _ = backward(trial_slots, trial, refit)
            if _bic(trial, n_states) < _bic(current, n_states):
                pair = f"{describe(slots[i])} and {describe(slots[j])}"
                log.append(f"merged {pair} into {describe(cand)}")
                for gone in (slots[i], slots[j]):
                    rejected.append(
                        (
                            gone,
                            f"{pair} together replaced by "
                            f"{describe(cand)}, fewer terms, as good a fit",
                        )
                    )
                slots, current = trial_slots, polish(trial_slots, trial.params)
                swap_checked.clear()  # the context changed: look again
                tried.add(cand)
                changed = True
                break
        # ---- 3. backward ----
        slots, current, removed = backward(slots, current, polish)
        for slot, p_val in removed:
            rejected.append(
                (slot, f"not significant in the joint refit (p = {p_val:.2g})")
            )
            log.append(f"removed {describe(slot)} (p = {p_val:.2g})")
            changed = True
        if not slots:
            current = assumed_fit
        # ---- 4. forward over the library ----
        if not search:
            break
        pool = [c for c in library_candidates if c not in slots and c not in tried]
        if not pool:
            break
        f_vals, steps = add_scores(make_problem(slots), current, pool, f_rows)
        best = int(np.argmax(f_vals))
        dof = max(current.n_residuals - current.params.size - 1, 1)
        p_best = float(stats.f.sf(f_vals[best], 1, dof))
        if p_best > alpha_term:
            if not changed:
                break
            continue
        slot = pool[best]
        tried.add(slot)
        trial_slots = slots + [slot]
        trial = refit(trial_slots, np.concatenate([current.params, [steps[best]]]))
        p = _p_add(current.cost, trial.cost, trial.n_residuals, trial.params.size)
        if p <= alpha_term:
            slots, current = trial_slots, polish(trial_slots, trial.params)
            log.append(f"added {describe(slot)} from the library (p = {p:.2g})")
            changed = True
        else:
            rejected.append(
                (slot, f"score test suggested it, refit did not confirm (p = {p:.2g})")
            )
        if not changed:
            break

    if not slots:
        return Confirmation([], None, rejected, float("nan"), log)
    p_total = _p_add(
        assumed_fit.cost,
        current.cost,
        current.n_residuals,
        current.params.size,
        n_added=len(slots),
    )
    if p_total > alpha:
        rejected.extend(
            (s, f"extended model not significant (p = {p_total:.2g})") for s in slots
        )
        return Confirmation([], None, rejected, p_total, log)
    return Confirmation(slots, current, rejected, p_total, log)


def make_problem_factory(
    base_rhs, features, n_states, measure, y, t, u, noise_cov, substeps
):
    """``slots -> OutputErrorProblem`` with everything else fixed."""

    def make(slots):
        return OutputErrorProblem(
            base_rhs,
            features,
            slots,
            n_states,
            measure,
            y,
            t,
            u,
            noise_cov,
            substeps=substeps,
        )

    return make
