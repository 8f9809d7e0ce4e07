"""Gauss-Newton with an l1-merit line search for the transcribed problem.

The iteration of :class:`~.transcription.MMESmoother`: each step solves the
KKT system of the linearised problem (``_kkt_step``), a line search on the
exact l1 merit function (cost + penalty on the dynamics defects) globalises
it, and the result is packaged with its costs. A mixin: it uses the
solver's dynamics, costs and KKT system.

Bounds on the parameters (``theta_bounds``) enter the subproblem itself
(``_bounded_step``): its step keeps ``theta`` inside the box for every step
length up to 1, and is zero at a point where a parameter is held on a bound
by data pushing outwards, so the convergence test below applies unchanged.
The iterates are only clipped to undo rounding: ``theta + (bound - theta)``
need not be the bound exactly, and a parameter meant to sit on its bound
(reported as such) must.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..core.blockwise import max_abs
from ..exceptions import DivergenceError
from .kkt import drop_kept_border
from .records import SmootherResult

__all__ = ["GaussNewton"]


#: a damped step that lowers the merit by less than this (in units of the
#: cost, a chi-square: a thousandth of one noise variance) makes no
#: difference to any test the package runs, whose decisions rest on cost
#: differences of several units
STALL_DECREASE = 1e-3
#: dynamics defects at most this fraction of the states' scale are closed
#: for every purpose (far below the 1e-6 of a trajectory that joins, a few
#: thousand roundings above zero): the convergence test then asks only that
#: the step no longer changes the cost
FEASIBLE = 1e-10
#: intervals probed before the whole-record test that a linearisation did
#: not change (:meth:`GaussNewton._same_quadratic_model`)
_SAME_PROBE = 256


class GaussNewton:
    """The Gauss-Newton iteration of :class:`~.transcription.MMESmoother`."""

    def _solve(self, W, lin):
        """:meth:`solve` in internal units from the linearisation ``lin``."""
        Winv = np.linalg.inv(W) if self.q else W
        x, d, theta = lin.x, lin.d, lin.theta
        # the data's cost, with the prior on the initial states if any
        meas = self.measurement_cost(lin.r) + self.prior_cost(x)
        mu = 0.0
        converged, deficient = False, False
        message = f"reached max_iter = {self.max_iter}"
        lam = np.zeros((self.N - 1, self.n))
        logdet = np.nan
        n_iter = stall = nonfinite = 0
        for n_iter in range(1, self.max_iter + 1):  # noqa: B007
            try:
                step = self._kkt_step(lin, W, Winv)
                dx, d_new, dth, lam, logdet, deficient, active = step
            except np.linalg.LinAlgError:
                self._raise_singular(lin)
            dd = d_new - d
            if not (
                np.isfinite(dx).all()
                and np.isfinite(dd).all()
                and np.isfinite(dth).all()
            ):
                raise DivergenceError(
                    "the Gauss-Newton step is not finite; the linearised "
                    "problem is too ill-conditioned (model exploding?)"
                )
            defect_l1 = float(np.abs(lin.defects).sum())
            mu = max(mu, 2.0 * float(np.max(np.abs(lam), initial=0.0)) * 1.5)
            cost0 = meas + self.model_error_cost(d, W)
            phi0 = cost0 + mu * defect_l1
            grad_dot_p = (
                -2.0 * float(np.einsum("kb,kb->", lin.r, self._apply_R_H(lin, dx, dth)))
                + 2.0 * float(np.einsum("k,ki,ij,kj->", self.h, d, W, dd))
                + self.prior_cost(x, dx)
            )
            slope = grad_dot_p - mu * defect_l1
            small = self.tol * max(phi0, np.finfo(float).tiny)
            # Stationary and feasible, each judged on its own: the merit's
            # slope adds mu times the sum of the defects' sizes, which on a
            # record of 10^6 samples stays above the tolerance for defects of
            # 1e-11 (rounding, a thousandth of what could move a cost): at
            # such a point the step changes the cost by nothing and closes
            # the last defects, so it is the last (one iteration of a long
            # record's fit).
            feasible = max_abs(lin.defects) <= FEASIBLE * self.scale(x)
            if -slope <= small or (feasible and abs(grad_dot_p) <= small):
                # Stationary to within tol: take the (tiny) step and stop.
                x, d, theta = x + dx, d_new, self._on_box(theta + dth, active)
                converged = True
                message = "converged"
                break
            # not the last step: its K^-1 E (kept with the factor for the
            # statistics of a converged fit) would sit beside the line
            # search's flows and the next linearisation
            drop_kept_border()
            start, unlinearisable = 1.0, None
            while True:
                alpha, trial, merit, bad = self._line_search(
                    x, d, theta, (dx, dd, dth), active, W, mu, phi0, slope, start
                )
                nonfinite += bad
                if trial is None:
                    break
                # Damped steps that no longer lower the merit measurably (an
                # inexact finite-difference Jacobian of the user's model
                # limits how far Gauss-Newton can go): stationary for all
                # purposes.
                floor = max(self.tol * phi0, STALL_DECREASE)
                stalled = alpha < 1 and phi0 - merit <= floor
                if stall + stalled >= 2:
                    break
                try:
                    new_lin = self.linearize(*trial)
                except DivergenceError as exc:
                    # The merit went down, but the model cannot be linearised
                    # at the new point (a square-root outflow whose RK4 stage
                    # lands just above an empty tank amplifies a perturbation
                    # a million-fold): a shorter step along the same
                    # direction, as for a step whose merit did not go down.
                    unlinearisable = exc
                    start = alpha / 2
                    if start < 2.0**-40:
                        raise
                    continue
                break
            if trial is None:
                if unlinearisable is not None:
                    raise unlinearisable
                message = "line search failed to decrease the merit function"
                break
            x, d, theta = trial
            stall = stall + 1 if stalled else 0
            if stall >= 2:
                converged = True
                message = "converged (the merit function stopped decreasing)"
                break
            previous, lin = lin, new_lin
            meas = self.measurement_cost(lin.r) + self.prior_cost(x)
            linear = alpha == 1.0 and self._same_quadratic_model(previous, lin)
            # the old linearisation (its A, B, defects and residuals: 136
            # bytes per sample of two states with five parameters) would
            # otherwise live through the next KKT step, a study's peak
            del previous
            if linear:
                # The problem is linear-quadratic (a linear model and
                # measurement): the full step solved it exactly, and the next
                # subproblem would be the same one with a zero step.
                converged = True
                message = "converged (linear problem, exact step)"
                break
        res = self._result(
            W, x, d, theta, lam, lin, logdet, converged, n_iter, message, deficient
        )
        res.nonfinite_trials = nonfinite
        return res

    def _line_search(self, x, d, theta, step, active, W, mu, phi0, slope, alpha):
        """Halve ``alpha`` from its start until the l1 merit decreases enough
        (Armijo): ``(alpha, (x, d, theta) or None, merit, trials that made
        the model blow up)``."""
        dx, dd, dth = step
        nonfinite = 0
        for _ in range(40):
            xt, dt_ = x + alpha * dx, d + alpha * dd
            tht = theta + alpha * dth
            if active is not None:
                tht = self._on_box(tht, active if alpha == 1.0 else None)
            with np.errstate(all="ignore"):
                phi_t = self.flow(xt, dt_, tht, jacobian=False)
                meas_t = self.measurement_cost(
                    self.residuals(xt, tht)
                ) + self.prior_cost(xt)
                merit = (
                    meas_t
                    + self.model_error_cost(dt_, W)
                    + mu * float(np.abs(phi_t - xt[1:]).sum())
                )
            if not np.isfinite(merit):
                nonfinite += 1  # this trial step made the model blow up
            elif merit <= phi0 + 1e-4 * alpha * slope:
                return alpha, (xt, dt_, tht), merit, nonfinite
            alpha *= 0.5
        return alpha, None, np.nan, nonfinite

    def _on_box(self, theta, active):
        """``theta`` clipped into the bounds (rounding only, see the module
        docstring); entries ``active`` puts on a bound set to it exactly."""
        bounds = getattr(self, "theta_bounds", None)
        if bounds is None:
            return theta
        theta = np.clip(theta, bounds[:, 0], bounds[:, 1])
        if active is not None:
            theta = np.where(active < 0, bounds[:, 0], theta)
            theta = np.where(active > 0, bounds[:, 1], theta)
        return theta

    def _result(
        self, W, x, d, theta, lam, lin, logdet, converged, n_iter, message, deficient
    ):
        """Package the solution (internal units) with its costs."""
        at_lin = lin.x is x and lin.d is d and lin.theta is theta
        if at_lin:
            # The last linearisation is at the returned point (a linear
            # problem's exact step, or max_iter after an accepted step): its
            # residuals and defects are these, the same numbers (its flow's
            # states are integrated as a flow without derivatives integrates
            # them). A second pass over the record would only repeat them.
            r, defects = lin.r, lin.defects
            with np.errstate(all="ignore"):
                meas = self.measurement_cost(r)
        else:
            with np.errstate(all="ignore"):
                r = self.residuals(x, theta)
                meas = self.measurement_cost(r)
                phi = self.flow(x, d, theta, jacobian=False)
                # in place: phi itself is not needed (no second array its size)
                defects = np.subtract(phi, x[1:], out=phi)
        max_defect = max_abs(defects)
        if not at_lin:
            # The last (sub-tolerance) step was taken without relinearising.
            # Keep A, G, B, H from just before it (they change by O(step))
            # with the exact defects and residuals at the returned point: a
            # warm start from here is then consistent up to that O(step).
            lin = dataclasses.replace(lin, x=x, d=d, theta=theta, defects=defects, r=r)
        if not (np.isfinite(x).all() and np.isfinite(theta).all()):
            raise DivergenceError("the estimate diverged to non-finite values")
        mec = self.model_error_cost(d, W)
        cost = meas + mec + self.prior_cost(x)
        n2ll = (
            cost + logdet + self._logdetR + (self.n_obs - self.n) * np.log(2.0 * np.pi)
        )
        if self._prior is not None:
            n2ll += self._prior[2]
        return SmootherResult(
            W=W,
            x=x,
            d=d,
            lam=lam,
            residuals=np.where(self.mask, r, np.nan),
            cost=cost,
            measurement_cost=meas,
            model_error_cost=mec,
            logdet=logdet,
            neg2_log_likelihood=float(n2ll),
            converged=converged,
            n_iter=n_iter,
            max_defect=max_defect,
            message=message,
            theta=theta,
            rank_deficient=bool(deficient),
            _lin=lin,
        )

    def _same_quadratic_model(self, old, new):
        """Whether the linearisation did not change over a full step.

        True for a linear model with a linear measurement: then the step was
        the exact solution. Tolerances allow for the finite-difference
        Jacobian's rounding (about 1e-10 relative).
        """
        if new.H.ndim != 2:
            return False
        tol = 1e-8

        def same(a, b, floor):
            if a.size == 0:
                return True
            # max |a| without a temporary of a's size
            scale = max(floor, float(a.max()), -float(a.min()))
            # A nonlinear model changes A (and B) on nearly every interval:
            # a few hundred of them settle it before a pass over the record
            # and its temporaries (on a long record that pass was 2 % of a
            # study). Rejecting on a subset is the answer of the whole test.
            rows = slice(None, None, max(1, a.shape[0] // _SAME_PROBE))
            if np.max(np.abs(b[rows] - a[rows])) > tol * scale:
                return False
            return max_abs(b, a) <= tol * scale

        return bool(
            same(old.A, new.A, 1.0)
            and same(old.G, new.G, 1e-300)
            and same(old.B, new.B, 1e-300)
            and max_abs(new.defects) <= tol * self.scale(new.x)
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
