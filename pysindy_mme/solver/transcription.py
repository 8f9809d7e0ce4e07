"""Direct transcription: MME and output error, linear in the number of samples.

Problem (Mook and Junkins' MME, discretised by direct transcription): find
the states ``x_k`` at the sample times and a model error ``d_k`` held
constant on each interval ``[t_k, t_{k+1}]`` (zero-order hold) that minimise

.. math::

    J = \\sum_k r_k^T R^{-1} r_k + \\sum_k h_k d_k^T W d_k,
    \\qquad r_k = y_k - g(x_k),\\ h_k = t_{k+1} - t_k,

subject to ``x_{k+1} = Phi_k(x_k, d_k)``, the flow of
``x' = f(x, u, t) + E d`` over one interval (classical RK4, optionally with
sub-steps), where ``E`` holds the identity columns of the error states. The
integral of the paper's cost is exact for a piecewise-constant ``d``.

Gauss-Newton: the dynamics and the measurement function are linearised about
the current trajectory (the RK4 variational equations give ``A_k = dPhi/dx``
and ``G_k = dPhi/dd`` exactly for the discrete map), and the
equality-constrained least-squares subproblem is solved exactly. Eliminating
``d_k = -(h_k W)^{-1} G_k^T lambda_k`` (the discrete form of the paper's
eq. 7) leaves a symmetric indefinite KKT system in ``[x_k, lambda_k]``,
ordered per sample, whose bandwidth is ``2 n - 1``. It is solved by LAPACK's
banded LU with partial pivoting (``dgbtrf``/``dgbtrs``), so one iteration
costs ``O(N n^3)`` time and ``O(N n^2)`` memory. A line search on an exact
l1 merit function (cost + penalty on the dynamics defects) globalises the
iteration for nonlinear models.

The same factorisation yields ``log|det K|``; for a linear(ised) Gaussian
model with a flat prior on ``x_0`` and ``d_k ~ N(0, (h_k W)^{-1})`` the
restricted marginal likelihood of ``W`` is

.. math::

    -2 \\log p(y | W) = J_{min}(W) + \\log|\\det K(W)|
    + \\sum_k \\log\\det R_k + (N_{obs} - n) \\log 2\\pi,

because ``|det K| = det(M) / prod_k det(h_k W)`` with ``M`` the Hessian of
``J / 2`` in the free variables ``(x_0, d)``.

A Gaussian prior ``N(0, P)`` on some states of each record's initial state
(``initial_prior``: an error model whose ``d`` has a stationary
distribution) adds ``x_0^T P^-1 x_0`` to ``J`` (its information to the
first block of the KKT matrix) and ``log det(2 pi P)`` per record to
``-2 log p(y | W)``: it is a measurement of those states, of value 0 and
covariance ``P``.

Units: the KKT pivots mix ``R^-1`` (state rows) with ``h W^-1`` (multiplier
rows), so in the data's own units a noise variance far from one (data in
nanometres, say) would spread them over more decades than double precision
holds, and a well-posed problem would look singular; states of very
different scales (a displacement of 1e-3 m next to a force of 50 N) would do
the same to each other, and finite-difference steps, the merit function and
the convergence tests would weigh them by their units. The solver therefore
works internally in one unit per state, ``S = diag(s)``, and one per
measured channel, ``Sy = diag(sy)`` (:mod:`.units`: ``sy`` the noise
standard deviations, ``s`` what the channels and the model give each
state): ``z = S^-1 x``, ``Sy^-1 y``, ``Sy^-1 R Sy^-1``, ``S^-1 f(S z)``,
``Sy^-1 g(S z)``, ``Sy^-1 C S``, ``S_e W S_e`` (``S_e`` the error states'
units). The units change with the user's units exactly as the states and
channels do, so the internal problem, and every answer, is the same in any
unit system; everything public is in the user's units.

Output error is the same problem with the dynamics as hard constraints (no
model error, ``q = 0``: ``S_k = 0`` in the KKT system) and global parameters
``theta`` (correction coefficients, physical parameters, measurement
offsets) bordering the band (:mod:`~pysindy_mme.solver.kkt`): every
sample interval is a shooting segment, all of them integrated as one
vectorised batch, and the continuity conditions close as Gauss-Newton
converges (multiple shooting in its limit, Bock's method, the paper's ref.
[9]). Started from the MME state estimate, it does not suffer single
shooting's local minima on long or chaotic records, and its cost is linear
in the record with Python loops over RK4 sub-steps only.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..core.blockwise import all_finite, first_true, max_abs, row_max_abs
from ..core.integrate import InputSignal, _small_matmul, rk4_flow
from ..core.jacobian import rowwise_jacobian
from ..exceptions import DivergenceError
from .gauss_newton import GaussNewton
from .kkt import (
    CHUNK,
    BandedKKT,
    Border,
    equilibrated_inverse,
    keep_factor,
    kept_factor,
    solve_reduced,
)
from .observability import unobservable_directions
from .records import Linearization, SmootherResult
from .units import Dynamics, channel_units, internal_unit, state_units

# A KKT pivot below this fraction of the largest one triggers the
# observability check (see MMESmoother._kkt_step).
_SUSPECT_PIVOT = 1e-10
# Growth of a perturbation over one interval (max |A_k|) beyond which the
# linearised model is treated as exploding.
_MAX_GROWTH = 1e6

__all__ = ["MMESmoother", "SmootherResult", "box_qp", "internal_unit"]


def box_qp(S, g, lower, upper):
    """Minimise ``1/2 v^T S v - g^T v`` over ``lower <= v <= upper``.

    ``S`` is symmetric positive semi-definite (a reduced Hessian) and
    ``lower <= 0 <= upper`` (entries may be infinite), so ``v = 0`` is
    feasible and the primal active-set method starts there: each pass
    solves for the free entries with the held ones fixed (equilibrated
    pseudo-inverse, like the unbounded step, so parameters of any scale and
    undetermined directions are handled alike), walks towards that solution
    until a bound blocks (the blocking entry is then held), and when nothing
    blocks releases a held entry whose multiplier has the wrong sign (the
    gradient ``S v - g`` pulls it inside). The objective never increases,
    and for a positive definite ``S`` the method ends in finitely many
    passes at the exact minimiser.

    Returns ``(v, active)``: ``active`` is -1 / +1 where ``v`` is held on
    its lower / upper bound, 0 elsewhere.
    """
    p = g.size
    # start on the bounds the current point already touches
    active = np.where(lower >= 0.0, -1, np.where(upper <= 0.0, 1, 0))
    v = np.zeros(p)
    for _ in range(4 * p + 10):
        held = active != 0
        target = np.where(active < 0, lower, np.where(active > 0, upper, 0.0))
        free = ~held
        if free.any():
            inverse, _ = equilibrated_inverse(S[np.ix_(free, free)])
            rhs = g[free] - S[np.ix_(free, held)] @ target[held]
            target[free] = inverse @ rhs
        step = target - v
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(
                step < 0,
                (lower - v) / step,
                np.where(step > 0, (upper - v) / step, np.inf),
            )
        room = np.where(free, room, np.inf)
        j = int(np.argmin(room))
        if room[j] < 1.0:
            v = v + max(room[j], 0.0) * step
            active[j] = -1 if step[j] < 0 else 1
            v[j] = lower[j] if step[j] < 0 else upper[j]
            continue
        v = target
        grad = S @ v - g
        # a held entry stays held while the gradient pushes it outwards (up
        # to rounding of the terms that make it up)
        slack = 1e-12 * (np.abs(g) + np.abs(S) @ np.abs(v))
        wrong = ((active < 0) & (grad < -slack)) | ((active > 0) & (grad > slack))
        if not wrong.any():
            break
        diag = np.sqrt(np.maximum(np.abs(np.diag(S)), np.finfo(float).tiny))
        j = int(np.argmax(np.where(wrong, np.abs(grad) / diag, -1.0)))
        active[j] = 0
    return v, active


def mask_patterns(mask):
    """``np.unique(mask, axis=0, return_inverse=True)`` without sorting rows.

    The same patterns in the same (lexicographic) order and the same inverse,
    so every sum over patterns is the same sum. Why: every solver built on a
    long record (each output-error trial fit builds one) sorted its ``N``
    rows, 0.4 s at 10^6 samples for a record without a single gap. A record
    without gaps is one pattern; otherwise each row is coded as an integer,
    the first channel the most significant bit (the order of the rows), and
    the integers are sorted.
    """
    mask = np.asarray(mask, dtype=bool)
    N, m = mask.shape
    if N and np.all(mask == mask[0]):
        return mask[:1].copy(), np.zeros(N, dtype=np.intp)
    if m > 62:  # no integer code: the general sort
        patterns, inverse = np.unique(mask, axis=0, return_inverse=True)
        return patterns, np.asarray(inverse).ravel()
    weights = np.left_shift(1, np.arange(m - 1, -1, -1, dtype=np.int64))
    codes, inverse = np.unique(mask.astype(np.int64) @ weights, return_inverse=True)
    patterns = (codes[:, None] & weights[None, :]) != 0
    return patterns, np.asarray(inverse).ravel()


class _Scaled:
    """``func(z * scale) / divide`` per column: a measurement function on the
    solver's states (a class, not a closure: a fit holding it pickles when
    the function does)."""

    def __init__(self, func, scale, divide):
        self.func, self.scale, self.divide = func, scale, divide

    def __call__(self, z):
        return self.func(z * self.scale) / self.divide


class _ScaledJacobian:
    """``Sy^-1 H(S z) S``: the measurement Jacobian on the solver's states."""

    def __init__(self, jacobian, scale, divide, shape):
        self.jacobian, self.scale, self.divide = jacobian, scale, divide
        self.shape = shape

    def __call__(self, z):
        h = np.asarray(self.jacobian(z * self.scale), dtype=float)
        return h.reshape(self.shape) * (
            self.scale[None, None, :] / self.divide[None, :, None]
        )


class MMESmoother(GaussNewton):
    """Direct transcription of MME / output error on one record (inputs checked).

    Parameters
    ----------
    model : ModelFunction or ParametricModel
        The model ``f(x, t, u)`` (or ``f(x, t, u; theta)`` with ``n_params``
        global parameters to estimate).
    y : ndarray (N, m)
        Measurements; NaN marks a missing value (its residual is dropped).
    t : ndarray (N,)
        Strictly increasing sample times.
    R : ndarray (m, m)
        Measurement noise covariance (positive definite).
    error_states : ndarray of int (q,)
        States the model error enters; empty for output error (the dynamics
        hold exactly).
    measurement : ndarray (m, n) or callable
        A linear measurement matrix ``C`` (``y = C x``) or a vectorised
        ``g(x) -> (N, m)``.
    measurement_jacobian : callable or None
        ``dg/dx(x) -> (N, m, n)`` for a callable ``measurement``; central
        differences if None.
    u : ndarray (N, m_u), callable ``u(t)``, InputSignal or None
        Known inputs.
    n_substeps : int
        RK4 steps per sample interval.
    max_iter : int
        Gauss-Newton iterations per solve.
    tol : float
        Stop when the first-order predicted decrease of the merit function
        is below ``tol`` times the merit.
    x_init : ndarray (N, n) or None
        Initial trajectory; by default the measured states are taken from the
        data (interpolated over missing samples) and the others are zero.
    theta_init : ndarray (p,), optional
        Starting parameters (required when the model has parameters).
    measurement_offsets : ndarray (m, p), optional
        ``y = g(x) + M theta``: parameters that shift the measurements
        (constant offsets per channel).
    input_hold : {"linear", "zoh"}
        How an input array is applied between samples.
    theta_bounds : ndarray (p, 2), optional
        ``[lower, upper]`` per parameter (``-inf`` / ``inf``: none). Every
        iterate stays inside: each Gauss-Newton step solves its subproblem
        with the bounds (:meth:`_bounded_step`).
    starts : sequence of int, optional
        Several records on one sample axis: the samples where a new record
        starts (after 0). Between the last sample of one record and the first
        of the next there is no dynamics link (a "break": no defect, no model
        error, the next record's first state is a free initial state), and
        ``t`` need only increase within each record.

    Attributes
    ----------
    initial_prior : callable or None
        None (the default): a flat prior on each record's initial state.
        Else ``initial_prior(W) -> (states, P)`` or None: a Gaussian prior
        ``N(0, P)`` (``P`` of shape ``(len(states), len(states))``, user
        units) on those states of each record's initial state, for the
        weight ``W`` of the solve (user units).
    unit : ndarray (n,)
        Each state's internal unit (:func:`.units.state_units`, from the
        noise and the starting trajectory: ``x_init`` or the data).
    channel_unit : ndarray (m,)
        Each measured channel's internal unit, its noise sd. ``y``, ``R``,
        ``model``, :meth:`initial_guess` and everything :meth:`solve` takes
        and returns are in the user's units; the underscored internals
        (``Rinv``, linearisations, KKT) are in the internal units.
    """

    # Intervals integrated per vectorised block (see kkt.CHUNK).
    _CHUNK = CHUNK

    def __init__(
        self,
        model,
        y,
        t,
        R,
        error_states,
        measurement,
        measurement_jacobian=None,
        u=None,
        n_substeps: int = 1,
        max_iter: int = 50,
        tol: float = 1e-8,
        x_init=None,
        theta_init=None,
        measurement_offsets=None,
        input_hold: str = "linear",
        theta_bounds=None,
        starts=None,
    ):
        self.model = model
        self.y = np.asarray(y, dtype=float)
        self.t = np.asarray(t, dtype=float)
        self.N, self.m = self.y.shape
        self.starts = np.unique(np.asarray([] if starts is None else starts, int))
        #: intervals that are breaks between records (no dynamics link)
        self.breaks = self.starts - 1
        self.n_records = 1 + self.starts.size
        self.h = np.diff(self.t)
        self.h[self.breaks] = 0.0  # a break is integrated over no time
        # the interval lengths to divide by (1 on a break, where d = 0)
        self._h_div = self.h.copy()
        self._h_div[self.breaks] = 1.0
        self.n = model.n_states
        self.es = np.asarray(error_states, dtype=int)
        self.q = self.es.size
        self.n_substeps = int(n_substeps)
        self.max_iter = int(max_iter)
        self.tol = float(tol)
        self.inputs = (
            u if isinstance(u, InputSignal) else InputSignal(u, self.t, input_hold)
        )
        self.mask = ~np.isnan(self.y)
        self.n_obs = int(self.mask.sum())
        self.R = np.asarray(R, dtype=float)
        self.x_init = None if x_init is None else np.asarray(x_init, dtype=float)
        self.theta_init = (
            np.zeros(int(getattr(model, "n_params", 0)))
            if theta_init is None
            else np.asarray(theta_init, float)
        )
        self.C = None if callable(measurement) else np.asarray(measurement, float)
        # Internal units (see the module docstring), set from the starting
        # trajectory: one per channel (its noise sd), one per state.
        sy = self.channel_unit = channel_units(self.R)
        s = self.unit = self._state_units(measurement, measurement_jacobian)
        self._f = Dynamics(model, s)
        self.p = self._f.p
        M = (
            np.zeros((self.m, self.p))
            if measurement_offsets is None
            else measurement_offsets
        )
        self._M = np.asarray(M, dtype=float) / sy[:, None]
        self.theta_bounds = None
        if theta_bounds is not None:
            self.theta_bounds = np.asarray(theta_bounds, dtype=float).reshape(self.p, 2)
        self._y0 = np.where(self.mask, self.y / sy, 0.0)
        if callable(measurement):
            self._g = _Scaled(measurement, s, sy)
            self._g_jac = None
            if measurement_jacobian is not None:
                # Sy^-1 H(S z) S
                self._g_jac = _ScaledJacobian(
                    measurement_jacobian, s, sy, (self.N, self.m, self.n)
                )
        else:
            self._C = self.C * (s[None, :] / sy[:, None])
        self._set_noise(self.R / np.outer(sy, sy))
        self._E = np.zeros((self.n, self.q))  # columns of E: the error states
        self._E[self.es, np.arange(self.q)] = 1.0
        # Names of the states in diagnostics (default x0, x1, ...).
        self.state_labels = None
        self.initial_prior = None
        #: the prior of the current solve in internal units:
        #: ``(states, information, -2 log of its normalisation)`` or None
        self._prior = None
        self._record_starts = np.concatenate([[0], self.starts]).astype(int)
        self._scale = None
        self._HRQ = None
        self._solving = False
        self._kkt = BandedKKT(self.N, self.n, self.breaks)

    # ------------------------------------------------------------------ setup
    def _set_noise(self, R):
        """Per-sample inverse covariances, missing channels dropped.

        ``R`` in internal units; sets ``Rinv`` and ``_logdetR``.
        """
        patterns, inverse = mask_patterns(self.mask)
        self.Rinv = np.zeros((self.N, self.m, self.m))
        self._logdetR = 0.0
        for p, pat in enumerate(patterns):
            rows = inverse == p
            idx = np.flatnonzero(pat)
            if idx.size == 0:
                continue
            sub = R[np.ix_(idx, idx)]
            block = np.zeros((self.m, self.m))
            block[np.ix_(idx, idx)] = np.linalg.inv(sub)
            self.Rinv[rows] = block
            self._logdetR += rows.sum() * np.linalg.slogdet(sub)[1]

    def _state_units(self, measurement, measurement_jacobian):
        """Each state's unit (:func:`.units.state_units`) from the starting
        trajectory (:meth:`initial_guess`: ``x_init`` or the data)."""
        x = np.nan_to_num(self.initial_guess()[0], posinf=0.0, neginf=0.0)
        fallback = internal_unit(self.R)
        if self.C is not None:
            H = self.C
        else:
            # the measurement's Jacobian at a sample of the trajectory, by
            # differences in provisional units (each state's RMS along it)
            rows = np.unique(np.linspace(0, self.N - 1, min(200, self.N)).astype(int))
            rms = np.sqrt(np.mean(x[rows] ** 2, axis=0))
            prov = np.where(rms > 0, rms, fallback)
            try:
                with np.errstate(all="ignore"):
                    if measurement_jacobian is not None:
                        H = measurement_jacobian(x)
                        H = np.asarray(H, float).reshape(self.N, self.m, self.n)
                    else:
                        H = (
                            rowwise_jacobian(
                                lambda z: measurement(z * prov),
                                x[rows] / prov,
                                scale=1.0,
                            )
                            / prov[None, None, :]
                        )
            except Exception:  # a measurement that fails here fails its checks
                H = np.zeros((self.m, self.n))
            H = np.where(np.isfinite(H), H, 0.0)
        return state_units(
            self.model,
            x,
            self.t,
            self.inputs.grid(),
            self.theta_init,
            H,
            self.channel_unit,
            self.h,
            fallback,
        )

    def u_grid(self):
        """Inputs on the sample grid (or None)."""
        return self.inputs.grid()

    def _measure(self, z, theta=None):
        """``g(z) + M theta`` on the whole trajectory (internal units)."""
        if self.C is not None:
            out = z @ self._C.T
        else:
            out = np.asarray(self._g(z), dtype=float).reshape(self.N, self.m)
        if self.p and theta is not None:
            out = out + self._M @ theta
        return out

    def measurement_jacobian(self, x):
        """``dg/dz`` in internal units at internal-unit ``x``: (m, n) or (N, m, n)."""
        if self.C is not None:
            return self._C
        if self._g_jac is not None:
            return np.asarray(self._g_jac(x), dtype=float).reshape(
                self.N, self.m, self.n
            )
        jac = np.empty((self.N, self.m, self.n))
        step = np.cbrt(np.finfo(float).eps) * np.maximum(np.abs(x), 1.0)
        for j in range(self.n):
            xp = x.copy()
            xm = x.copy()
            xp[:, j] += step[:, j]
            xm[:, j] -= step[:, j]
            jac[:, :, j] = (self._measure(xp) - self._measure(xm)) / (
                2.0 * step[:, [j]]
            )
        return jac

    def initial_guess(self):
        """Trajectory from the data (or ``x_init``) and ``d = 0`` (user units)."""
        d = np.zeros((self.N - 1, self.q))
        if self.x_init is not None:
            return self.x_init.copy(), d
        filled = self.y.copy()
        idx = np.arange(self.N)
        for j in range(self.m):
            ok = self.mask[:, j]
            if ok.any():
                filled[:, j] = np.interp(idx, idx[ok], self.y[ok, j])
            else:
                filled[:, j] = 0.0
        if self.C is not None:
            x = np.linalg.lstsq(self.C, filled.T, rcond=None)[0].T
        else:
            x = np.zeros((self.N, self.n))
        return x, d

    def scale(self, x):
        """A state scale used to recognise a model that explodes."""
        if self._scale is None:
            s = float(np.max(np.abs(x))) if x.size else 0.0
            self._scale = s if s > 0 else 1.0
        return self._scale

    # ------------------------------------------------------------- dynamics
    def flow(
        self, x, d, theta=None, jacobian: bool = True, extra=None, only_extra=False
    ):
        """``Phi_k(x_k, d_k; theta)`` for all intervals (internal units).

        With ``jacobian``, also ``A_k = dPhi/dx``, ``G_k = dPhi/dd``,
        ``B_k = dPhi/dtheta`` (exact for the discrete map). ``extra`` is an
        optional ``(n_extra, forcing)`` pair: ``forcing(z, t, u) -> (K, n,
        n_extra)`` is the derivative of the right-hand side with respect to
        parameters that are not in the model (at zero); their sensitivities
        are returned as a fourth array (score tests of candidate terms).
        ``only_extra``: return ``(phi, X)`` only; the flow then carries the
        extra columns alone (not ``A``, ``G``, ``B``: the same numbers for
        ``X``, in fewer passes), except with overflow terms, whose split
        needs them all.
        """
        theta = self.theta_init if theta is None else theta
        n, q, p = self.n, self.q, self.p
        n_extra = 0 if extra is None else extra[0]
        K = self.N - 1
        f = self._f
        # overflow terms, solved exactly around each RK4 step; theta's first
        # entry is column n + q of the flow's derivatives
        split = f.split_at(theta, n + q)
        lean = bool(only_extra and n_extra and jacobian and split is None)
        full = jacobian and not lean
        phi = np.empty((K, n))
        A = np.empty((K, n, n)) if full else None
        G = np.empty((K, n, q)) if full else None
        B = np.empty((K, n, p)) if full else None
        X = np.empty((K, n, n_extra)) if n_extra else None
        for lo in range(0, K, self._CHUNK):
            sl = slice(lo, min(lo + self._CHUNK, K))
            Ed = d[sl] @ self._E.T
            k_sl = sl.stop - sl.start

            def rhs(z, s, u, Ed=Ed):
                return f(z, s, u, theta) + Ed

            def jac_p(z, s, u, k_sl=k_sl):
                if lean:
                    return extra[1](z, s, u)
                if not (p or n_extra):
                    return self._E  # d enters additively: dF/dd = E
                parts = [np.broadcast_to(self._E, (k_sl, n, q))]
                if p:
                    parts.append(f.param_jacobian(z, s, u, theta))
                if n_extra:
                    parts.append(extra[1](z, s, u))
                return np.concatenate(parts, axis=2)

            out = rk4_flow(
                rhs,
                x[sl],
                self.t[sl],
                self.h[sl],
                lambda frac, sl=sl: self.inputs.on_intervals(frac, sl),
                self.n_substeps,
                jac_x=(lambda z, s, u: f.jacobian(z, s, u, theta))
                if jacobian
                else None,
                jac_p=jac_p,
                n_params=n_extra if lean else q + p + n_extra,
                split=split,
                state_columns=not lean,
            )
            phi[sl] = out.phi
            if lean:
                X[sl] = out.D
            elif jacobian:
                A[sl] = out.D[:, :, :n]
                G[sl] = out.D[:, :, n : n + q]
                B[sl] = out.D[:, :, n + q : n + q + p]
                if n_extra:
                    X[sl] = out.D[:, :, n + q + p :]
        if self.breaks.size:
            # no dynamics link across a break: no defect, no sensitivities
            kb = self.breaks
            phi[kb] = x[kb + 1]
            if full:
                A[kb] = G[kb] = B[kb] = 0.0
            if jacobian and n_extra:
                X[kb] = 0.0
        if not jacobian:
            return phi
        if only_extra and n_extra:
            return phi, X
        return (phi, A, G, B, X) if n_extra else (phi, A, G, B)

    def _check_flow(self, phi, x):
        """Raise if one interval of the model explodes (or is not finite)."""
        limit = 1e6 * self.scale(x)

        def bad(sl):
            # column by column: a reduction over each row's n entries would
            # run numpy's inner loop n elements long
            out = np.zeros(sl.stop - sl.start, dtype=bool)
            with np.errstate(all="ignore"):
                for j in range(phi.shape[1]):
                    col = phi[sl, j]
                    out |= ~np.isfinite(col)
                    out |= np.abs(col - x[sl, j]) > limit
            return out

        k = first_true(bad, phi.shape[0])
        if k >= 0:
            with np.errstate(all="ignore"):
                x_k, phi_k = x[k] * self.unit, phi[k] * self.unit
            raise DivergenceError(
                "assumed_model blows up within one sample interval (interval "
                f"{k}, t = {self.t[k]:.6g} to {self.t[k + 1]:.6g}, starting from "
                f"x = {x_k.tolist()}): integrating it there gives "
                f"{phi_k.tolist()}. The model is unstable or stiff at this "
                "sampling rate; check the model and the units of the data, or "
                "increase n_substeps (MME(n_substeps=...); discover(n_substeps="
                "...); on the command line --substeps)."
            )

    def linearize(self, x, d, theta=None) -> Linearization:
        """The KKT data at ``(x, d, theta)`` (internal units)."""
        theta = self.theta_init if theta is None else np.asarray(theta, float)
        phi, A, G, B = self.flow(x, d, theta, jacobian=True)
        self._check_flow(phi, x)
        if not (all_finite(A) and all_finite(G) and all_finite(B)):
            raise DivergenceError(
                "the Jacobian of assumed_model is not finite along the current "
                "trajectory; the model cannot be linearised there"
            )
        growth = row_max_abs(A)
        if growth.max(initial=0.0) > _MAX_GROWTH:
            # A perturbation that grows a million-fold within one interval
            # (a model with finite-time blow-up near the trajectory, or RK4
            # far outside its stability region) makes the linearisation, and
            # with it the KKT system, numerically meaningless. Without this
            # the W search runs on until the KKT matrix looks singular and
            # the error blames observability.
            k = int(np.argmax(growth))
            raise DivergenceError(
                "assumed_model amplifies perturbations by a factor of "
                f"{growth[k]:.3g} within one sample interval (interval {k}, "
                f"t = {self.t[k]:.6g} to {self.t[k + 1]:.6g}, at x = "
                f"{(x[k] * self.unit).tolist()}): it is unstable or stiff at "
                "this sampling rate, at least near the estimated trajectory. "
                "Check the model and the units of the data, or increase "
                "n_substeps (MME(n_substeps=...); discover(n_substeps=...); on "
                "the command line --substeps)."
            )
        r = self.residuals(x, theta)
        H = self.measurement_jacobian(x)
        # in place: phi is not needed beyond its defects
        defects = np.subtract(phi, x[1:], out=phi)
        return Linearization(
            x=x, d=d, theta=theta, A=A, G=G, B=B, defects=defects, r=r, H=H
        )

    # ----------------------------------------------------------------- costs
    def residuals(self, x, theta=None):
        """``y - g(x) - M theta`` in internal units, 0 where ``y`` is missing."""
        return np.where(self.mask, self._y0 - self._measure(x, theta), 0.0)

    def measurement_cost(self, r):
        return float(np.einsum("ki,kij,kj->", r, self.Rinv, r))

    def model_error_cost(self, d, W):
        return float(np.einsum("k,ki,ij,kj->", self.h, d, W, d))

    def prior_cost(self, x, dx=None):
        """``sum x_0^T P^-1 x_0`` over the records' initial states (0 without
        a prior); with ``dx``, its slope along ``dx`` instead."""
        if self._prior is None:
            return 0.0
        idx, info, _ = self._prior
        z0 = x[self._record_starts][:, idx]
        if dx is not None:
            return 2.0 * float(
                np.einsum("ri,ij,rj->", z0, info, dx[self._record_starts][:, idx])
            )
        return float(np.einsum("ri,ij,rj->", z0, info, z0))

    def _set_prior(self, W):
        """:attr:`initial_prior` at the weight ``W`` (user units), internally."""
        prior = None if self.initial_prior is None else self.initial_prior(W)
        if prior is None:
            self._prior = None
            return
        idx, P = prior
        idx = np.asarray(idx, dtype=int)
        P = np.atleast_2d(np.asarray(P, dtype=float))
        su = self.unit[idx]
        info = np.linalg.inv(P / np.outer(su, su))
        # per record log det(2 pi P) in user units: the conversion of the
        # likelihood in solve() treats every initial state as flat (det S
        # per state), which a normalised prior is not
        norm = self._record_starts.size * np.linalg.slogdet(2.0 * np.pi * P)[1]
        self._prior = (idx, 0.5 * (info + info.T), float(norm))

    # ------------------------------------------------------------------- KKT
    def kkt_system(self, lin: Linearization, W=None, Winv=None):
        """Factorise the KKT matrix at ``lin``; returns ``(fac, HR, GW, E, D)``.

        ``E``/``D`` border the band for the parameters (``p = 0``: empty).
        Raises ``LinAlgError`` if the subproblem is singular.
        """
        n, N, p = self.n, self.N, self.p
        H = lin.H
        if H.ndim == 2:
            # linear measurement: H^T R^-1 and H^T R^-1 H never change (kept
            # for the iterations of a solve only, see solve)
            HRQ = self._HRQ
            if HRQ is None:
                HR = np.einsum("ai,kab->kib", H, self.Rinv)
                HRQ = (HR, HR @ H)
                if self._solving:
                    self._HRQ = HRQ
            HR, Q = HRQ
        else:
            HR = np.einsum("kai,kab->kib", H, self.Rinv)  # H^T Rinv
            Q = HR @ H
        if self._prior is not None:
            idx, info, _ = self._prior
            Q = Q.copy()  # never the cached one
            for k0 in self._record_starts:
                Q[k0][np.ix_(idx, idx)] += info
        GW = S = None
        if self.q:
            GW, S = _error_blocks(lin.G, Winv, self._h_div)
        # the matrix depends on the linearisation's A (G, H) and on W only:
        # a fit's statistics at its last step's linearisation (the result
        # keeps its A) reuse that step's factor while no other was made
        key = (self, lin.A, lin.G, lin.H, W.tobytes() if W is not None else b"")
        fac = kept_factor(key)
        if fac is None:
            fac = self._kkt.factor(Q, lin.A, S)
            keep_factor(key, fac)
        # the border by its blocks: B is the linearisation's own array
        Ex = HR @ self._M if p and np.any(self._M) else None
        E = Border(Ex, lin.B, N, n, p)
        D = np.zeros((p, p))
        if p:
            RM = np.einsum("kab,bp->kap", self.Rinv, self._M)
            D = np.einsum("ap,kaq->pq", self._M, RM)
        return fac, HR, GW, E, D

    def _kkt_step(self, lin: Linearization, W, Winv):
        """One Gauss-Newton subproblem.

        Returns ``(dx, d_new, dtheta, lam, logdet, rank_deficient, active)``;
        ``active`` (None without bounds) is -1 / +1 for a parameter the step
        puts or holds on its lower / upper bound, else 0.
        """
        n, N = self.n, self.N
        fac, HR, GW, E, D = self.kkt_system(lin, W, Winv)
        # A zero pivot computed in floating point is rarely exactly zero (it
        # is rounding, ~1e-16 relative), while a weakly determined but
        # well-posed problem (a tiny W lets the unmeasured states wander) has
        # legitimately tiny pivots too, so the pivots alone cannot tell the
        # two apart: a suspiciously small one is settled by the observability
        # of the linearisation, which does not depend on W.
        if fac.pivot_ratio <= _SUSPECT_PIVOT and self._unobservable_directions(lin):
            raise np.linalg.LinAlgError("singular KKT system")
        rhs = np.zeros((N, 2 * n))
        rhs[:, :n] = np.einsum("kib,kb->ki", HR, lin.r)
        if self._prior is not None:
            idx, info, _ = self._prior
            k0 = self._record_starts
            rhs[np.ix_(k0, idx)] -= lin.x[np.ix_(k0, idx)] @ info
        rhs[:-1, n:] = -lin.defects
        if self.q:
            rhs[:-1, n:] += np.einsum("kiq,kq->ki", lin.G, lin.d)
        c = (
            np.einsum("ap,kab,kb->p", self._M, self.Rinv, lin.r)
            if self.p
            else np.zeros(0)
        )
        # K^-1 E stays with the factor until the iteration knows whether
        # this step is the last (GaussNewton._solve): at a converged fit the
        # statistics that follow solve the same bordered system again
        sol = solve_reduced(fac, E, D, rhs, c, keep_border=True)
        z, dtheta, active = sol.z, sol.dtheta, None
        if self.theta_bounds is not None:
            z, dtheta, active = self._bounded_step(fac, E, D, rhs, c, sol, lin.theta)
        dx = z[:, :n]
        lam = z[:-1, n:]
        d_new = lin.d
        if self.q:
            d_new = -np.einsum("kiq,ki->kq", GW, lam) / self._h_div[:, None]
        logdet = fac.logdet
        if self.p:
            sign, logdet_sc = np.linalg.slogdet(sol.Sc)
            logdet += logdet_sc if sign != 0 else np.inf
        return dx, d_new, dtheta, lam, logdet, sol.rank_deficient, active

    def project(self, theta):
        """``theta`` clipped into ``theta_bounds`` (itself without bounds)."""
        theta = np.asarray(theta, dtype=float)
        if self.theta_bounds is None:
            return theta
        return np.clip(theta, self.theta_bounds[:, 0], self.theta_bounds[:, 1])

    def _bounded_step(self, fac, E, D, b, c, sol, theta):
        """The Gauss-Newton step with ``theta + dtheta`` kept inside the bounds.

        The bounds act on ``theta`` only, which borders the band: eliminating
        the states leaves the subproblem in ``dtheta`` alone, the quadratic
        ``1/2 dtheta^T Sc dtheta - g^T dtheta`` (``Sc`` the reduced Hessian,
        ``g = c - E^T K^-1 b``), now over a box. That small dense problem is
        solved exactly (:func:`box_qp`) and the states follow from one more
        banded solve, ``z = K^-1 (b - E dtheta)``. Solving the subproblem
        with its bounds, rather than projecting the free step, is what makes
        a parameter held on a bound a proper stopping point: at a KKT point
        of the bounded problem (pinned there, the data pushing outward) the
        bounded step is zero, so the predicted decrease, the convergence
        test, vanishes; a projected free step would still point outwards
        and the line search would fail instead of converging. Every trial
        point ``theta + alpha dtheta`` (``0 < alpha <= 1``) is then inside
        the box too (it is convex), and the step is a descent direction of
        the merit function like the free one.

        Costs nothing extra while the free step stays inside the box (it is
        then the bounded step too, and is returned unchanged).
        """
        lower = np.minimum(self.theta_bounds[:, 0] - theta, 0.0)
        upper = np.maximum(self.theta_bounds[:, 1] - theta, 0.0)
        free = sol.dtheta
        if np.all((free > lower) & (free < upper)):
            return sol.z, free, np.zeros(self.p, dtype=int)
        Kb = fac.solve(b)
        g = c - E.t_dot(Kb[None])[:, 0]
        dtheta, active = box_qp(sol.Sc, g, lower, upper)
        z = Kb - fac.solve(E.dot(dtheta))
        return z, dtheta, active

    # ----------------------------------------------------------------- solve
    def solve(self, W=None, start: SmootherResult | None = None) -> SmootherResult:
        """Gauss-Newton with an l1-merit line search for a fixed ``W``.

        ``W`` (ignored for output error, ``q = 0``) and ``start`` (a previous
        result of this solver, the warm start) and the result are in the
        user's units.
        """
        W = np.zeros((0, 0)) if W is None else np.atleast_2d(np.asarray(W, float))
        if W.shape == (1, 1) and self.q != 1:
            W = W[0, 0] * np.eye(self.q)
        if not self.q:
            W = np.zeros((0, 0))
        s, sy, se = self.unit, self.channel_unit, self.unit[self.es]
        self._set_prior(W)
        # H^T R^-1 and H^T R^-1 H are kept for the iterations of one solve
        # only: a finished fit keeps its solver for later statistics and
        # warm starts, and on a long record a study holds several of them
        # (48 bytes per sample each for two states); recomputing them for a
        # statistic is one einsum
        self._solving = True
        try:
            # the starting linearisation is passed, not bound here: this
            # frame would hold it through every iteration of the solve (a
            # third linearisation alive at the peak of a study)
            res = self._solve(W * np.outer(se, se), self._start_lin(start))
        finally:
            self._solving = False
            self._HRQ = None
        # Back to the user's units. J is unit-free; the multipliers (of J / 2
        # against defects in x) scale as 1 / s; the density of the N_obs
        # observations given the n free initial states as 1 / (the product
        # of the observed values' sy) times det(S) per free initial state,
        # hence |det K| as det(S)^-2 per record (flat prior on x_0, see the
        # docstring: the K of the user's units is diag(S^-1, S) K diag(S^-1,
        # S), the last multiplier block of each record a dummy).
        log_det_s = float(np.sum(np.log(s)))
        log_sy = float(np.sum(self.mask.sum(axis=0) * np.log(sy)))
        # one free initial state per record (the solver's likelihood counts
        # one; the others' constant is added here, the same for every W)
        records = self.n_records
        extra = (self.n_records - 1) * self.n * np.log(2.0 * np.pi)
        defects = res._lin.defects if res._lin is not None else np.zeros((0, self.n))
        return dataclasses.replace(
            res,
            W=W,
            x=res.x * s,
            d=res.d * se,
            lam=res.lam / s,
            residuals=res.residuals * sy,
            logdet=res.logdet - 2.0 * records * log_det_s,
            neg2_log_likelihood=res.neg2_log_likelihood
            - extra
            + 2.0 * (log_sy - records * log_det_s),
            # max |defects * s| column by column (s > 0: the same number)
            max_defect=float(
                np.max([s[j] * max_abs(defects[:, j]) for j in range(self.n)])
            ),
        )

    def _start_lin(self, start: SmootherResult | None):
        """The linearisation a solve from ``start`` begins with (internal units)."""
        if start is not None and start._lin is not None:
            return start._lin
        s, se = self.unit, self.unit[self.es]
        x, d = (start.x, start.d) if start is not None else self.initial_guess()
        theta = start.theta if start is not None and self.p else self.theta_init
        return self.linearize(x / s, d / se, self.project(theta))

    def start_from(self, x, theta, d=None) -> SmootherResult:
        """A warm start at a given trajectory and parameters (user units)."""
        d = np.zeros((self.N - 1, self.q)) if d is None else d
        nan = float("nan")
        return SmootherResult(
            W=np.zeros((0, 0)),
            x=np.asarray(x, float),
            d=d,
            lam=np.zeros(0),
            residuals=np.zeros(0),
            cost=nan,
            measurement_cost=nan,
            model_error_cost=nan,
            logdet=nan,
            neg2_log_likelihood=nan,
            converged=False,
            n_iter=0,
            max_defect=nan,
            message="start",
            theta=np.asarray(theta, float),
        )

    def _unobservable_directions(self, lin, max_steps: int = 1000):
        """See :func:`.observability.unobservable_directions`."""
        return unobservable_directions(
            lin.A, lin.H, self.mask, self.state_labels, max_steps
        )

    def _apply_R_H(self, lin, dx, dtheta=None):
        """``Rinv_k (H_k dx_k + M dtheta)`` for every sample."""
        H = lin.H
        Hdx = dx @ H.T if H.ndim == 2 else np.einsum("kai,ki->ka", H, dx)
        if self.p and dtheta is not None:
            Hdx = Hdx + self._M @ dtheta
        return np.einsum("kab,kb->ka", self.Rinv, Hdx)


def _error_blocks(G, Winv, h):
    """``G W^-1`` (``(K, n, q)``) and ``S = G W^-1 G^T / h`` (``(K, n, n)``).

    With one error state every entry is a single product, so the flows'
    small products (:func:`~pysindy_mme.core.integrate._small_matmul`, over
    the rows) give numpy's batched matmul's numbers without its per-matrix
    overhead (72 ms against 11 for 10^6 rows of two states). With more,
    numpy's matmul as before (its sums may be ordered otherwise).
    """
    if G.shape[2] != 1:
        GW = G @ Winv
        return GW, (GW @ np.swapaxes(G, 1, 2)) / h[:, None, None]
    GW = np.multiply(G, Winv[0, 0])
    S = _small_matmul(GW, np.swapaxes(G, 1, 2))
    S /= h[:, None, None]
    return GW, S
