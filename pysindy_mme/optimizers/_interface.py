"""The scikit-learn side of the optimizers: tags, input checks of predict.

:class:`EstimatorInterface` is mixed into :class:`~.stepwise.
FloatingFStepwise` before pysindy's ``BaseOptimizer`` (a scikit-learn
``LinearRegression``), whose tags would claim sparse input.
"""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils.validation import check_is_fitted

from ..exceptions import ExcludedFeaturesWarning, StepwiseCycleWarning
from ._checks import InvalidParameterError, _dense_real

__all__ = [
    "ConstantNotInLibraryWarning",
    "EstimatorInterface",
    "array_ndim",
    "warn_constant_lost",
    "warn_cycle",
    "warn_excluded",
    "warn_not_settled",
]


class ConstantNotInLibraryWarning(UserWarning):
    """The constant is significant but no library column carries it.

    With ``fit_intercept=False`` (pysindy's convention) ``coef_`` is then fit
    through the origin; add a constant column to the library to model it.
    """


def array_ndim(y) -> int:
    """Number of dimensions of an array-like target (2 if it cannot be told)."""
    try:
        return np.asarray(y).ndim
    except (TypeError, ValueError):
        return 2


def warn_excluded(excluded: dict, name) -> None:
    """One warning listing the library columns that can never be selected."""
    listed = "; ".join(f"{name(j)}: {why}" for j, why in excluded.items())
    warnings.warn(
        f"{len(excluded)} library column(s) can never be selected ({listed})",
        ExcludedFeaturesWarning,
        stacklevel=3,
    )


def warn_cycle(target: int, cycle: dict) -> None:
    """The warning of a selection that returned to a model it had visited."""
    warnings.warn(
        f"FloatingFStepwise returned to a model it had already visited "
        f"(target {target}, phase {cycle['phase']}, iteration "
        f"{cycle['iteration']}): a cycle of {cycle['length']} models; stopping "
        "at the one with the largest overall F-ratio",
        StepwiseCycleWarning,
        stacklevel=4,
    )


def warn_not_settled(target: int, max_iter: int) -> None:
    """The warning of a selection stopped by ``max_iter``."""
    warnings.warn(
        f"FloatingFStepwise reached max_iter={max_iter} on target {target} "
        "before the selection settled; the last model is kept",
        ConvergenceWarning,
        stacklevel=4,
    )


def warn_constant_lost(targets) -> None:
    """The warning of a significant constant that no library column carries."""
    warnings.warn(
        f"the constant is significant in {', '.join(targets)} but the library "
        "has no constant column: coef_ is fit through the origin (pysindy "
        "prints and ensembles coef_ only). Add a constant column (e.g. "
        "include_bias=True) to model it, or give fit_intercept=True to "
        "keep it in intercept_ outside SINDy",
        ConstantNotInLibraryWarning,
        stacklevel=3,
    )


class EstimatorInterface:
    """Tags that say what ``fit`` accepts, and a checked ``predict``."""

    # LinearRegression's tags read ``positive``; coefficients are unconstrained.
    positive = False

    def __sklearn_tags__(self):
        """scikit-learn's tags, made to say what ``fit`` accepts.

        No sparse input (LinearRegression's tag says yes; the library is read
        as a dense array); NaN in ``x`` is accepted (columns with non-finite
        values are set aside, rows that are all NaN dropped).
        """
        tags = super().__sklearn_tags__()
        tags.input_tags.sparse = False
        tags.input_tags.allow_nan = True
        return tags

    def _more_tags(self):  # scikit-learn < 1.6
        return {"allow_nan": True, "X_types": ["2darray"]}

    def predict(self, x):
        """``x @ coef_.T + intercept_``, reading only the columns in use.

        Shape ``(n_samples, n_targets)``, or ``(n_samples,)`` when :meth:`fit`
        was given a 1-D target.

        Columns with zero coefficients are not read, so non-finite values in
        set-aside library columns do not spoil predictions.
        """
        check_is_fitted(self, "coef_")
        x = _dense_real(x, "x")
        if x.ndim != 2:
            raise InvalidParameterError(
                f"x must have shape (n_samples, {self.coef_.shape[1]}), got "
                f"{x.shape}: Reshape your data (x.reshape(-1, 1) for one feature, "
                "x.reshape(1, -1) for one sample)"
            )
        if x.shape[1] != self.coef_.shape[1]:
            raise InvalidParameterError(
                f"X has {x.shape[1]} features, but {type(self).__name__} is expecting "
                f"{self.coef_.shape[1]} features as input"
            )
        used = np.flatnonzero(np.any(self.coef_ != 0, axis=0))
        out = x[:, used] @ self.coef_[:, used].T + self.intercept_
        # 1-D when fit was given a 1-D target (scikit-learn's convention)
        return out[:, 0] if getattr(self, "_y_ndim", 2) == 1 else out
