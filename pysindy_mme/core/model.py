"""Uniform access to a user's dynamical model ``dx/dt = f(x, t[, u])``.

Users hand us models in several forms: a vectorised callable ``f(x, t)`` or
``f(x, t, u)``, a fitted ``pysindy.SINDy`` model, or an ``ExtendedModel``.
:class:`ModelFunction` hides the difference, checks shapes and finiteness on
every call, and offers a finite-difference Jacobian and an ODE simulator, so
that the estimator, the discovery study and the example systems all call a
model the same way.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable

import numpy as np
from scipy.integrate import solve_ivp

from .integrate import InputSignal, simulate
from .jacobian import rowwise_jacobian
from .relaxation import Overflows, overflow_columns_of, split_form

__all__ = ["ModelFunction", "as_model_function", "simulate_model"]


def _accepts_input(func: Callable) -> bool:
    """Whether ``func`` takes a third positional argument (the input ``u``)."""
    try:
        params = inspect.signature(func).parameters.values()
    except (TypeError, ValueError):  # builtins, some C callables
        return False
    positional = [
        p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
    ]
    has_varargs = any(p.kind == p.VAR_POSITIONAL for p in params)
    return has_varargs or len(positional) >= 3


class ModelFunction:
    """A validated, vectorised right-hand side ``f(x, t, u)``.

    Parameters
    ----------
    func : callable, pysindy.SINDy or object with ``predict(x, u=None)``
        The model. A callable gets ``x`` of shape ``(n_samples, n_states)``,
        ``t`` of shape ``(n_samples,)`` and, if it takes a third argument,
        ``u`` of shape ``(n_samples, n_inputs)`` (or ``None``).
    n_states : int
        Number of states the model must return.
    name : str
        Argument name used in error messages.
    """

    def __init__(self, func, n_states: int, name: str = "assumed_model"):
        self.n_states = int(n_states)
        self.name = name
        self._func = func
        if hasattr(func, "predict") and not callable(func):
            self._kind = "predict"
        elif hasattr(func, "predict") and hasattr(func, "optimizer"):
            self._kind = "predict"  # a pysindy SINDy model
        elif callable(func):
            self._kind = "callable"
            self._takes_u = _accepts_input(func)
        else:
            raise TypeError(
                f"{name} must be a callable f(x, t) / f(x, t, u), a fitted "
                f"pysindy SINDy model or an ExtendedModel; got {type(func).__name__}"
            )

    @property
    def takes_input(self) -> bool:
        """Whether the model accepts an input ``u`` (a third argument)."""
        return self._kind != "callable" or self._takes_u

    def __call__(self, x, t, u=None) -> np.ndarray:
        x = np.atleast_2d(np.asarray(x, dtype=float))
        t = np.broadcast_to(np.asarray(t, dtype=float), (x.shape[0],))
        if self._kind == "predict":
            if u is None:
                out = self._func.predict(x)
            else:
                out = self._func.predict(x, u=np.atleast_2d(u))
        elif self._takes_u:
            out = self._func(x, t, u)
        else:
            out = self._func(x, t)
        out = np.asarray(out, dtype=float)
        if out.shape != x.shape:
            # One state: (n_samples,) is unambiguous. Anything else of the right
            # size (e.g. equations stacked as rows) would be silently scrambled.
            if x.shape[1] == 1 and out.shape == (x.shape[0],):
                return out.reshape(x.shape)
            hint = (
                " (equations as rows? build the result with np.column_stack)"
                if out.shape == x.shape[::-1] and x.shape[0] != x.shape[1]
                else ""
            )
            raise ValueError(
                f"{self.name} returned an array of shape {out.shape} for x of "
                f"shape {x.shape}; it must return dx/dt with the same shape as x "
                f"(n_samples, n_states){hint}"
            )
        return out

    def unchecked(self):
        """The model as a bare ``f(x, t, u)`` with no shape checks.

        For hot loops (fixed-step integration) after :meth:`check` has
        validated the model once; rows of ``x`` must be states. A callable
        with an ``unchecked()`` method of its own (an
        :class:`~pysindy_mme.ExtendedModel`) supplies its bare form.
        """
        func = self._func
        own = getattr(func, "unchecked", None)
        if self._kind == "callable" and callable(own):
            return own()
        if self._kind == "predict":
            return _PredictRates(func)
        if self._takes_u:
            return func
        return _WithoutInput(func)

    def check(self, x, t, u=None) -> np.ndarray:
        """Evaluate once and raise a clear error on a bad shape or value."""
        out = self(x, t, u)
        if not np.all(np.isfinite(out)):
            bad = int(np.argmax(~np.all(np.isfinite(out), axis=1)))
            raise ValueError(
                f"{self.name} returned non-finite values (first at sample {bad}, "
                f"x = {np.asarray(x)[bad].tolist()}); check the model and the units "
                "of the data"
            )
        return out

    def jacobian(self, x, t, u=None, f0=None) -> np.ndarray:
        """Jacobian ``df/dx`` of shape ``(n_samples, n_states, n_states)``.

        Central differences on every sample at once, so its cost is
        ``2 n_states`` vectorised model evaluations.
        """
        return rowwise_jacobian(lambda z: self(z, t, u), x)


class _PredictRates:
    """``f(x, t, u)`` of a model with ``predict`` (a class, not a closure:
    what holds it pickles when the model does)."""

    def __init__(self, model):
        self.model = model

    def __call__(self, x, t, u):
        out = self.model.predict(x) if u is None else self.model.predict(x, u=u)
        return np.asarray(out, dtype=float).reshape(x.shape)


class _WithoutInput:
    """``f(x, t, u)`` of a model ``f(x, t)`` that takes no input."""

    def __init__(self, func):
        self.func = func

    def __call__(self, x, t, u):
        return self.func(x, t)


def as_model_function(func, n_states: int, name: str = "assumed_model"):
    """Return ``func`` wrapped as a :class:`ModelFunction` (idempotent)."""
    if isinstance(func, ModelFunction):
        return func
    return ModelFunction(func, n_states, name=name)


class _Budget(Exception):
    """Raised inside the right-hand side when a simulation takes too many steps."""


# solve_ivp's own methods; "rk4" and "auto" are ours (an OdeSolver subclass
# passes through to solve_ivp as well)
_IVP_METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")


def _lean(f: ModelFunction, x0, t0, u0):
    """``f`` as a bare ``(x (1, n), t (1,), u (1, m) or None) -> (1, n)``.

    An integrator calls the model tens of thousands of times on one row, where
    the checks of :meth:`ModelFunction.__call__` cost as much as the model.
    :meth:`ModelFunction.unchecked` is used if, at ``x0``, the checked call
    passes and the bare one returns a float array of the right shape; else
    the checked ``f``, so that the integrator meets a bad model's error
    (a wrong shape, say) as it always did.
    """
    x, tt = x0[None, :], np.array([t0], dtype=float)
    try:
        with np.errstate(all="ignore"):
            f(x, tt, u0)
            raw = f.unchecked()
            probe = raw(x, tt, u0)
    except Exception:  # the integrator meets it again and says so
        return f
    ok = isinstance(probe, np.ndarray) and probe.shape == x.shape
    return raw if ok and probe.dtype == np.float64 else f


def _run_adaptive(f, x0, t, signal, method, rtol, atol, allowed, limit):
    """``solve_ivp``: ``(x, reason or None, whether the budget ran out)``."""
    # an adaptive stepper integrates the whole right-hand side (a model's
    # overflow terms included: see _Rates.full)
    lean = _lean(f, x0, t[0], signal.at(t[:1]))
    lean = getattr(lean, "full", lean)
    budget = [allowed]
    reached = [t[0]]  # the furthest time evaluated: how far a stalled run got

    def rhs(s, x):
        budget[0] -= 1
        if budget[0] < 0:
            raise _Budget
        reached[0] = max(reached[0], s)
        s_row = np.array([s])
        return lean(x[None, :], s_row, signal.at(s_row))[0]

    # Bound the state so that a diverging model ends the run instead of hanging.
    def blow_up(s, x):
        size = float(np.max(np.abs(x)))
        return limit - size if np.isfinite(size) else -1.0

    blow_up.terminal = True
    out = np.full((t.size, x0.size), np.nan)
    reason, exhausted = None, False
    try:
        with np.errstate(all="ignore"):
            sol = solve_ivp(
                rhs,
                (t[0], t[-1]),
                x0,
                t_eval=t,
                method=method,
                rtol=rtol,
                atol=atol,
                events=blow_up,
            )
        out[: sol.y.shape[1]] = sol.y.T
        if sol.status == 1 or not sol.success or sol.y.shape[1] < t.size:
            reason = "it left the bound" if sol.status == 1 else sol.message
    except _Budget:
        reason = (
            f"it needed more than {allowed} model evaluations by t = "
            f"{reached[0]:.6g} (stiff or exploding)"
        )
        exhausted = True
    except (ValueError, FloatingPointError) as exc:  # root finding on NaN, say
        reason = f"the integrator failed ({exc})"
    return out, reason, exhausted


def _run_rk4(f, x0, t, signal, substeps, limit):
    """Fixed-step RK4 on the sample grid: ``(x, reason or None)``."""

    inputs = None if signal.is_none else signal
    out = np.full((t.size, x0.size), np.nan)
    out[0] = x0
    try:
        lean = _lean(f, x0, t[0], signal.on_intervals(0.0, slice(0, 1)))

        def rhs(x, s, u):  # integrate.simulate's form: s a float, u (m,)
            return lean(x, np.array([s]), None if u is None else u[None, :])

        split = getattr(lean, "split", None)
        run = simulate(rhs, x0, t, inputs, substeps=substeps, bound=limit, split=split)
    except (ValueError, FloatingPointError) as exc:
        return out, f"the integrator failed ({exc})"
    out = run.x[0]
    k = int(run.diverged_at[0])
    if k < 0:
        return out, None
    if k == 0:
        return out, "not finite"
    # simulate blanks the step that went wrong: redo it to say how it went wrong
    again = simulate(
        rhs,
        out[k - 1],
        t[k - 1 : k + 1],
        None if inputs is None else inputs.subset(k - 1, k + 1),
        substeps=substeps,
        bound=np.inf,
        split=split,
    )
    finite = bool(np.all(np.isfinite(again.x[0, 1])))
    return out, "it left the bound" if finite else "it stopped being finite"


def _outcome(out, reason, t, x0, on_divergence, hint=""):
    """``out`` for a run that finished; else NaN rows or a DivergenceError."""
    from ..exceptions import DivergenceError

    finite = np.all(np.isfinite(out), axis=1)
    if reason is None and np.all(finite):
        return out
    if on_divergence == "raise":
        k = int(np.argmin(finite)) if not np.all(finite) else t.size - 1
        last = out[k - 1] if k > 0 else x0
        worst = int(np.argmax(np.abs(last)))
        raise DivergenceError(
            f"the simulation diverged near t = {t[k]:.6g}: {reason or 'not finite'}; "
            f"state {worst} was {last[worst]:.6g} at t = {t[max(k - 1, 0)]:.6g}"
            f"{hint}"
        )
    return out


def _check_method(method, substeps):
    """``method`` normalised (``"rk4"``, ``"auto"`` or solve_ivp's), checked."""
    if isinstance(method, str):
        if method.lower() in ("rk4", "auto"):
            method = method.lower()
        elif method not in _IVP_METHODS:
            raise ValueError(
                "method must be 'rk4', 'auto' or one of solve_ivp's "
                f"{list(_IVP_METHODS)}, got {method!r}"
            )
    if (
        isinstance(substeps, bool)
        or not isinstance(substeps, (int, np.integer))
        or substeps < 1
    ):
        raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
    return method


def simulate_model(
    model,
    x0,
    t,
    u=None,
    *,
    n_states: int | None = None,
    rtol: float = 1e-9,
    atol: float = 1e-11,
    method: str = "LSODA",
    substeps: int = 4,
    input_hold: str = "linear",
    max_evaluations: int | None = None,
    on_divergence: str = "nan",
) -> np.ndarray:
    """Integrate ``dx/dt = model(x, t, u)`` from ``x0`` and sample it on ``t``.

    Parameters
    ----------
    model : callable or ModelFunction
        Vectorised right-hand side (see :class:`ModelFunction`).
    x0 : array-like, shape (n_states,)
    t : array-like, shape (n_samples,)
        Increasing sample times; the simulation starts at ``t[0]``.
    u : array-like of shape (n_samples, n_inputs), callable ``u(t)`` or None
        Input; arrays are held between samples as ``input_hold`` says.
    rtol, atol : float
        Tolerances of the adaptive methods (not used by ``"rk4"``).
    method : str or scipy OdeSolver, default "LSODA"
        ``"LSODA"`` (or another :func:`scipy.integrate.solve_ivp` method):
        adaptive, to ``rtol``/``atol``. ``"rk4"``: classical RK4 with
        ``substeps`` fixed steps per sample interval
        (:func:`pysindy_mme.core.integrate.simulate`, the integrator of the
        study's own free runs); it costs ``4 substeps (n_samples - 1)`` model
        evaluations whatever the model, steps through kinks and jumps
        (``sign(v)``) where an adaptive method stalls, and is accurate to
        ``O(h^4)`` on smooth stretches and ``O(h)`` (``h`` = interval /
        ``substeps``) across a discontinuity of the right-hand side.
        ``"auto"``: LSODA, and if it exhausts ``max_evaluations``, RK4 once
        instead, with a :class:`~pysindy_mme.DiscoveryWarning`.
    substeps : int, default 4
        RK4 steps per sample interval (``"rk4"`` and the fallback of
        ``"auto"``).
    input_hold : {"linear", "zoh", "cubic"}
        How an array ``u`` goes between samples
        (:class:`~pysindy_mme.core.integrate.InputSignal`): linear
        interpolation, zero-order hold (``u[k]`` on ``[t[k], t[k+1])``, as a
        digital controller applies it) or a cubic through the neighbours.
    max_evaluations : int, optional
        Budget of model evaluations of the adaptive methods (default
        ``200 n_samples + 10^4``): a stiff or exploding model stops here
        instead of hanging. RK4's cost is fixed (above) and has no budget.
    on_divergence : {"nan", "raise"}
        What a run that blows up (leaves ``1e6`` times the initial scale, or
        the finite range) or exhausts its budget gives: NaN in the rows it
        did not reach, or a :class:`~pysindy_mme.DivergenceError` naming the
        time and the state.

    Returns
    -------
    x : ndarray, shape (n_samples, n_states)
    """
    import warnings

    from ..exceptions import DiscoveryWarning

    method = _check_method(method, substeps)
    x0 = np.asarray(x0, dtype=float).ravel()
    t = np.asarray(t, dtype=float)
    f = as_model_function(model, n_states or x0.size)
    signal = InputSignal(u, t, hold=input_hold)
    allowed = int(max_evaluations or 200 * t.size + 10_000)
    limit = 1e6 * max(1.0, float(np.max(np.abs(x0))))
    rk4_hint = (
        f" (fixed-step RK4, {substeps} steps per sample interval: a stiff model "
        "needs more substeps, or an adaptive method)"
    )
    if method == "rk4":
        out, reason = _run_rk4(f, x0, t, signal, int(substeps), limit)
        return _outcome(out, reason, t, x0, on_divergence, rk4_hint)
    adaptive = "LSODA" if method == "auto" else method
    out, reason, exhausted = _run_adaptive(
        f, x0, t, signal, adaptive, rtol, atol, allowed, limit
    )
    if method == "auto" and exhausted:
        warnings.warn(
            f"LSODA needed more than {allowed} model evaluations (a stiff model, "
            "or a kink or jump in the model that it does not declare, such as "
            "np.sign in the assumed model); simulated with fixed-step RK4 on the "
            f"sample grid instead ({substeps} steps per sample interval). "
            "method='rk4' skips the attempt; method='LSODA' never falls back",
            DiscoveryWarning,
            stacklevel=2,
        )
        out, reason = _run_rk4(f, x0, t, signal, int(substeps), limit)
        return _outcome(out, reason, t, x0, on_divergence, rk4_hint)
    return _outcome(out, reason, t, x0, on_divergence)


class ParametricModel:
    """``x' = f(x, t, u; p) + sum_j c_j e_{s_j} phi_j(x, u)``, ``theta = [p, c]``.

    The model an estimator fits parameters of: the assumed model with its own
    (physical) parameters ``p`` and correction coefficients ``c``, each on one
    library function ``phi_j`` in the equation of state ``s_j`` (a *slot*).

    Parameters
    ----------
    base : callable ``(x (K, n), t (K,), u (K, m) or None, p (n_physical,)) -> (K, n)``
        The assumed model, vectorised over rows, unchecked (validate first).
    n_states : int
    n_physical : int
        Number of parameters of ``base`` (0: ``p`` is an empty array).
    features : callable ``(z (K, n + m), columns) -> (K, len(columns))``
        Library columns at ``z`` = states then inputs.
    slots : sequence of (state, column)
    n_extra : int
        Trailing parameters the dynamics do not depend on (measurement
        offsets, say): ``theta = [p, c, extra]``.
    """

    def __init__(
        self, base, n_states, n_physical=0, features=None, slots=(), n_extra=0
    ):
        self.base = base
        self.n_states = int(n_states)
        self.n_physical = int(n_physical)
        self.features = features
        self.slots = [(int(i), int(c)) for i, c in slots]
        # overflow terms of a state are solved exactly around each RK4 step
        # (:mod:`~pysindy_mme.core.relaxation`), not in the right-hand side
        self.overflows = Overflows(
            self.slots, overflow_columns_of(features), self.n_states
        )
        self._smooth = [
            k for k in range(len(self.slots)) if k not in self.overflows.positions
        ]
        # a base model with overflow terms of its own (an ExtendedModel's
        # bare right-hand side) brings their split, at its fixed coefficients
        self._base_split = getattr(base, "split", None)
        smooth_slots = [self.slots[k] for k in self._smooth]
        self.used = sorted({c for _, c in smooth_slots})
        position = {c: k for k, c in enumerate(self.used)}
        self._rows = np.array([i for i, _ in smooth_slots], dtype=int)
        self._cols = np.array([position[c] for _, c in smooth_slots], dtype=int)
        self.n_params = self.n_physical + len(self.slots) + int(n_extra)
        self._last = (None, None, None)  # (x, u, features at x): one-entry cache

    def _phi(self, x, u):
        """The used library columns at ``x`` (cached for the same ``x`` object:
        an integrator evaluates the model, its Jacobian and its parameter
        derivative at each stage point)."""
        last_x, last_u, phi = self._last
        if x is not last_x or u is not last_u:
            phi = self.features(self._z(x, u), self.used)
            self._last = (x, u, phi)
        return phi

    def _z(self, x, u):
        return (
            x
            if u is None
            else np.hstack([x, np.broadcast_to(u, (len(x), u.shape[-1]))])
        )

    def base_part(self, x, t, u, theta) -> np.ndarray:
        """The assumed model alone at its parameters ``theta[:n_physical]``."""
        return np.array(self.base(x, t, u, theta[: self.n_physical]), dtype=float)

    def _coefficients(self, theta):
        """The coefficients of the terms in the right-hand side (the
        overflow terms are solved apart: :meth:`split_at`)."""
        return theta[self.n_physical : self.n_physical + len(self.slots)][self._smooth]

    def _coefficient_matrix(self, theta):
        coef = np.zeros((len(self.used), self.n_states))
        np.add.at(coef, (self._cols, self._rows), self._coefficients(theta))
        return coef

    def __call__(self, x, t, u, theta) -> np.ndarray:
        out = self.base_part(x, t, u, theta)
        if self.used:
            out += self._phi(x, u) @ self._coefficient_matrix(theta)
        return out

    def split_at(self, theta, first_column=None):
        """The overflow terms at ``theta`` as ``split(X, D, h)`` (user units)
        for :func:`~pysindy_mme.core.integrate.rk4_flow`, or None. With
        ``first_column``, the column of ``D`` that holds ``theta[0]``: the
        split then updates the coefficients' columns too."""
        if not self.overflows:
            return self._base_split
        coefs = np.asarray(theta, dtype=float)[
            self.n_physical : self.n_physical + len(self.slots)
        ]
        column_of = None
        if first_column is not None:
            column_of = _ColumnOf(int(first_column) + self.n_physical)
        own = self.overflows.bound(coefs, column_of)
        return own if self._base_split is None else _Both(self._base_split, own)

    @property
    def has_exact_correction_jacobian(self) -> bool:
        return not self.used or hasattr(self.features, "gradient")

    def correction_jacobian(self, x, u, theta, out=None, unit=None) -> np.ndarray:
        """``d (correction) / dx``, ``(K, n, n)``, from the features' gradient.

        With ``unit`` (one per state), in the solver's internal units:
        ``S^-1 J S`` for ``S = diag(unit)``. With ``out`` (``(K, n, n)``),
        added into it in place and returned: the integrators call this at
        every RK4 stage, and at 10^6 samples each ``(K, n, n)`` temporary
        (a zeroed answer, its rescaled copy, the sum) is 32 MB to allocate,
        fault in and write.
        """
        K, n = x.shape
        if out is None:
            out = np.zeros((K, n, n))
        if not self.used:
            return out
        grad = self.features.gradient(self._z(x, u), self.used)
        coefs = self._coefficients(theta)
        for state, col, coef in zip(self._rows, self._cols, coefs):
            # row ``state`` of S^-1 J S: coef * grad * unit / unit[state].
            # Element by element: each operation then runs over the K rows
            # (numpy's loop over a (K, n) view with n = 2 is 10x slower)
            for j in range(n):
                factor = coef if unit is None else coef * (unit[j] / unit[state])
                out[:, state, j] += grad[:, col, j] * factor
        return out

    def jacobian(self, x, t, u, theta) -> np.ndarray:
        """``df/dx`` (central differences, all rows at once): ``(K, n, n)``."""
        return rowwise_jacobian(lambda z: self(z, t, u, theta), x)

    def param_jacobian(self, x, t, u, theta) -> np.ndarray:
        """``df/dtheta``: ``(K, n, n_params)``; exact for the coefficients."""
        K, n = x.shape
        out = np.zeros((K, n, self.n_params))
        n_p = self.n_physical
        if n_p:
            p = np.asarray(theta[:n_p], dtype=float)
            step = 1e-6 * np.maximum(np.abs(p), 1e-6 * max(np.max(np.abs(p)), 1.0))
            for j in range(n_p):
                hi, lo = p.copy(), p.copy()
                hi[j] += step[j]
                lo[j] -= step[j]
                out[:, :, j] = (
                    np.asarray(self.base(x, t, u, hi))
                    - np.asarray(self.base(x, t, u, lo))
                ) / (2.0 * step[j])
        if self.used:
            phi = self._phi(x, u)
            out[:, self._rows, n_p + np.asarray(self._smooth)] = phi[:, self._cols]
        return out


class RatesAt:
    """A parametric model at fixed ``theta`` as ``(x, t, u) -> dx/dt``, with
    the split of its overflow terms as ``split`` (what the integrators read)."""

    def __init__(self, model, theta):
        self.model, self.theta = model, theta
        self.split = model.split_at(theta)

    def __call__(self, x, t, u=None):
        return self.model(x, t, u, self.theta)


class AsBase:
    """A right-hand side ``(x, t, u)`` as a base model with no parameters,
    ``(x, t, u, p)``, for a :class:`ParametricModel`; the split of its
    overflow terms (:func:`~.relaxation.split_form`) is kept as ``split``."""

    def __init__(self, rhs):
        self.rhs, self.split = split_form(rhs)

    def __call__(self, x, t, u, p):
        return self.rhs(x, t, u)


class _Both:
    """Two splits one after the other (each exact; they act on different terms)."""

    def __init__(self, first, second):
        self.first, self.second = first, second

    def __call__(self, X, D, h):
        X, D = self.first(X, D, h)
        return self.second(X, D, h)


class _ColumnOf:
    """``position -> first + position`` (a class: what holds it pickles)."""

    def __init__(self, first):
        self.first = first

    def __call__(self, position):
        return self.first + position
