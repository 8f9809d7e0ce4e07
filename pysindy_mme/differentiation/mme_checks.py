"""Everything :class:`~.mme.MME` checks before it solves, as a mixin.

Settings, measurements, the measurement model, inputs, the noise, the
weight, and the first evaluation of the model with the structural
observability check: each raises a ``ValueError``/``TypeError`` naming the
argument, before any long computation.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..core.constraints import Boolean, Integer, Interval, Options, check_parameters
from ..core.integrate import HOLDS
from ..core.noise import estimate_noise_variance, noise_covariance
from ..core.tables import sig
from ..core.validation import (
    as_float_array,
    check_finite,
    check_indices,
    check_positive_number,
)
from ..exceptions import UnobservableError
from ..solver.observability import unobservable_states
from .error_models import resolve_error_model

__all__ = ["MMEChecks"]


# What each of MME's scalar settings may be: one check, one message
# (core.constraints). The model, measurements, noise, error states, error
# model and W are checked against the data (below).
PARAMETER_CONSTRAINTS = {
    "n_states": [Integer(1)],
    "target": [Options("error", "derivative")],
    "input_hold": [Options(*HOLDS)],
    "n_substeps": [Integer(1)],
    "max_iter": [Integer(1)],
    "tol": [Interval(0.0, None, closed="neither")],
    "verbose": [Boolean()],
}


class MMEChecks:
    """The checks of :class:`~.mme.MME` (reads its parameters)."""

    # ---------------------------------------------------------- validation
    def _check_settings(self) -> int:
        """Check the estimator's own parameters; returns ``n_states``."""
        if self.assumed_model is None:
            raise TypeError(
                "assumed_model is required: the model f(x, t) or f(x, t, u) "
                "(MME(assumed_model=f, n_states=2, ...))"
            )
        check_parameters(self, PARAMETER_CONSTRAINTS)
        n = self.n_states
        return int(n)

    def _check_error_model(self):
        """The prior on ``d``, resolved through the registry and checked."""
        return resolve_error_model(self.error_model)

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
        hidden = unobservable_states(model, x0, t, ug, Hpat, unit=smoother.unit)
        if hidden:
            bad_err = [i for i in hidden if i in set(es.tolist())]
            what = (
                f"error_states {bad_err} cannot be seen in the measurements"
                if bad_err
                else f"states {hidden} cannot be seen in the measurements"
            )
            raise UnobservableError(
                f"{what}: no measured quantity depends on them, directly or "
                f"through the assumed model, so their initial value and model "
                f"error are undetermined (states {hidden} are unobservable). "
                "Measure them (measured / measurement_matrix) or change the model. "
                "(Checked along the starting trajectory and perturbations of "
                "it: if the model depends on them only elsewhere, past a kink or "
                "a dead zone, start there: MME.fit(..., x_guess=...).)"
            )

    def _noise(self, y, t, m):
        """The noise covariance ``R`` and how it was found.

        Returns ``(R, diagnostics)``: ``diagnostics`` is the list of
        :class:`~pysindy_mme.NoiseDiagnostics` when ``noise_variance="auto"``,
        None when the noise was stated. A quantised channel whose estimate is
        at the quantisation level does not raise: it gets the rounding's
        variance ``step^2 / 12`` and ``determined=False``, so that the study
        can say it is inconclusive.
        """
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
                    "data look noise-free); give noise_variance"
                )
            doubts = "; ".join(
                f"channel {d.channel}: {d.reason}"
                for d in diagnostics
                if not d.reliable and d.determined
            )
            # Quantised channels at the quantisation level: the noise is not
            # determined, whatever the spectrum says; said first and plainly.
            undetermined = "; ".join(
                f"channel {d.channel} is quantised with step "
                f"{sig(d.quantisation_step)} and its noise is at the quantisation "
                "level, so the noise is NOT determined by the data: the rounding's "
                f"variance step^2/12 = {sig(d.variance)} is used"
                for d in diagnostics
                if not d.determined
            )
            quantised = ", ".join(
                f"channel {d.channel} quantised with step {sig(d.quantisation_step)}"
                for d in diagnostics
                if d.determined and np.isfinite(d.quantisation_step)
            )
            warnings.warn(
                "noise_variance='auto': estimated the measurement noise variance "
                f"as [{', '.join(sig(v) for v in var)}] (sd "
                f"[{', '.join(sig(v) for v in np.sqrt(var))}]) from the noise floor "
                "of the data's spectrum"
                + (f" ({quantised}; the rounding is included)" if quantised else "")
                + (f"; {undetermined}" if undetermined else "")
                + (f"; not reliable - {doubts}" if doubts else "")
                + ". Give noise_variance if it is known",
                UserWarning,
                stacklevel=4,
            )
            return np.diag(var), diagnostics
        return noise_covariance(nv, m), None

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
