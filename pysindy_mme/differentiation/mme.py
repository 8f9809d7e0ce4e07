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

from ..core.integrate import HOLDS
from ..core.model import as_model_function
from ..core.noise import estimate_noise_variance
from ..core.tables import sig
from ..core.validation import (
    as_float_array,
    check_finite,
    check_indices,
    check_positive_number,
    check_time,
)
from ..exceptions import DivergenceError
from .noise import difference_noise_variance, noise_covariance
from .observability import unobservable_states
from .random_walk import RandomWalkModel, random_walk_problem
from .transcription import MMESmoother
from .weight import WSearch, channel_ratios, search_W

__all__ = ["MME", "MMEProblem", "difference_noise_variance", "noise_covariance"]


@dataclass
class MMEProblem:
    """A checked MME problem (see :meth:`MME.check`).

    Attributes
    ----------
    smoother : MMESmoother
        The solver, set up (``error_model`` applied).
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


class MME(BaseDifferentiation):
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
        model with ``predict(x, u=None)``.
    n_states : int
        Number of states of the model.
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
    error_model : {"white", "random_walk"}, default "white"
        What ``W`` penalises. ``"white"`` (the paper): the model error itself,
        ``integral d^T W d dt``, with ``d`` held constant between samples; the
        estimate of ``d`` is as rough as the data allow (for a measured
        position and an error in its acceleration, ``d`` is the second
        derivative of a cubic smoothing spline). ``"random_walk"``: ``d`` is a
        continuous extra state and ``W`` weighs its rate,
        ``integral d'^T W d' dt`` (``d`` a random walk, in Kalman-filter
        terms); the right prior for a smooth model error such as a missing
        term of the state, it gives a markedly better ``d`` and a better
        estimate of unmeasured states (the paper's Van der Pol record:
        ``benchmarks/bench_mme_accuracy.py``), at about twice the cost per solve for
        two states. Everything else (``W`` tuning, outputs) is the same.
    W : "auto", "ml", float, array-like (q,) or (q, q)
        Weight of the model-error integral (of its rate with
        ``error_model="random_walk"``). ``"auto"`` (the paper): a scalar
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
        With ``error_model="random_walk"`` ``d`` is continuous and
        ``d_`` holds its values at the sample times.
    d_intervals_ : ndarray (n_samples - 1, q)
        Model error on each interval ``[t_k, t_{k+1}]`` for the error states
        (with ``error_model="random_walk"``, its mean over the interval).
    derivative_ : ndarray (n_samples, n_states)
        ``f(x_hat, t, u) + E d_`` at the sample times.
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
    results. The data may be in any units: the solver works internally in
    units of (a power of two near) the noise standard deviation, and every
    attribute is in the data's units.
    Missing measurements (NaN) are allowed when calling :meth:`fit` directly
    (pysindy's own input checks reject NaN); every measured channel needs at
    least 2 observed values. Irregular sampling is fine.

    Errors: ``ValueError``/``TypeError`` naming the argument for bad input
    (checked before any long computation), including states that no
    measurement can see (found structurally up front, or numerically when
    the estimation problem turns out singular, naming the unseen direction);
    :class:`~pysindy_mme.smoother.DivergenceError` (a ``FloatingPointError``)
    if the assumed model blows up between samples or amplifies perturbations
    a million-fold within one sample interval along the estimate (unstable
    or stiff at the sampling rate); ``ConvergenceWarning`` if Gauss-Newton
    stops early.
    """

    def __init__(
        self,
        assumed_model,
        n_states,
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
    def fit(self, y, t=1.0, u=None):
        """Estimate the states and the model error from measurements.

        Parameters
        ----------
        y : array-like (n_samples, m) or (n_samples,)
            Measurements; NaN marks a missing value.
        t : float or array-like (n_samples,)
            Time step or strictly increasing sample times.
        u : array-like (n_samples, n_inputs), callable or None
            Inputs; overrides the constructor's ``u``.

        Returns
        -------
        self
        """
        problem = self.check(y, t, u)
        smoother, W_spec, R, n = (
            problem.smoother,
            problem.W_spec,
            problem.noise_covariance,
            problem.n_states,
        )

        def solve(W, start):
            return self._solve(smoother, W, start)

        if isinstance(W_spec, str):
            search = search_W(smoother, W_spec, solve, self.verbose)
        else:
            res = solve(W_spec, None)
            scalar = np.allclose(W_spec, W_spec[0, 0] * np.eye(W_spec.shape[0]))
            search = WSearch(
                result=res,
                W=float(W_spec[0, 0]) if scalar else W_spec,
                n_iter=res.n_iter,
                converged=res.converged,
            )
        self._store(smoother, search, R, n)
        return self

    # ---------------------------------------------------------- validation
    def _check_settings(self) -> int:
        """Check the estimator's own parameters; returns ``n_states``."""
        n = self.n_states
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
            raise TypeError(f"n_states must be a positive integer, got {n!r}")
        if n < 1:
            raise ValueError(f"n_states must be a positive integer, got {n}")
        for name in ("max_iter", "n_substeps"):
            val = getattr(self, name)
            if isinstance(val, bool) or not isinstance(val, (int, np.integer)):
                raise TypeError(f"{name} must be a positive integer, got {val!r}")
            if val < 1:
                raise ValueError(f"{name} must be a positive integer, got {val}")
        check_positive_number(self.tol, "tol")
        if self.error_model not in ("white", "random_walk"):
            raise ValueError(
                "error_model must be 'white' or 'random_walk', got "
                f"{self.error_model!r}"
            )
        if self.target not in ("error", "derivative"):
            raise ValueError(
                f"target must be 'error' or 'derivative', got {self.target!r}"
            )
        if self.input_hold not in HOLDS:
            raise ValueError(
                "input_hold must be 'linear', 'zoh' or 'cubic', got "
                f"{self.input_hold!r}"
            )
        return int(n)

    @staticmethod
    def _check_measurements(y):
        y = as_float_array(y, "y (the measurements)", ndim=(1, 2), allow_nan=True)
        if y.ndim == 1:
            y = y[:, None]
        N = y.shape[0]
        if N < 3:
            raise ValueError(f"y (the measurements) needs at least 3 samples, got {N}")
        observed = np.sum(~np.isnan(y), axis=0)
        if not observed.any():
            raise ValueError(
                "y (the measurements) has no observed value (all NaN); NaN marks "
                "a missing measurement"
            )
        if observed.min() < 2:
            j = int(np.argmin(observed))
            raise ValueError(
                f"y (the measurements) column {j} has {int(observed[j])} observed "
                "value(s) (the rest are NaN); every measured channel needs at "
                "least 2. Drop the channel (measured / measurement_matrix) or "
                "give more data"
            )
        return y

    def _measurement_model(self, n: int, m: int):
        """``(measurement, jacobian)``: a matrix ``C`` or a callable ``g``."""
        given = [
            name
            for name in ("measured", "measurement_matrix", "measurement_function")
            if getattr(self, name) is not None
        ]
        if len(given) > 1:
            raise ValueError(
                f"give only one of measured, measurement_matrix and "
                f"measurement_function; got {', '.join(given)}"
            )
        g_jac = None
        if self.measurement_function is not None:
            if not callable(self.measurement_function):
                raise TypeError("measurement_function must be callable g(x)")
            measurement = self.measurement_function
            if self.measurement_jacobian is not None:
                if not callable(self.measurement_jacobian):
                    raise TypeError("measurement_jacobian must be callable")
                g_jac = self.measurement_jacobian
        elif self.measurement_matrix is not None:
            C = as_float_array(self.measurement_matrix, "measurement_matrix", ndim=2)
            if C.shape[1] != n:
                raise ValueError(
                    f"measurement_matrix must have n_states = {n} columns, got "
                    f"shape {C.shape}"
                )
            measurement = C
        else:
            if self.measured is None:
                idx = np.arange(n)
            else:
                idx = check_indices(self.measured, n, "measured")
            measurement = np.eye(n)[idx]
        if not callable(measurement) and measurement.shape[0] != m:
            raise ValueError(
                f"y (the measurements) has {m} column(s) but the measurement model "
                f"gives {measurement.shape[0]} (measured / measurement_matrix)"
            )
        return measurement, g_jac

    def _check_inputs(self, u, N, model):
        u = self.u if u is None else u
        if u is not None and not callable(u):
            u = as_float_array(u, "u", ndim=(1, 2))
            if u.ndim == 1:
                u = u[:, None]
            if u.shape[0] != N:
                raise ValueError(
                    f"u has {u.shape[0]} rows but y has {N} samples; give u on "
                    "the sample grid"
                )
        if u is not None and not model.takes_input:
            raise ValueError(
                "u was given but assumed_model takes no input: define it as f(x, t, u)"
            )
        return u

    def check(self, y, t=1.0, u=None) -> MMEProblem:
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
        model = as_model_function(self.assumed_model, n, name="assumed_model")
        if model.n_states != n:
            raise ValueError(
                f"assumed_model is a ModelFunction for {model.n_states} states but "
                f"n_states = {n}"
            )
        y = self._check_measurements(y)
        N, m = y.shape
        t = check_time(t, N, "t")
        measurement, g_jac = self._measurement_model(n, m)
        R = self._noise(y, t, m)
        es = (
            np.arange(n)
            if self.error_states is None
            else check_indices(self.error_states, n, "error_states")
        )
        W_spec = self._W_spec(es.size)
        u = self._check_inputs(u, N, model)

        def make_smoother(model, error_states, measurement, measurement_jacobian):
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
            )

        smoother = make_smoother(model, es, measurement, g_jac)
        self._check_first_evaluation(smoother, model, measurement, es)
        if self.error_model == "random_walk":
            # The same problem with d as q extra states (d' = w): the solver
            # then penalises the rate w with W. An error state is observable
            # exactly when the state it enters is, so the checks above hold.
            aug_model, aug_measurement, aug_jac = random_walk_problem(
                model, es, measurement, g_jac
            )
            smoother = make_smoother(
                aug_model, n + np.arange(es.size), aug_measurement, aug_jac
            )
            # d_j, the model error of state j, in singularity diagnostics
            smoother.state_labels = [f"x{i}" for i in range(n)] + [
                f"d{i} (model error of x{i})" for i in es
            ]
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
        )

    @staticmethod
    def _check_first_evaluation(smoother, model, measurement, es):
        """Evaluate model and measurement once; check observability up front."""
        x0, _ = smoother.initial_guess()
        t = smoother.t
        N, m = smoother.N, smoother.m
        if callable(measurement):
            try:
                gx = np.asarray(measurement(x0), dtype=float)
            except Exception as exc:
                raise ValueError(
                    f"measurement_function failed on x of shape {x0.shape}: {exc}"
                ) from exc
            if gx.shape != (N, m):
                raise ValueError(
                    f"measurement_function returned shape {gx.shape} for x of "
                    f"shape {x0.shape}; expected {(N, m)} to match y"
                )
            check_finite(gx, "measurement_function output")
        # First evaluation of the model: shape and finiteness.
        ug = smoother.u_grid()
        try:
            model.check(x0, t, ug)
        except ValueError:
            raise
        except Exception as exc:
            raise ValueError(
                f"assumed_model failed on its first evaluation (x of shape "
                f"{x0.shape}): {type(exc).__name__}: {exc}"
            ) from exc
        if callable(measurement):
            jac = smoother.measurement_jacobian(x0 / smoother.unit)
            Hpat = np.abs(jac).max(axis=0) > 0
        else:
            Hpat = measurement != 0
        hidden = unobservable_states(model, x0, t, ug, Hpat)
        if hidden:
            bad_err = [i for i in hidden if i in set(es.tolist())]
            what = (
                f"error_states {bad_err} cannot be seen in the measurements"
                if bad_err
                else f"states {hidden} cannot be seen in the measurements"
            )
            raise ValueError(
                f"{what}: no measured quantity depends on them, directly or "
                f"through the assumed model, so their initial value and model "
                f"error are undetermined (states {hidden} are unobservable). "
                "Measure them (measured / measurement_matrix) or change the model."
            )

    def _noise(self, y, t, m):
        nv = self.noise_variance
        if isinstance(nv, str):
            if nv != "auto":
                raise ValueError(
                    f"noise_variance must be 'auto', a number, a vector or a "
                    f"matrix; got {nv!r}"
                )
            var, diagnostics = estimate_noise_variance(
                y, t, warn=False, return_diagnostics=True
            )
            if np.any(var <= 0):
                raise ValueError(
                    "noise_variance='auto' estimated a zero noise variance (the "
                    "data look noise-free or quantised); give noise_variance"
                )
            doubts = "; ".join(
                f"channel {d.channel}: {d.reason}"
                for d in diagnostics
                if not d.reliable
            )
            warnings.warn(
                "noise_variance='auto': estimated the measurement noise variance "
                f"as [{', '.join(sig(v) for v in var)}] (sd "
                f"[{', '.join(sig(v) for v in np.sqrt(var))}]) from the noise floor "
                "of the data's spectrum"
                + (f"; not reliable - {doubts}" if doubts else "")
                + ". Give noise_variance if it is known",
                UserWarning,
                stacklevel=4,
            )
            return np.diag(var)
        return noise_covariance(nv, m)

    def _W_spec(self, q):
        W = self.W
        if isinstance(W, str):
            if W not in ("auto", "ml"):
                raise ValueError(
                    f"W must be 'auto', 'ml', a positive number or a positive "
                    f"definite (q, q) matrix; got {W!r}"
                )
            return W
        arr = as_float_array(W, "W", ndim=(0, 1, 2))
        if arr.ndim == 0:
            check_positive_number(float(arr), "W")
            return float(arr) * np.eye(q)
        if arr.ndim == 1:
            if arr.size != q or np.any(arr <= 0):
                raise ValueError(
                    f"W as a vector must hold {q} positive weights (one per "
                    f"error state), got {arr.tolist()}"
                )
            return np.diag(arr)
        if arr.shape != (q, q):
            raise ValueError(f"W must be ({q}, {q}) for {q} error states")
        try:
            np.linalg.cholesky(0.5 * (arr + arr.T))
        except np.linalg.LinAlgError:
            raise ValueError("W must be positive definite") from None
        return 0.5 * (arr + arr.T)

    # ------------------------------------------------------------- solving
    def _solve(self, smoother, W, start):
        try:
            return smoother.solve(W, start)
        except DivergenceError:
            raise
        except np.linalg.LinAlgError as exc:
            raise ValueError(
                f"{exc}. Check measured / measurement_matrix and error_states."
            ) from None

    # -------------------------------------------------------------- output
    def _store(self, smoother, search: WSearch, R, n):
        res = search.result
        N = smoother.N
        x = res.x[:, :n]
        if not isinstance(smoother.model, RandomWalkModel):  # d held per interval
            es = smoother.es
            d_int = res.d
            d_grid = np.empty((N, smoother.q))
            d_grid[1:-1] = 0.5 * (d_int[1:] + d_int[:-1])
            d_grid[0] = d_int[0]
            d_grid[-1] = d_int[-1]
            model = smoother.model
        else:  # "random_walk": d is the augmented part of the state
            es = smoother.model.es
            d_grid = res.x[:, n:]
            d_int = 0.5 * (d_grid[1:] + d_grid[:-1])
            model = smoother.model.base
        d_full = np.zeros((N, n))
        d_full[:, es] = d_grid
        self.t_ = smoother.t.copy()
        self.smoothed_x_ = x
        self.d_ = d_full
        self.d_intervals_ = d_int
        self.derivative_ = model(x, smoother.t, smoother.u_grid()) + d_full
        self.W_ = search.W
        self.W_at_bound_ = bool(search.at_bound)
        self.W_history_ = search.history
        self.covariance_ratio_ = channel_ratios(res, smoother)
        self.residuals_ = res.residuals
        self.noise_variance_ = R
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
