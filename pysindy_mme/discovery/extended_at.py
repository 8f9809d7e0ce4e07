"""The extended model at a fit's quantities, as the study prints it.

One place for the study (its extended model, the held-out refit's, the
coefficients' draws) and for :meth:`~.result.Discovery.validate` (the draws
on a new record), which the study module imports.
"""

from __future__ import annotations

import numpy as np

from ..core.extended import ExtendedModel

__all__ = ["extended_model_at"]


def extended_model_at(study, proposals, fit, x_hat, substeps) -> ExtendedModel:
    """The model as printed: the assumed model at ``fit``'s parameters plus
    ``fit.slots`` with ``fit``'s coefficients; its fixed-step simulations
    take the study's RK4 steps per sample, so that a user reproduces the
    study's free runs."""
    n_lib = len(proposals.feature_names)
    coef = np.zeros((study.n_states, n_lib))
    intercept = np.zeros(study.n_states)
    for (i, c), v in zip(fit.slots, fit.coefficients):
        if c == proposals.constant_column:
            intercept[i] = v
        else:
            coef[i, c] = v
    z_ref = x_hat if study.u is None else np.hstack([x_hat, study.u])
    return ExtendedModel(
        study.assumed_at(fit.physical),
        proposals.library,
        coef,
        study.state_names,
        study.input_names,
        intercept=intercept,
        assumed_equations=study.assumed_equations,
        z_reference=z_ref,
        substeps=substeps,
    )
