"""The solver's internal units, and the model as the solver sees it.

The KKT pivots mix ``R^-1`` (state rows) with ``h W^-1`` (multiplier rows),
so the solver works in units of ``s``, a power of two near the noise
standard deviation (:func:`internal_unit`); :class:`Dynamics` is the model
in those units, with its Jacobians.
"""

from __future__ import annotations

import numpy as np

from ..core.model import ModelFunction, rowwise_jacobian

__all__ = ["Dynamics", "internal_unit"]


def internal_unit(R) -> float:
    """The solver's internal unit: a power of two near the noise's std. dev.

    With ``R / s^2`` of order one the KKT pivots of the state rows
    (``~ R^-1``) and of the multiplier rows (``~ h W^-1 ~ R`` at the
    reference weight) are of order one together, whatever the data's units.
    """
    sd = float(np.sqrt(np.mean(np.diag(np.atleast_2d(R)))))
    return float(np.ldexp(1.0, int(np.round(np.log2(sd)))))


class Dynamics:
    """The model in internal units: ``f_s(z, theta) = f(s z, theta) / s``.

    Wraps a :class:`ModelFunction` (no parameters) or a
    :class:`~pysindy_mme.core.model.ParametricModel`. Finite-difference
    Jacobians step in ``z``; a model with its own Jacobian keeps it
    (``d f_s / dz = J(s z)``).
    """

    def __init__(self, model, unit: float):
        self.model, self.unit = model, unit
        self._last = (None, None)  # (z, s z): the same z gives the same array
        self.n = model.n_states
        self.p = int(getattr(model, "n_params", 0))
        self.parametric = hasattr(model, "param_jacobian")
        own = type(model).jacobian is not ModelFunction.jacobian
        self._own_jacobian = isinstance(model, ModelFunction) and own

    def _user(self, z):
        """``s z``, the same array object for the same ``z`` (so the model can
        reuse what it computed at that point)."""
        if self._last[0] is not z:
            self._last = (z, self.unit * z)
        return self._last[1]

    def __call__(self, z, t, u, theta):
        s = self.unit
        if self.parametric:
            return self.model(self._user(z), t, u, theta) / s
        return self.model(s * z, t, u) / s

    def jacobian(self, z, t, u, theta):
        if self._own_jacobian:
            return self.model.jacobian(self.unit * z, t, u)
        s = self.unit
        if self.parametric and self.model.has_exact_correction_jacobian:
            # finite differences of the assumed model only (steps in z); the
            # correction's Jacobian is exact: d/dz [c(s z) / s] = c'(s z)
            base = rowwise_jacobian(
                lambda zz: self.model.base_part(s * zz, t, u, theta) / s, z
            )
            return base + self.model.correction_jacobian(self._user(z), u, theta)
        return rowwise_jacobian(lambda zz: self(zz, t, u, theta), z)

    def param_jacobian(self, z, t, u, theta):
        if not self.p:
            return np.zeros((z.shape[0], self.n, 0))
        return self.model.param_jacobian(self._user(z), t, u, theta) / self.unit
