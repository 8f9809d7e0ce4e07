"""Van der Pol as an extended model: the ignorance model plus its correction.

Shared by the tests that need a fitted :class:`~pysindy_mme.ExtendedModel`
without running a study (its simulation, its bare form and Jacobian): the
assumed ``x1' = x2, x2' = 0`` and the correction ``x2' += -x1 + x2 -
x1^2 x2`` on a library fitted to a circle of radius 2.
"""

from __future__ import annotations

import numpy as np
import pysindy as ps

from pysindy_mme import ExtendedModel

__all__ = ["vdp_extended_model"]


def vdp_extended_model(library=None):
    """``(model, t)``: the extended model on ``library`` (default
    ``PolynomialLibrary(3)``) and the 401 times the library was fitted on."""
    t = np.linspace(0.0, 10.0, 401)
    x = np.column_stack([2.0 * np.cos(t), -2.0 * np.sin(t)])
    lib = (library or ps.PolynomialLibrary(degree=3)).fit(x)
    names = lib.get_feature_names(["x1", "x2"])
    coef = np.zeros((2, len(names)))
    for name, c in {"x1": -1.0, "x2": 1.0, "x1^2 x2": -1.0}.items():
        coef[1, names.index(name)] = c

    def assumed(x, t):
        return np.column_stack([x[:, 1], np.zeros(len(x))])

    return ExtendedModel(assumed, lib, coef, ["x1", "x2"]), t
