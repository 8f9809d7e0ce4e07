"""Confirm proposed correction terms against the measurements themselves.

The stepwise regression of the MME model error proposes terms, but its
F-ratios are computed on ``d(t)``, an estimate that is smooth (strongly
autocorrelated) and shrunk toward zero, so they overstate significance and a
large library can leave many superfluous terms. The measurements, on the
other hand, carry white noise of known variance, so F-tests on simulation
residuals are valid. This module therefore re-runs the selection in
*output-error* space:

* forward: the proposed terms are tried in the order the regression chose
  them; each is kept only if refitting the extended model (initial state and
  all kept coefficients) reduces the whitened residual sum of squares
  significantly (partial F-test at level ``alpha``);
* backward: kept terms whose refitted coefficient is no longer significant
  (Wald test) are removed one at a time, weakest first;
* finally the extended model is F-tested against the assumed model.

The refit also removes the shrinkage bias of the regression coefficients.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from ._output_error import OutputErrorProblem, OutputErrorResult

__all__ = ["confirm_terms", "Confirmation"]


@dataclass
class Confirmation:
    """Outcome of :func:`confirm_terms`.

    Attributes
    ----------
    slots : list of (state, feature) pairs kept
    fit : OutputErrorResult or None
        Final refit (None when no term is kept).
    rejected : list of (slot, reason) for proposed terms not kept
    correction_p_value : float
        F-test of the extended against the assumed model (NaN if no term).
    log : list of str
        One line per decision, for the report.
    """

    slots: list
    fit: OutputErrorResult | None
    rejected: list = field(default_factory=list)
    correction_p_value: float = float("nan")
    log: list = field(default_factory=list)


def _p_add(cost_small, cost_big, n_res, n_params_big, n_added=1) -> float:
    dof = max(n_res - n_params_big, 1)
    if not np.isfinite(cost_big) or cost_big <= 0:
        return 1.0 if not np.isfinite(cost_big) else 0.0
    f_stat = ((cost_small - cost_big) / n_added) / (cost_big / dof)
    return float(stats.f.sf(f_stat, n_added, dof)) if f_stat > 0 else 1.0


def _wald_p(fit: OutputErrorResult, n_states: int) -> np.ndarray:
    coefs = fit.params[n_states:]
    se = fit.std_errors[n_states:]
    dof = max(fit.n_residuals - fit.params.size, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = 2 * stats.t.sf(np.abs(coefs / se), dof)
    return np.where(np.isfinite(p), p, 1.0)


def confirm_terms(
    make_problem,
    proposals,
    start_values,
    assumed_fit: OutputErrorResult,
    n_states: int,
    alpha: float,
    describe,
) -> Confirmation:
    """Forward-backward selection of ``proposals`` by output-error F-tests.

    Parameters
    ----------
    make_problem : callable ``slots -> OutputErrorProblem``
    proposals : list of (state, feature) slots, in the order to try them
    start_values : list of float
        Regression coefficient of each proposal (the starting value).
    assumed_fit : OutputErrorResult
        Fit of the assumed model (initial state only).
    describe : callable ``slot -> str`` for the log.
    """
    log = []
    rejected = []
    slots, values = [], []
    current = assumed_fit
    for slot, value in zip(proposals, start_values):
        trial_slots = slots + [slot]
        params0 = np.concatenate([current.params, [value]])
        trial = make_problem(trial_slots).fit(params0)
        # the regression value may start the refit in a poor basin; from 0 the
        # new term starts as a small perturbation of the current model.
        if not np.isfinite(trial.cost) or trial.cost >= current.cost:
            retry = make_problem(trial_slots).fit(
                np.concatenate([current.params, [0.0]])
            )
            if retry.cost < trial.cost:
                trial = retry
        p = _p_add(current.cost, trial.cost, trial.n_residuals, trial.params.size)
        if p <= alpha:
            slots, current = trial_slots, trial
            values = list(trial.params[n_states:])
            log.append(f"kept {describe(slot)} (p = {p:.2g})")
        else:
            rejected.append(
                (slot, f"does not improve the fit to the data (p = {p:.2g})")
            )
            log.append(f"rejected {describe(slot)} (p = {p:.2g})")

    # backward: drop terms no longer significant in the joint refit
    while slots:
        pvals = _wald_p(current, n_states)
        worst = int(np.argmax(pvals))
        if pvals[worst] <= alpha:
            break
        slot = slots[worst]
        keep = [k for k in range(len(slots)) if k != worst]
        slots = [slots[k] for k in keep]
        rejected.append(
            (slot, f"not significant in the joint refit (p = {pvals[worst]:.2g})")
        )
        log.append(f"removed {describe(slot)} (p = {pvals[worst]:.2g})")
        if not slots:
            current = assumed_fit
            break
        params0 = np.concatenate(
            [current.params[:n_states], current.params[n_states:][keep]]
        )
        current = make_problem(slots).fit(params0)
    del values

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
