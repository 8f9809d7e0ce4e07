"""Output error: fit a model's parameters to the measurements themselves.

The regression of the MME model error on library functions is biased (the
estimator shrinks ``d(t)``) and its F-ratios are inflated (``d(t)`` is
smooth). Measurements carry white noise of known covariance, so the unbiased
fit and valid tests compare the model's *trajectory* with the data:

    minimise  sum_k (y_k - g(x_k) - o)^T R^-1 (y_k - g(x_k) - o)
    subject to x_{k+1} = Phi_k(x_k; p, c)

over the states, the assumed model's physical parameters ``p``, the
correction coefficients ``c`` and measurement offsets ``o``.

How, and why this way (measured, see ``benchmarks/bench_long_records.py``):
the dynamics are imposed by **direct transcription**, every sample interval a
shooting segment, through the same banded KKT solver as MME
(:class:`~pysindy_mme.differentiation.MMESmoother` with hard constraints and
the parameters bordering the band). Single shooting (one simulation from
``x0``, finite-difference Jacobians from ``n_params + 1`` simulations)
costs a Python loop per sample and, over many periods or a chaotic record,
has a cost surface full of local minima: on the paper's Van der Pol case
over 1,000 s it converged to a wrong model. Transcription started from the
MME state estimate keeps every interval close to the data while the
continuity conditions close, its sensitivities are exact (variational
equations of the RK4 map), its Python loops run over RK4 stages only, and
its cost grows linearly with the record. At convergence the defects are at
rounding level, so the trajectory is the model's simulation from its fitted
initial state.

Statistics: the covariance of the parameters is ``s^2 Sc^-1``, ``Sc`` the
reduced Hessian from the bordered KKT system (equilibrated before it is
inverted, so parameters of any scale are handled), ``s^2 = cost / dof``.
A candidate term's score test (the partial F it would have, linearised)
comes from the same factorisation: its one-interval sensitivities ``B`` are
the forcing of one extra solve.

Bounds on the physical parameters (``bounds``): every Gauss-Newton step
solves its subproblem inside them (:meth:`MMESmoother._bounded_step`), so no
iterate leaves the box. A parameter that ends on a bound the data push it
against is ``at_bound``: it is not free there, so the statistics (its
standard error NaN, the others' covariance, the score tests) are those of
the model with it held at the bound.

Walls: an overflow term in its own state's equation (``over(h1, L)`` in
``h1'``, solved exactly: :mod:`~pysindy_mme.core.relaxation`) with a
negative coefficient ``a`` is a wall above ``L``. A tank that cannot rise
above its rim is the limit ``a -> -inf``, which a fit walks towards without
end; the coefficient is bounded at ``a >= -WALL_DECAY / dt`` (the excess
decays by ``exp(-WALL_DECAY)`` within one sample interval ``dt``, 10: a
clamp, as far as data sampled at ``dt`` can tell). A coefficient that ends
there is ``at_wall``: held, like a parameter on its bound, and the
coefficients of the terms routing the excess elsewhere are fractions of it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from ..core.blockwise import all_finite, max_abs
from ..core.integrate import InputSignal
from ..core.model import AsBase, ParametricModel, RatesAt
from ..core.relaxation import Overflows, overflow_columns_of
from ..exceptions import DivergenceError
from .kkt import ReducedBorder, equilibrated_inverse, solve_reduced, undetermined
from .statistics import residual_inflation
from .transcription import MMESmoother

__all__ = ["OutputErrorFit", "OutputErrorModel"]

# Candidate sensitivities per banded solve: n_samples * n_states * group <=
# this (a solve's right-hand sides, their copy and solution are several times
# the sensitivities).
#: an overflow coefficient in its own state's equation is bounded at
#: ``-WALL_DECAY / dt``: the excess then decays by exp(-10) = 5e-5 within a
#: sample interval, with a time constant of a tenth of it. Stiffer is no
#: closer to the data (they cannot resolve it) and worse for Gauss-Newton:
#: the flow's derivative through the wall is exp(a h) per half step, and
#: near zero the states at the rim are undetermined and their defects stall
#: (tanks seed 4 at 50: the right model's trajectory did not join)
WALL_DECAY = 10.0
#: flows that differ by at most this much relative to the states (about a
#: thousand units in the last place) are the same map computed twice:
#: rounding, not a change of integrator the fit could follow
SAME_FLOW = 1e-13
_SCORE_ELEMENTS = 1 << 22
# Candidate sensitivities per pass of the variational equations (one flow with
# Jacobians, the cost of a linearisation, whatever the group): at most 64 MB
# of float64, the passes' groups of equal size. At 10^6 samples of two states
# the seven candidates of one equation of a cubic library take two passes
# (4 + 3) instead of one per pair; one pass of all seven held 107 MB beside
# the factor and the eliminated border, the peak of a long record's study.
_FLOW_ELEMENTS = 1 << 23


@dataclass
class OutputErrorFit:
    """One output-error fit.

    Attributes
    ----------
    slots : tuple of (state, column)
        The correction terms, in the order of ``coefficients``.
    theta : ndarray
        ``[physical parameters, coefficients, offsets]``.
    x : ndarray (N, n)
        Fitted trajectory (the model's simulation from ``x[0]``).
    cost : float
        Whitened residual sum of squares ``sum r^T R^-1 r``.
    n_residuals : int
        Observed measurement values.
    n_free : int
        Fitted quantities: initial state + parameters (those held on a bound,
        ``at_bound``, not counted: they are not free there).
    covariance : ndarray (p, p)
        ``s^2 Sc^-1`` with ``s^2 = cost / dof`` (NaN if not identifiable).
    x0_covariance : ndarray (n, n)
        Covariance of the fitted initial state ``x[0]``, likewise.
    converged : bool
        Gauss-Newton converged and every trajectory stayed finite.
    message : str
    rank_deficient : bool
        Some combination of parameters is not determined by the data.
    n_iter : int
    at_wall : ndarray of bool (n_slots,)
        The term is an overflow in its own state's equation whose
        coefficient ended on the wall limit (see the module docstring): held
        there, not counted as free, its standard error NaN.
    at_bound : ndarray of bool (n_physical,)
        The physical parameter ended on one of its bounds (within a relative
        1e-12; the solver leaves a parameter there only while the data push
        it outwards). Its standard error is NaN and the covariance of the
        others is computed with it held there.
    joined : bool
        The trajectory follows the model (every defect below 1e-6 of the
        state's scale): a fit that is not joined is no model's trajectory,
        and its cost is no model's cost.
    """

    slots: tuple
    theta: np.ndarray
    x: np.ndarray
    cost: float
    n_residuals: int
    n_free: int
    converged: bool
    message: str
    rank_deficient: bool
    n_iter: int
    n_physical: int = 0
    n_offsets: int = 0
    _cov: tuple | None = None
    _state: object = None
    _engine: object = None
    _inflation: float | None = None
    at_bound: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    joined: bool = True
    at_wall: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    #: the solver's state was released (keep_statistics) or never kept (a
    #: fit loaded from a file): what needs it refuses the fit
    _released: bool = False

    def __post_init__(self):
        if self.at_bound.size != self.n_physical:
            self.at_bound = np.zeros(self.n_physical, dtype=bool)
        if self.at_wall.size != len(self.slots):
            self.at_wall = np.zeros(len(self.slots), dtype=bool)

    @property
    def held(self) -> np.ndarray:
        """Entries of ``theta`` held on a bound (``at_bound``, ``at_wall``)."""
        out = np.zeros(self.theta.size, dtype=bool)
        out[: self.n_physical] = self.at_bound
        out[self.n_physical : self.n_physical + len(self.slots)] = self.at_wall
        return out

    def keep_statistics(self) -> OutputErrorFit:
        """Compute the statistics that need the solver's state, then drop it.

        A fit keeps its last linearisation and solver (sensitivities,
        weights, the trajectory's flows: about 130-180 bytes per sample) so
        that its covariance is computed only when asked for, its score tests
        need no new linearisation and :meth:`OutputErrorModel.resume` can go
        on from it. Once none of that is needed, this computes
        :attr:`covariance`, :attr:`x0_covariance` and :attr:`inflation`
        (the numbers a report reads) and releases the rest: at 10^6 samples
        two such fits held through the gain stage were a quarter of its
        peak. Afterwards score tests and the integrator check refuse the fit
        (``ValueError``) and ``resume`` refits from ``theta`` and ``x``.
        Returns the fit.
        """
        if self._state is not None:
            self.inflation  # noqa: B018 - computed and cached now
            self._covariances()
            self._state = None
            self._released = True
        return self

    def _require_linearisation(self, what: str) -> None:
        if self._released:
            raise ValueError(
                f"{what} needs the fit's linearisation, which this fit no longer "
                "holds (released by keep_statistics(), or loaded from a file): "
                "refit its terms (OutputErrorModel.fit) to test them"
            )

    def _covariances(self):
        # computed on first use: most trial fits are judged by their cost alone
        if self._cov is None:
            p, n = self.theta.size, self.x.shape[1]
            self._cov = (
                self._engine._covariance(self)
                if self._engine is not None
                else (
                    np.full((p, p), np.nan),
                    np.full((n, n), np.nan),
                    np.full((p, n), np.nan),
                )
            )
        return self._cov

    @property
    def covariance(self) -> np.ndarray:
        return self._covariances()[0]

    @property
    def x0_covariance(self) -> np.ndarray:
        return self._covariances()[1]

    @property
    def theta_x0_covariance(self) -> np.ndarray:
        """``(p, n)``: the covariance of ``theta`` with the initial state,
        likewise (NaN for a fit loaded from a file of version 4 or older, or
        where a parameter is not determined)."""
        cov = self._covariances()
        if len(cov) > 2:
            return cov[2]
        return np.full((self.theta.size, self.x.shape[1]), np.nan)

    @property
    def inflation(self) -> float:
        """Variance inflation of the residuals from their autocorrelation.

        Tests and standard errors assume white residuals, which a right model
        fitted to white measurement noise leaves. A model that misses
        dynamics (real data, always a little) leaves smooth, correlated
        residuals, and every test would then overstate significance, so a
        short record of a real system would "need" dozens of terms. The
        pooled lag-1 autocorrelation ``rho`` of the whitened residuals gives
        the AR(1) long-run inflation ``(1 + rho) / (1 - rho)``, by which test
        statistics are divided and variances multiplied (and the effective
        sample size is ``n / inflation``). A ``rho`` within sampling noise of
        zero (below ``2 / sqrt(n)``) counts as white: 1.
        """
        if self._inflation is None:
            self._inflation = 1.0
            fixed = getattr(self._engine, "noise_inflation", None)
            if fixed is not None:
                self._inflation = float(fixed)
            elif self._state is not None and np.isfinite(self.cost):
                self._inflation = residual_inflation(
                    self._state[1].residuals, self._engine.R
                )
        return self._inflation

    @property
    def dof(self) -> float:
        """Residual degrees of freedom, effective (see :attr:`inflation`)."""
        return max(self.n_residuals / self.inflation - self.n_free, 1.0)

    @property
    def residual_variance(self) -> float:
        """``cost / (n - n_free)``: 1 for a right model and right noise."""
        return self.cost / max(self.n_residuals - self.n_free, 1)

    @property
    def ok(self) -> bool:
        """A usable fit: finite cost (it may still not have converged)."""
        return bool(np.isfinite(self.cost))

    @property
    def coefficients(self) -> np.ndarray:
        a = self.n_physical
        return self.theta[a : a + len(self.slots)]

    @property
    def physical(self) -> np.ndarray:
        return self.theta[: self.n_physical]

    @property
    def offsets(self) -> np.ndarray:
        return self.theta[self.n_physical + len(self.slots) :]

    @property
    def std_errors(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def coefficient_p_values(self) -> np.ndarray:
        """Two-sided Wald p-values of the coefficients (1 where undefined)."""
        a = self.n_physical
        se = self.std_errors[a : a + len(self.slots)]
        with np.errstate(divide="ignore", invalid="ignore"):
            p = 2 * stats.t.sf(np.abs(self.coefficients / se), self.dof)
        return np.where(np.isfinite(p) & (se > 0), p, 1.0)

    def confidence_intervals(self, level: float = 0.95) -> np.ndarray:
        half = stats.t.ppf(0.5 + level / 2.0, self.dof) * self.std_errors
        return np.column_stack([self.theta - half, self.theta + half])

    def bic(self, inflation: float | None = None) -> float:
        """Bayesian information criterion (up to a constant), effective sample.

        Models are compared at one ``inflation`` (a poor model's residuals
        are more correlated; dividing each cost by its own inflation would
        favour it): :func:`better_bic` passes the smaller of the two.
        """
        inflation = self.inflation if inflation is None else inflation
        return bic_of(self.cost, self.n_residuals, len(self.slots), inflation)


def bic_of(cost, n_residuals, n_terms, inflation) -> float:
    """The BIC of :meth:`OutputErrorFit.bic` from its parts: ``cost`` over
    ``inflation``, plus ``n_terms`` times the log of the effective sample
    (``n_residuals`` over ``inflation``, at least 2)."""
    n_eff = max(n_residuals / inflation, 2.0)
    return cost / inflation + n_terms * np.log(n_eff)


class OutputErrorModel:
    """Output-error fits of one record for any set of correction terms.

    Parameters
    ----------
    base : callable ``(x, t, u, p) -> dx/dt``
        The assumed model (vectorised, unchecked) with its physical
        parameters ``p``.
    n_states, n_physical : int
    features : callable ``(z, columns) -> values`` (library columns)
    y, t : measurements and times
    inputs : InputSignal or None
    R : ndarray (m, m)
    measurement : ndarray (m, n) or callable
    n_offsets : int
        0, or ``m``: a constant offset per measured channel.
    n_substeps : int
        RK4 steps per sample interval.
    bounds : ndarray (n_physical, 2) or None
        ``[lower, upper]`` per physical parameter (``-inf`` / ``inf``: none);
        every fit keeps them inside. Coefficients and offsets are unbounded.
    starts : sequence of int, optional
        Several records on one sample axis: the samples where a new record
        starts. The defect constraint across each break is dropped, so every
        record's first state is a free initial state (counted in ``n_free``);
        the parameters and the correction are shared.
    """

    def __init__(
        self,
        base,
        n_states,
        features,
        y,
        t,
        inputs,
        R,
        measurement,
        n_physical=0,
        n_offsets=0,
        n_substeps=1,
        bounds=None,
        starts=None,
    ):
        self.starts = np.asarray([] if starts is None else starts, dtype=int)
        self.n_records = 1 + self.starts.size
        self.base = base
        self.n_states = int(n_states)
        self.n_physical = int(n_physical)
        self.n_offsets = int(n_offsets)
        self.features = features
        self.y = np.asarray(y, dtype=float)
        self.t = np.asarray(t, dtype=float)
        self.inputs = (
            inputs if isinstance(inputs, InputSignal) else InputSignal(inputs, self.t)
        )
        self.R = np.asarray(R, dtype=float)
        self.measurement = measurement
        self.n_substeps = int(n_substeps)
        self.bounds = None
        if bounds is not None:
            bounds = np.asarray(bounds, dtype=float)
            if bounds.shape != (self.n_physical, 2):
                raise ValueError(
                    f"bounds must have shape ({self.n_physical}, 2), got {bounds.shape}"
                )
            # no finite bound: no bounds (the free solver, bit for bit)
            if np.any(np.isfinite(bounds)):
                self.bounds = bounds
        self.n_residuals = int(np.isfinite(self.y).sum())
        #: variance inflation of the measurement noise (None: each fit's own)
        self.noise_inflation = None

    # ----------------------------------------------------------------- setup
    def _solver(self, slots, theta0, max_iter, tol, x_start=None):
        model = ParametricModel(
            self.base,
            self.n_states,
            self.n_physical,
            self.features,
            slots,
            n_extra=self.n_offsets,
        )
        m = self.y.shape[1]
        offsets = None
        if self.n_offsets:
            offsets = np.zeros((m, model.n_params))
            offsets[:, model.n_params - self.n_offsets :] = np.eye(m)
        return MMESmoother(
            model,
            self.y,
            self.t,
            self.R,
            [],
            self.measurement,
            u=self.inputs,
            n_substeps=self.n_substeps,
            max_iter=max_iter,
            tol=tol,
            theta_init=theta0,
            measurement_offsets=offsets,
            theta_bounds=self._theta_bounds(model.n_params, slots),
            starts=self.starts,
            # the internal units of the states the data do not measure come
            # from the starting trajectory (and the model at theta0)
            x_init=x_start,
        )

    def _theta_bounds(self, p, slots=()):
        """Bounds on all of ``theta`` (p, 2): the physical ones, the walls'
        limits, none for the rest (None when nothing is bounded)."""
        walls = self.wall_positions(slots)
        if self.bounds is None and not walls:
            return None
        out = np.tile([-np.inf, np.inf], (p, 1))
        if self.bounds is not None:
            out[: self.n_physical] = self.bounds
        for k in walls:
            out[self.n_physical + k, 0] = -self.wall_limit
        return out

    @property
    def wall_limit(self) -> float:
        """The largest wall coefficient magnitude: ``WALL_DECAY / dt``."""
        steps = np.diff(self.t)
        steps = steps[steps > 0]
        return WALL_DECAY / float(np.max(steps)) if steps.size else np.inf

    def wall_positions(self, slots) -> list:
        """Positions in ``slots`` of overflow terms in their own state's equation."""
        over = Overflows(slots, overflow_columns_of(self.features), self.n_states)
        return [item.rate for item in over.items if item.rate is not None]

    def _at_wall(self, theta, slots) -> np.ndarray:
        """Which terms of ``slots`` sit on the wall limit (rel. 1e-12)."""
        out = np.zeros(len(slots), dtype=bool)
        limit = self.wall_limit
        for k in self.wall_positions(slots):
            value = theta[self.n_physical + k]
            out[k] = abs(value + limit) <= 1e-12 * limit
        return out

    def _at_bound(self, theta):
        """Which physical parameters of ``theta`` sit on a bound (rel. 1e-12)."""
        if self.bounds is None:
            return np.zeros(self.n_physical, dtype=bool)
        value, bounds = theta[: self.n_physical, None], self.bounds
        with np.errstate(invalid="ignore"):
            close = np.abs(value - bounds) <= 1e-12 * np.abs(bounds)
        return np.any(close & np.isfinite(bounds), axis=1)

    def fit(
        self, slots, theta0, x_start, max_iter: int = 50, tol: float = 1e-9
    ) -> OutputErrorFit:
        """Fit the initial state and ``theta`` from a starting trajectory.

        A fit whose model blows up along the way, or cannot be linearised,
        is returned with an infinite cost and ``converged=False`` (its
        message says why), so that callers reject it instead of crashing.
        ``tol`` is the relative predicted decrease of the cost at which
        Gauss-Newton stops (1e-9 of a chi-square of ``N`` is far below one
        unit: negligible for every test). A ``theta0`` outside the bounds
        starts from its projection onto them.
        """
        slots = tuple((int(i), int(c)) for i, c in slots)
        theta0 = np.asarray(theta0, dtype=float)
        bounds = self._theta_bounds(theta0.size, slots)
        if bounds is not None:
            theta0 = np.clip(theta0, bounds[:, 0], bounds[:, 1])
        solver = self._solver(slots, theta0, max_iter, tol, x_start)
        return self._run(slots, solver, solver.start_from(x_start, theta0), theta0)

    def resume(
        self, fit: OutputErrorFit, max_iter: int = 50, tol: float = 1e-9
    ) -> OutputErrorFit:
        """Carry ``fit`` on: up to ``max_iter`` more Gauss-Newton iterations.

        The same terms from where ``fit`` stopped, with its solver (internal
        units and all) and its last linearisation: a fresh :meth:`fit` from
        ``fit.x`` and ``fit.theta`` would linearise the same point again (on
        a long record most of the cost of an iteration) and rebuild the
        solver. The iterates are those of that fresh fit up to rounding of
        the units (and, after a fit that stopped on its tolerance, a
        Jacobian from just before its last sub-tolerance step, which the
        next accepted step replaces). A fit without a solver state, or of
        another engine, is refitted with :meth:`fit`.
        """
        if fit._state is None or fit._engine is not self or not fit.ok:
            return self.fit(fit.slots, fit.theta, fit.x, max_iter=max_iter, tol=tol)
        solver, res = fit._state
        solver.max_iter, solver.tol = int(max_iter), float(tol)
        return self._run(fit.slots, solver, res, fit.theta)

    def _run(self, slots, solver, start, theta0) -> OutputErrorFit:
        """Gauss-Newton of ``solver`` from ``start``, packaged as a fit."""
        x_start = start.x
        try:
            res = solver.solve(None, start)
        except (DivergenceError, np.linalg.LinAlgError, FloatingPointError) as exc:
            return self._failed(slots, theta0, x_start, f"model diverged: {exc}")
        # Joined: every defect below 1e-6 of the trajectory's scale, both in
        # the solver's units (each state's own, about its noise sd): in the
        # user's units one state's defect would be judged by another's scale
        # (a velocity of 1e2 mm/s would excuse a defect of 1e-4 m).
        # (blockwise: the solver's own checks, without record-sized temporaries)
        z = res._lin.x
        bounded = all_finite(res.x) and max_abs(res._lin.defects) <= 1e-6 * max(
            1.0, max_abs(z)
        )
        # a fit during which some trial made the model blow up is not called
        # converged, even when the line search stepped back to a finite point
        converged = bool(res.converged and bounded and not res.nonfinite_trials)
        message = res.message
        if not bounded:
            message += (
                "; the trajectory does not follow the model "
                f"(largest defect {res.max_defect:.3g})"
            )
        if res.nonfinite_trials:
            message += (
                f"; {res.nonfinite_trials} trial step(s) made the model blow up "
                "(the line search stepped back)"
            )
        at_bound = self._at_bound(res.theta)
        at_wall = self._at_wall(res.theta, slots)
        fit = OutputErrorFit(
            slots=slots,
            theta=res.theta,
            x=res.x,
            cost=float(res.measurement_cost),
            n_residuals=self.n_residuals,
            n_free=self.n_states * self.n_records
            + res.theta.size
            - int(at_bound.sum())
            - int(at_wall.sum()),
            converged=converged,
            message=message,
            rank_deficient=res.rank_deficient,
            n_iter=res.n_iter,
            n_physical=self.n_physical,
            n_offsets=self.n_offsets,
            _state=(solver, res),
            _engine=self,
            at_bound=at_bound,
            joined=bool(bounded),
            at_wall=at_wall,
        )
        return fit

    def fit_held(self, slots, theta, x_start, max_iter: int = 50) -> OutputErrorFit:
        """Fit the initial state only, the parameters held at ``theta``.

        The returned fit reports ``theta`` with an undefined (NaN) covariance.
        """
        slots = tuple((int(i), int(c)) for i, c in slots)
        theta = np.asarray(theta, dtype=float)
        model = ParametricModel(
            self.base,
            self.n_states,
            self.n_physical,
            self.features,
            slots,
            n_extra=self.n_offsets,
        )

        held = OutputErrorModel(
            AsBase(RatesAt(model, theta)),
            self.n_states,
            self.features,
            self.y,
            self.t,
            self.inputs,
            self.R,
            self.measurement,
            n_substeps=self.n_substeps,
            starts=self.starts,
        )
        fit = held.fit((), np.zeros(0), x_start, max_iter=max_iter)
        return OutputErrorFit(
            slots=slots,
            theta=theta,
            x=fit.x,
            cost=fit.cost,
            n_residuals=fit.n_residuals,
            n_free=fit.n_free,
            converged=fit.converged,
            message=fit.message + " (parameters held)",
            rank_deficient=False,
            n_iter=fit.n_iter,
            n_physical=self.n_physical,
            n_offsets=self.n_offsets,
            joined=fit.joined,
        )

    def _failed(self, slots, theta0, x_start, message):
        p = theta0.size
        return OutputErrorFit(
            slots=slots,
            theta=theta0,
            x=np.asarray(x_start, dtype=float),
            cost=np.inf,
            n_residuals=self.n_residuals,
            n_free=self.n_states * self.n_records + p,
            converged=False,
            message=message,
            rank_deficient=False,
            n_iter=0,
            n_physical=self.n_physical,
            n_offsets=self.n_offsets,
        )

    def with_substeps(self, n_substeps: int) -> OutputErrorModel:
        """The same record and model, integrated with ``n_substeps``."""
        other = OutputErrorModel(
            self.base,
            self.n_states,
            self.features,
            self.y,
            self.t,
            self.inputs,
            self.R,
            self.measurement,
            self.n_physical,
            self.n_offsets,
            n_substeps,
            self.bounds,
            self.starts,
        )
        other.noise_inflation = self.noise_inflation
        return other

    def integrator_effect(self, fit: OutputErrorFit):
        """How far the fit would move with twice the RK4 steps (linearised).

        The finer integrator changes each interval's flow by
        ``Phi_fine - Phi``; one Gauss-Newton step of the finer problem from
        this solution (the factorised KKT system of the fit, one bordered
        solve) gives the change of the parameters and of the trajectory.
        Returns ``(dtheta, change)``: ``change`` is the largest change of the
        fitted measurements in noise standard deviations or the predicted
        change of the cost in units of chi-square, whichever is larger (the
        refit's own tests are half a standard error and one unit of
        chi-square); NaN when the fit has no KKT system.
        """
        p = fit.theta.size
        fit._require_linearisation("the integrator check")
        if fit._state is None:
            return np.full(p, np.nan), np.nan
        solver, res = fit._state
        finer = self.with_substeps(2 * self.n_substeps)._solver(
            fit.slots, fit.theta, 1, 1e-9, fit.x
        )
        d = np.zeros((solver.N - 1, 0))
        with np.errstate(all="ignore"):
            # each solver's flow in its own units, the change in the fit's
            phi = solver.flow(res.x / solver.unit, d, res.theta, jacobian=False)
            change = (
                finer.flow(res.x / finer.unit, d, res.theta, jacobian=False)
                * finer.unit
                / solver.unit
                - phi
            )
        if not np.all(np.isfinite(change)):
            return np.full(p, np.inf), np.inf
        if np.max(np.abs(change), initial=0.0) <= SAME_FLOW * np.max(np.abs(phi)):
            # the two integrators agree to rounding (a step far inside RK4's
            # accuracy): there is no change for the fit to follow
            return np.zeros(p), 0.0
        _, _, (fac, _, _, E, D) = self._kkt_at(fit)
        rhs = np.zeros((solver.N, 2 * solver.n))
        rhs[:-1, solver.n :] = -change
        E, D, free = self._free_border(fit, E, D)
        sol = solve_reduced(fac, E, D, rhs, np.zeros(E.p))
        dtheta = np.zeros(p)  # a parameter held on its bound stays there
        dtheta[free] = sol.dtheta
        # How far the fit moves, in any units the same number: the change of
        # the fitted measurements in the solver's channel units (each
        # channel's noise sd), or the change of the cost it predicts (in
        # units of chi-square, to second order), whichever is larger.
        # (The largest change of any state over the mean noise sd was not
        # unit-free: it compared a velocity in m/s with a noise in m.)
        dx, H = sol.z[:, : solver.n], res._lin.H
        dy = dx @ H.T if H.ndim == 2 else np.einsum("kai,ki->ka", H, dx)
        M = solver._M[:, free]
        if M.shape[1]:
            dy = dy + M @ sol.dtheta
        Rdy = np.einsum("kab,kb->ka", solver.Rinv, dy)
        dcost = float(np.sum(Rdy * (dy - 2.0 * res._lin.r)))
        return dtheta, max(float(np.max(np.abs(dy), initial=0.0)), abs(dcost))

    # ------------------------------------------------------------ statistics
    def _kkt_at(self, fit):
        solver, res = fit._state
        return solver, res, solver.kkt_system(res._lin)

    @staticmethod
    def _free_border(fit, E, D):
        """``(E, D, free)`` without the parameters held on a bound.

        A parameter at a bound the data push it against is not free: to first
        order it stays there, so the statistics are those of the model with
        it fixed (its columns of the border dropped).
        """
        free = ~fit.held
        if free.all():
            return E, D, free
        return E.columns(free), D[np.ix_(free, free)], free

    def _covariance(self, fit):
        """``s^2 Sc^-1`` and the initial state's covariance, at the solution.

        The inverse of the bordered KKT matrix holds, in its parameter block,
        ``Sc^-1`` and, in the ``x_0`` block, the covariance of the initial
        state (both in units of the Hessian of ``J / 2``): ``n`` extra solves.
        A direction the data do not determine gets NaN, and so does a
        parameter held on a bound (``at_bound``): the rest is computed with
        it fixed there.
        """
        p, n = fit.theta.size, self.n_states
        nan = (
            np.full((p, p), np.nan),
            np.full((n, n), np.nan),
            np.full((p, n), np.nan),
        )
        if fit._state is None:
            return nan
        try:
            solver, res, (fac, _, _, E, D) = self._kkt_at(fit)
        except np.linalg.LinAlgError:
            return nan
        unit = solver.unit
        b = np.zeros((solver.N, 2 * n, n))
        b[0, :n, :] = np.eye(n)
        E, D, free = self._free_border(fit, E, D)
        sol = solve_reduced(fac, E, D, b, np.zeros((E.p, n)), rows=slice(0, 1))
        s2 = fit.residual_variance * fit.inflation
        x0_cov = sol.z[0, :n, :] * s2 * np.outer(unit, unit)  # to user units
        x0_cov = 0.5 * (x0_cov + x0_cov.T)
        if not p:
            return np.zeros((0, 0)), x0_cov, np.zeros((0, n))
        inverse, _ = equilibrated_inverse(sol.Sc)
        sub = inverse * s2
        # the parameter rows of the same columns: their covariance with x_0
        cross_sub = np.asarray(sol.dtheta, dtype=float).reshape(-1, n) * s2 * unit
        bad = undetermined(sol.Sc)
        if np.any(bad):
            # a direction the data do not determine (two parameters doing one
            # job): the variances of the parameters in it are unknown
            sub[bad, :] = np.nan
            sub[:, bad] = np.nan
            cross_sub[bad, :] = np.nan
            fit.rank_deficient = True
        if free.all():
            return sub, x0_cov, cross_sub
        cov = np.full((p, p), np.nan)
        cov[np.ix_(free, free)] = sub
        cross = np.full((p, n), np.nan)
        cross[free] = cross_sub
        return cov, x0_cov, cross

    def scores(self, fit: OutputErrorFit, candidates):
        """Linearised partial F (and a first step) for adding each candidate.

        The response of the fitted trajectory to one unit of a new
        coefficient, with everything already in the model re-optimised, is
        the solution of the KKT system forced by that term's one-interval
        sensitivities; its projection on the residual is the score. Returns
        ``(f_values, steps)``; 0 for candidates whose values are not finite.
        """
        k_c = len(candidates)
        zeros = np.zeros(k_c)
        fit._require_linearisation("a score test")
        if not k_c or fit._state is None or not np.isfinite(fit.cost):
            return zeros, zeros
        try:
            solver, res, (fac, _, _, E, D) = self._kkt_at(fit)
        except np.linalg.LinAlgError:
            return zeros, zeros
        n, N = solver.n, solver.N
        lin = res._lin
        # the model's parameters are re-optimised, except those held on a bound
        E, D, free = self._free_border(fit, E, D)
        M = solver._M[:, free]
        per_sample = max(N * n, 1)
        group = max(1, _SCORE_ELEMENTS // per_sample)
        flow_group = max(group, _FLOW_ELEMENTS // per_sample)
        passes = -(-k_c // flow_group)
        flow_group = -(-k_c // passes)  # the passes' groups of equal size
        num = np.zeros(k_c)
        den = np.zeros(k_c)
        scale = np.ones(k_c)
        # K^-1 E and the reduced Hessian once for all groups: each group's
        # banded solve is then its own columns only
        border = ReducedBorder(fac, E, D)
        del E
        H = lin.H
        for lo_f in range(0, k_c, flow_group):
            # one pass of the variational equations for many candidates (the
            # pass costs a linearisation whatever their number), then the
            # banded solves in smaller groups (their buffers are several
            # times the sensitivities); each candidate's numbers are those
            # of a pass of its own
            sens_f, finite_f = self._candidate_sensitivities(
                solver, res, candidates[lo_f : lo_f + flow_group]
            )
            for lo_g in range(0, sens_f.shape[2], group):
                lo = lo_f + lo_g
                sens = sens_f[:, :, lo_g : lo_g + group]
                finite = finite_f[lo_g : lo_g + group]
                g = sens.shape[2]
                # Each candidate's forcing at unit size: the unit of a
                # coefficient (of y^3 in metres or in millimetres) is the user's
                # choice, and the test below of a response lost to rounding must
                # not depend on it (num / size and den / size^2 leave the score
                # as it is; the step is scaled back).
                with np.errstate(all="ignore"):
                    size = np.sqrt(np.mean(sens**2, axis=(0, 1)))
                size = np.where(np.isfinite(size) & (size > 0), size, 1.0)
                scale[lo : lo + g] = size
                # the forcing written straight into the solve's columns
                cols = border.new_columns(g)
                # minus the sensitivities over their size, divided where it
                # is written (a quotient beside it was half the columns'
                # size, at the peak of a long record's study); x / -s is
                # -(x / s) exactly
                np.divide(
                    np.moveaxis(sens, 2, 0), -size[:, None, None], out=cols[:, :-1, n:]
                )
                dtheta = border.solve_columns(cols, np.zeros((D.shape[0], g)))
                dx = cols[:, :, :n]  # (G, N, n)
                dy = (
                    np.einsum("ai,gki->gka", H, dx)
                    if H.ndim == 2
                    else np.einsum("kai,gki->gka", H, dx)
                )
                del cols, dx
                if M.shape[1]:
                    dy = dy + np.einsum("ap,pg->ga", M, dtheta)[:, None, :]
                Rdy = np.einsum("kab,gkb->gka", solver.Rinv, dy)
                num[lo : lo + g] = np.einsum("gka,ka->g", Rdy, lin.r)
                den[lo : lo + g] = np.einsum("gka,gka->g", Rdy, dy)
                # a term not finite along the trajectory cannot be scored
                num[lo : lo + g][~finite] = np.nan
                del dy, Rdy  # not beside the next group's columns
            # the next pass's sensitivities must not be made beside these
            # (sens, a view, would keep them alive)
            del sens_f, sens
        ssr = fit.cost
        # raw residual degrees of freedom, the statistic corrected for
        # correlated residuals (OutputErrorFit.inflation)
        dof = max(fit.n_residuals - fit.n_free - 1, 1) / fit.inflation
        with np.errstate(divide="ignore", invalid="ignore"):
            usable = (
                np.isfinite(num) & np.isfinite(den) & (den > 1e-12 * max(ssr, 1e-300))
            )
            dssr = np.where(usable, num**2 / np.where(usable, den, 1.0), 0.0)
            f_values = dssr / np.maximum(ssr - dssr, 1e-300) * dof
            step = np.where(usable, num / np.where(usable, den, 1.0), 0.0) / scale
        return np.nan_to_num(f_values), np.nan_to_num(step)

    def _candidate_sensitivities(self, solver, res, candidates):
        """One-interval sensitivities ``dPhi_k / dc`` of candidate terms at 0.

        Returns ``(sens (N-1, n, G), finite (G,))``; a candidate with a
        non-finite value anywhere along the trajectory is not finite.
        """
        cols = sorted({c for _, c in candidates})
        pos = {c: k for k, c in enumerate(cols)}
        n = self.n_states
        unit = solver.unit

        def forcing(z, s, u):
            zz = unit * z
            zz = zz if u is None else np.hstack([zz, u])
            with np.errstate(all="ignore"):
                phi = self.features(zz, cols)
            out = np.zeros((z.shape[0], n, len(candidates)))
            for j, (state, col) in enumerate(candidates):
                out[:, state, j] = phi[:, pos[col]]
            return out / unit[:, None]

        x_int = res.x / unit
        d = np.zeros((solver.N - 1, 0))
        with np.errstate(all="ignore"):
            _, sens = solver.flow(
                x_int,
                d,
                res.theta,
                jacobian=True,
                extra=(len(candidates), forcing),
                only_extra=True,
            )
        finite = np.all(np.isfinite(sens), axis=(0, 1))
        sens[:, :, ~finite] = 0.0
        return sens, finite
