"""``error_model="random_walk"``: the model error as extra states.

``[x, d]' = [f(x, t, u) + E d, w]``: ``d`` is continuous and ``W`` weighs
its rate ``w``, so the same transcription solver estimates a smooth model
error; the measurement ignores the ``d`` block.
"""

from __future__ import annotations

import numpy as np

from ..core.model import ModelFunction

__all__ = ["RandomWalkModel", "random_walk_problem"]


class RandomWalkModel(ModelFunction):
    """``[x, d]' = [f(x, t, u) + E d, 0]``: the model error as extra states.

    The Jacobian is exact in the ``d`` block and finite differences (of the
    base model only) in the ``x`` block.
    """

    def __init__(self, base: ModelFunction, error_states):
        self.base = base
        self.n_base = base.n_states
        self.es = np.asarray(error_states, dtype=int)
        super().__init__(self._rhs, base.n_states + self.es.size, name=base.name)

    def _rhs(self, z, t, u):
        n = self.n_base
        out = np.zeros_like(z)  # d' = 0: the rate is the model error w
        out[:, :n] = self.base(z[:, :n], t, u)
        out[:, self.es] += z[:, n:]
        return out

    def jacobian(self, x, t, u=None, f0=None) -> np.ndarray:
        z = np.atleast_2d(np.asarray(x, dtype=float))
        n = self.n_base
        J = np.zeros((z.shape[0], self.n_states, self.n_states))
        J[:, :n, :n] = self.base.jacobian(z[:, :n], t, u)
        J[:, self.es, n + np.arange(self.es.size)] = 1.0
        return J


def random_walk_problem(model, es, measurement, g_jac):
    """The augmented model and measurement of ``error_model="random_walk"``."""
    n, q = model.n_states, es.size
    aug_model = RandomWalkModel(model, es)
    if not callable(measurement):
        return (
            aug_model,
            np.hstack([measurement, np.zeros((len(measurement), q))]),
            None,
        )

    def g(z):
        return measurement(z[:, :n])

    jac = None
    if g_jac is not None:

        def jac(z):
            J = np.asarray(g_jac(z[:, :n]), dtype=float)
            return np.concatenate([J, np.zeros(J.shape[:2] + (q,))], axis=2)

    return aug_model, g, jac
