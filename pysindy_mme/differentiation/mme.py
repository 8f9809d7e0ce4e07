"""Minimum model error (MME) estimation as a pysindy differentiation method.

:class:`MME` takes noisy measurements of some states of a system and an
assumed model ``x' = f(x, u, t)``, and estimates the full state trajectory
and the model error ``d(t)`` that the model needs to follow the data
(Mook and Junkins 1988; Kolodziej and Mook, section II). The weight ``W``
on the model error is set by the paper's covariance constraint (the
measurement-minus-estimate variance equals the noise variance) or by
maximum marginal likelihood. The numerical solver lives in
:mod:`pysindy_mme.smoother`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from pysindy.differentiation import BaseDifferentiation
from sklearn.exceptions import ConvergenceWarning

from ..core.model import as_model_function
from ..core.noise import difference_noise_variance, noise_covariance
from ..core.validation import (
    as_float_array,
    check_indices,
    check_time,
)
from ..exceptions import DivergenceError, UnobservableError
from ..solver.transcription import MMESmoother
from .error_models import ErrorModel, SolverInputs
from .mme_checks import MMEChecks
from .weight import WSearch, channel_ratios

__all__ = ["MME", "MMEProblem", "difference_noise_variance", "noise_covariance"]


@dataclass
class MMEProblem:
    """A checked MME problem (see :meth:`MME.check`).

    Attributes
    ----------
    smoother : MMESmoother
        The solver, set up (``error_model`` applied).
    error_model : ErrorModel
        The prior on ``d``, resolved (a copy of an object, or the model a
        name stands for) and checked.
    W_spec : str or ndarray
        ``"auto"``, ``"ml"`` or the fixed ``(q, q)`` weight.
    noise_covariance : ndarray (m, m)
    n_states : int
    error_states : ndarray of int
    measurement : ndarray (m, n) or callable
        ``C`` of ``y = C x``, or ``g(x)``.
    measurement_jacobian : callable or None
    model : ModelFunction
        The assumed model, checked.
    y, t, u
        The checked data (``u`` as given on the grid, a callable or None).
    noise_diagnostics : list of NoiseDiagnostics or None
        How ``noise_variance="auto"`` found the noise of each channel
        (``determined=False``: quantised at the quantisation level, the noise
        is not known); None when the noise was stated.
    """

    smoother: object
    W_spec: object
    noise_covariance: np.ndarray
    n_states: int
    error_states: np.ndarray
    measurement: object
    measurement_jacobian: object
    model: object
    y: np.ndarray
    t: np.ndarray
    u: object
    noise_diagnostics: object = None
    error_model: ErrorModel = None


class MME(MMEChecks, BaseDifferentiation):
    """Minimum model error estimator (a pysindy differentiation method).

    Model ``x' = f(x, u, t) + E d(t)`` where ``E`` holds the identity
    columns of ``error_states``; measurements ``y_k = g(x(t_k)) + v_k``,
    ``v_k ~ N(0, R)``. The estimate minimises

    ``J = sum_k r_k^T R^-1 r_k + integral d^T W d dt``,  ``r_k = y_k - g(x_k)``

    with ``d`` held constant between samples (zero-order hold). When called
    by pysindy (``SINDy(differentiation_method=MME(...)).fit(y, t)``), ``y``
    holds the measurements only; the full state estimate is stored in
    ``smoothed_x_``, which pysindy then uses as the state, and the returned
    array is the model error (``target="error"``), so SINDy identifies the
    correction to ``f``.

    Parameters
    ----------
    assumed_model : callable, pysindy.SINDy or ExtendedModel
        Vectorised ``f(x, t)`` or ``f(x, t, u)`` with ``x`` of shape
        ``(n_samples, n_states)``, returning the same shape; or any fitted
        model with ``predict(x, u=None)``. Required to fit; None only in an
        MME handed to :func:`discover` as its settings (``mme=MME(W=5.0)``),
        which fills it in.
    n_states : int
        Number of states of the model (required to fit, as above).
    measured : sequence of int, optional
        Indices of the measured states (``y[:, j]`` measures state
        ``measured[j]``). If none of ``measured``, ``measurement_matrix`` and
        ``measurement_function`` is given, all states are measured.
    measurement_matrix : array-like (m, n_states), optional
        Linear measurement ``y = C x``.
    measurement_function : callable, optional
        Nonlinear measurement ``g(x) -> (n_samples, m)``.
    measurement_jacobian : callable, optional
        ``dg/dx(x) -> (n_samples, m, n_states)``; central differences if
        omitted.
    noise_variance : "auto", float, array-like (m,) or (m, m)
        Measurement noise: one variance for every channel, one per channel,
        or a full covariance ``R``. ``"auto"`` estimates a variance per channel
        from the white-noise floor of the data's spectrum
        (:func:`~pysindy_mme.estimate_noise_variance`, which does not take
        fast signal for noise) and warns with the value.
    error_states : sequence of int, optional
        States whose equation has a model error (default: all).
    error_model : str or ErrorModel, default "white"
        The prior on ``d`` (:mod:`~pysindy_mme.differentiation.error_models`),
        an object or the name of a registered one. ``"white"`` (the paper,
        :class:`~.error_models.WhiteNoise`): ``W`` weighs the model error
        itself, ``integral d^T W d dt``, with ``d`` held constant between
        samples; the estimate of ``d`` is as rough as the data allow (for a
        measured position and an error in its acceleration, ``d`` is the
        second derivative of a cubic smoothing spline). ``"random_walk"``
        (:class:`~.error_models.RandomWalk`): ``d`` is a continuous extra
        state and ``W`` weighs its rate, ``integral d'^T W d' dt`` (``d`` a
        random walk, in Kalman-filter terms); the right prior for a smooth
        model error such as a missing term of the state, it gives a markedly
        better ``d`` and a better estimate of unmeasured states (the paper's
        Van der Pol record: ``benchmarks/bench_mme_accuracy.py``), at about
        twice the cost per solve for two states. The registry lists the
        others. Everything else (``W`` tuning, outputs) is the same.
    W : "auto", "ml", float, array-like (q,) or (q, q)
        Weight of the model-error integral (of the rate that drives ``d``
        when the error model makes ``d`` a state). ``"auto"`` (the paper): a
        scalar
        times the identity chosen so that the mean over measured channels of
        ``mean(r_j^2) / R_jj`` (generally ``trace(R^-1 S) / m``) equals 1, the
        covariance constraint. Residuals of a fit that uses ``edf`` degrees of
        freedom have expected square ``R (1 - edf / N)``, so asking for ``R``
        itself smooths somewhat more than needed; and since the ratio is flat
        in W, the sampling scatter of the noise's own variance (about
        ``sqrt(2 / N)``) moves W a lot (on the paper's Van der Pol record,
        0.3 to 22 over 20 noise seeds). ``"ml"``: a scalar maximising the
        restricted marginal likelihood of the data (flat prior on ``x_0``,
        ``d`` white noise of intensity ``W^-1``); stable across noise seeds
        and the principled choice when ``R`` is known and the model error
        really is rough, white-noise-like; for a smooth model error it
        smooths less than the covariance constraint. A number or matrix
        fixes ``W``.
    target : {"error", "derivative"}
        What calling the estimator returns: the model error ``d`` (shape
        ``(n_samples, n_states)``, zero outside ``error_states``), or the
        derivative estimate ``f(x_hat) + E d``.
    u : array-like (n_samples, n_inputs), callable ``u(t)`` or None
        Known inputs on the sample grid (interpolated linearly between
        samples) or as a function of time. pysindy does not pass ``u`` to
        the differentiation method, so it is given here, or to :meth:`fit`
        (which takes precedence).
    input_hold : {"linear", "zoh"}, default "linear"
        How an input array acts between samples: linear interpolation, or
        zero-order hold (``u_k`` on ``[t_k, t_{k+1})``, the way a digital
        signal generator or controller applies it).
    n_substeps : int, default 1
        RK4 steps per sample interval in the discretised dynamics.
    max_iter : int, default 50
        Gauss-Newton iterations per solve.
    tol : float, default 1e-8
        Relative tolerance on the predicted decrease of the cost.
    verbose : bool, default False
        Print the W search.

    Attributes
    ----------
    t_ : ndarray (n_samples,)
        Sample times of the last fit.
    smoothed_x_ : ndarray (n_samples, n_states)
        State estimate.
    d_ : ndarray (n_samples, n_states)
        Model error at the sample times: the mean of the two adjacent
        zero-order-hold values (the first/last interval's value at the ends);
        zero in states without model error.
        With an error model that makes ``d`` a state (``"random_walk"``)
        ``d`` is continuous and ``d_`` holds its values at the sample times.
    d_intervals_ : ndarray (n_samples - 1, q)
        Model error on each interval ``[t_k, t_{k+1}]`` for the error states
        (with ``d`` a state, its mean over the interval).
    derivative_ : ndarray (n_samples, n_states)
        ``f(x_hat, t, u) + E d_`` at the sample times.
    error_model_ : ErrorModel
        The prior used (a copy of ``error_model``, or the model its name
        stands for), with its own fitted attributes if it has any.
    W_ : float or ndarray (q, q)
        The weight used (a float when it is a scalar multiple of the identity).
    W_at_bound_ : bool
        The covariance constraint (or likelihood maximum) could not be met
        within ``[1e-12, 1e12]`` times the data's reference scale; ``W_`` is
        the bound.
    W_history_ : list of (W, value)
        The W search: covariance ratio ("auto") or ``-2 log p(y|W)`` ("ml").
    covariance_ratio_ : ndarray (m,)
        ``mean(r_j^2) / R_jj`` per measured channel (observed samples only).
    residuals_ : ndarray (n_samples, m)
        ``y - g(x_hat)``; NaN where ``y`` is missing.
    noise_variance_ : ndarray (m, m)
        The noise covariance ``R`` used.
    cost_ : float
        ``J`` at the solution.
    log_likelihood_ : float
        Restricted log marginal likelihood ``log p(y | W)`` (Laplace
        approximation for nonlinear models), up to the flat prior on ``x_0``.
    converged_ : bool
        Whether the final Gauss-Newton solve (and every solve of the W
        search) converged.
    n_iter_ : int
        Gauss-Newton iterations of the final solve.
    n_iter_total_ : int
        Gauss-Newton iterations over the whole fit, W search included.
    max_defect_ : float
        Largest dynamics defect of the discretised solution.

    Notes
    -----
    pysindy calls the differentiation method once per trajectory; the
    attributes describe the last call. Each call starts from scratch (the
    W search from the reference scale), so the result does not depend on
    what the estimator fitted before: the same inputs give bit-identical
    results. The data may be in any units, each state in its own: the
    solver works internally in one unit per state and per channel (about
    the noise standard deviation, :mod:`~pysindy_mme.solver.units`),
    and every attribute is in the data's units.
    Missing measurements (NaN) are allowed when calling :meth:`fit` directly
    (pysindy's own input checks reject NaN); every measured channel needs at
    least 2 observed values. Irregular sampling is fine.

    Errors: ``ValueError``/``TypeError`` naming the argument for bad input
    (checked before any long computation), including states that no
    measurement can see (found structurally up front, or numerically when
    the estimation problem turns out singular, naming the unseen direction:
    :class:`~pysindy_mme.UnobservableError`, a ``ValueError``);
    :class:`~pysindy_mme.smoother.DivergenceError` (a ``FloatingPointError``)
    if the assumed model blows up between samples or amplifies perturbations
    a million-fold within one sample interval along the estimate (unstable
    or stiff at the sampling rate); ``ConvergenceWarning`` if Gauss-Newton
    stops early.
    """

    def __init__(
        self,
        assumed_model=None,
        n_states=None,
        measured=None,
        measurement_matrix=None,
        measurement_function=None,
        measurement_jacobian=None,
        noise_variance="auto",
        error_states=None,
        error_model="white",
        W="auto",
        target="error",
        u=None,
        input_hold="linear",
        n_substeps=1,
        max_iter=50,
        tol=1e-8,
        verbose=False,
    ):
        self.assumed_model = assumed_model
        self.n_states = n_states
        self.measured = measured
        self.measurement_matrix = measurement_matrix
        self.measurement_function = measurement_function
        self.measurement_jacobian = measurement_jacobian
        self.noise_variance = noise_variance
        self.error_states = error_states
        self.error_model = error_model
        self.W = W
        self.target = target
        self.u = u
        self.input_hold = input_hold
        self.n_substeps = n_substeps
        self.max_iter = max_iter
        self.tol = tol
        self.verbose = verbose

    # ------------------------------------------------------------- pysindy
    def _differentiate(self, x, t=1.0):
        """Fit to the measurements ``x`` and return ``d`` or ``dx/dt``."""
        self.fit(x, t)
        return self.d_ if self.target == "error" else self.derivative_

    def extended_model(self, sindy_model, assumed_equations=None, check=True):
        """The assumed model plus the correction ``sindy_model`` learned.

        ``sindy_model`` is a ``pysindy.SINDy`` fitted with this estimator as
        its differentiation method (so it holds the correction only); see
        :func:`~pysindy_mme.differentiation.sindy_route.extended_model_from_sindy`
        (and prefer :func:`~pysindy_mme.discover`, which refits the terms to
        the measurements, when the coefficients matter).
        """
        from .sindy_route import extended_model_from_sindy

        return extended_model_from_sindy(self, sindy_model, assumed_equations, check)

    # ----------------------------------------------------------------- fit
    def fit(self, y, t=1.0, u=None, starts=None, x_guess=None):
        """Estimate the states and the model error from measurements.

        Parameters
        ----------
        y : array-like (n_samples, m) or (n_samples,)
            Measurements; NaN marks a missing value.
        t : float or array-like (n_samples,)
            Time step or strictly increasing sample times.
        u : array-like (n_samples, n_inputs), callable or None
            Inputs; overrides the constructor's ``u``.
        starts : sequence of int, optional
            Several records concatenated on one sample axis: the samples
            where a new record starts. Each record has its own initial state
            and no model error links it to the one before; ``t`` need only
            increase within each record.
        x_guess : array-like (n_samples, n_states), optional
            The trajectory Gauss-Newton starts from (default: the measured
            states interpolated, the unmeasured ones at zero). Give one where
            the model depends on every state when an unmeasured state at
            zero sits where the model is flat in it (an empty tank under a
            square-root outflow): there the problem is singular
            (:class:`~pysindy_mme.UnobservableError`). Only the start: the
            estimate is the solution the iterations reach from it.

        Returns
        -------
        self
        """
        problem = self.check(y, t, u, starts, x_guess)
        smoother = problem.smoother

        def solve(W, start):
            return self._solve(smoother, W, start)

        search = problem.error_model.search(
            smoother, problem.W_spec, solve, self.verbose
        )
        self._store(problem, search)
        return self

    def check(self, y, t=1.0, u=None, starts=None, x_guess=None) -> MMEProblem:
        """Check the settings against the data and set up the solver.

        Everything :meth:`fit` checks, without solving (the cost is one
        evaluation of the model on the initial guess): bad input raises here,
        before any long computation. ``noise_variance="auto"`` is estimated
        (and warned about) here.

        Returns
        -------
        MMEProblem
        """
        n = self._check_settings()
        error_model = self._check_error_model()
        model = as_model_function(self.assumed_model, n, name="assumed_model")
        if model.n_states != n:
            raise ValueError(
                f"assumed_model is a ModelFunction for {model.n_states} states but "
                f"n_states = {n}"
            )
        y = self._check_measurements(y)
        N, m = y.shape
        starts = self._check_starts(starts, N)
        if starts.size and np.ndim(t) == 1:
            bounds = [0, *starts.tolist(), N]
            t = np.asarray(t, dtype=float)
            if t.size != N:
                raise ValueError(
                    f"t has {t.size} entries but the data have {N} samples"
                )
            for a, b in zip(bounds[:-1], bounds[1:]):
                check_time(t[a:b], b - a, "t")
        else:
            t = check_time(t, N, "t")
        measurement, g_jac = self._measurement_model(n, m)
        R, noise_diagnostics = self._noise_of_records(y, t, m, starts)
        es = (
            np.arange(n)
            if self.error_states is None
            else check_indices(self.error_states, n, "error_states")
        )
        W_spec = self._W_spec(es.size)
        u = self._check_inputs(u, N, model)
        guess = self._check_guess(x_guess, N, n)

        def make_smoother(model, error_states, measurement, measurement_jacobian):
            x_init = None
            if guess is not None:
                # a coloured error model's own states (appended) start at zero
                extra = np.zeros((N, model.n_states - n))
                x_init = np.hstack([guess, extra]) if extra.size else guess
            return MMESmoother(
                model,
                y,
                t,
                R,
                error_states,
                measurement,
                measurement_jacobian=measurement_jacobian,
                u=u,
                n_substeps=int(self.n_substeps),
                max_iter=int(self.max_iter),
                tol=float(self.tol),
                input_hold=self.input_hold,
                starts=starts,
                x_init=x_init,
            )

        base = make_smoother(model, es, measurement, g_jac)
        self._check_first_evaluation(base, model, measurement, es)
        smoother = error_model.smoother(
            SolverInputs(
                base=base,
                model=model,
                error_states=es,
                measurement=measurement,
                measurement_jacobian=g_jac,
                build=make_smoother,
            )
        )
        return MMEProblem(
            smoother=smoother,
            W_spec=W_spec,
            noise_covariance=R,
            n_states=n,
            error_states=es,
            measurement=measurement,
            measurement_jacobian=g_jac,
            model=model,
            y=y,
            t=t,
            u=u,
            noise_diagnostics=noise_diagnostics,
            error_model=error_model,
        )

    @staticmethod
    def _check_starts(starts, N) -> np.ndarray:
        """The samples where a new record starts, checked (sorted, unique)."""
        if starts is None:
            return np.zeros(0, dtype=int)
        arr = np.unique(np.asarray(starts, dtype=int).ravel())
        bounds = np.concatenate([[0], arr, [N]])
        if arr.size and (arr[0] < 2 or arr[-1] > N - 2 or np.any(np.diff(bounds) < 2)):
            raise ValueError(
                f"starts must split the {N} samples into records of at least 2 "
                f"samples each, got {np.asarray(starts).tolist()}"
            )
        return arr

    def _noise_of_records(self, y, t, m, starts):
        """:meth:`_noise` pooled over the records (weighted by their samples)."""
        if not starts.size or not isinstance(self.noise_variance, str):
            return self._noise(y, t, m)
        bounds = [0, *starts.tolist(), y.shape[0]]
        parts = [
            self._noise(y[a:b], t[a:b], m) for a, b in zip(bounds[:-1], bounds[1:])
        ]
        weights = np.diff(bounds) / y.shape[0]
        R = sum(w * np.asarray(r, dtype=float) for w, (r, _) in zip(weights, parts))
        longest = int(np.argmax(np.diff(bounds)))
        return R, parts[longest][1]

    @staticmethod
    def _check_guess(x_guess, N, n):
        """``x_guess`` checked and copied (None stays None)."""
        if x_guess is None:
            return None
        guess = as_float_array(x_guess, "x_guess", ndim=2)  # a copy, finite
        if guess.shape != (N, n):
            raise ValueError(
                f"x_guess must have shape (n_samples, n_states) = ({N}, {n}), got "
                f"{guess.shape}"
            )
        return guess

    # ------------------------------------------------------------- solving
    def _solve(self, smoother, W, start):
        try:
            return smoother.solve(W, start)
        except DivergenceError:
            raise
        except np.linalg.LinAlgError as exc:
            raise UnobservableError(
                f"{exc}. Check measured / measurement_matrix and error_states; "
                "if the states are observable elsewhere, the model may be flat in "
                "an unmeasured state along this trajectory (a square-root outflow "
                "at an empty tank, a dead zone): start from a trajectory where it "
                "is not (MME.fit(..., x_guess=...))."
            ) from None

    # -------------------------------------------------------------- output
    def _store(self, problem: MMEProblem, search: WSearch):
        smoother, n = problem.smoother, problem.n_states
        res = search.result
        x = res.x[:, :n]
        reading = problem.error_model.read(smoother, res, n)
        d_full = np.zeros((smoother.N, n))
        d_full[:, problem.error_states] = reading.d
        self.t_ = smoother.t.copy()
        self.smoothed_x_ = x
        self.d_ = d_full
        self.d_intervals_ = reading.d_intervals
        self.derivative_ = reading.model(x, smoother.t, smoother.u_grid()) + d_full
        self.error_model_ = problem.error_model
        self.W_ = search.W
        self.W_at_bound_ = bool(search.at_bound)
        self.W_history_ = search.history
        self.covariance_ratio_ = channel_ratios(res, smoother)
        self.residuals_ = res.residuals
        self.noise_variance_ = problem.noise_covariance
        self.cost_ = res.cost
        self.log_likelihood_ = -0.5 * res.neg2_log_likelihood
        self.n_iter_ = res.n_iter
        self.n_iter_total_ = int(search.n_iter)
        self.max_defect_ = res.max_defect
        self.converged_ = bool(res.converged and search.converged)
        if not self.converged_:
            warnings.warn(
                "MME: Gauss-Newton did not converge "
                f"({res.message if not res.converged else 'during the W search'}"
                f"; {res.n_iter} iterations, max_iter = {self.max_iter}); the "
                "estimate may be inaccurate. Increase max_iter or check the "
                "assumed model.",
                ConvergenceWarning,
                stacklevel=3,
            )
