"""The five steps of the study, each a function returning a small record.

1. :func:`fit_assumed_model` - the assumed model against the data: its
   output-error fit (initial state) and a chi-square test of consistency;
2. :func:`estimate_model_error` - :class:`MME`: the full state and the model
   error ``d(t)``;
3. :func:`~pysindy_mme.discovery.propose.propose_terms` - the regression of
   ``d(t)`` on the library proposes terms;
4. :func:`confirm_on_measurements` - output-error tests on the measurements
   settle them (:mod:`.confirm`), and the answer is checked against a finer
   integration step;
5. :func:`measure_gain` - simulation error of both models, in-sample and on
   a validation record (:mod:`.gain`).
"""

from __future__ import annotations

import warnings
import weakref
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np
from scipy import stats
from sklearn.base import clone

from ..core.integrate import RK4_H_RHO, simulate_guided
from ..core.jacobian import rowwise_jacobian
from ..core.model import ParametricModel
from ..core.relaxation import Overflows, overflow_columns_of
from ..core.tables import sig
from ..exceptions import DivergenceError, UnobservableError
from ..protocols import ValidationContext
from ..protocols.runs import FreeRun, free_run, measurement_function, pooled_runs
from ..protocols.uncertainty import coefficient_draws
from ..solver.output_error import OutputErrorFit, OutputErrorModel
from .conclusion import Overshoot
from .confirm import Confirmation, confirm_terms
from .doubts import stop_reason
from .gain import Gain
from .identifiability import exact_trade_offs, gauge_choice
from .long_record import confirm_long_record, reduced_study, search_part
from .memory import memory_evidence
from .run_sensitivity import spread_sentence

__all__ = [
    "AssumedFit",
    "ErrorEstimate",
    "fit_assumed_model",
    "fix_gauges",
    "baseline",
    "parameter_sensitivities",
    "set_aside_parameter_duplicates",
    "estimate_model_error",
    "confirm_on_measurements",
    "measure_gain",
    "output_error_engine",
    "proposal_rows",
    "rk4_steps_of",
    "rk4_substeps",
    "step_size_check",
    "memory_null",
    "study_memory",
    "in_sample_run",
    "hold_out",
    "overshoots",
]


@dataclass
class AssumedFit:
    """Step 1: the assumed model's output-error fit and consistency test."""

    fit: OutputErrorFit
    chi2: float
    dof: int
    p_value: float
    substeps: int
    notes: list = field(default_factory=list)


@dataclass
class ErrorEstimate:
    """Step 2: MME's estimate of the states and the model error."""

    mme: object
    x: np.ndarray
    d: np.ndarray
    summary: dict
    notes: list = field(default_factory=list)
    #: the grey-box parameters MME ran with (empty without parameters)
    physical: np.ndarray = field(default_factory=lambda: np.zeros(0))


def _base(study):
    """The assumed model as ``(x, t, u, p) -> dx/dt`` (validated, unchecked);
    ``p`` its grey-box parameters (empty without)."""
    return _AssumedRates(study)


class _AssumedRates:
    """:func:`_base`'s callable: a module-level class, not a closure, so that
    the fits holding it (and a :class:`~.result.Discovery`) pickle whenever
    the user's model does."""

    def __init__(self, study):
        self.names = tuple(study.parameter_names)
        self.raw = study.raw_model if self.names else None
        self.f = None if self.names else study.model.unchecked()

    def __call__(self, x, t, u, p):
        tt = np.broadcast_to(np.asarray(t, dtype=float), (x.shape[0],))
        if self.f is None:
            values = dict(zip(self.names, (float(v) for v in p)))
            out = self.raw(x, tt, u, values)
            return np.asarray(out, dtype=float).reshape(x.shape)
        # reshaped: a one-state model may answer (n_rows,)
        return np.asarray(self.f(x, tt, u), dtype=float).reshape(x.shape)


def spectral_radius(rhs_rows, x) -> float:
    """The largest ``|eigenvalue|`` of the model's Jacobian along ``x``: its
    fastest time scale is ``1 / radius``.

    ``rhs_rows(z, stride)``: the model at the rows ``z``, which are every
    ``stride``-th row of ``x`` (a sample of 200 points is enough).
    """
    stride = max(1, x.shape[0] // 200)
    xs = x[::stride]
    if not xs.size:
        return 0.0
    jac = rowwise_jacobian(lambda z: rhs_rows(z, stride), xs, rel_step=1e-6)
    jac[~np.isfinite(jac)] = 0.0
    return float(np.max(np.abs(np.linalg.eigvals(jac))))


def rk4_substeps(study, rhs_rows, x, t) -> int:
    """RK4 steps per interval so that ``h * spectral radius <= 0.5``.

    The spectral radius of the model's Jacobian along the trajectory sets
    the fastest time scale; RK4 is accurate to ~1e-5 relative per step at
    ``h rho = 0.5`` (:data:`~pysindy_mme.core.integrate.RK4_H_RHO`). At least
    the estimator's own ``n_substeps``.
    """
    rho = spectral_radius(rhs_rows, x)
    steps = np.diff(t)
    starts = getattr(study, "starts", ())
    if len(starts) and t.size == study.t.size:
        steps = np.delete(steps, np.asarray(starts, dtype=int) - 1)  # no breaks
    dt = float(np.max(steps))
    auto = int(min(50, max(1, np.ceil(dt * rho / RK4_H_RHO))))
    return max(auto, int(study.mme.n_substeps))


def extended_rows(study, physical, slots, coefs, proposals):
    """The assumed model at ``physical`` plus the terms ``slots`` with
    ``coefs``, as ``rhs_rows(x, stride)`` along every ``stride``-th sample
    (see :func:`spectral_radius`). Overflow terms of states are left out:
    the fits and runs solve them exactly around each RK4 step
    (:mod:`~pysindy_mme.core.relaxation`), so their stiffness asks for no
    step."""
    u = study.u
    model = study.model_at(physical)
    split = Overflows(
        slots, proposals.evaluate.overflow_columns(), study.n_states
    ).positions
    coefs = [c for k, c in enumerate(coefs) if k not in split]
    slots = [s for k, s in enumerate(slots) if k not in split]
    columns = [c for _, c in slots]

    def rhs_rows(x, stride):
        ts = study.t[::stride][: x.shape[0]]
        us = None if u is None else u[::stride][: x.shape[0]]
        out = np.array(model(x, ts, us), dtype=float)
        if slots:
            z = x if us is None else np.hstack([x, us])
            with np.errstate(all="ignore"):
                values = proposals.evaluate(z, columns)
            for k, (i, _) in enumerate(slots):
                out[:, i] += coefs[k] * values[:, k]
        return out

    return rhs_rows


def rk4_steps_of(study, physical, slots, coefs, proposals, x) -> int:
    """RK4 steps per interval for the assumed model at ``physical`` plus the
    terms ``slots`` with ``coefs``, along ``x`` (:func:`rk4_substeps`;
    overflow terms left out, :func:`extended_rows`)."""
    rows = extended_rows(study, physical, slots, coefs, proposals)
    return rk4_substeps(study, rows, x, study.t)


def output_error_engine(study, features, substeps) -> OutputErrorModel:
    """An :class:`OutputErrorModel` of the fitting record."""
    return OutputErrorModel(
        _base(study),
        study.n_states,
        features,
        study.y,
        study.t,
        study.inputs,
        study.noise_cov,
        study.measurement,
        n_physical=study.n_parameters,
        n_offsets=study.y.shape[1] if study.offsets else 0,
        n_substeps=substeps,
        bounds=study.fit_bounds,
        starts=study.starts,
    )


def initial_theta(study) -> np.ndarray:
    """``[parameters, offsets]`` to start the assumed model's fit from."""
    offsets = np.zeros(study.y.shape[1] if study.offsets else 0)
    return np.concatenate([study.parameter_init, offsets])


def fit_assumed_model(study) -> AssumedFit:
    """Step 1: output-error fit of the assumed model (initial state only).

    Started from the measured states (the unmeasured ones at zero), with as
    many RK4 steps per interval as the model's time scales need there.
    Grey-box parameters in an exact trade-off at the guesses are first
    given a gauge (:func:`fix_gauges`).
    """

    def rows(x, stride):
        return study.model(x, study.t[::stride][: len(x)], _rows(study.u, stride, x))

    substeps = rk4_substeps(study, rows, study.x_init, study.t)
    fix_gauges(study, substeps)
    engine = output_error_engine(study, None, substeps)
    theta = initial_theta(study)
    fit = engine.fit((), theta, study.x_init)
    if not fit.converged and study.n_states > study.y.shape[1]:
        # Unmeasured states start at zero, which can be far from anything
        # the model could follow (a velocity of 0 under a moving position):
        # the fit may then stall at an infeasible point, or wander to
        # parameters that make the model stiff. MME at the guessed
        # parameters gives every state a start that follows the model.
        # Or from a trajectory of the guessed model itself (its initial
        # state fitted with the parameters held): a point that follows the
        # model, from which Gauss-Newton's merit can only fall, and which
        # keeps it out of the basin of a stiff, degenerate model (a mass
        # that goes to zero with its damping) that the data cannot reject
        # before the trajectory joins.
        for start in (
            _fit_from_mme_start,
            _fit_from_guessed_trajectory,
            _fit_from_free_run,
        ):
            retry = start(study, engine, theta)
            if retry is not None and _rank(retry) > _rank(fit):
                fit = retry
            if fit.converged:
                break
    if study.gauges and fit.ok:
        fit = _release_needless_gauges(study, engine, fit, substeps)
    return _assumed_fit(study, fit, substeps)


def _parameter_labels(study) -> list:
    """A name per entry of the assumed model's ``theta``: parameters, offsets."""
    names = list(study.parameter_names)
    if study.offsets:
        names += [f"offset of {name}" for name in study.channel_names]
    return names


def fix_gauges(study, substeps) -> None:
    """Hold a grey-box parameter of each exact trade-off at its guess.

    The trade-offs are found at the guesses (the guessed model's own run,
    its initial state fitted with the parameters held:
    :func:`~.identifiability.gauge_choice`), before any fit can walk along
    them. A held parameter is a gauge, as a unit is: the model's family is
    the same, every other quantity is estimated relative to it, and it is
    not counted as a fitted quantity (the tests' degrees of freedom and the
    covariances are those of the model with it fixed, as for a parameter
    on a bound). Sets ``study.gauges``.
    """
    study.gauges = []
    if not study.n_parameters:
        return
    engine = output_error_engine(study, None, substeps)
    held = engine.fit_held((), initial_theta(study), study.x_init)
    if not held.ok:
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        chosen = gauge_choice(
            engine, held, _parameter_labels(study), study.state_names, study.measured
        )
    study.gauges = [trade for _, trade in chosen]


def _release_needless_gauges(study, engine, fit, substeps):
    """Step 1's fit with the gauges that still fix an exact trade-off there.

    A trade-off found at the guesses holds wherever it is a symmetry of the
    model (a hidden state's scale); one that was exact only at the guesses
    (a parameter multiplied by a state that happened to be still there)
    is not, and its parameter is released and the fit continued from where
    it stopped.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        found = exact_trade_offs(
            engine, fit, _parameter_labels(study), study.state_names, study.measured
        )
    still = {name for trade in found for name in trade.names}
    kept = [trade for trade in study.gauges if trade.gauge in still]
    if len(kept) == len(study.gauges):
        return fit
    study.gauges = kept
    freer = output_error_engine(study, None, substeps)
    refit = freer.fit((), fit.theta, fit.x)
    return refit if refit.ok else fit


def _rank(fit):
    """Converged first, then a trajectory that joins, then the lower cost."""
    return (fit.converged, fit.joined, -fit.cost)


def _fit_from_guessed_trajectory(study, engine, theta):
    """The assumed model's fit started from the guessed model's own run."""
    held = engine.fit_held((), theta, study.x_init)
    if not held.ok:
        return None
    return engine.fit((), theta, held.x)


def _fit_from_free_run(study, engine, theta):
    """The assumed model's fit started from the guessed model's free run.

    The last resort of step 1. The two starts before it begin at the
    measured states with the unmeasured ones at zero, and Gauss-Newton
    must make that trajectory follow the model; where the model is flat in
    an unmeasured state at zero (a square-root outflow from an empty
    tank), their linearisation sees nothing of it and the line search
    stalls. A free run of the guessed model from the first sample follows
    the model by construction (the tank fills from the pump), so the fit
    starts where its trajectory already joins.
    """
    model = study.model_at(study.parameter_init)
    runs = []
    for rows in study.record_slices:
        x0 = study.x_init[rows][0]
        with np.errstate(all="ignore"):
            sim = simulate_guided(
                model,
                x0,
                study.t[rows],
                study.inputs.subset(rows.start, rows.stop),
                engine.n_substeps,
                study.x_init[rows],
            )
        if not sim.ok[0]:
            return None
        runs.append(sim.x[0])
    return engine.fit((), theta, np.vstack(runs))


def _fit_from_mme_start(study, engine, theta):
    """The assumed model's fit started from MME's states at the guesses."""
    mme = _mme_at_guesses(study)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _fit_mme(mme, study, study.y)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, DivergenceError):
        return None
    x_hat = np.asarray(mme.smoothed_x_)
    if not np.all(np.isfinite(x_hat)):
        return None
    return engine.fit((), theta, x_hat)


def _rows(u, stride, x):
    return None if u is None else u[::stride][: len(x)]


def _assumed_fit(study, fit, substeps, notes=()) -> AssumedFit:
    notes = list(notes)
    if not fit.converged:
        notes.append(
            "the output-error fit of the assumed model did not converge "
            f"({stop_reason(fit)})"
        )
    dof = max(fit.n_residuals - study.n_states * study.n_records, 1)
    p = float(stats.chi2.sf(fit.cost, dof)) if np.isfinite(fit.cost) else 0.0
    return AssumedFit(
        fit=fit,
        chi2=float(fit.cost),
        dof=dof,
        p_value=p,
        substeps=substeps,
        notes=notes,
    )


def baseline(study, assumed: AssumedFit, engine: OutputErrorModel, x_hat) -> AssumedFit:
    """The assumed model's fit by ``engine``'s discretisation: the tests' baseline.

    Step 4's F-tests compare fits made with the same RK4 steps. When step 4
    needs more steps than step 1 used, or step 1 did not converge, the
    assumed model is refitted by ``engine``, from step 1's trajectory and
    from MME's, and the better fit is kept (and reported).
    """
    if engine.n_substeps == assumed.substeps and assumed.fit.converged:
        return assumed
    theta = assumed.fit.theta if assumed.fit.ok else initial_theta(study)
    fits = [engine.fit((), theta, assumed.fit.x), engine.fit((), theta, x_hat)]
    best = min(fits, key=lambda f: (not f.converged, f.cost))
    return _assumed_fit(study, best, engine.n_substeps)


def estimate_model_error(study, assumed: AssumedFit) -> ErrorEstimate:
    """Step 2: MME on the fitting record.

    The assumed model enters with the parameters (and the measurements
    without the offsets) that step 1 fitted.
    """
    mme = clone(study.mme)
    y = study.y
    physical = np.asarray(assumed.fit.physical, float)
    notes = []
    if study.n_parameters and study.hidden is not None:
        # With the hidden state frozen (z' = 0), step 1's parameters absorb
        # its effect (a fitted stiffness takes on a hysteresis' stiffness),
        # and MME would estimate z as what is left over. At the guesses, the
        # user's split between parameters and hidden state holds.
        # (documented with discover's hidden_states: not a warning)
        physical = np.asarray(study.parameter_init, float)
    if study.n_parameters:
        mme.set_params(assumed_model=study.assumed_at(physical))
    if study.offsets and assumed.fit.ok:
        y = study.y - assumed.fit.offsets
    try:
        try:
            _fit_mme(mme, study, y)
        except UnobservableError as exc:
            if not assumed.fit.ok:
                raise
            # From the data's start (unmeasured states at zero) the model
            # can be flat in a hidden state (a square-root outflow from an
            # empty tank), and MME's problem singular there; step 1's
            # trajectory follows the model where it sees every state.
            _fit_mme(mme, study, y, x_guess=assumed.fit.x)
            notes.append(
                "MME was started from the assumed model's fitted trajectory: "
                f"from the data's start its problem was singular ({exc})"
            )
    except DivergenceError as exc:
        # Stiff near the fitted trajectory (a Torricelli outflow near an
        # empty tank) at MME's own steps, where step 1 already needed more:
        # MME again with step 1's RK4 steps per interval.
        why = str(exc).split(":")[0]
        if assumed.substeps > mme.n_substeps:
            mme.set_params(n_substeps=int(assumed.substeps))
            try:
                _fit_mme(mme, study, y)
                notes.append(
                    f"MME needed {assumed.substeps} RK4 steps per sample interval "
                    f"(as the assumed model's fit did): at its own "
                    f"{study.mme.n_substeps} it failed ({why})"
                )
                why = None
            except DivergenceError:
                pass
        if why is not None:
            if not study.n_parameters:
                raise
            # The fitted parameters make the model too stiff for MME near
            # its estimate (a square-root outflow at an empty tank): the
            # model error is estimated at the user's guesses instead; the
            # confirmation refits the parameters with the terms anyway.
            mme = _mme_at_guesses(study)
            physical = np.asarray(study.parameter_init, float)
            _fit_mme(mme, study, y)
            notes.append(
                "MME could not integrate the assumed model at its fitted "
                f"parameters near the estimated states ({why}); d(t) was "
                "estimated at the guessed parameters instead"
            )
    if not mme.converged_:
        notes.append("MME did not converge; the state estimate may be poor")
    x_hat = np.asarray(mme.smoothed_x_)
    d_hat = np.asarray(mme.d_)
    f_hat = study.model_at(physical)(x_hat, study.t, study.u)
    summary = {}
    for i in study.error_states:
        rms_d = float(np.sqrt(np.mean(d_hat[:, i] ** 2)))
        rms_total = float(np.sqrt(np.mean((f_hat[:, i] + d_hat[:, i]) ** 2)))
        summary[study.state_names[i]] = {
            "rms_d": rms_d,
            "rms_dynamics": rms_total,
            "share": rms_d / rms_total if rms_total > 0 else float("nan"),
        }
    return ErrorEstimate(
        mme=mme, x=x_hat, d=d_hat, summary=summary, notes=notes, physical=physical
    )


def memory_null(study, estimate, x_null, seed: int = 0):
    """``null(i)``: what the memory test finds in ``d_i`` on a record of a
    model without any state the assumed model lacks (None: not measured).

    The record is the measurement of ``x_null`` (a trajectory of the model
    the study found, whose correction is a function of the present states)
    plus fresh noise of the study's covariance (seed ``seed``: the study is
    repeatable); MME estimates ``d`` on it at the study's ``W``, from
    ``x_null``, and the memory test reads it as it read the study's. What
    the history adds there (:attr:`~.memory.MemoryEvidence.history_gain`)
    is what MME's own estimation, at this sampling rate, noise and ``W``,
    shows as memory. Computed at the first call only (one MME solve at a
    fixed ``W``); asked for only where the test suspects a missing state
    (:func:`~.memory.discount_estimation_error`).
    """
    cache = {}

    def null(i):
        if "evidence" not in cache:
            cache["evidence"] = _null_memory(study, estimate, x_null, seed)
        found = cache["evidence"]
        return None if found is None else found.get(int(i))

    return null


def _null_memory(study, estimate, x_null, seed):
    """``{state: history gain}`` on the null record (None: MME fails there)."""
    fitted_mme = estimate.mme
    mme = clone(fitted_mme)
    mme.set_params(W=np.asarray(fitted_mme.W_, dtype=float))
    x_null = np.asarray(x_null, dtype=float)
    with np.errstate(all="ignore"):
        y = np.asarray(measurement_function(study.measurement)(x_null), float)
    y = np.where(np.isfinite(study.y), y, np.nan)  # the record's gaps and clips
    rng = np.random.default_rng(seed)
    y = y + rng.multivariate_normal(
        np.zeros(y.shape[1]), np.asarray(study.noise_cov, float), y.shape[0]
    )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _fit_mme(mme, study, y, x_guess=x_null)
    except (DivergenceError, UnobservableError, np.linalg.LinAlgError):
        return None
    found = study_memory(study, mme.smoothed_x_, mme.d_)
    return {ev.state: ev.history_gain for ev in found}


def study_memory(study, x, d) -> list:
    """The memory test (:func:`~.memory.memory_evidence`) of the states ``x``
    and model error ``d`` estimated on a record of ``study``."""
    return memory_evidence(
        x,
        d,
        study.u,
        # a hidden state's own equation is not tested: its estimate comes
        # from the same d(t), so its relation to d is not evidence
        [
            int(i)
            for i in study.error_states
            if study.hidden is None or int(i) not in study.hidden.indices
        ],
        study.starts if study.starts.size else (0,),
    )


def _mme_at_guesses(study):
    """A fresh copy of the study's MME, its model at the guessed parameters."""
    mme = clone(study.mme)
    if study.n_parameters:
        mme.set_params(assumed_model=study.assumed_at(study.parameter_init))
    return mme


def _fit_mme(mme, study, y, x_guess=None):
    # keywords only when used: an MME subclass may override fit(y, t, u)
    extra = {} if x_guess is None else {"x_guess": x_guess}
    if study.n_records > 1:
        extra["starts"] = study.starts
    mme.fit(y, study.t, study.inputs.u, **extra)


def parameter_sensitivities(study, x_hat, p_hat):
    """``df/dp`` of the assumed model along ``x_hat``: ``(N, n, n_parameters)``
    (None without grey-box parameters)."""
    if not study.n_parameters:
        return None
    return ParametricModel(
        _base(study), study.n_states, study.n_parameters
    ).param_jacobian(x_hat, study.t, study.u, np.asarray(p_hat, dtype=float))


def set_aside_parameter_duplicates(study, proposals, x_hat, sens) -> None:
    """Library terms that only re-do a parameter of the assumed model.

    With grey-box parameters, a library function whose effect on an
    equation is the same as a parameter's (``x1`` in ``x2'`` when the model
    has ``-k x1``: correlation above 0.9999 along the estimated trajectory)
    would only re-estimate that parameter: it is neither proposed nor
    offered, and the report says why (``proposals.rejected``). ``sens``:
    :func:`parameter_sensitivities` at ``x_hat``.
    """
    if sens is None:
        return
    u = study.u
    z = x_hat if u is None else np.hstack([x_hat, u])
    duplicates = {}
    for state, col in {*proposals.slots, *proposals.candidates}:
        with np.errstate(all="ignore"):
            phi = proposals.evaluate(z, [col])[:, 0]
        for k, name in enumerate(study.parameter_names):
            g = sens[:, state, k]
            if np.std(phi) > 0 and np.std(g) > 0:
                r = abs(np.corrcoef(phi, g)[0, 1])
                if r > 0.9999:
                    duplicates[(state, col)] = (
                        f"duplicates the assumed model's parameter {name} (its change "
                        "is reported as a parameter, not as a missing effect)"
                    )
    keep = [
        (s, v)
        for s, v in zip(proposals.slots, proposals.start_values)
        if s not in duplicates
    ]
    # every duplicate is said, proposed or not (with partialled regressions
    # a parameter's own shape is never proposed, only offered)
    proposals.rejected.extend((s, duplicates[s]) for s in sorted(duplicates))
    proposals.slots = [s for s, _ in keep]
    proposals.start_values = [v for _, v in keep]
    proposals.candidates = [c for c in proposals.candidates if c not in duplicates]


def confirm_on_measurements(
    study, engine, assumed: AssumedFit, estimate, proposals, progress=None
) -> Confirmation:
    """Step 4: settle the proposals on the measurements (see :mod:`.confirm`).

    With ``refit=False`` the regression's terms and values are kept and only
    the initial state is fitted (for comparison; not recommended).
    """

    def describe(slot):
        i, c = slot
        return f"{study.state_names[i]}: {proposals.name(c)}"

    if not study.refit:
        fit = None
        if proposals.slots:
            base = assumed.fit
            theta = np.concatenate(
                [base.physical, np.asarray(proposals.start_values), base.offsets]
            )
            fit = engine.fit_held(proposals.slots, theta, estimate.x)
        return Confirmation(list(proposals.slots) if fit else [], fit)

    def steps_of(on):  # RK4 steps a fit's model needs on the record of ``on``
        return lambda fit: rk4_steps_of(
            on, fit.physical, fit.slots, fit.coefficients, proposals, fit.x
        )

    settings = dict(
        proposals=proposals.slots,
        start_values=proposals.start_values,
        alpha=study.alpha,
        describe=describe,
        library_candidates=proposals.candidates,
        progress=progress,
        min_effect=study.min_effect,
    )
    part = _search_part(study, engine, assumed, estimate, proposals)
    if part is not None:
        part_engine = output_error_engine(
            reduced_study(study, part),
            proposals.evaluate,
            engine.n_substeps,
        )
        part_engine.noise_inflation = engine.noise_inflation
        confirmation = confirm_long_record(
            study,
            engine,
            part_engine,
            assumed.fit,
            estimate,
            part,
            settings,
            steps_of,
        )
    else:
        confirmation = confirm_terms(
            engine,
            assumed.fit,
            x_start=estimate.x,
            mme_start=(estimate.x, estimate.d, estimate.physical),
            steps_of=steps_of(study),
            **settings,
        )
    confirmation.rejected[:0] = list(proposals.rejected)
    drop_smoothing_artefacts(
        engine, confirmation, proposals.library, describe, estimate.x
    )
    return confirmation


def proposal_rows(study, assumed: AssumedFit, proposals):
    """The assumed model at its fitted parameters plus every term the
    regression proposed, at the regression's values, as ``rhs_rows(x,
    stride)`` (:func:`extended_rows`): the model whose time scales step 4's
    RK4 steps and the part of a long record it searches are chosen for."""
    coef = proposals.coefficients
    rows, cols = np.nonzero(coef)
    slots = [(int(i), int(j)) for i, j in zip(rows, cols)]
    return extended_rows(
        study, assumed.fit.physical, slots, coef[rows, cols], proposals
    )


def _search_part(study, engine, assumed, estimate, proposals):
    """The part of a long record step 4 searches on (None: the whole record;
    :func:`~.long_record.search_part`), at the fastest time scale of the
    assumed model with the regression's proposals along MME's states."""

    def radius():  # only asked for on a record long enough to need it
        return spectral_radius(proposal_rows(study, assumed, proposals), estimate.x)

    return search_part(study, engine.n_substeps, radius)


# A kept term whose coefficient changes by more than a fifth of itself
# when the kinks are smoothed over half the width describes the smoothing,
# not the plant (a term of the plant is set by the data, whatever the width
# far below the data's scale).
ARTEFACT_SHARE = 0.2


def drop_smoothing_artefacts(
    engine, confirmation, library, describe, x_start=None
) -> None:
    """Remove kept terms that only compensate the smoothing of kinks.

    The fit is repeated at half the smoothing width (:func:`_half_width_refit`);
    a term whose coefficient moves by more than ARTEFACT_SHARE of itself and by more
    than two standard errors is dropped, the rest refitted, and the reason
    recorded in ``confirmation.rejected``. In place.

    The rest is refitted from the fit's trajectory, and where that does not
    converge, from ``x_start`` (MME's states, where every fit of the search
    starts): the trajectory was shaped by the dropped term, and on a stiff
    kink (a 150 kg axis at 2 kHz read to 50 nm) Gauss-Newton from it took
    steps of 1/256-1/1024 and did not converge in 50 iterations.
    """
    fit = confirmation.fit
    if fit is None:
        return
    half = _half_width_refit(engine, fit, library)
    if half is None or not half[0].ok:
        return
    check = half[0]
    a, k = fit.n_physical, len(fit.slots)
    before, after = fit.coefficients, check.theta[a : a + k]
    se = fit.std_errors[a : a + k]
    with np.errstate(invalid="ignore"):
        moved = (np.abs(after - before) > ARTEFACT_SHARE * np.abs(before)) & (
            np.abs(after - before) > 2.0 * np.where(np.isfinite(se), se, 0.0)
        )
    walls = _walls(fit.slots, before, after, moved)
    if walls:
        moved[walls] = False
        names = " and ".join(describe(fit.slots[j]) for j in walls)
        factor = float(np.median(after[walls] / before[walls]))
        text = (
            f"{names} kept as one flow between states whose rate follows the "
            f"kinks' smoothing (x{sig(factor, 3)} at half the width, the split "
            "between the equations unchanged): the data say it is fast, a wall "
            "such as an overflow, not how fast; the sizes of its coefficients are "
            "lower bounds, not estimates"
        )
        confirmation.log.append(text)
        confirmation.notes.append(text)
    if not np.any(moved):
        return
    keep = [j for j in range(k) if not moved[j]]
    slots = [fit.slots[j] for j in keep]
    for j in np.flatnonzero(moved):
        confirmation.rejected.append(
            (
                fit.slots[j],
                f"its coefficient depends on the smoothing of the kinks "
                f"({sig(before[j])} -> {sig(after[j])} at half the width): it "
                "compensates the integration of a kink, not an effect of the plant",
            )
        )
        confirmation.log.append(
            f"removed {describe(fit.slots[j])}: depends on the kinks' smoothing"
        )
    if not slots:
        confirmation.slots, confirmation.fit = [], None
        return
    theta = np.concatenate([fit.physical, before[keep], fit.offsets])
    refit = engine.fit(slots, theta, fit.x)
    if not refit.converged and x_start is not None:
        again = engine.fit(slots, theta, x_start)
        if again.converged or (again.ok and not refit.ok):
            refit = again
    if refit.ok:
        confirmation.slots, confirmation.fit = slots, refit


# A flow's coefficients at half the width, as multiples of their values at
# the full width, agree to within this ratio when only its rate changed.
WALL_SPLIT = 1.1


def _walls(slots, before, after, moved) -> list:
    """Indices of moved terms that are one flow growing stiffer as a whole.

    A weir or an overflow is a wall: the data say only that water above the
    rim leaves at once, so the fitted rate of ``max(h1 - L, 0)`` is as
    large as the kink's smoothing lets it be, and doubles when the width
    halves. Where the same function is kept in several equations (out of one
    state, into another) and all its coefficients grow by one factor, the
    flow and its split are the data's; only its speed is the smoothing's.
    A term in one equation that moves (a Stribeck bump imitating sticking)
    is still an artefact.
    """
    out = []
    columns = {c for _, c in slots}
    for c in columns:
        idx = [j for j, slot in enumerate(slots) if slot[1] == c]
        if len(idx) < 2 or not all(moved[j] for j in idx):
            continue
        with np.errstate(all="ignore"):
            factors = after[idx] / before[idx]
        if (
            np.all(np.isfinite(factors))
            and np.all(factors > 1.0)
            and factors.max() <= WALL_SPLIT * factors.min()
        ):
            out.extend(idx)
    return sorted(out)


def step_size_check(
    engine: OutputErrorModel, fit: OutputErrorFit, names=None
) -> str | None:
    """Refit with twice the RK4 steps; a note if the answer moves.

    A coefficient that moves by more than half its standard error, or a
    cost that changes by more than one unit (of chi-square), means the
    result depends on the integrator (a stiff or non-smooth model): said so.
    The refit is skipped when its linearised prediction
    (:meth:`OutputErrorModel.integrator_effect`) moves no parameter by a
    tenth of its standard error, and neither the fitted measurements by a
    tenth of the noise nor the cost by a tenth of a chi-square unit (both
    unit-free, so the decision does not depend on the data's units).
    ``names`` (one per entry of ``fit.theta``, offsets may be left out) lets
    the note name the quantities that moved most.
    """
    dtheta, dx = engine.integrator_effect(fit)
    se = fit.std_errors
    # <=: a parameter held at its bound has no standard error and no move
    if dx < 0.1 and np.all(np.abs(dtheta) <= 0.1 * np.where(np.isfinite(se), se, 0.0)):
        return None
    finer = engine.with_substeps(2 * engine.n_substeps)
    check = finer.fit(fit.slots, fit.theta, fit.x, max_iter=20)
    if not check.ok:
        return (
            "the extended model cannot be fitted with a finer integration step "
            f"({check.message}): its result depends on the integrator"
        )
    se = fit.std_errors
    moved = np.abs(check.theta - fit.theta) > 0.5 * np.where(np.isfinite(se), se, 0.0)
    if np.any(moved) or abs(check.cost - fit.cost) > 1.0:
        return (
            "the result changes with the integration step (refitted with twice "
            f"the RK4 steps: cost {fit.cost:.6g} -> {check.cost:.6g}"
            f"{_moved_most(fit.theta, check.theta, se, names)}): the model is "
            "stiff or not smooth at this sampling rate; treat its numbers with care, "
            f"or run the study with discover(n_substeps={2 * engine.n_substeps}) "
            f"(command line: --substeps {2 * engine.n_substeps})"
        )
    return None


@dataclass(frozen=True)
class SmoothingCheck:
    """What refitting with every smoothed kink at half its width showed.

    Attributes
    ----------
    ok : bool
        No coefficient or parameter moved by half a standard error.
    text : str
        The finding, as a note (or the line shown with the extended model).
    misfit_ratio : float or None
        The extended model's misfit beyond the noise at half the width (and
        twice the RK4 steps), as a share of the misfit at the width of the
        fit (RMSE-like: the square root of the ratio of the costs in excess
        of the residuals' count). Below 1 the misfit follows the
        integration of the kinks; None where not measured (the refit failed,
        or the fit is within the noise already).
    """

    ok: bool
    text: str
    misfit_ratio: float | None = None


def smoothing_check(engine, fit, library, describe, names=None):
    """Refit with every smoothed kink at half its width (a :class:`SmoothingCheck`).

    A library that smooths its kinks for the integrators (``widths_``, as
    :class:`~pysindy_mme.PhysicsLibrary` does) must show that the width does
    not move the answer: the fit is repeated with the widths halved and the
    RK4 steps doubled (a narrower kink is a stiffer one), from the fit's
    own trajectory. ``ok`` is False when a coefficient or parameter moves
    by more than half its standard error. None when no kept term is a
    smoothed kink. ``describe(column) -> name``.
    """
    half = _half_width_refit(engine, fit, library)
    if half is None:
        return None
    check, columns = half
    widths = library.widths_
    what = ", ".join(f"{describe(c)} over {sig(widths[c], 2)}" for c in columns)
    if not check.ok:
        return SmoothingCheck(
            False,
            f"kinks integrated smoothed ({what}): the model cannot be fitted at "
            f"half the width ({check.message}); its non-smooth terms depend on "
            "the smoothing",
        )
    ratio = _misfit_ratio(fit, check)
    se = fit.std_errors
    moved = np.abs(check.theta - fit.theta) > 0.5 * np.where(np.isfinite(se), se, 0.0)
    if np.any(moved):
        most = _moved_most(fit.theta, check.theta, se, names)
        return SmoothingCheck(
            False,
            f"kinks integrated smoothed ({what}); at half the width (and twice "
            f"the RK4 steps) the result moves{most}: "
            "treat the non-smooth terms' coefficients with care (PhysicsLibrary("
            "smoothing=...) sets the width)",
            ratio,
        )
    return SmoothingCheck(
        True,
        f"kinks integrated smoothed ({what}, PhysicsLibrary smoothing); refitted "
        "at half the width and twice the RK4 steps, no coefficient or parameter "
        "moved by half a standard error: the width does not change the result",
        ratio,
    )


def _misfit_ratio(fit, check) -> float | None:
    """:attr:`SmoothingCheck.misfit_ratio` of ``fit`` and its refit ``check``.

    A cost is a chi-square in noise units: a model that fits to the noise
    leaves about one unit per residual degree of freedom, ``inflation``
    units with correlated residuals (:attr:`OutputErrorFit.inflation`, as
    the consistency test reads it). What is beyond that is the model's
    misfit; measured only where it is at least as large as the noise's
    share itself (a ratio of two noise-sized numbers says nothing).
    """
    count = fit.inflation * fit.dof
    excess = fit.cost - count
    if not (np.isfinite(excess) and excess >= count and np.isfinite(check.cost)):
        return None
    return float(np.sqrt(max(check.cost - count, 0.0) / excess))


#: the half-width refit of each fit still alive: ``id(fit) -> (weak
#: reference to the fit, library, widths, RK4 steps, result)``. The study
#: refits at half the width twice from the same fit when no term is dropped
#: as a smoothing artefact (step 4 to find artefacts, the report to check
#: the width): the second is the first's answer. (A fit compares by value,
#: so it is no dictionary key; the entry goes when the fit does.)
_HALF_WIDTH: dict = {}


def _half_width_refit(engine, fit, library):
    """``(fit at half the smoothing width, smoothed columns)`` or None.

    With the RK4 steps doubled: a narrower kink is a stiffer one. From the
    fit's own trajectory and values; the library's widths are restored.
    The same fit, library, widths and RK4 steps give the refit made before
    (:data:`_HALF_WIDTH`).
    """
    widths = getattr(library, "widths_", None)
    if widths is None:
        return None
    widths = np.asarray(widths, dtype=float)
    known = _HALF_WIDTH.get(id(fit))
    if (
        known is not None
        and known[0]() is fit
        and known[1] is library
        and np.array_equal(known[2], widths)
        and known[3] == engine.n_substeps
    ):
        return known[4]
    half = _refit_at_half_width(engine, fit, library, widths)
    if known is None:
        weakref.finalize(fit, _HALF_WIDTH.pop, id(fit), None)
    _HALF_WIDTH[id(fit)] = (
        weakref.ref(fit),
        library,
        widths.copy(),
        engine.n_substeps,
        half,
    )
    return half


def _refit_at_half_width(engine, fit, library, widths):
    """:func:`_half_width_refit` without the memory of earlier refits."""
    # overflow terms of states are solved exactly, unsmoothed (core.relaxation)
    split = Overflows(
        fit.slots, overflow_columns_of(engine.features), engine.n_states
    ).positions
    columns = sorted(
        {
            c
            for k, (_, c) in enumerate(fit.slots)
            if k not in split and c < widths.size and widths[c] > 0
        }
    )
    if not columns:
        return None
    saved = widths.copy()
    try:
        library.widths_ = 0.5 * saved
        library._plans = {}  # its cached evaluation plans hold the widths
        finer = engine.with_substeps(2 * engine.n_substeps)
        check = finer.fit(fit.slots, fit.theta, fit.x, max_iter=20)
    finally:
        library.widths_ = saved
        library._plans = {}
    return check, columns


def _moved_most(before, after, se, names, shown=3) -> str:
    """``; y^3 in v' -7.065e+05 -> -7.061e+05 (0.9 se), ...``: the largest
    moves in units of the standard error."""
    k = len(before) if names is None else min(len(names), len(before))
    if k == 0:
        return ""
    with np.errstate(divide="ignore", invalid="ignore"):
        in_se = np.abs(after[:k] - before[:k]) / se[:k]
    in_se = np.where(np.isfinite(in_se), in_se, 0.0)
    parts = []
    for j in np.argsort(-in_se)[:shown]:
        if in_se[j] <= 0:
            break
        name = f"theta[{j}]" if names is None else names[j]
        parts.append(
            f"{name} {sig(before[j])} -> {sig(after[j])} ({sig(in_se[j], 2)} se)"
        )
    return "; " + ", ".join(parts) if parts else ""


def measure_gain(
    study, fits: dict, models: dict, features, substeps, build_extended=None
) -> Gain:
    """Step 5: free runs of both models, in sample and on held-out data.

    ``fits``: ``{"assumed": OutputErrorFit, "extended": OutputErrorFit}``;
    ``models``: the same keys, ``(x, t, u) -> dx/dt`` row-wise, the models
    as printed. Every RMSE is a free run of the model from its fitted
    initial state (never the fit's own trajectory, whose intervals need not
    join when the fit did not converge). Out of sample: the validation
    record when given, else a held-out stretch (:func:`held_out_runs`).
    ``build_extended(fit)``: the extended model at a fit's quantities, for
    the draws that tell whether a validation run's miss is their
    uncertainty (:mod:`~pysindy_mme.protocols.uncertainty`).
    """
    runs = {
        name: in_sample_run(study, fits[name], models[name], substeps)
        for name in ("assumed", "extended")
    }
    gain = Gain(
        channel_names=study.channel_names,
        rmse_assumed=runs["assumed"].rmse,
        rmse_extended=runs["extended"].rmse,
        noise_floor=np.sqrt(np.diag(study.noise_cov)),
        in_sample_runs=runs,
        converged={name: bool(fits[name].converged) for name in runs},
    )
    for name, run in runs.items():
        if run.diverged_at is not None:
            gain.notes.append(
                f"the {name} model's free run from its fitted initial state "
                f"diverged at t = {run.diverged_at:.6g}: it has no in-sample RMSE"
            )
    if study.validation is None:
        return gain
    extended = fits["extended"]
    draws = (
        {"extended": partial(coefficient_draws, extended, build_extended)}
        if build_extended is not None and extended.slots
        else None
    )
    outcome = study.validation_protocol.evaluate(
        ValidationContext(study, models, features, substeps, runs, draws=draws)
    )
    _set_out_of_sample(gain, outcome)
    return gain


def _set_out_of_sample(gain, outcome) -> None:
    """The out-of-sample numbers of a protocol's ``outcome`` on ``gain``."""
    runs, source = outcome.runs, outcome.source
    gain.validation_runs = runs
    gain.validation_rmse_assumed = runs["assumed"].rmse
    gain.validation_rmse_extended = runs["extended"].rmse
    gain.validation_window = outcome.window
    gain.validation_source = source
    gain.validation_method = outcome.method
    gain.held_out_converged = bool(outcome.converged)
    for name, run in runs.items():
        if run.diverged_at is not None:
            gain.notes.append(
                f"the {name} model's free run on {source} diverged at "
                f"t = {run.diverged_at:.6g}: it has no out-of-sample RMSE"
            )
    # the candidate explanation's run only: an assumed model that spreads
    # its start's error is a worse predictor, and the report's gain table
    # marks it (a warning there would be in nearly every study of an
    # unstable or undamped assumed model)
    spread = spread_sentence(gain, "extended")
    if spread is not None:
        gain.notes.append(
            f"{spread}: its out-of-sample RMSE there can measure that estimate "
            "as much as the model. A longer window for the initial state, or "
            "predictions a few samples ahead (KStepAhead), measure the model"
        )


def in_sample_run(study, fit, model, substeps) -> FreeRun:
    """The free run of ``model`` from ``fit``'s initial state over the record.

    Offsets (``offsets=True``) are the fit's; the RMSE is over every
    observed sample. The fit's trajectory is only the guess Newton's method
    starts from: the answer is the model's own simulation.
    """
    measure = measurement_function(study.measurement)
    offsets = _offsets(study, fit)

    def shifted(x):
        return measure(x) + offsets

    guess = np.where(np.isfinite(fit.x), fit.x, 0.0)
    if study.n_records == 1:
        return free_run(
            model, fit.x[0], study.t, study.inputs, substeps, shifted, study.y, 0, guess
        )
    # several records: each run restarts from its record's fitted initial state
    runs = [
        free_run(
            model,
            fit.x[part.start],
            study.t[part],
            study.inputs.subset(part.start, part.stop),
            substeps,
            shifted,
            study.y[part],
            0,
            guess[part],
        )
        for part in study.record_slices
    ]
    pooled = pooled_runs(
        [{"run": r} for r in runs], [study.y[p] for p in study.record_slices]
    )
    run = pooled["run"]
    run.window = None
    run.x0s = [fit.x[p.start] for p in study.record_slices]
    return run


#: the refits without the held-out data stop at this relative predicted
#: decrease of their cost: what is measured on them is a free-run RMSE, which
#: a remaining 0.1 % of the cost moves by about 0.05 %, against the 10 %
#: margin an explanation needs (a large-residual fit of the assumed model,
#: or one of a hysteretic law, creeps toward 1e-9 for hundreds of iterations)
HELD_OUT_TOL = 1e-3


def _refit_without(
    study, keep, window, fits, build_extended, features, substeps, **rest
):
    """Both models refitted on the samples ``keep`` only (an assumed model
    with no parameter or offset is the same model without them): ``(the
    study on them, {"assumed", "extended"} models, both refits converged,
    the extended refit's coefficients' draws)``
    (:func:`~pysindy_mme.protocols.uncertainty.coefficient_draws`).
    ``rest``: further fields of the reduced study (its record breaks)."""
    u = study.u
    reduced = replace(
        study,
        y=study.y[keep],
        t=study.t[keep],
        u=None if u is None else u[keep],
        inputs=study.inputs.subset(keep.start, keep.stop),
        x_init=study.x_init[keep],
        validation_window=window,
        **rest,
    )
    engine = output_error_engine(reduced, features, substeps)
    a, e = fits["assumed"], fits["extended"]
    if a.theta.size:
        refit_a = engine.fit((), a.theta, a.x[keep], tol=HELD_OUT_TOL)
        assumed_model, settled = study.model_at(refit_a.physical), _settled(refit_a)
    else:
        # nothing in the assumed model is fitted (its initial state is the
        # window's, not the fit's): it is the same model without the stretch
        assumed_model, settled = study.model_at(a.physical), True
    if not e.slots:
        models = {"assumed": assumed_model, "extended": assumed_model}
        return reduced, models, settled, None
    refit_e = engine.fit(e.slots, e.theta, e.x[keep], tol=HELD_OUT_TOL)
    models = {"assumed": assumed_model, "extended": build_extended(refit_e)}
    # made only where a run misses beyond the noise (the refit's covariance
    # is a bordered solve over the record)
    draws = {"extended": partial(coefficient_draws, refit_e, build_extended)}
    return reduced, models, settled and _settled(refit_e), draws


def _settled(fit) -> bool:
    """A held-out refit good enough for a free-run RMSE: Gauss-Newton
    stopped at its tolerance. Its trajectory need not join to 1e-6 (the
    free run uses only its initial state and parameters)."""
    return bool(fit.ok and (fit.converged or fit.message.startswith("converged")))


def hold_out(
    study, gain, fits, build_extended, features, substeps, states=None
) -> None:
    """Out-of-sample numbers on ``gain`` from a stretch held out of the
    fitting data (no validation record; nothing when the data cannot spare
    one): the study's :class:`~pysindy_mme.protocols.HeldOut` protocol, both
    models refitted without the stretch by :func:`_refit_without`."""

    def refit_without(keep, window, **rest):
        return _refit_without(
            study, keep, window, fits, build_extended, features, substeps, **rest
        )

    context = ValidationContext(
        study, {}, features, substeps, gain.in_sample_runs, refit_without, states
    )
    outcome = study.validation_protocol.evaluate(context)
    if outcome is not None:
        _set_out_of_sample(gain, outcome)


def _offsets(study, fit):
    return fit.offsets if study.offsets else np.zeros(study.y.shape[1])


#: a free run beyond the data's extreme reading by more than this many noise
#: sd crosses a level the data never pass
OVERSHOOT_SD = 3.0


def overshoots(study, fit, run, model_name) -> list:
    """Levels the data never pass that a free run of the record crosses.

    ``run``: the model's in-sample free run from ``fit``'s initial state.
    Per measured channel and side: the run goes beyond the highest (lowest)
    reading, clipped ones included, by more than ``OVERSHOOT_SD`` noise sd,
    and where it does the data sit at that extreme (most of those samples
    read within ``2 OVERSHOOT_SD`` sd of it: the data level off, or the
    sensor clips, while the model goes on). A model that passes the data's
    range where the data are far from it misses the dynamics, not a limit,
    and is not named here.
    """
    readings = study.readings if study.readings is not None else study.y
    readings = np.asarray(readings, dtype=float)
    with np.errstate(all="ignore"):
        pred = measurement_function(study.measurement)(run.x) + _offsets(study, fit)
    sd = np.sqrt(np.diag(study.noise_cov))
    out = []
    for j, name in enumerate(study.channel_names):
        y, p = readings[:, j], pred[:, j]
        seen = np.isfinite(y)
        if not seen.any():
            continue
        for side, sign in (("ceiling", 1.0), ("floor", -1.0)):
            level = sign * float(np.max(sign * y[seen]))
            with np.errstate(invalid="ignore"):
                beyond = np.isfinite(p) & (sign * (p - level) > OVERSHOOT_SD * sd[j])
                at_extreme = sign * (level - y) <= 2 * OVERSHOOT_SD * sd[j]
            read = beyond & seen
            if not read.any() or 2 * np.sum(read & at_extreme) < np.sum(read):
                continue
            clipped = study.clipped is not None and study.clipped.on(j, side)
            out.append(
                Overshoot(
                    model=model_name,
                    channel=name,
                    side=side,
                    reached=sign * float(np.max(sign * p[beyond])),
                    level=level,
                    clipped=bool(clipped),
                )
            )
    return out
