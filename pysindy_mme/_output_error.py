"""Output-error least squares: fit initial state and coefficients to measurements.

The regression of the MME model error on library functions is biased toward
zero, because the estimator shrinks ``d(t)``. The unbiased answer compares
*simulations* of the extended model with the measurements themselves:

    minimise  sum_k || L (y_k - g(x(t_k; x0, c))) ||^2

over the initial state ``x0`` and the correction coefficients ``c`` (``L``
whitens the measurement noise). Residuals and their finite-difference
Jacobian come from one batched fixed-step RK4 simulation of all perturbed
parameter vectors at once (the model is vectorised over rows), so a Jacobian
costs one simulation's worth of Python overhead, not ``n_params + 1``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

__all__ = ["batch_simulate", "OutputErrorProblem", "OutputErrorResult"]


def batch_simulate(rhs, x0, t, u=None, substeps: int = 2) -> np.ndarray:
    """Integrate ``B`` trajectories at once with classical RK4.

    Parameters
    ----------
    rhs : callable ``rhs(x, s, u_s) -> (B, n)``
        ``x`` has shape ``(B, n)``, ``s`` is a float time, ``u_s`` the input at
        ``s`` (shape ``(m,)``) or None.
    x0 : ndarray (B, n)
    t : ndarray (N,)
        Output times (any spacing); each interval takes ``substeps`` steps.
    u : ndarray (N, m) or None
        Input on ``t``, interpolated linearly inside intervals.

    Returns
    -------
    x : ndarray (B, N, n)
        Trajectories; a trajectory that leaves the finite range (blows up) is
        NaN from then on, so callers can penalise it instead of crashing.
    """
    x = np.array(x0, dtype=float)
    out = np.full((x.shape[0], t.size, x.shape[1]), np.nan)
    out[:, 0] = x
    limit = 1e8 * max(1.0, float(np.nanmax(np.abs(x))))
    alive = np.all(np.isfinite(x), axis=1)
    with np.errstate(all="ignore"):
        _rk4_loop(rhs, x, t, u, substeps, out, limit, alive)
    return out


def _rk4_loop(rhs, x, t, u, substeps, out, limit, alive):
    """The time loop of :func:`batch_simulate` (fills ``out`` in place)."""
    for k in range(t.size - 1):
        h = (t[k + 1] - t[k]) / substeps
        for s in range(substeps):
            s0 = t[k] + s * h
            if u is None:
                ua = um = ub = None
            else:
                frac0, frach, frac1 = (
                    s / substeps,
                    (s + 0.5) / substeps,
                    (s + 1) / substeps,
                )
                ua = u[k] + frac0 * (u[k + 1] - u[k])
                um = u[k] + frach * (u[k + 1] - u[k])
                ub = u[k] + frac1 * (u[k + 1] - u[k])
            k1 = rhs(x, s0, ua)
            k2 = rhs(x + 0.5 * h * k1, s0 + 0.5 * h, um)
            k3 = rhs(x + 0.5 * h * k2, s0 + 0.5 * h, um)
            k4 = rhs(x + h * k3, s0 + h, ub)
            x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        bad = ~np.all(np.isfinite(x) & (np.abs(x) < limit), axis=1)
        if np.any(bad & alive):
            alive &= ~bad
            x[bad] = np.nan
        out[:, k + 1] = x


@dataclass
class OutputErrorResult:
    """Result of an output-error fit.

    Attributes
    ----------
    params : ndarray (n_params,)
        ``[x0, coefficients]``.
    covariance : ndarray (n_params, n_params)
        Asymptotic covariance ``s^2 (J^T J)^-1`` (NaN where not identifiable).
    cost : float
        Whitened residual sum of squares at the solution.
    initial_cost : float
    n_residuals : int
    converged : bool
    message : str
    residuals : ndarray (n_residuals,) or None
        Whitened residuals at the solution.
    jacobian : ndarray (n_residuals, n_params) or None
        Their Jacobian with respect to ``params``.
    """

    params: np.ndarray
    covariance: np.ndarray
    cost: float
    initial_cost: float
    n_residuals: int
    converged: bool
    message: str
    residuals: np.ndarray | None = None
    jacobian: np.ndarray | None = None

    @property
    def std_errors(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def confidence_intervals(self, level: float = 0.95) -> np.ndarray:
        dof = max(self.n_residuals - self.params.size, 1)
        half = stats.t.ppf(0.5 + level / 2.0, dof) * self.std_errors
        return np.column_stack([self.params - half, self.params + half])


class OutputErrorProblem:
    """Fit ``x0`` and correction coefficients of ``x' = f(x) + C theta(x)``.

    Parameters
    ----------
    base_rhs : callable ``(x (B, n), s, u_s) -> (B, n)``
        The assumed model, vectorised over rows.
    features : callable ``(z (B, n + m), columns) -> (B, len(columns))``
        Evaluates the given candidate columns (``z`` = states then inputs);
        only the columns some slot uses are ever evaluated.
    slots : list of (state, feature) pairs
        Which coefficient each fitted parameter is: ``C[state, feature]``.
    n_states : int
    measure : callable ``x (..., n) -> (..., m_y)``
        Measurement function.
    y : ndarray (N, m_y)
        Measurements, NaN where missing.
    t : ndarray (N,)
    u : ndarray (N, m) or None
    noise_cov : ndarray (m_y, m_y)
    held_coefficients : ndarray (len(slots),), optional
        Hold the coefficients at these values and fit the initial state only
        (then the parameter vector is ``x0`` alone).
    """

    def __init__(
        self,
        base_rhs,
        features,
        slots,
        n_states,
        measure,
        y,
        t,
        u,
        noise_cov,
        substeps=2,
        held_coefficients=None,
    ):
        self.base_rhs = base_rhs
        self.features = features
        self.slots = list(slots)
        self.n_states = n_states
        self.measure = measure
        self.y = y
        self.t = t
        self.u = u
        self.substeps = substeps
        self.mask = np.isfinite(y)
        # Whitening: L^T L = R^-1, so ||L r||^2 = r^T R^-1 r.
        self.whiten = np.linalg.cholesky(np.linalg.inv(noise_cov)).T
        # Evaluate only the columns in use, at positions 0..len(used)-1.
        self.used = sorted({feat for _, feat in self.slots})
        position = {feat: k for k, feat in enumerate(self.used)}
        self._state_pos = [(state, position[feat]) for state, feat in self.slots]
        self.n_features = len(self.used)
        self.held = (
            None
            if held_coefficients is None
            else np.asarray(held_coefficients, dtype=float)
        )

    # one batched simulation for many parameter vectors
    def _simulate(self, params: np.ndarray) -> np.ndarray:
        n = self.n_states
        params = np.atleast_2d(params)
        if self.held is not None:
            params = np.hstack([params, np.tile(self.held, (params.shape[0], 1))])
        x0 = params[:, :n]
        coef = np.zeros((params.shape[0], n, max(self.n_features, 1)))
        for j, (state, pos) in enumerate(self._state_pos):
            coef[:, state, pos] = params[:, n + j]

        def rhs(x, s, us):
            dx = self.base_rhs(x, s, us)
            if self.slots:
                z = x if us is None else np.hstack([x, np.tile(us, (x.shape[0], 1))])
                theta = self.features(z, self.used)
                dx = dx + np.einsum("bp,bnp->bn", theta, coef)
            return dx

        return batch_simulate(rhs, x0, self.t, self.u, self.substeps)

    def residuals_batch(self, params: np.ndarray) -> np.ndarray:
        """Whitened residuals ``(B, n_residuals)`` for a batch of parameters."""
        x = self._simulate(np.atleast_2d(params))
        y_hat = self.measure(x)  # (B, N, m_y)
        r = (self.y[None] - y_hat) @ self.whiten.T
        mask = np.broadcast_to(self.mask, r.shape)
        return r[mask].reshape(r.shape[0], -1)

    def cost(self, params) -> float:
        r = self.residuals_batch(params)[0]
        return float(r @ r) if np.all(np.isfinite(r)) else np.inf

    def fit(self, params0, max_nfev: int = 60, tol: float = 1e-10) -> OutputErrorResult:
        """Gauss-Newton with a trust region (scipy ``least_squares``, 'trf')."""
        params0 = np.asarray(params0, dtype=float)
        # Relative finite-difference steps, so that data in any units (tiny or
        # huge coefficients) are differentiated alike; a parameter at 0 takes
        # its step from the size of the others.
        size = np.abs(params0)
        fallback = 1e-3 * (size.max() if size.max() > 0 else 1.0)
        typical = np.where(size > 0, size, fallback)
        cache = {}

        def evaluate(p):
            key = p.tobytes()
            if key not in cache:
                size_p = np.abs(p)
                steps = np.sqrt(np.finfo(float).eps) * np.where(
                    size_p > 1e-3 * typical, size_p, typical
                )
                batch = np.vstack([p, p + np.diag(steps)])
                r = self.residuals_batch(batch)
                base = r[0]
                if not np.all(np.isfinite(base)):
                    # A parameter vector whose simulation blows up is a very bad
                    # fit, not an error: a large residual makes the trust region
                    # step back.
                    base = np.where(np.isfinite(base), base, 1e4)
                    jac = np.zeros((base.size, p.size))
                else:
                    jac = (r[1:] - base[None]).T / steps[None]
                    jac[~np.isfinite(jac)] = 0.0
                cache.clear()
                cache[key] = (base, jac)
            return cache[key]

        r0 = evaluate(params0)[0]
        initial_cost = float(r0 @ r0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            sol = optimize.least_squares(
                lambda p: evaluate(p)[0],
                params0,
                jac=lambda p: evaluate(p)[1],
                method="trf",
                x_scale="jac",
                max_nfev=max_nfev,
                xtol=tol,
                ftol=tol,
            )
        base, jac = evaluate(sol.x)
        cost = float(base @ base)
        n_res = base.size
        dof = max(n_res - sol.x.size, 1)
        with np.errstate(all="ignore"):
            try:
                cov = np.linalg.pinv(jac.T @ jac) * (cost / dof)
            except np.linalg.LinAlgError:
                cov = np.full((sol.x.size, sol.x.size), np.nan)
        return OutputErrorResult(
            params=sol.x,
            covariance=cov,
            cost=cost,
            initial_cost=initial_cost,
            n_residuals=n_res,
            converged=bool(sol.status > 0) and np.isfinite(cost),
            message=str(sol.message),
            residuals=base,
            jacobian=jac,
        )
