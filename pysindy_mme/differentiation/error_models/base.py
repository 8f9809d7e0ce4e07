"""What an error model is: MME's prior on ``d(t)`` as an object.

An error model answers three questions for :class:`~..mme.MME`, each a
method, so that MME itself has no branch per model:

* :meth:`ErrorModel.smoother`: the estimation problem as one the direct
  transcription solver already solves (:class:`~..transcription.MMESmoother`:
  states at the samples, a zero-order-hold input ``w`` penalised by
  ``sum_k h_k w_k^T W w_k``). The white model is that problem as stated
  (``w = d``); a correlated model augments the state with ``d`` and lets
  ``w`` drive it (:class:`AugmentedErrorModel`).
* :meth:`ErrorModel.search`: ``W`` by the covariance constraint or the
  marginal likelihood (:func:`~..weight.search_W`), and the model's own
  parameters if it has any (a correlation time, say).
* :meth:`ErrorModel.read`: ``d`` at the samples and on the intervals, read
  back from the solution.

The objects are settings (their constructor arguments) plus, after MME has
fitted with them, fitted attributes ending in ``_``; MME works on a copy
(``MME.error_model_``), never on the object it was given.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...core.model import ModelFunction
from ..weight import WSearch, search_W

__all__ = [
    "AugmentedErrorModel",
    "AugmentedModel",
    "ErrorModel",
    "ErrorReading",
    "SolverInputs",
]


@dataclass(frozen=True)
class SolverInputs:
    """The checked problem, as :meth:`ErrorModel.smoother` receives it.

    Attributes
    ----------
    base : MMESmoother
        The solver of the problem as stated (``d`` held on each interval,
        ``W`` on ``d``), already built and checked.
    model : ModelFunction
        The assumed model ``f(x, t, u)``.
    error_states : ndarray of int (q,)
    measurement : ndarray (m, n) or callable
        ``C`` of ``y = C x``, or ``g(x)``.
    measurement_jacobian : callable or None
    build : callable
        ``build(model, error_states, measurement, measurement_jacobian)``: a
        solver on the same data, noise, inputs and settings.
    """

    base: object
    model: object
    error_states: np.ndarray
    measurement: object
    measurement_jacobian: object
    build: Callable


@dataclass(frozen=True)
class ErrorReading:
    """The model error read back from a solution (:meth:`ErrorModel.read`).

    Attributes
    ----------
    d : ndarray (N, q)
        ``d`` at the sample times.
    d_intervals : ndarray (N - 1, q)
        ``d`` on each interval (its mean over the interval).
    model : ModelFunction
        The assumed model (without any augmentation).
    """

    d: np.ndarray
    d_intervals: np.ndarray
    model: object


class ErrorModel:
    """Base class of MME's priors on the model error ``d(t)``.

    Subclasses set :attr:`name` (and :attr:`aliases`), the strings
    ``error_model=`` accepts for them once listed in the registry
    (:data:`~.ERROR_MODELS`), a one-line :attr:`summary` for help texts,
    and implement :meth:`smoother` and :meth:`read`; one with parameters of
    its own checks them in :meth:`check` and may estimate them in
    :meth:`search`.
    """

    #: the name ``error_model=`` accepts (and the command line's --error-model)
    name: ClassVar[str] = ""
    #: other accepted names
    aliases: ClassVar[tuple] = ()
    #: one line for help texts
    summary: ClassVar[str] = ""

    def check(self) -> None:
        """Check the model's own parameters (raise ``ValueError``/``TypeError``
        naming them); nothing to check by default."""

    def smoother(self, inputs: SolverInputs):
        """The solver that estimates ``x`` and ``d`` under this prior."""
        raise NotImplementedError

    def search(self, smoother, W_spec, solve, verbose: bool = False) -> WSearch:
        """``W`` (and the model's own parameters) and the solution there.

        ``W_spec`` is ``"auto"``, ``"ml"`` or a fixed ``(q, q)`` matrix;
        ``solve(W, start)`` solves for one ``W`` (warm start ``start``).
        """
        if isinstance(W_spec, str):
            return search_W(smoother, W_spec, solve, verbose)
        res = solve(W_spec, None)
        scalar = np.allclose(W_spec, W_spec[0, 0] * np.eye(W_spec.shape[0]))
        return WSearch(
            result=res,
            W=float(W_spec[0, 0]) if scalar else W_spec,
            n_iter=res.n_iter,
            converged=res.converged,
        )

    def read(self, smoother, result, n_states: int) -> ErrorReading:
        """``d`` from a solution of :meth:`smoother`'s solver."""
        raise NotImplementedError

    def __repr__(self) -> str:
        settings = [
            p.name
            for p in inspect.signature(type(self)).parameters.values()
            if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
        ]
        args = ", ".join(f"{p}={getattr(self, p)!r}" for p in settings)
        return f"{type(self).__name__}({args})"


class AugmentedModel(ModelFunction):
    """``[x, d]' = [f(x, t, u) + E d, F d]``: the model error as extra states.

    ``F`` (``rate``, ``(q, q)``) is the model error's own dynamics, the rate
    ``w`` added to ``d'`` is what the solver holds on each interval and
    ``W`` weighs. :class:`~..units.Dynamics` recognises the augmentation
    (``augments = True``): it differentiates the base model in internal
    units and takes the ``d`` blocks exactly. ``rate`` is read at every
    evaluation, so a search over a parameter of ``F`` can reuse one solver.
    """

    augments = True

    def __init__(self, base: ModelFunction, error_states, rate):
        self.base = base
        self.n_base = base.n_states
        self.es = np.asarray(error_states, dtype=int)
        self.rate = np.asarray(rate, dtype=float).reshape(self.es.size, self.es.size)
        super().__init__(self._rhs, base.n_states + self.es.size, name=base.name)

    def _rhs(self, z, t, u):
        n = self.n_base
        out = np.empty_like(z)
        out[:, :n] = self.base(z[:, :n], t, u)
        out[:, self.es] += z[:, n:]
        out[:, n:] = z[:, n:] @ self.rate.T
        return out

    def jacobian(self, x, t, u=None, f0=None) -> np.ndarray:
        z = np.atleast_2d(np.asarray(x, dtype=float))
        n = self.n_base
        J = np.zeros((z.shape[0], self.n_states, self.n_states))
        J[:, :n, :n] = self.base.jacobian(z[:, :n], t, u)
        J[:, self.es, n + np.arange(self.es.size)] = 1.0
        J[:, n:, n:] = self.rate
        return J


class AugmentedErrorModel(ErrorModel):
    """An error model with ``d`` as extra states: ``d' = F d + w``.

    Subclasses give ``F`` (:meth:`rate`) and, when ``d`` has a stationary
    distribution, the prior on each record's initial ``d``
    (:meth:`initial_covariance`; flat by default); the solver then
    estimates ``d`` as a continuous state and ``W`` weighs the rate ``w``.
    An error state is observable exactly when the state it enters is, so
    the checks MME made on the problem as stated hold for the augmented
    one.
    """

    def rate(self, q: int) -> np.ndarray:
        """``F``, the ``(q, q)`` dynamics of the model error."""
        raise NotImplementedError

    def initial_covariance(self, W):
        """Covariance ``P`` of each record's initial ``d`` (prior ``N(0, P)``)
        for the weight ``W`` (``(q, q)``, user units), or None: a flat prior,
        the default (a random walk has no stationary distribution)."""
        return None

    def smoother(self, inputs: SolverInputs):
        model, es = inputs.model, np.asarray(inputs.error_states, dtype=int)
        n, q = model.n_states, es.size
        aug_model = AugmentedModel(model, es, self.rate(q))
        measurement, g_jac = _augmented_measurement(
            inputs.measurement, inputs.measurement_jacobian, n, q
        )
        smoother = inputs.build(aug_model, n + np.arange(q), measurement, g_jac)
        smoother.initial_prior = _InitialPrior(self, n + np.arange(q))
        # d_j, the model error of state j, in singularity diagnostics
        smoother.state_labels = [f"x{i}" for i in range(n)] + [
            f"d{i} (model error of x{i})" for i in es
        ]
        return smoother

    def read(self, smoother, result, n_states: int) -> ErrorReading:
        d = result.x[:, n_states:]
        return ErrorReading(
            d=d, d_intervals=0.5 * (d[1:] + d[:-1]), model=smoother.model.base
        )


class _InitialPrior:
    """``W -> (states, P)`` or None: the solver's ``initial_prior`` hook."""

    def __init__(self, model, states):
        self.model, self.states = model, states

    def __call__(self, W):
        P = self.model.initial_covariance(W)
        return None if P is None else (self.states, P)


def _augmented_measurement(measurement, g_jac, n, q):
    """The measurement of ``[x, d]``: it ignores the ``d`` block."""
    if not callable(measurement):
        return np.hstack([measurement, np.zeros((len(measurement), q))]), None

    def g(z):
        return measurement(z[:, :n])

    jac = None
    if g_jac is not None:

        def jac(z):
            J = np.asarray(g_jac(z[:, :n]), dtype=float)
            return np.concatenate([J, np.zeros(J.shape[:2] + (q,))], axis=2)

    return g, jac
