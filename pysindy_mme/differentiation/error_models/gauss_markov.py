"""``error_model="gauss_markov"`` (alias ``"ou"``): a model error that forgets.

The first-order Gauss-Markov (Ornstein-Uhlenbeck) prior,

    ``d' = -d / tau + w``,  ``W`` weighing the rate ``w``,

makes ``d`` a continuous extra state, as the random walk does, with a
memory of ``tau``: its autocorrelation is ``exp(-|s| / tau)`` and its
stationary covariance ``P = tau W^-1 / 2``. In the cost it is
``integral (d' + d / tau)^T W (d' + d / tau) dt``, plus
``d_0^T P^-1 d_0`` for each record's initial ``d``: ``d`` starts in its
stationary distribution (``x_0`` keeps the flat prior of every MME model).
A flat prior on ``d_0`` would not do: when ``tau`` is short the data see
``d_0`` only through its first ``tau`` of decay, so ``d_0`` would absorb
the noise there (on the paper's record with ``tau = 0.03``, ``d_0 = 131``
and ``x2(0)`` off by 3.8), and the improper prior's volume, about
``1 / tau^2``, would bias the likelihood towards short ``tau``.

Relation to the other two priors:

* ``tau -> infinity``: ``d' = w``, the random walk (``"random_walk"``) with
  the same ``W``.
* ``tau -> 0`` with ``W / tau^2`` held fixed: the spectrum of ``d``,
  ``W^-1 / (omega^2 + tau^-2)``, tends to the flat ``tau^2 / W`` at every
  frequency the data resolve, so ``d`` tends to white noise, the paper's
  ``"white"`` with ``W_white = W / tau^2`` (in the cost, ``d / tau``
  dominates ``d'``). The white model holds ``d`` on each sample interval,
  so the two agree once ``tau`` is short against the estimate's own time
  scale but not against the integration step (a shorter ``tau`` is
  refused: use ``"white"``). On the paper's record the likelihood at the
  shortest ``tau`` is the white model's to 0.2 in ``-2 log p``.

``tau`` is estimated by the marginal likelihood, under whichever rule sets
``W``. The covariance constraint is one scalar equation: it fixes how much
the estimate smooths, but every ``tau`` meets it at its own ``W(tau)``, so
it cannot choose the shape of the prior; the restricted marginal likelihood
can (it is what ``W="ml"`` maximises over ``W``, and with the stationary
prior on ``d_0`` it compares priors of different ``tau`` on the same data).
So, for each trial ``tau`` the usual W search runs
(:func:`~..weight.search_W`), and ``tau`` minimises
``-2 log p(y | W(tau), tau)``:

* ``W="ml"``: the profile likelihood, i.e. the joint maximum over
  ``(W, tau)``;
* ``W="auto"`` (the paper's rule): the likelihood along the constraint
  curve: the constraint sets the level of smoothing, the likelihood the
  correlation time;
* a fixed ``W``: the likelihood at that ``W``.

The search is over ``log tau`` between the integration step (the longest
sample interval over ``n_substeps``: below it RK4 no longer resolves the
decay, and the prior is the white one for all the data can tell) and the
record's duration (beyond it the prior is the random walk for all the data
can tell): a grid of half a decade, then Brent's method between the
neighbours of the best grid point (to 2 % in ``tau``). A maximum on either
end says which limit the data favour (``tau_at_bound_``). A number for
``tau`` fixes it: the fit then costs what the random walk's does.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.optimize import minimize_scalar

from ..weight import WSearch
from .base import AugmentedErrorModel, SolverInputs

__all__ = ["GaussMarkov"]

# log10 spacing of the grid over tau, and Brent's tolerance in log tau
_GRID_DECADES = 0.5
_XATOL = 0.02


class GaussMarkov(AugmentedErrorModel):
    """The model error as an Ornstein-Uhlenbeck process: ``d' = -d/tau + w``.

    Parameters
    ----------
    tau : "auto" or float, default "auto"
        Correlation time of the model error, in the units of ``t``.
        ``"auto"``: estimated by the marginal likelihood with ``W`` set by
        MME's rule (module docstring); a number fixes it.

    Attributes
    ----------
    tau_ : float
        The correlation time used (set when MME fits with the model: on
        ``MME.error_model_``, a copy; the object given stays unfitted).
    tau_at_bound_ : bool
        The likelihood was largest on an end of the search range (the
        integration step: the white limit; the record's duration: the
        random-walk limit).
    tau_history_ : list of (tau, W, -2 log p(y))
        The search over ``tau`` (each with its ``W``), sorted by ``tau``;
        empty for a fixed ``tau``.
    """

    name = "gauss_markov"
    aliases = ("ou",)
    summary = (
        "gauss_markov (d' = -d/tau + w: a d with memory tau, estimated; "
        "between white and random_walk)"
    )

    def __init__(self, tau="auto"):
        self.tau = tau

    def check(self) -> None:
        tau = self.tau
        if isinstance(tau, str) and tau == "auto":
            return
        if (
            isinstance(tau, (bool, str))
            or not np.isscalar(tau)
            or not np.isfinite(tau)
            or tau <= 0
        ):
            raise ValueError(
                f"GaussMarkov: tau must be 'auto' or a positive number (the "
                f"model error's correlation time), got {tau!r}"
            )

    def rate(self, q: int) -> np.ndarray:
        return -np.eye(q) / self._tau

    def initial_covariance(self, W):
        """The stationary covariance ``tau W^-1 / 2`` of ``d``."""
        return 0.5 * self._tau * np.linalg.inv(np.atleast_2d(W))

    def smoother(self, inputs: SolverInputs):
        base = inputs.base
        step = float(np.max(base.h)) / base.n_substeps
        duration = float(np.sum(base.h))
        self._range = (np.log(step), np.log(max(duration, step)))
        if isinstance(self.tau, str):
            self._tau = float(np.exp(np.mean(self._range)))
        else:
            self._tau = float(self.tau)
            if self._tau < step:
                raise ValueError(
                    f"GaussMarkov: tau = {self._tau:.4g} is shorter than the "
                    f"integration step {step:.4g} (the longest sample interval "
                    "over n_substeps): the decay is not resolved. Raise "
                    "n_substeps, or use error_model='white' (the tau -> 0 limit)"
                )
        return super().smoother(inputs)

    def search(self, smoother, W_spec, solve, verbose: bool = False) -> WSearch:
        if not isinstance(self.tau, str):
            self.tau_, self.tau_at_bound_, self.tau_history_ = self._tau, False, []
            return super().search(smoother, W_spec, solve, verbose)
        profile = _Profile(self, smoother, W_spec, solve, verbose)
        lo, hi = self._range
        n_grid = max(int(np.ceil((hi - lo) / np.log(10.0) / _GRID_DECADES)), 1) + 1
        grid = np.linspace(lo, hi, n_grid)
        values = [profile(lt) for lt in grid]
        i = int(np.argmin(values))
        if 0 < i < n_grid - 1:
            minimize_scalar(
                profile,
                bounds=(grid[i - 1], grid[i + 1]),
                method="bounded",
                options={"xatol": _XATOL},
            )
        best_logtau, best = profile.best
        for caught in profile.best_warnings:  # those of the tau chosen only
            warnings.warn(caught.message, caught.category, stacklevel=3)
        self._tau = self.tau_ = float(np.exp(best_logtau))
        self.tau_at_bound_ = best_logtau in (lo, hi)
        self.tau_history_ = profile.history()
        smoother.model.rate = self.rate(smoother.model.es.size)
        return WSearch(
            result=best.result,
            W=best.W,
            history=best.history,
            at_bound=best.at_bound,
            n_iter=profile.n_iter,
            converged=profile.converged,
        )


class _Profile:
    """``log tau -> -2 log p(y | W(tau), tau)``, memoised, best search kept.

    Only the best W search is kept (each holds a solution of O(N) arrays),
    with the warnings it gave: a W search at a trial ``tau`` that warns
    (the constraint not met in range, say) says nothing about the fit.
    """

    def __init__(self, model, smoother, W_spec, solve, verbose):
        self.model, self.smoother, self.W_spec = model, smoother, W_spec
        self.solve, self.verbose = solve, verbose
        self.values, self.Ws = {}, {}
        self.best = (None, None)
        self.best_warnings = []
        self.n_iter, self.converged = 0, True

    def __call__(self, logtau):
        logtau = float(logtau)
        if logtau in self.values:
            return self.values[logtau]
        tau = float(np.exp(logtau))
        model = self.model
        model._tau = tau
        self.smoother.model.rate = model.rate(self.smoother.model.es.size)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            search = AugmentedErrorModel.search(
                model, self.smoother, self.W_spec, self.solve, self.verbose
            )
        value = float(search.result.neg2_log_likelihood)
        self.values[logtau], self.Ws[logtau] = value, search.W
        self.n_iter += int(search.n_iter)
        self.converged &= bool(search.converged)
        if self.best[1] is None or value < self.values[self.best[0]]:
            self.best, self.best_warnings = (logtau, search), list(caught)
        if self.verbose:
            W = np.array2string(np.asarray(search.W), precision=6)
            print(f"MME: tau = {tau:.6g}, W = {W}, -2 log p = {value:.6g}")
        return value

    def history(self):
        return sorted((float(np.exp(k)), self.Ws[k], v) for k, v in self.values.items())
