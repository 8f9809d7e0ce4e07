""":func:`discover`: what the assumed model gets wrong, why, the fix, the gain.

The study runs the five steps of :mod:`.steps` in order, each taking the
records of the ones before, and assembles a :class:`~.result.Discovery`.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from ..core.progress import Progress
from ..core.tables import p_value, sig
from ..exceptions import DiscoveryWarning
from ..solver.statistics import partial_f_p_value, residual_inflation
from .conclusion import (
    RUNAWAY_FACTOR,
    TRADE_OFF_CORRELATION,
    Evidence,
    MissingState,
    conclude,
    memory_decides,
)
from .confirm import RIVAL_BIC
from .doubts import correlated_pairs, doubt_notes, generalisation_note
from .estimates import TermEstimate
from .extended_at import extended_model_at
from .identifiability import exact_trade_offs
from .inputs import check_study
from .memory import discount_estimation_error
from .options import as_options, refuse_moved
from .propose import propose_terms
from .result import Discovery
from .run_sensitivity import rounding_note, rounding_sets_run, spread_sentence
from .steps import (
    baseline,
    confirm_on_measurements,
    estimate_model_error,
    fit_assumed_model,
    hold_out,
    measure_gain,
    memory_null,
    output_error_engine,
    overshoots,
    parameter_sensitivities,
    proposal_rows,
    rk4_steps_of,
    rk4_substeps,
    set_aside_parameter_duplicates,
    smoothing_check,
    step_size_check,
    study_memory,
)

__all__ = ["discover", "prepare_study", "run_study"]


def discover(
    y,
    t=None,
    *,
    assumed_model=None,
    n_states=None,
    measured=None,
    noise_variance=None,
    error_states=None,
    feature_library=None,
    optimizer=None,
    u=None,
    validation=None,
    mme=None,
    options=None,
    **removed,
):
    """Find what an assumed model gets wrong, name the cause, fix it, measure it.

    Parameters
    ----------
    y : array-like (n_samples, n_measured), or a list of records
        Noisy measurements of the states listed in ``measured``; NaN marks a
        missing sample. Several records (experiments) of one system: a list
        of arrays (with ``t`` a list of time arrays and ``u`` a list of input
        arrays or None), or a list of :class:`~pysindy_mme.Record` (then no
        ``t`` / ``u``). Each record has its own initial state; all share the
        grey-box parameters and the correction terms (the records are
        concatenated with no dynamics link between one and the next: no
        model error, no defect; each record's free run restarts from its own
        fitted initial state, and the RMSEs are pooled over the records).
        Without ``validation`` the last record is held out whole to measure
        the gain out of sample.
    t : array-like (n_samples,) or float, or a list of them
        Strictly increasing sample times (or the time step); with several
        records one per record, each starting anywhere.
    assumed_model : callable, pysindy model or ExtendedModel
        The user's simulation model ``f(x, t)`` or ``f(x, t, u)``, vectorised.
    n_states : int
    measured : sequence of int, optional
        Measured state indices (default: all states).
    noise_variance : float, array (n_measured,) or (n_measured, n_measured), or "auto"
        Measurement noise (co)variance. "auto" estimates it from the data.
    error_states : sequence of int, optional
        States whose equation may be wrong (default: all).
    feature_library : pysindy feature library, optional
        Candidate functions of the states (and inputs); default
        ``PolynomialLibrary(degree=3)``.
    optimizer : pysindy optimizer, optional
        Default :class:`FloatingFStepwise` ``()``.
    u : array-like (n_samples, n_inputs), optional
        Known inputs on the sample grid.
    validation : record(s) or a validation protocol, optional
        How the gain is measured out of sample (:mod:`pysindy_mme.protocols`).
        Another record, ``(y, t)``, ``(y, t, u)`` or a
        :class:`~pysindy_mme.Record`, or a list of them: each model's initial
        state is estimated from the record's first 50 samples, then the model
        runs free (:class:`~pysindy_mme.protocols.LeadingWindow`; with a list
        the RMSEs are pooled over the records, each record's own runs in
        ``gain.validation_runs[name].records``). A protocol object sets the
        window and the way of scoring:
        ``LeadingWindow(record, window=100)``, ``KStepAhead(10, record)``
        (predictions 10 samples ahead), ``HeldOut(fraction=0.2)`` (a stretch
        of the fitting data held out, both models refitted without it: the
        default when no record is given), or your own subclass of
        :class:`~pysindy_mme.protocols.ValidationProtocol`.
    mme : MME, optional
        The estimator's settings: ``MME(W=..., error_model=...,
        input_hold=..., n_substeps=..., measurement_function=..., ...)``
        (see :class:`MME`). The model and the measurements given here
        (``assumed_model``, ``n_states``, ``measured``, ``noise_variance``,
        ``error_states``, ``u``) fill in what it leaves unset; giving one in
        both places is an error. Without it: ``W="auto"``, the white error
        model, linear input hold, one RK4 step per sample interval (raised
        to what the model's fastest time scale needs).
    options : StudyOptions or dict, optional
        Everything else the study may be told (names, grey-box parameters,
        hidden states, significance, sensors...): see
        :class:`~pysindy_mme.StudyOptions`.

    Returns
    -------
    Discovery

    Notes
    -----
    Thirteen parameters: the six that name the model and the measurements
    are the design's contract (``discover(y, t, assumed_model=f,
    n_states=2, measured=[0], noise_variance=0.01, error_states=[1],
    feature_library=...)``), and grouping any of them would make the common
    call longer. Keywords of earlier versions (``alpha=``, ``W=``,
    ``validation_window=``, ...) raise a ``TypeError`` saying where each
    went.
    """
    study, opts = prepare_study(
        y,
        t,
        assumed_model=assumed_model,
        n_states=n_states,
        measured=measured,
        noise_variance=noise_variance,
        error_states=error_states,
        feature_library=feature_library,
        optimizer=optimizer,
        u=u,
        validation=validation,
        mme=mme,
        options=options,
        **removed,
    )
    return run_study(study, Progress(opts.verbose))


def prepare_study(
    y,
    t=None,
    *,
    assumed_model=None,
    n_states=None,
    measured=None,
    noise_variance=None,
    error_states=None,
    feature_library=None,
    optimizer=None,
    u=None,
    validation=None,
    mme=None,
    options=None,
    **removed,
):
    """:func:`discover`'s arguments checked: ``(Study, StudyOptions)``.

    Everything :func:`discover` does before the first long computation, so
    that :func:`~.many.discover_many` can check every study before any
    starts and then run exactly what :func:`discover` would
    (``run_study`` on the checked study).
    """
    refuse_moved(removed)
    opts = as_options(options)
    given = dict(
        assumed_model=assumed_model,
        n_states=n_states,
        measured=measured,
        noise_variance=noise_variance,
        error_states=error_states,
    )
    study = check_study(
        y,
        t,
        mme=mme,
        feature_library=feature_library,
        optimizer=optimizer,
        feature_names=opts.feature_names,
        u=u,
        validation=validation,
        alpha=opts.alpha,
        refit=opts.refit,
        assumed_equations=opts.assumed_equations,
        input_hold="linear" if mme is None else mme.input_hold,
        parameters=opts.parameters,
        offsets=opts.offsets,
        min_effect=opts.min_effect,
        clipped=opts.clipped,
        hidden_states=opts.hidden_states,
        **given,
    )
    return study, opts


def run_study(study, progress: Progress) -> Discovery:
    """The five steps on a checked :class:`~.inputs.Study`, in order."""
    progress.stage(f"checked: {study.t.size} samples, {study.n_states} states")
    assumed = fit_assumed_model(study)  # 1
    progress.stage(f"1. assumed model: chi2 = {assumed.chi2:.6g} on {assumed.dof} dof")
    estimate = estimate_model_error(study, assumed)  # 2
    progress.stage(f"2. MME: W = {np.asarray(estimate.mme.W_)}")
    sens = parameter_sensitivities(study, estimate.x, assumed.fit.physical)
    proposals = propose_terms(study, estimate.x, estimate.d, sens)  # 3
    set_aside_parameter_duplicates(study, proposals, estimate.x, sens)
    progress.stage(f"3. regression of d(t) proposes {len(proposals.slots)} term(s)")
    substeps = max(assumed.substeps, _substeps(study, assumed, proposals, estimate.x))
    engine = output_error_engine(study, proposals.evaluate, substeps)
    engine.noise_inflation = residual_inflation(
        estimate.mme.residuals_, study.noise_cov
    )
    assumed = baseline(study, assumed, engine, estimate.x)
    confirmation = confirm_on_measurements(  # 4
        study, engine, assumed, estimate, proposals, progress.step
    )
    progress.stage(f"4. confirmed {len(confirmation.slots)} term(s)")
    engine, assumed, substeps = _finer_if_needed(
        study, engine, assumed, confirmation, proposals, estimate.x, substeps
    )
    extended_fit = confirmation.fit or assumed.fit
    extended = extended_model_at(study, proposals, extended_fit, estimate.x, substeps)
    fits = {"assumed": assumed.fit, "extended": extended_fit}
    models = {"assumed": study.model_at(assumed.fit.physical), "extended": extended}
    # the integrator check reads the extended fit's linearisation
    step_note = (
        None
        if confirmation.fit is None
        else step_size_check(
            engine, confirmation.fit, _term_names(study, proposals, confirmation.slots)
        )
    )
    # where rounding sets each model's free run: read from the fits'
    # linearisations (the same object twice when no term was kept)
    rounding = {
        name: rounding_sets_run(fit, study.t, study.record_slices)
        for name, fit in fits.items()
        if name == "assumed" or fit is not fits["assumed"]
    }
    # From here on the fits are read, not tested or resumed: their
    # statistics are computed now and their linearisations released (two
    # fits' flows and sensitivities, a quarter of the gain stage's peak
    # at 10^6 samples, held while its free runs and refits build their own)
    for fit in fits.values():
        fit.keep_statistics()

    def build_extended(fit):
        return extended_model_at(study, proposals, fit, estimate.x, substeps)

    gain = measure_gain(  # 5
        study, fits, models, proposals.evaluate, substeps, build_extended
    )
    for name, where in rounding.items():
        rmse = np.asarray(gain.in_sample_runs[name].rmse, dtype=float)
        # a run that diverged is reported as such (RMSE inf) already
        if where is not None and np.all(np.isfinite(rmse)):
            gain.rounding_set[name] = where.time
            gain.notes.append(rounding_note(name, where, rmse))
    if study.validation is None and confirmation.slots:
        hold_out(
            study,
            gain,
            fits,
            build_extended,
            proposals.evaluate,
            substeps,
            estimate.x,
        )
    progress.stage("5. gain measured")
    # named among the warnings and the conclusion's reasons alike
    rivals = rival_sentences(study, proposals, confirmation)
    notes, smoothing, kink_misfit = _notes(
        study,
        assumed,
        estimate,
        proposals,
        confirmation,
        gain,
        engine,
        step_note,
        rivals,
    )
    terms, estimates = _terms(study, proposals, confirmation)
    names = _quantity_names(study, proposals, extended_fit)
    trade_offs = _with_gauges(
        study,
        exact_trade_offs(
            engine, extended_fit, names, study.state_names, study.measured
        ),
    )
    final = "extended" if confirmation.slots else "assumed"
    crossed = overshoots(study, fits[final], gain.in_sample_runs[final], final)
    memory = study_memory(study, estimate.x, estimate.d)

    def evidence_with(memory):
        return _evidence(
            study,
            assumed,
            confirmation,
            gain,
            names,
            trade_offs,
            crossed,
            memory,
            kink_misfit,
            rivals,
        )

    evidence = evidence_with(memory)
    if memory_decides(evidence):
        # the claim would be made: weigh it against a record without a state
        # first (one MME solve; not made where the claim is not)
        memory, discounted = _weighed_memory(study, estimate, fits[final].x, memory)
        notes += discounted
        evidence = evidence_with(memory)
    conclusion = conclude(evidence)
    for note in notes:
        warnings.warn(note, DiscoveryWarning, stacklevel=3)
    return Discovery(
        study=study,
        assumed=assumed,
        estimate=estimate,
        proposals=proposals,
        confirmation=confirmation,
        gain=gain,
        extended_model=extended,
        terms=terms,
        term_estimates=estimates,
        verdict=conclusion.verdict,
        warnings=notes,
        extended_fit=confirmation.fit,
        substeps=substeps,
        conclusion=conclusion.label,
        reasons=list(conclusion.reasons),
        advice=list(conclusion.advice),
        trade_offs=trade_offs,
        smoothing=smoothing,
        memory=memory,
        kink_misfit=kink_misfit,
    )


def _weighed_memory(study, estimate, x_null, memory):
    """``(memory, notes)``: the memory test's findings weighed against a null
    record of the trajectory ``x_null`` (:func:`~.memory.discount_estimation_error`,
    :func:`~.steps.memory_null`), and a note for each suspicion it set aside."""
    memory = discount_estimation_error(memory, memory_null(study, estimate, x_null))
    notes = [
        f"the model error of {study.state_names[m.state]}' has a history that "
        f"predicts {100 * m.history_gain:.0f}% of it beyond the present states, "
        "but on a record simulated from the model found (which has no such "
        f"state) and estimated the same way it predicts {100 * m.null_gain:.0f}"
        "%: MME's own estimation error shows as memory at this sampling rate "
        "and noise, so no missing state is claimed"
        for m in memory
        if m.null_gain is not None and not m.suspected
    ]
    return memory, notes


def _with_gauges(study, trade_offs) -> list:
    """The final fit's trade-offs, each one a gauge fixes marked with it.

    The check perturbs every quantity, the gauges too, so it finds the
    directions they fix again (with the terms that share them: a square
    root of a hidden level scales with it); those are named as fixed by the
    gauge, not as undetermined.
    """
    held = [trade.gauge for trade in study.gauges]
    out = []
    for trade in trade_offs:
        gauge = next((name for name in held if name in trade.names), "")
        out.append(replace(trade, gauge=gauge) if gauge else trade)
    return out


def _quantity_names(study, proposals, fit) -> list:
    """A name per entry of ``fit.theta``: parameters, terms, offsets."""
    names = _term_names(study, proposals, fit.slots)
    if study.offsets:
        names += [f"offset of {name}" for name in study.channel_names]
    return names


def _evidence(
    study,
    assumed,
    confirmation,
    gain,
    names,
    trade_offs,
    crossed=(),
    memory=(),
    kink_misfit=None,
    rivals=(),
) -> Evidence:
    fit = confirmation.fit or assumed.fit
    noise = study.noise_doubt
    k0 = len(study.parameter_names)
    vanished = _vanished(study, fit, assumed.fit)
    doubts, doubt_advice = _parameter_doubts(study, fit, vanished)
    return Evidence(
        contradicted=bool(assumed.p_value < study.alpha),
        consistency=(
            f"the assumed model's chi2 = {sig(assumed.chi2)} on {assumed.dof} "
            f"residual dof, p = {p_value(assumed.p_value)} (alpha = {study.alpha})"
        ),
        terms=names[k0 : k0 + len(confirmation.slots)],
        assumed_converged=bool(assumed.fit.converged),
        extended_converged=bool(confirmation.fit is None or confirmation.fit.converged),
        rmse_assumed=np.asarray(gain.rmse_assumed, float),
        rmse_extended=np.asarray(gain.rmse_extended, float),
        noise_floor=np.asarray(gain.noise_floor, float),
        channel_names=list(study.channel_names),
        out_assumed=gain.validation_rmse_assumed,
        out_extended=gain.validation_rmse_extended,
        out_source=gain.validation_source,
        out_converged=bool(gain.held_out_converged),
        out_spread=spread_sentence(gain, "extended"),
        out_uncertainty=_out_uncertainty(gain),
        rivals=list(rivals),
        unidentified=[str(t) for t in trade_offs if not t.gauge]
        + _undetermined(fit, names, set(vanished)),
        vanished=list(vanished.values()),
        gauges=[str(t) for t in trade_offs if t.gauge],
        parameters=doubts,
        parameter_advice=doubt_advice,
        noise_doubt=noise,
        overshoots=list(crossed),
        kink_misfit=kink_misfit,
        memory=[
            MissingState(
                study.state_names[m.state],
                m.describe(study.state_names[m.state]),
                _hidden_name(study),
            )
            for m in memory
            if m.suspected
        ],
    )


def _hidden_name(study) -> str:
    """A name for a suggested hidden state that no state or input has."""
    taken = set(study.state_names) | set(study.input_names)
    for name in ("z", "w", "h1", "h2", "h3"):
        if name not in taken:
            return name
    return "hidden"


#: a grey-box parameter whose standard error is at most this share of its
#: scale (the larger of its guess and the assumed model's own fit) is pinned
#: by the data, even when its value is within a standard error of zero
PINNED_SHARE = 0.05


def _vanished(study, fit, assumed_fit) -> dict:
    """``{k: sentence}``: grey-box parameters the extended fit puts at zero
    within a standard error that is small against what the assumed model
    alone needed (the tanks' linear outflow rates beside the square-root
    law: 4e-5 +- 1.5e-4 where the assumed fit had 0.03).

    The data determine them: that part of the assumed model is not there,
    and the correction does its work. Their relative standard error is large
    only because their value is zero, and a "sign change" within a standard
    error of zero is none; so they are a finding, not a doubt.
    """
    out = {}
    k0 = len(study.parameter_names)
    if not k0 or fit is assumed_fit:
        return out
    se = fit.std_errors[:k0]
    held = np.asarray(fit.held, dtype=bool)[:k0]
    for k, name in enumerate(study.parameter_names):
        value = float(fit.physical[k])
        alone = float(assumed_fit.physical[k])
        scale = max(abs(alone), abs(float(study.parameter_init[k])))
        if held[k] or not (np.isfinite(se[k]) and se[k] > 0) or scale == 0:
            continue
        if abs(value) < se[k] <= PINNED_SHARE * scale:
            out[k] = (
                f"{name} = {sig(value)} +- {sig(se[k])} is zero within its standard "
                f"error, which is {sig(100 * se[k] / scale, 2)} % of the "
                f"{sig(alone)} the assumed model alone needed: the correction does "
                "the work of that part of the assumed model"
            )
    return out


def _undetermined(fit, names, pinned=()) -> list:
    """Kept quantities the data do not pin down: an undefined or larger-than-
    the-value standard error, or estimates correlated beyond the limit.
    ``pinned``: indices whose value is zero within a small standard error
    (:func:`_vanished`), determined although their relative error is large."""
    k = min(len(names), fit.theta.size)
    if k == 0:
        return []
    theta = np.asarray(fit.theta[:k], float)
    cov = np.asarray(fit.covariance[:k, :k], float)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    held = np.zeros(k, dtype=bool)  # at a bound: a limit, named as such
    flags = np.asarray(fit.held, dtype=bool)[:k]  # a bound, a wall limit
    held[: flags.size] = flags
    determined = np.isfinite(se) & (se > 0)
    out = []
    for j in np.flatnonzero(~held):
        if not determined[j]:
            out.append(f"{names[j]} is not determined by the data (no standard error)")
        elif se[j] > abs(theta[j]) and j not in pinned:
            out.append(
                f"{names[j]} = {sig(theta[j])} has a standard error larger than its "
                f"value ({sig(se[j])})"
            )
    pairs = correlated_pairs(
        cov,
        names[:k],
        ~determined,
        limit=TRADE_OFF_CORRELATION,
        most=None,
        values=theta,
    )
    out += [
        f"{a} and {b} trade off (correlation of their estimates {r:+.4f})"
        for a, b, r in pairs
    ]
    return out


def _parameter_doubts(study, fit, vanished=()) -> tuple:
    """Grey-box parameters that ran away from the guess or sit on a bound.

    Returns ``(sentences, advice)``: a sentence per parameter, and the
    advice for them written in the user's own parameter names (the bounds
    that would keep each one where its guess says it belongs), or None.
    ``vanished``: parameters pinned at zero (:func:`_vanished`), a finding
    said apart, not a runaway.
    """
    out, bounds, on_bound = [], {}, []
    gauge = study.parameter_gauge
    limits = np.asarray(study.parameter_bounds, dtype=float)
    for k, name in enumerate(study.parameter_names):
        guess, value = float(study.parameter_init[k]), float(fit.physical[k])
        if gauge[k]:
            continue  # held at the guess on purpose (a gauge), said apart
        if fit.at_bound[k]:
            out.append(f"{name} = {sig(value)} sits on its bound")
            on_bound.append(name)
            continue
        if guess == 0.0 or not np.isfinite(value) or k in vanished:
            continue
        ratio = value / guess
        lower, upper = limits[k] if k < len(limits) else (-np.inf, np.inf)
        if ratio < 0:
            out.append(
                f"{name} changed sign: {sig(guess)} guessed, {sig(value)} fitted"
            )
            # keep the guess's sign, and whatever bound the user gave
            lower, upper = (max(lower, 0.0), upper) if guess > 0 else (lower, 0.0)
            bounds[name] = (guess, lower, upper)
        elif ratio > RUNAWAY_FACTOR or ratio < 1.0 / RUNAWAY_FACTOR:
            out.append(
                f"{name} moved from the guess {sig(guess)} to {sig(value)} "
                f"({sig(ratio, 3)}x): it has most likely absorbed a missing effect"
            )
            a, b = sorted((guess / RUNAWAY_FACTOR, guess * RUNAWAY_FACTOR))
            bounds[name] = (guess, max(lower, a), min(upper, b))
    return out, _parameter_advice(bounds, on_bound)


def _bound_text(value, missing: str = "None") -> str:
    """A bound as the advice writes it; ``missing`` where there is none."""
    return missing if not np.isfinite(value) else sig(value)


def _parameter_advice(bounds: dict, on_bound: list):
    """The advice for doubtful parameters, in the user's names; None if none."""
    parts = []
    if bounds:
        spec = ", ".join(
            f"'{name}': ({sig(g)}, {_bound_text(lo)}, {_bound_text(hi)})"
            for name, (g, lo, hi) in bounds.items()
        )
        flags = ",".join(
            f"{name}={sig(g)}:{_bound_text(lo, '')}:{_bound_text(hi, '')}"
            for name, (g, lo, hi) in bounds.items()
        )
        parts.append(
            f"bounds from what you know of the parameters (parameters={{{spec}}}, "
            f"with the other parameters as before; command line: --parameters "
            f"{flags},...)"
        )
    if on_bound:
        parts.append(f"checking the bound of {', '.join(on_bound)}")
    if not parts:
        return None
    return " or ".join(parts) + ", or a library without terms that re-do them"


def _substeps(study, assumed, proposals, x_hat) -> int:
    """RK4 steps per interval for the assumed model plus the proposals."""
    return rk4_substeps(study, proposal_rows(study, assumed, proposals), x_hat, study.t)


def _finer_if_needed(study, engine, assumed, confirmation, proposals, x_hat, substeps):
    """The confirmed model's own RK4 steps: ``(engine, assumed, substeps)``.

    The steps per interval were chosen for the regression's proposals; the
    confirmed terms, at their fitted values, may be faster (a hysteretic law
    whose decay rate grows with ``|v|``). When they need more steps, both
    fits are polished with them, so that every later number (the gain, the
    checks, the printed model's simulations) integrates the model as fast
    as it is.
    """
    fit = confirmation.fit
    if fit is None or not fit.ok:
        return engine, assumed, substeps
    needed = rk4_steps_of(
        study, fit.physical, fit.slots, fit.coefficients, proposals, fit.x
    )
    if needed <= substeps:
        return engine, assumed, substeps
    finer = output_error_engine(study, proposals.evaluate, needed)
    finer.noise_inflation = engine.noise_inflation
    refit = finer.fit(fit.slots, fit.theta, fit.x)
    base = baseline(study, assumed, finer, x_hat)
    if not (refit.ok and base.fit.ok):
        return engine, assumed, substeps
    confirmation.fit = refit
    confirmation.correction_p_value = partial_f_p_value(
        base.fit, refit, n_added=len(refit.slots)
    )
    confirmation.log.append(
        f"polished with {needed} RK4 steps per interval (the confirmed terms are "
        f"faster than the proposals, which had {substeps})"
    )
    return finer, base, needed


def _out_uncertainty(gain):
    """Whether the extended model's out-of-sample miss is its estimates'
    (:mod:`~pysindy_mme.protocols.uncertainty`; None: not measured)."""
    runs = gain.validation_runs or {}
    run = runs.get("extended")
    return None if run is None else run.uncertainty


def _terms(study, proposals, confirmation):
    """``terms`` and the :class:`TermEstimate` list of the kept terms."""
    terms = {study.state_names[i]: {} for i in study.error_states}
    fit = confirmation.fit
    if fit is None:
        return terms, []
    ci = fit.confidence_intervals()[fit.n_physical :]
    se = fit.std_errors[fit.n_physical :]
    p_values = fit.coefficient_p_values()
    z = fit.x if study.u is None else np.hstack([fit.x, study.u])
    with np.errstate(all="ignore"):
        values = proposals.evaluate(z, [c for _, c in confirmation.slots])
    contributions = values * fit.coefficients
    dynamics = study.model_at(fit.physical)(fit.x, study.t, study.u)
    estimates = []
    for k, (i, c) in enumerate(confirmation.slots):
        name = study.state_names[i]
        coefficient = float(fit.coefficients[k])
        terms[name][proposals.name(c)] = coefficient
        same_eq = [j for j, (ii, _) in enumerate(confirmation.slots) if ii == i]
        correction = contributions[:, same_eq].sum(axis=1)
        rms_term = float(np.sqrt(np.mean(contributions[:, k] ** 2)))
        rms_corr = float(np.sqrt(np.mean(correction**2)))
        rms_dyn = float(np.sqrt(np.mean((dynamics[:, i] + correction) ** 2)))
        estimates.append(
            TermEstimate(
                state=name,
                feature=proposals.name(c),
                coefficient=coefficient,
                regression_coefficient=_regression_value(proposals, i, c),
                std_error=float(se[k]) if se[k] > 0 else float("nan"),
                ci_low=float(ci[k, 0]),
                ci_high=float(ci[k, 1]),
                partial_f=_partial_f(proposals, study, i, c),
                p_value=float(p_values[k]) if se[k] > 0 else float("nan"),
                rms_term=rms_term,
                share_of_correction=rms_term / rms_corr if rms_corr > 0 else np.nan,
                share_of_dynamics=rms_term / rms_dyn if rms_dyn > 0 else np.nan,
            )
        )
    return terms, estimates


def _regression_value(proposals, state, column) -> float:
    if column == proposals.constant_column:
        return float(proposals.intercepts[state])
    value = float(proposals.coefficients[state, column])
    return value if value != 0 else float("nan")


def _partial_f(proposals, study, state, column) -> float:
    """Partial F of ``column`` in the stepwise model of ``state`` (NaN if none)."""
    tables = getattr(proposals.optimizer, "anova_", None)
    if tables is None or column == proposals.constant_column:
        return float("nan")
    table = tables[list(study.error_states).index(state)]
    support = list(np.asarray(getattr(table, "features", ())))
    partial = np.asarray(getattr(table, "partial_f", []))
    if column in support and len(partial) == len(support):
        return float(partial[support.index(column)])
    return float("nan")


def rival_sentences(study, proposals, confirmation) -> list:
    """A sentence per rival of the kept terms (:attr:`.confirm.Confirmation.rivals`)."""
    out = []
    kept = list(confirmation.slots)
    k0 = len(study.parameter_names)
    for slots, delta in getattr(confirmation, "rivals", []):
        own = [s for s in kept if s not in slots]
        theirs = [s for s in slots if s not in kept]
        names = _term_names(study, proposals, own + theirs)[k0:]
        own_names, their_names = names[: len(own)], names[len(own) :]
        out.append(
            f"the data tell {_and(own_names)} from {_and(their_names)} only weakly: "
            f"the model with {_and(their_names)} in place of {_and(own_names)} "
            f"fits nearly as well (its BIC is {sig(delta, 2)} above this one's; "
            f"strong evidence needs {RIVAL_BIC:g}), so which of them the effect "
            "is, these data do not say"
        )
    return out


def _and(names) -> str:
    names = list(names) or ["no term"]
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def _term_names(study, proposals, slots) -> list:
    """A name per grey-box parameter and per term of ``slots`` (no offsets)."""
    return list(study.parameter_names) + [
        f"{proposals.name(c)} in {study.state_names[i]}'" for i, c in slots
    ]


def _notes(
    study,
    assumed,
    estimate,
    proposals,
    confirmation,
    gain,
    engine,
    step_note=None,
    rivals=(),
):
    """Everything the user must know about how far to trust the numbers:
    ``(notes, smoothing, kink_misfit)``, the second the smoothing check's
    finding when it found the width harmless (shown with the extended
    model), the third its :attr:`~.steps.SmoothingCheck.misfit_ratio`
    (None: not measured).
    ``step_note``: the integrator check's (:func:`~.steps.step_size_check`),
    made while the fit still had its linearisation; ``rivals``: the
    sentences of :func:`rival_sentences`."""
    notes = list(estimate.notes) + list(assumed.notes) + list(gain.notes)
    notes += list(confirmation.notes)
    notes += list(rivals)
    shown = ""
    kink_misfit = None
    fit = confirmation.fit
    if fit is not None:
        names = _term_names(study, proposals, confirmation.slots)
        notes += doubt_notes(fit, names)
        general = generalisation_note(
            gain, names[len(study.parameter_names) :], study.channel_names
        )
        if general:
            notes.append(general)
        from scipy import stats

        # with correlated residuals the cost and the count shrink together
        p_fit = float(stats.chi2.sf(fit.cost / fit.inflation, fit.dof))
        if p_fit < study.alpha:
            notes.append(
                "the extended model still does not fit the data to the noise level "
                f"(chi2 = {sig(fit.cost)} over {fit.n_residuals} residuals"
                f"{_effective(fit)}, p = {p_fit:.2g}): the library may lack the "
                "missing effect, the "
                "noise variance may be too small, or the search stopped in a local "
                "optimum"
            )
        notes += _noise_sanity(study, fit)
        if step_note:
            notes.append(step_note)
        smoothing = smoothing_check(
            engine, fit, proposals.library, proposals.name, names
        )
        if smoothing is not None:
            if smoothing.ok:
                shown = smoothing.text
            else:
                notes.append(smoothing.text)
            kink_misfit = smoothing.misfit_ratio
        smoothed = (
            set()
            if smoothing is None
            else {
                c
                for _, c in confirmation.slots
                if c < len(proposals.library.widths_)
                and proposals.library.widths_[c] > 0
            }
        )
        used = {c for _, c in confirmation.slots} - smoothed
        for c in sorted(used & set(proposals.nonsmooth)):
            notes.append(
                f"{proposals.name(c)} is {proposals.nonsmooth[c]}; the integrators "
                "take it as it is (fits through a jump may stall): PhysicsLibrary's "
                "effects (Coulomb, Saturation, Overflow, ...) integrate their kinks "
                "smoothed and check that the width does not matter"
            )
    return notes, shown, kink_misfit


def _effective(fit) -> str:
    """The test's degrees of freedom, and why they differ from the count."""
    plain = fit.n_residuals - fit.n_free
    if abs(fit.dof - plain) < 0.5:
        return f", {sig(fit.dof, 6)} dof"
    return (
        f"; the residuals are correlated ({sig(fit.inflation, 3)} residuals per "
        f"independent one), so tested as {sig(fit.cost / fit.inflation)} on "
        f"{sig(fit.dof, 5)} effective dof"
    )


def _noise_sanity(study, fit) -> list:
    """Fitted residuals far below the stated noise: say so, and the likely slip."""
    ratio = fit.residual_variance  # 1 when the model fits to the stated noise
    if not np.isfinite(ratio) or ratio >= 0.25:
        return []
    sd = np.sqrt(np.diag(study.noise_cov))
    fitted = sd * np.sqrt(ratio)
    return [
        "the extended model fits the measurements far below the stated noise "
        f"(residual sd {', '.join(sig(v) for v in fitted)} where the noise sd is "
        f"{', '.join(sig(v) for v in sd)}): was a standard deviation given as a "
        "variance (noise_variance is the variance, sd squared), or did an 'auto' "
        "estimate take signal for noise? Tests and intervals assume the stated noise"
    ]
