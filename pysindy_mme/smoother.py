"""The minimum model error estimation solver, linear in the number of samples.

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

Units: the KKT pivots mix ``R^-1`` (state rows) with ``h W^-1`` (multiplier
rows), so in the data's own units a noise variance far from one (data in
nanometres, say) would spread them over more decades than double precision
holds, and a well-posed problem would look singular. The solver therefore
works internally in units of ``s``, a power of two near the noise standard
deviation: ``z = x / s``, ``y / s``, ``R / s^2``, ``f(s z) / s``,
``g(s z) / s``, ``W s^2``. A power of two makes the change of units exact in
floating point; everything public is in the user's units.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import lapack

from .core.model import ModelFunction
from .exceptions import DivergenceError

# A KKT pivot below this fraction of the largest one triggers the
# observability check (see MMESmoother._solve_kkt).
_SUSPECT_PIVOT = 1e-10
# Growth of a perturbation over one interval (max |A_k|) beyond which the
# linearised model is treated as exploding.
_MAX_GROWTH = 1e6

__all__ = [
    "DivergenceError",
    "MMESmoother",
    "SmootherResult",
    "unobservable_states",
]


def internal_unit(R) -> float:
    """The solver's internal unit: a power of two near the noise's std. dev.

    With ``R / s^2`` of order one the KKT pivots of the state rows
    (``~ R^-1``) and of the multiplier rows (``~ h W^-1 ~ R`` at the
    reference weight) are of order one together, whatever the data's units.
    """
    sd = float(np.sqrt(np.mean(np.diag(np.atleast_2d(R)))))
    return float(np.ldexp(1.0, int(np.round(np.log2(sd)))))


def _scaled_model(model: ModelFunction, unit: float) -> ModelFunction:
    """``f_s(z) = f(s z) / s``; its finite-difference Jacobian steps in ``z``."""
    if unit == 1.0:
        return model

    def f(z, t, u):
        return model(unit * z, t, u) / unit

    scaled = ModelFunction(f, model.n_states, name=model.name)
    if type(model).jacobian is not ModelFunction.jacobian:
        # A model with its own Jacobian keeps it: d f_s / dz = J(s z).
        scaled.jacobian = lambda z, t, u=None, f0=None: model.jacobian(unit * z, t, u)
    return scaled


@dataclass
class _Linearization:
    """Everything the KKT system needs at one trajectory (independent of W)."""

    x: np.ndarray  # (N, n)
    d: np.ndarray  # (N-1, q)
    A: np.ndarray  # (N-1, n, n)
    G: np.ndarray  # (N-1, n, q)
    defects: np.ndarray  # (N-1, n): Phi_k(x_k, d_k) - x_{k+1}
    r: np.ndarray  # (N, m) residuals, 0 where y is missing
    H: np.ndarray  # (N, m, n) or (m, n) for a linear measurement


@dataclass
class SmootherResult:
    """Solution of the MME problem for one weight ``W``.

    Attributes
    ----------
    W : ndarray (q, q)
    x : ndarray (N, n)
        State estimate at the sample times.
    d : ndarray (N-1, q)
        Model error, constant on each interval.
    lam : ndarray (N-1, n)
        Multipliers of the dynamics constraints (of ``J / 2``).
    residuals : ndarray (N, m)
        ``y - g(x)``; NaN where ``y`` is missing.
    cost : float
        ``J`` at the solution.
    measurement_cost, model_error_cost : float
        Its two parts.
    logdet : float
        ``log|det K|`` of the last KKT matrix (see the module docstring).
    neg2_log_likelihood : float
        ``-2 log p(y | W)`` (restricted, Laplace approximation if nonlinear).
    converged : bool
    n_iter : int
        Gauss-Newton iterations (KKT solves).
    max_defect : float
        Largest dynamics defect ``|Phi_k(x_k, d_k) - x_{k+1}|`` at the end.
    message : str
    """

    W: np.ndarray
    x: np.ndarray
    d: np.ndarray
    lam: np.ndarray
    residuals: np.ndarray
    cost: float
    measurement_cost: float
    model_error_cost: float
    logdet: float
    neg2_log_likelihood: float
    converged: bool
    n_iter: int
    max_defect: float
    message: str
    _lin: _Linearization | None = field(default=None, repr=False)


class MMESmoother:
    """Minimum model error estimation on one trajectory (inputs already checked).

    Parameters
    ----------
    model : ModelFunction
        The assumed model ``f(x, t, u)``.
    y : ndarray (N, m)
        Measurements; NaN marks a missing value (its residual is dropped).
    t : ndarray (N,)
        Strictly increasing sample times.
    R : ndarray (m, m)
        Measurement noise covariance (positive definite).
    error_states : ndarray of int (q,)
        States the model error enters.
    measurement : ndarray (m, n) or callable
        A linear measurement matrix ``C`` (``y = C x``) or a vectorised
        ``g(x) -> (N, m)``.
    measurement_jacobian : callable or None
        ``dg/dx(x) -> (N, m, n)`` for a callable ``measurement``; central
        differences if None.
    u : ndarray (N, p), callable ``u(t) -> (N, p)`` or None
        Known inputs; arrays are interpolated linearly between samples.
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

    Attributes
    ----------
    unit : float
        The internal unit ``s`` (:func:`internal_unit`). ``y``, ``R``,
        ``model``, :meth:`initial_guess` and everything :meth:`solve` takes
        and returns are in the user's units; the underscored internals
        (``Rinv``, linearisations, KKT) are in units of ``s``.
    """

    def __init__(
        self,
        model: ModelFunction,
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
    ):
        self.model = model
        self.y = np.asarray(y, dtype=float)
        self.t = np.asarray(t, dtype=float)
        self.h = np.diff(self.t)
        self.N, self.m = self.y.shape
        self.n = model.n_states
        self.es = np.asarray(error_states, dtype=int)
        self.q = self.es.size
        self.n_substeps = int(n_substeps)
        self.max_iter = int(max_iter)
        self.tol = float(tol)
        self._u = u
        self._u_cache = {}
        self.mask = ~np.isnan(self.y)
        self.n_obs = int(self.mask.sum())
        self.R = np.asarray(R, dtype=float)
        # Internal units (see the module docstring): a linear measurement
        # y = C x is unit-free; g and f are wrapped.
        s = self.unit = internal_unit(self.R)
        self._f = _scaled_model(model, s)
        self._y0 = np.where(self.mask, self.y / s, 0.0)
        if callable(measurement):
            self.C = None
            self._g = (lambda z: measurement(s * z) / s) if s != 1.0 else measurement
            self._g_jac = None
            if measurement_jacobian is not None:
                self._g_jac = (
                    (lambda z: measurement_jacobian(s * z))
                    if s != 1.0
                    else measurement_jacobian
                )
        else:
            self.C = np.asarray(measurement, dtype=float)
        self._set_noise(self.R / s**2)
        # Columns of E (the error states) in the [x, d] derivative layout.
        self._Eb = np.zeros((self.n, self.n + self.q))
        self._Eb[self.es, self.n + np.arange(self.q)] = 1.0
        self.x_init = None if x_init is None else np.asarray(x_init, dtype=float)
        # Names of the states in diagnostics (default x0, x1, ...).
        self.state_labels = None
        self._scale = None
        self._HRQ = None
        self._band = None

    # ------------------------------------------------------------------ setup
    def _set_noise(self, R):
        """Per-sample inverse covariances, missing channels dropped.

        ``R`` in internal units; sets ``Rinv`` and ``_logdetR``.
        """
        patterns, inverse = np.unique(self.mask, axis=0, return_inverse=True)
        inverse = np.asarray(inverse).ravel()
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

    def _u_at(self, frac: float, sl=slice(None)):
        """Input at ``t_k + frac * h_k`` for the intervals ``sl`` (cached)."""
        if self._u is None:
            return None
        key = round(float(frac), 12)
        if key not in self._u_cache:
            if callable(self._u):
                s = self.t[:-1] + frac * self.h
                val = np.asarray(self._u(s), dtype=float).reshape(s.size, -1)
            else:
                u = self._u
                val = (1.0 - frac) * u[:-1] + frac * u[1:]
            self._u_cache[key] = val
        return self._u_cache[key][sl]

    def u_grid(self):
        """Inputs on the sample grid (or None)."""
        if self._u is None:
            return None
        if callable(self._u):
            return np.asarray(self._u(self.t), dtype=float).reshape(self.N, -1)
        return self._u

    def _measure(self, z):
        """``g(z)`` on the whole trajectory (internal units)."""
        if self.C is not None:
            return z @ self.C.T
        out = np.asarray(self._g(z), dtype=float)
        return out.reshape(self.N, self.m)

    def _measurement_jacobian(self, x):
        """``dg/dx`` (unit-free) at internal-unit ``x``: (m, n) or (N, m, n)."""
        if self.C is not None:
            return self.C
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
    # Intervals integrated per vectorised block: bounded temporaries stay in
    # cache and in the allocator's free lists (fresh multi-MB arrays cost page
    # faults), which keeps the time per sample flat up to 10^6 samples.
    _CHUNK = 1 << 15

    def flow(self, x, d, jacobian: bool = True):
        """``Phi_k(x_k, d_k)`` for all intervals, and optionally ``A_k, G_k``.

        Classical RK4 with ``n_substeps`` steps per interval; the derivatives
        come from the same stages (the variational equations of the discrete
        map), so Gauss-Newton sees the exact Jacobian of what it solves.
        """
        n, q = self.n, self.q
        K = self.N - 1
        phi = np.empty((K, n))
        A = np.empty((K, n, n)) if jacobian else None
        G = np.empty((K, n, q)) if jacobian else None
        for lo in range(0, K, self._CHUNK):
            sl = slice(lo, min(lo + self._CHUNK, K))
            out = self._flow_block(x, d, sl, jacobian)
            if jacobian:
                phi[sl], D = out
                A[sl] = D[:, :, :n]
                G[sl] = D[:, :, n:]
            else:
                phi[sl] = out
        return (phi, A, G) if jacobian else phi

    def _flow_block(self, x, d, sl, jacobian):
        """RK4 (and its variational equations) on the intervals ``sl``."""
        n, q, s = self.n, self.q, self.n_substeps
        X = np.array(x[sl], dtype=float)
        K = X.shape[0]
        h = self.h[sl]
        hs = (h / s)[:, None]
        hs3 = hs[:, :, None]
        Ed = np.zeros((K, n))
        Ed[:, self.es] = d[sl]
        t0 = self.t[sl]
        D = None
        if jacobian:
            D = np.zeros((K, n, n + q))
            D[:, :, :n] = np.eye(n)
        f = self._f
        for j in range(s):
            c0 = j / s
            tj = t0 + c0 * h
            half = tj + 0.5 * hs[:, 0]
            end = tj + hs[:, 0]
            u0, uh, u1 = (
                self._u_at(c0, sl),
                self._u_at((j + 0.5) / s, sl),
                self._u_at((j + 1.0) / s, sl),
            )
            k1 = f(X, tj, u0) + Ed
            X2 = X + 0.5 * hs * k1
            k2 = f(X2, half, uh) + Ed
            X3 = X + 0.5 * hs * k2
            k3 = f(X3, half, uh) + Ed
            X4 = X + hs * k3
            k4 = f(X4, end, u1) + Ed
            if jacobian:
                dk1 = f.jacobian(X, tj, u0) @ D + self._Eb
                dk2 = f.jacobian(X2, half, uh) @ (D + 0.5 * hs3 * dk1) + self._Eb
                dk3 = f.jacobian(X3, half, uh) @ (D + 0.5 * hs3 * dk2) + self._Eb
                dk4 = f.jacobian(X4, end, u1) @ (D + hs3 * dk3) + self._Eb
                D = D + hs3 / 6.0 * (dk1 + 2.0 * dk2 + 2.0 * dk3 + dk4)
            X = X + hs / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return (X, D) if jacobian else X

    def _check_flow(self, phi, x):
        """Raise if one interval of the model explodes (or is not finite)."""
        with np.errstate(all="ignore"):
            jump = np.abs(phi - x[:-1])
            bad = ~np.isfinite(phi).all(axis=1) | (
                jump.max(axis=1) > 1e6 * self.scale(x)
            )
        if bad.any():
            k = int(np.argmax(bad))
            with np.errstate(all="ignore"):
                x_k, phi_k = x[k] * self.unit, phi[k] * self.unit
            raise DivergenceError(
                "assumed_model blows up within one sample interval (interval "
                f"{k}, t = {self.t[k]:.6g} to {self.t[k + 1]:.6g}, starting from "
                f"x = {x_k.tolist()}): integrating it there gives "
                f"{phi_k.tolist()}. The model is unstable or stiff at this "
                "sampling rate; check the model and the units of the data, or "
                "increase n_substeps."
            )

    def linearize(self, x, d) -> _Linearization:
        phi, A, G = self.flow(x, d, jacobian=True)
        self._check_flow(phi, x)
        if not (np.isfinite(A).all() and np.isfinite(G).all()):
            raise DivergenceError(
                "the Jacobian of assumed_model is not finite along the current "
                "trajectory; the model cannot be linearised there"
            )
        growth = np.abs(A).max(axis=(1, 2))
        if growth.max() > _MAX_GROWTH:
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
                "n_substeps."
            )
        r = np.where(self.mask, self._y0 - self._measure(x), 0.0)
        H = self._measurement_jacobian(x)
        return _Linearization(x=x, d=d, A=A, G=G, defects=phi - x[1:], r=r, H=H)

    # ----------------------------------------------------------------- costs
    def residuals(self, x):
        """``y - g(x)`` in internal units, 0 where ``y`` is missing."""
        return np.where(self.mask, self._y0 - self._measure(x), 0.0)

    def measurement_cost(self, r):
        return float(np.einsum("ki,kij,kj->", r, self.Rinv, r))

    def model_error_cost(self, d, W):
        return float(np.einsum("k,ki,ij,kj->", self.h, d, W, d))

    # ------------------------------------------------------------------- KKT
    def _factor_kkt(self, lin: _Linearization, W, Winv):
        """Assemble and factorise the KKT matrix of one Gauss-Newton subproblem.

        Unknowns per sample k: ``[dx_k (n), lam_k (n)]``; the last
        multiplier block is a dummy identity so every block has size 2n.
        Matrix entry (i, j) lives in ``ab[kl + ku + i - j, j]`` (LAPACK band
        storage); ``abT`` is its transpose in C order, so ``abT.T`` is the
        Fortran-ordered array dgbtrf factorises in place without a copy.

        Returns ``(lu, piv, HR, GW, logdet, pivot_ratio)`` with
        ``HR = H^T R^-1``, ``GW = G W^-1`` and ``pivot_ratio`` the smallest
        over the largest pivot magnitude. Raises ``LinAlgError`` if a pivot
        is exactly zero (or the pivots are not finite).
        """
        n, N = self.n, self.N
        kl = ku = 2 * n - 1
        ldab = 2 * kl + ku + 1
        diag = kl + ku
        H = lin.H
        if H.ndim == 2:
            # linear measurement: H^T R^-1 and H^T R^-1 H never change
            if self._HRQ is None:
                HR = np.einsum("ai,kab->kib", H, self.Rinv)
                self._HRQ = (HR, HR @ H)
            HR, Q = self._HRQ
        else:
            HR = np.einsum("kai,kab->kib", H, self.Rinv)  # H^T Rinv
            Q = HR @ H
        G = lin.G
        GW = G @ Winv  # (N-1, n, q)
        S = (GW @ np.swapaxes(G, 1, 2)) / self.h[:, None, None]
        A = lin.A
        # Column b of block k holds, from row offset diag - b: the entries of
        # rows x_k (Q_k[:, b]) and lam_k (A_k[:, b]); column n + b (lam_k's)
        # holds rows x_k (A_k^T) and lam_k (-S_k), and x_{k+1}'s -1 below.
        # One band buffer per smoother, reused: a fresh O(N) allocation per
        # iteration costs more in page faults than the factorisation itself.
        # (The LU overwrites it, so it is consumed before the next call.)
        if self._band is None:
            self._band = np.empty((N, 2 * n, ldab))
        abT = self._band
        K = N - 1
        # Block by block, so each block stays in cache over the passes.
        for lo in range(0, N, self._CHUNK):
            hi = min(lo + self._CHUNK, N)
            blk = abT[lo:hi]
            blk.fill(0.0)
            m = min(hi, K) - lo  # rows of this block that have an interval
            for b in range(n):
                blk[:, b, diag - b : diag - b + n] = Q[lo:hi, :, b]
                blk[:m, b, diag + n - b : diag + 2 * n - b] = A[lo : lo + m, :, b]
                blk[:m, n + b, diag - n - b : diag - b] = A[lo : lo + m, b, :]
                blk[:m, n + b, diag - b : diag - b + n] = -S[lo : lo + m, :, b]
                # (x_{k+1} row b, lam_k col b) and (lam_k row b, x_{k+1} col b)
                blk[:m, n + b, diag + n] = -1.0
                blk[1 if lo == 0 else 0 :, b, diag - n] = -1.0
        abT[-1, n:, :] = 0.0
        abT[-1, np.arange(n, 2 * n), diag] = 1.0  # dummy multiplier, last block
        ab = abT.reshape(N * 2 * n, ldab).T
        lu, piv, info = lapack.dgbtrf(ab, kl, ku, overwrite_ab=1)
        if info < 0:  # pragma: no cover - a bug, not a user error
            raise RuntimeError(f"dgbtrf: illegal argument {-info}")
        udiag = np.abs(lu[diag])
        umax = float(np.max(udiag))
        if info > 0 or not (np.isfinite(umax) and umax > 0):
            raise np.linalg.LinAlgError("singular KKT system")
        logdet = float(np.sum(np.log(udiag)))
        return lu, piv, HR, GW, logdet, float(np.min(udiag)) / umax

    def _kkt_solve(self, lu, piv, rhs):
        """Solve with the factorised KKT matrix; ``rhs`` is (N, 2n[, k])."""
        n, N = self.n, self.N
        kl = ku = 2 * n - 1
        shape = rhs.shape
        flat = rhs.reshape(N * 2 * n, -1)
        sol, info = lapack.dgbtrs(lu, kl, ku, flat, piv)
        return sol.reshape(shape)

    def _solve_kkt(self, lin: _Linearization, W, Winv):
        """One Gauss-Newton subproblem: returns (dx, d_new, lam, logdet).

        Raises ``LinAlgError`` if the subproblem is singular.
        """
        n, N = self.n, self.N
        lu, piv, HR, GW, logdet, pivot_ratio = self._factor_kkt(lin, W, Winv)
        # A zero pivot computed in floating point is rarely exactly zero (it
        # is rounding, ~1e-16 relative), while a weakly determined but
        # well-posed problem (a tiny W lets the unmeasured states wander) has
        # legitimately tiny pivots too, so the pivots alone cannot tell the
        # two apart: a suspiciously small one is settled by the observability
        # of the linearisation, which does not depend on W.
        if pivot_ratio <= _SUSPECT_PIVOT and self._unobservable_directions(lin):
            raise np.linalg.LinAlgError("singular KKT system")
        rhs = np.zeros((N, 2 * n))
        rhs[:, :n] = np.einsum("kib,kb->ki", HR, lin.r)
        rhs[:-1, n:] = -lin.defects + np.einsum("kiq,kq->ki", lin.G, lin.d)
        sol = self._kkt_solve(lu, piv, rhs)
        dx = sol[:, :n]
        lam = sol[:-1, n:]
        d_new = -np.einsum("kiq,ki->kq", GW, lam) / self.h[:, None]
        return dx, d_new, lam, logdet

    # ----------------------------------------------------------------- solve
    def solve(self, W, start: SmootherResult | None = None) -> SmootherResult:
        """Gauss-Newton with an l1-merit line search for a fixed ``W``.

        ``W`` and ``start`` (a previous result of this smoother, the warm
        start) and the result are in the user's units.
        """
        W = np.atleast_2d(np.asarray(W, dtype=float))
        if W.shape == (1, 1) and self.q != 1:
            W = W[0, 0] * np.eye(self.q)
        s = self.unit
        if start is not None and start._lin is not None:
            lin = start._lin
        else:
            x, d = (start.x, start.d) if start is not None else self.initial_guess()
            lin = self.linearize(x / s, d / s)
        res = self._solve(W * s**2, lin)
        # Back to the user's units. J is unit-free; the multipliers (of J / 2
        # against defects in x) scale as 1 / s; the density of the N_obs
        # observations given the n free initial states as s^-(N_obs - n),
        # hence |det K| as s^-2n (flat prior on x_0, see the docstring).
        log_s = float(np.log(s))
        return dataclasses.replace(
            res,
            W=W,
            x=res.x * s,
            d=res.d * s,
            lam=res.lam / s,
            residuals=res.residuals * s,
            logdet=res.logdet - 2.0 * self.n * log_s,
            neg2_log_likelihood=res.neg2_log_likelihood
            + 2.0 * (self.n_obs - self.n) * log_s,
            max_defect=res.max_defect * s,
        )

    def _solve(self, W, lin: _Linearization) -> SmootherResult:
        """:meth:`solve` in internal units from the linearisation ``lin``."""
        Winv = np.linalg.inv(W)
        x, d = lin.x, lin.d
        r = lin.r
        meas = self.measurement_cost(r)
        mu = 0.0
        converged = False
        message = f"reached max_iter = {self.max_iter}"
        lam = np.zeros((self.N - 1, self.n))
        logdet = np.nan
        n_iter = 0
        for n_iter in range(1, self.max_iter + 1):  # noqa: B007
            try:
                dx, d_new, lam, logdet = self._solve_kkt(lin, W, Winv)
            except np.linalg.LinAlgError:
                self._raise_singular(lin)
            dd = d_new - d
            if not (np.isfinite(dx).all() and np.isfinite(dd).all()):
                raise DivergenceError(
                    "the Gauss-Newton step is not finite; the linearised "
                    "problem is too ill-conditioned (model exploding?)"
                )
            defect_l1 = float(np.abs(lin.defects).sum())
            mu = max(mu, 2.0 * float(np.max(np.abs(lam), initial=0.0)) * 1.5)
            cost0 = meas + self.model_error_cost(d, W)
            phi0 = cost0 + mu * defect_l1
            grad_dot_p = -2.0 * float(
                np.einsum("kb,kb->", lin.r, self._apply_R_H(lin, dx))
            ) + 2.0 * float(np.einsum("k,ki,ij,kj->", self.h, d, W, dd))
            slope = grad_dot_p - mu * defect_l1
            if -slope <= self.tol * max(phi0, np.finfo(float).tiny):
                # Stationary to within tol: take the (tiny) step and stop.
                x, d = x + dx, d_new
                converged = True
                message = "converged"
                break
            alpha, accepted = 1.0, False
            for _ in range(40):
                xt, dt_ = x + alpha * dx, d + alpha * dd
                phi_t = self.flow(xt, dt_, jacobian=False)
                rt = self.residuals(xt)
                meas_t = self.measurement_cost(rt)
                merit = (
                    meas_t
                    + self.model_error_cost(dt_, W)
                    + mu * float(np.abs(phi_t - xt[1:]).sum())
                )
                if np.isfinite(merit) and merit <= phi0 + 1e-4 * alpha * slope:
                    accepted = True
                    break
                alpha *= 0.5
            if not accepted:
                message = "line search failed to decrease the merit function"
                break
            x, d = xt, dt_
            previous, lin = lin, self.linearize(x, d)
            meas = self.measurement_cost(lin.r)
            if alpha == 1.0 and self._same_quadratic_model(previous, lin):
                # The problem is linear-quadratic (a linear model and
                # measurement): the full step solved it exactly, and the next
                # subproblem would be the same one with a zero step.
                converged = True
                message = "converged (linear problem, exact step)"
                break
        r = self.residuals(x)
        meas = self.measurement_cost(r)
        phi = self.flow(x, d, jacobian=False)
        max_defect = float(np.max(np.abs(phi - x[1:]), initial=0.0))
        if lin.x is not x:
            # The last (sub-tolerance) step was taken without relinearising.
            # Keep A, G, H from just before it (they change by O(step)) with
            # the exact defects and residuals at the returned point: a warm
            # start from here is then consistent up to that O(step) change.
            lin = _Linearization(
                x=x, d=d, A=lin.A, G=lin.G, defects=phi - x[1:], r=r, H=lin.H
            )
        if not np.isfinite(x).all():
            raise DivergenceError("the estimate diverged to non-finite values")
        mec = self.model_error_cost(d, W)
        cost = meas + mec
        n2ll = (
            cost + logdet + self._logdetR + (self.n_obs - self.n) * np.log(2.0 * np.pi)
        )
        resid = np.where(self.mask, r, np.nan)
        return SmootherResult(
            W=W,
            x=x,
            d=d,
            lam=lam,
            residuals=resid,
            cost=cost,
            measurement_cost=meas,
            model_error_cost=mec,
            logdet=logdet,
            neg2_log_likelihood=float(n2ll),
            converged=converged,
            n_iter=n_iter,
            max_defect=max_defect,
            message=message,
            _lin=lin,
        )

    def _same_quadratic_model(self, old: _Linearization, new: _Linearization):
        """Whether the linearisation did not change over a full step.

        True for a linear model with a linear measurement: then the step was
        the exact solution. Tolerances allow for the finite-difference
        Jacobian's rounding (about 1e-10 relative).
        """
        if new.H.ndim != 2:
            return False
        tol = 1e-8
        scale_A = max(1.0, float(np.max(np.abs(old.A), initial=0.0)))
        scale_G = max(1e-300, float(np.max(np.abs(old.G), initial=0.0)))
        return bool(
            np.max(np.abs(new.A - old.A), initial=0.0) <= tol * scale_A
            and np.max(np.abs(new.G - old.G), initial=0.0) <= tol * scale_G
            and np.max(np.abs(new.defects), initial=0.0) <= tol * self.scale(new.x)
        )

    def _raise_singular(self, lin):
        """The KKT system is singular: say what cannot be observed."""
        directions = self._unobservable_directions(lin)
        if directions is None:
            detail = ": nothing is measured"
        elif directions:
            detail = (
                "; the measurements do not see the initial-state direction(s) "
                + "; ".join(f"[{p}]" for p in directions)
                + " (state indices from 0)"
            )
        else:
            detail = ""
        raise np.linalg.LinAlgError(
            "the estimation problem is singular: the states are not all "
            "observable from the measurements, so the initial state (no "
            "prior is used) or the model error is undetermined" + detail
        )

    def _unobservable_directions(self, lin, max_steps: int = 1000):
        """The initial-state directions no measurement sees, as text.

        Stacks ``H_k Phi(k, 0)`` (the linearised sensitivity of the k-th
        measurement to ``x_0``, with the model error held at zero) over the
        first ``max_steps`` samples (so a state first seen later than that
        would be reported; the check is only consulted when the KKT system
        looks singular) and returns the right singular vectors with negligible
        singular values, each written as ``+1 x0 -1 x1``; ``[]`` if there are
        none, ``None`` if nothing is measured there. ``Phi`` is renormalised
        at every step: only the directions matter, and an unstable model
        would otherwise overflow it.
        """
        n = self.n
        K = min(self.N, max_steps)
        P = np.empty((K, n, n))
        P[0] = np.eye(n)
        for k in range(1, K):
            Pk = lin.A[k - 1] @ P[k - 1]
            size = float(np.max(np.abs(Pk)))
            if not (np.isfinite(size) and size > 0):
                K = k
                break
            P[k] = Pk / size
        P = P[:K]
        H = lin.H
        O = np.einsum("ai,kij->kaj", H, P) if H.ndim == 2 else H[:K] @ P
        O = O[self.mask[:K]]  # (observed values, n)
        if O.shape[0] == 0:
            return None
        if not np.isfinite(O).all():
            return []
        try:
            # R of a QR first: the SVD of a tall O only needs its n x n factor
            if O.shape[0] > n:
                O = np.linalg.qr(O, mode="r")
            _, sv, vt = np.linalg.svd(O, full_matrices=True)
        except np.linalg.LinAlgError:
            return []
        sv = np.concatenate([sv, np.zeros(n - sv.size)])
        null = vt[sv <= 1e-8 * max(sv.max(), 1e-300)]
        parts = []
        for v in null:
            v = v / np.max(np.abs(v))
            v = v * np.sign(v[np.flatnonzero(np.abs(v) > 1e-6)[0]])  # first is +
            labels = self.state_labels or [f"x{j}" for j in range(n)]
            terms = [f"{c:+.3g} {labels[j]}" for j, c in enumerate(v) if abs(c) > 1e-6]
            parts.append(" ".join(terms))
        return parts

    def _apply_R_H(self, lin, dx):
        """``Rinv_k H_k dx_k`` for every sample."""
        H = lin.H
        Hdx = dx @ H.T if H.ndim == 2 else np.einsum("kai,ki->ka", H, dx)
        return np.einsum("kab,kb->ka", self.Rinv, Hdx)


def unobservable_states(
    model: ModelFunction,
    x,
    t,
    u,
    measurement_pattern,
    n_points: int = 40,
    seed: int = 0,
):
    """States that cannot influence any measurement (structural check).

    A state is seen if a measured quantity depends on it directly, or if it
    drives (through a nonzero entry of ``df/dx``) a state that is seen. An
    entry counts as nonzero above ``1e-10`` times the largest entry of its
    row (its equation). The pattern is the union over a few samples of the
    initial trajectory and random perturbations of them, so that a
    derivative that happens to vanish on the initial guess (e.g.
    ``d(x1 x2)/dx1`` at ``x2 = 0``) is not mistaken for a structural zero.

    Returns
    -------
    list of int
        Indices of the states that no measurement can see.
    """
    x = np.asarray(x, dtype=float)
    n = x.shape[1]
    rng = np.random.default_rng(seed)
    idx = np.unique(np.linspace(0, x.shape[0] - 1, min(n_points, x.shape[0])))
    idx = idx.astype(int)
    xs = x[idx]
    ts = np.asarray(t, dtype=float)[idx]
    us = None
    if u is not None:
        us = (
            np.asarray(u(ts), dtype=float).reshape(ts.size, -1)
            if callable(u)
            else np.asarray(u)[idx]
        )
    scale = np.maximum(np.std(x, axis=0), 0.1 * np.max(np.abs(x), axis=0))
    scale = np.where(scale > 0, scale, 1.0)
    pattern = np.zeros((n, n), dtype=bool)
    for trial in range(3):
        pts = xs if trial == 0 else xs + scale * rng.standard_normal(xs.shape)
        with np.errstate(all="ignore"):
            jac = model.jacobian(pts, ts, us)
        finite = np.isfinite(jac)
        mag = np.where(finite, np.abs(jac), 0.0)
        # Relative to the largest entry of the same equation (row): one
        # threshold for the whole Jacobian would erase a coupling of 1 next
        # to a stiff -1e11 elsewhere (a model in the wrong units), and the
        # error would wrongly blame observability.
        row_max = np.maximum(mag.max(axis=-1, keepdims=True), np.finfo(float).tiny)
        pattern |= (mag > 1e-10 * row_max).any(axis=0)
    seen = np.asarray(measurement_pattern, dtype=bool).any(axis=0)
    changed = True
    while changed:
        # state i is seen if it drives a seen state j: df_j/dx_i != 0
        new = seen | (pattern[seen, :].any(axis=0))
        changed = bool((new != seen).any())
        seen = new
    return [int(i) for i in np.flatnonzero(~seen)]
