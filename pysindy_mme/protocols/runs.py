"""Free runs scored against a record: what every validation protocol returns.

A :class:`FreeRun` is a model simulated from an initial state and scored
against the measurements (RMSE per channel over the samples it is scored
on). :func:`window_runs` is the benchmarks' protocol on one record: each
model's initial state fitted to the record's leading window only (an
output-error fit of the initial state and the offsets, no parameters), then
the model runs free over the record.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np
from sklearn.base import clone

from ..core.integrate import InputSignal, simulate_guided
from ..core.model import AsBase
from ..exceptions import DivergenceError, UnobservableError
from ..solver.output_error import OutputErrorModel
from .spread import (
    determined_until,
    noise_covariance_of,
    run_spread,
    spread_columns,
    start_covariance_of,
)
from .uncertainty import AT_THE_NOISE, MissColumns, RunUncertainty

__all__ = [
    "FreeRun",
    "free_run",
    "measurement_function",
    "observed_window",
    "pooled_runs",
    "rmse",
    "window_runs",
]


def rmse(y, y_hat) -> np.ndarray:
    """RMSE per channel over observed samples; inf if a prediction is not finite."""
    y = np.asarray(y, dtype=float)
    y_hat = np.asarray(y_hat, dtype=float)
    observed = np.isfinite(y)
    out = np.empty(y.shape[1])
    for j in range(y.shape[1]):
        obs = observed[:, j]
        pred = y_hat[obs, j]
        out[j] = (
            np.inf
            if not np.all(np.isfinite(pred))
            else float(np.sqrt(np.mean((y[obs, j] - pred) ** 2)))
        )
    return out


@dataclass
class FreeRun:
    """A free-run simulation of one model on a record.

    Attributes
    ----------
    x0 : ndarray (n,)
        Initial state (fitted to the record, or to its leading window).
    x : ndarray (N, n)
        The simulation (NaN after a divergence; for k-step-ahead predictions,
        NaN where nothing was predicted).
    rmse : ndarray (m,)
        Over the samples scored; inf when the run diverged.
    diverged_at : float or None
        Time at which the run left the bound, if it did.
    model : callable
        The model that ran, ``(x, t, u) -> dx/dt`` (as printed).
    window : int or None
        Leading samples the initial state was estimated from (None for an
        in-sample run); longer than asked when readings in it were clipped
        or missing.
    """

    x0: np.ndarray
    x: np.ndarray
    rmse: np.ndarray
    diverged_at: float | None = None
    model: object = None
    window: int | None = None
    #: with several records: each record's own run (``rmse`` is pooled)
    records: list | None = None
    #: with several fitting records: each record's fitted initial state
    x0s: list | None = None
    #: k-step-ahead predictions: the sample each prediction starts from (its
    #: initial state, in ``x0s``, fitted to the ``window`` samples before it)
    starts: list | None = None
    #: k-step-ahead predictions: samples predicted from each start (``k``)
    horizon: int | None = None
    #: a run from a window's estimate: the first scored time at which the
    #: spread its initial state's standard error causes passes the noise
    #: (:mod:`.spread`; None: determined throughout, or not measured)
    determined_until: float | None = None
    #: on data the model was not fitted to: whether its miss is the
    #: uncertainty of its coefficients and start (:mod:`.uncertainty`; None:
    #: not measured, the run at the noise or no coefficients' draws given)
    uncertainty: RunUncertainty | None = None


def free_run(model, x0, t, inputs: InputSignal, substeps, measure, y, window, guess):
    """Simulate from ``x0`` over ``t``; RMSE of ``measure(x)`` after ``window``.

    ``model(x (K, n), t (K,), u (K, m) or None) -> dx/dt``. The run is the
    exact RK4 free run from ``x0``, computed for the whole record at once
    from ``guess`` (a state estimate of the record: it only speeds Newton's
    method up, the answer does not depend on it; see
    :func:`~pysindy_mme.core.integrate.simulate_guided`). The bound is 1e6
    times the larger of the data's and the initial state's magnitude.
    """
    scale = max(float(np.nanmax(np.abs(y))), float(np.max(np.abs(x0))), 1e-300)
    sim = simulate_guided(model, x0, t, inputs, substeps, guess, bound=1e6 * scale)
    x = sim.x[0]
    at = int(sim.diverged_at[0])
    err = rmse(y[window:], measure(x)[window:])
    return FreeRun(
        x0=x0,
        x=x,
        rmse=err,
        diverged_at=None if at < 0 else float(t[at]),
        model=model,
    )


def pooled_runs(per_record: list, ys: list) -> dict:
    """One :class:`FreeRun` per model from its runs on several records.

    ``x`` is the records' runs one after the other, ``x0`` the first
    record's initial state, ``records`` the runs themselves, and ``rmse``
    pooled over the records: the root of the mean squared error over every
    sample each run scores (after its window), all records together. A run
    that diverged on any record has no pooled RMSE (inf).
    """
    out = {}
    for name in per_record[0]:
        runs = [r[name] for r in per_record]
        sq = np.zeros(ys[0].shape[1])
        count = np.zeros(ys[0].shape[1])
        for run, y in zip(runs, ys):
            seen = _scored(run, y).sum(axis=0)
            # each record's RMSE times its count is its sum of squares
            sq += np.asarray(run.rmse, float) ** 2 * seen
            count += seen
        with np.errstate(all="ignore"):
            pooled = np.sqrt(sq / np.maximum(count, 1))
        diverged = [r.diverged_at for r in runs if r.diverged_at is not None]
        spread = [r.determined_until for r in runs if r.determined_until is not None]
        out[name] = FreeRun(
            x0=runs[0].x0,
            x=np.vstack([r.x for r in runs]),
            rmse=np.where(np.isfinite(pooled), pooled, np.inf),
            diverged_at=diverged[0] if diverged else None,
            model=runs[0].model,
            window=runs[0].window,
            records=runs,
            # the earliest of the records' (each record's in ``records``)
            determined_until=min(spread) if spread else None,
        )
    return out


def _scored(run: FreeRun, y) -> np.ndarray:
    """Which readings of ``y`` the run's RMSE is over (boolean, like ``y``)."""
    y = np.asarray(y, float)
    seen = np.isfinite(y)
    if run.starts is not None:  # k-step-ahead: the predicted samples only
        return seen & np.isfinite(run.x[:, :1])
    seen[: run.window or 0] = False
    return seen


def measurement_function(C):
    """``x -> y`` of a measurement: a matrix ``C`` or a callable."""
    if callable(C):
        return lambda x: np.asarray(C(np.atleast_2d(x)), dtype=float)
    return lambda x: np.asarray(x) @ np.asarray(C).T


def observed_window(window, y) -> int:
    """Leading samples holding ``window`` readings (rows with a finite
    reading), at most all but one: a window of censored (clipped) or missing
    readings is lengthened until the initial state has ``window`` to go by."""
    seen = np.cumsum(np.any(np.isfinite(np.asarray(y, float)), axis=1))
    reach = int(np.searchsorted(seen, window)) + 1  # rows up to the window-th
    return int(min(max(window, reach), y.shape[0] - 1))


def record_guess(study, record):
    """A state estimate of ``record`` (MME with the study's settings): where
    the window fits start and the guess Newton's method starts the free runs
    from (the runs themselves depend on the window only). A study that has
    one already (``states_guess``: a stretch of its own record) gives it."""
    y_v, t_v, u_v = record
    known = getattr(study, "states_guess", None)
    if known is not None and np.shape(known) == (len(t_v), study.n_states):
        return np.asarray(known, dtype=float)
    estimate = clone(study.mme).set_params(u=u_v)
    with warnings.catch_warnings():
        # an internal start-up estimate: its notes are not about the user's study
        warnings.simplefilter("ignore")
        try:
            estimate.fit(y_v, t_v)
        except (DivergenceError, UnobservableError):
            # The guessed model can be stiff or flat near this record's
            # estimate (a square-root outflow at an empty tank) where it was
            # not on the fitting record. The guess only starts the window
            # fits and Newton's free runs (their answers do not depend on
            # it): the data's own start serves, measured states
            # interpolated and the unmeasured ones at zero.
            smoother = estimate.check(y_v, t_v).smoother
            return np.asarray(smoother.initial_guess()[0][:, : study.n_states])
    return np.asarray(estimate.smoothed_x_)


def run_guess(study, name: str, guess):
    """Where Newton's method starts model ``name``'s free run: the study's
    own run of that model over the record (``run_guesses``) when it has one
    of the record's shape, finite throughout, else ``guess`` (a state
    estimate). Either gives the same run (:func:`free_run`)."""
    own = (getattr(study, "run_guesses", None) or {}).get(name)
    if own is None:
        return guess
    own = np.asarray(own, dtype=float)
    if own.shape != np.shape(guess) or not np.all(np.isfinite(own)):
        return guess
    return own


def window_fit(study, model_rhs, features, substeps, y, t, inputs, guess):
    """``(x0, offsets)`` of ``model_rhs`` fitted to the window ``y`` (an
    output-error fit of the initial state and, with ``study.offsets``, the
    measurement offsets; nothing else)."""
    return _start(
        study, _window_fit(study, model_rhs, features, substeps, y, t, inputs, guess)
    )


def _start(study, fit):
    """``(x0, offsets)`` of a window fit."""
    return fit.x[0], (fit.offsets if study.offsets else 0.0)


def _window_fit(study, model_rhs, features, substeps, y, t, inputs, guess):
    """The output-error fit behind :func:`window_fit`."""
    m_off = y.shape[1] if study.offsets else 0
    return OutputErrorModel(
        AsBase(model_rhs),
        study.n_states,
        features,
        y,
        t,
        inputs,
        study.noise_cov,
        study.measurement,
        n_offsets=m_off,
        n_substeps=substeps,
    ).fit((), np.zeros(m_off), guess)


#: a window whose fitted initial state has a standard error (from the noise
#: alone) larger than this share of some state's spread over the record has
#: not determined it at all (the paper's Van der Pol case at 40 Hz, 50
#: samples: 3-9 % depending on the record; the same 50 samples at 4 kHz
#: 300 %, and at 100 kHz a study started its free runs from a velocity of
#: -88 where the record's was about -2) ...
X0_UNDETERMINED = 1.0
#: ... and is then doubled until that share is at most this (or a fifth of
#: the record). Not a test that the run does not depend on its initial state:
#: on an attracting cycle the share stops falling (the data forget the
#: initial state's contracting part, and so does the run), which is why a
#: window that determines the state only to 9 % is kept; the run's own
#: sensitivity to the initial state would be the measure (not computed)
X0_RELATIVE_SE = 0.05


def _x0_relative_se(fit, spread) -> float:
    """The largest standard error of ``fit``'s initial state over the
    states' ``spread`` (inf where it is not determined)."""
    # the noise's share only: a model's misfit is its own
    cov = noise_covariance_of(fit)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    seen = np.isfinite(spread) & (spread > 0)
    rel = np.where(np.isfinite(np.diag(cov)), se, np.inf)[seen] / spread[seen]
    return float(np.max(rel, initial=0.0))


def determined_window(study, models, features, substeps, record, inputs, guess, window):
    """``(window, {name: (x0, offsets)}, {name: x0 covariance})``: the
    leading window, each model's initial state and offsets fitted to it, and
    that state's covariance from the noise alone
    (:func:`.spread.noise_covariance_of`). A window that leaves some model's
    initial state undetermined (:data:`X0_UNDETERMINED`) is doubled until it
    determines them all to :data:`X0_RELATIVE_SE`, up to a fifth of the
    record.

    A window of a fixed number of samples is a fixed share of a period only
    at one sampling rate: at a high rate it sees a sliver of the motion, and
    the unmeasured states fitted to it are noise (the free runs then score
    their initial state, not the model).
    """
    y_v, t_v, _ = record
    spread = np.nanstd(np.asarray(guess, dtype=float), axis=0)
    longest = max(window, observed_window(y_v.shape[0] // 5, y_v))

    def fitted(w):
        return {
            name: _window_fit(
                study,
                model_rhs,
                features,
                substeps,
                y_v[:w],
                t_v[:w],
                inputs.subset(0, w),
                guess[:w],
            )
            for name, model_rhs in models.items()
        }

    fits = fitted(window)
    worst = max(_x0_relative_se(f, spread) for f in fits.values())
    if worst > X0_UNDETERMINED:
        while worst > X0_RELATIVE_SE and window < longest:
            longer = min(observed_window(2 * window, y_v), longest)
            try:
                # a model that cannot follow a longer stretch (it diverges,
                # or the stretch leaves a state unobservable) keeps the
                # window it could follow
                longer_fits = fitted(longer)
            except (DivergenceError, UnobservableError, np.linalg.LinAlgError):
                break
            window, fits = longer, longer_fits
            worst = max(_x0_relative_se(f, spread) for f in fits.values())
    starts = {name: _start(study, f) for name, f in fits.items()}
    return window, starts, {name: noise_covariance_of(f) for name, f in fits.items()}


def window_runs(study, models: dict, features, substeps, record, window) -> dict:
    """Initial state from the leading ``window`` samples (lengthened where
    they do not determine it: :func:`determined_window`), then a free run,
    per model; RMSE over the samples after the window.

    ``study`` is read for ``mme``, ``inputs.hold``, ``measurement``,
    ``noise_cov``, ``n_states`` and ``offsets``; ``record`` is ``(y, t, u)``.
    """
    y_v, t_v, u_v = record
    window = observed_window(window, y_v)
    inputs_v = InputSignal(u_v, t_v, study.inputs.hold)
    measure = measurement_function(study.measurement)
    guess = record_guess(study, record)
    window, starts, x0_covs = determined_window(
        study, models, features, substeps, record, inputs_v, guess, window
    )
    noise_sd = np.sqrt(np.diag(np.atleast_2d(study.noise_cov)))
    runs = {}
    for name, model_rhs in models.items():
        x0, offsets = starts[name]

        def shifted(x, offsets=offsets):
            return measure(x) + offsets

        runs[name] = free_run(
            model_rhs,
            x0,
            t_v,
            inputs_v,
            substeps,
            shifted,
            y_v,
            window,
            run_guess(study, name, guess),
        )
        runs[name].window = window
        if runs[name].diverged_at is None:
            spread = run_spread(
                model_rhs,
                runs[name].x,
                t_v,
                inputs_v,
                substeps,
                shifted,
                x0_covs[name],
            )
            runs[name].determined_until = determined_until(
                spread, noise_sd, t_v, window
            )
    return runs


def measure_uncertainty(
    study, runs, models, draws, features, substeps, record, *, every=False
) -> None:
    """Set ``runs[name].uncertainty`` for each ``name`` in ``draws``: whether
    that window run's miss of ``record`` is the uncertainty of its model's
    coefficients and start (:mod:`.uncertainty`).

    ``draws``: ``{name: make}``, ``make()`` the models ``models[name]`` at
    its coefficients moved one standard deviation along each eigenvector of
    their covariance (:func:`.uncertainty.coefficient_draws`; None: not
    measured), called only for a run that is measured. Measured where the
    run misses by more than
    :data:`.uncertainty.AT_THE_NOISE` times the noise (``every``: whatever
    it misses by, a record whose run is pooled with others', the pool's
    miss judged: its columns are kept for that); a run that diverged has no
    miss to judge.
    """
    noise_sd = np.sqrt(np.diag(np.atleast_2d(study.noise_cov)))
    for name, make in (draws or {}).items():
        run = runs.get(name)
        if run is None or run.diverged_at is not None:
            continue
        if not every and at_the_noise(run.rmse, noise_sd):
            continue  # a run at the noise needs no explaining (nor the runs)
        models_at_draws = make()
        if models_at_draws is None:
            continue
        columns = miss_columns(
            study, run, models[name], models_at_draws, features, substeps, record
        )
        found = columns.uncertainty(run.rmse)
        # the columns are kept only to be pooled: a result keeps the numbers
        # (the columns are the record's size times the directions)
        run.uncertainty = found if every else replace(found, columns=None)


def miss_columns(study, run, model, models_at_draws, features, substeps, record):
    """The :class:`.uncertainty.MissColumns` of ``run`` (a run of ``model``
    from its window, :func:`window_runs`): each draw's run, its start fitted
    to the same window, minus ``run`` in the measured channels, and the
    start's (and the offsets') covariance carried along the run, over the
    scored samples. The window is fitted again for the start's covariance
    (from the run itself: the same start, without a state estimate of the
    record)."""
    y_v, t_v, u_v = record
    w = run.window
    inputs = InputSignal(u_v, t_v, study.inputs.hold)
    measure = measurement_function(study.measurement)
    m_off = y_v.shape[1] if study.offsets else 0

    def fitted(rhs):
        return _window_fit(
            study,
            rhs,
            features,
            substeps,
            y_v[:w],
            t_v[:w],
            inputs.subset(0, w),
            run.x[:w],
        )

    own = fitted(model)
    offsets = own.offsets if study.offsets else 0.0

    def shifted(x, offsets=offsets):
        return measure(x) + offsets

    nominal = shifted(run.x)[w:]
    changes = []
    for drawn in models_at_draws:
        try:
            x0, off = _start(study, fitted(drawn))
        except (DivergenceError, UnobservableError, np.linalg.LinAlgError):
            changes.append(np.full_like(nominal, np.inf))
            continue

        def at_draw(x, off=off):
            return measure(x) + off

        moved = free_run(drawn, x0, t_v, inputs, substeps, at_draw, y_v, w, run.x)
        if moved.diverged_at is not None:
            changes.append(np.full_like(nominal, np.inf))
        else:
            changes.append(at_draw(moved.x)[w:] - nominal)
    cov = start_covariance_of(own, m_off)
    start = np.empty(run.x.shape[:1] + (nominal.shape[1], cov.shape[0]))
    for rows, HZ in spread_columns(model, run.x, t_v, inputs, substeps, shifted, cov):
        start[rows] = HZ
    observed = np.isfinite(np.asarray(y_v, float)[w:])
    noise_sd = np.sqrt(np.diag(np.atleast_2d(study.noise_cov)))
    return MissColumns(changes, start[w:], observed, noise_sd)


def at_the_noise(rmse, noise_sd) -> bool:
    """The RMSE is within :data:`.uncertainty.AT_THE_NOISE` of the noise,
    combined over channels."""
    ratio = np.asarray(rmse, float) / np.asarray(noise_sd, float)
    return bool(np.sqrt(np.mean(ratio**2)) <= AT_THE_NOISE)
