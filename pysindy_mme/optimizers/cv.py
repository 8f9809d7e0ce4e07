"""FloatingFStepwiseCV: the entry level chosen by blocked cross-validation.

Rows of a SINDy regression are samples of trajectories: neighbours are
correlated, so shuffled K-fold cross-validation leaks information from the
training rows into the held-out ones and favours models that are too large.
Here the rows are cut into ``n_splits`` contiguous blocks; each block is held
out in turn, with ``gap`` rows on either side left out of the training set,
and the held-out derivatives are predicted by the model fitted on the rest.
"""

from __future__ import annotations

import html
import numbers

import numpy as np
from pysindy.optimizers import BaseOptimizer
from sklearn.base import clone
from sklearn.utils.validation import check_is_fitted

from ._checks import InvalidParameterError, check_data
from ._interface import EstimatorInterface
from .robust import newey_west_lags
from .stepwise import FloatingFStepwise

__all__ = ["FloatingFStepwiseCV", "blocked_folds"]

DEFAULT_ALPHAS = (1e-6, 1e-4, 1e-3, 1e-2, 5e-2, 2e-1)


def blocked_folds(n_rows: int, n_splits: int, gap: int):
    """``(train, test)`` row indices: contiguous test blocks, ``gap`` rows spared.

    The ``gap`` rows on each side of a test block belong to neither set, so
    that no training row is a close time neighbour of a test row.
    """
    edges = np.linspace(0, n_rows, n_splits + 1).astype(int)
    rows = np.arange(n_rows)
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        train = (rows < lo - gap) | (rows >= hi + gap)
        yield rows[train], rows[lo:hi]


class FloatingFStepwiseCV(EstimatorInterface, BaseOptimizer):
    """:class:`FloatingFStepwise` with ``alpha`` chosen by blocked cross-validation.

    For each level in ``alphas`` the optimizer is fitted on all but one
    contiguous block of rows and scored on that block (mean squared error of
    each target divided by the target's variance, averaged over targets and
    blocks); the chosen level is then refitted on all rows.

    Use it when the default level (0.01) may not suit the data: very long
    records (where even small true effects are significant and a stricter
    level keeps the model small) or very noisy ones (where a looser level
    keeps weak terms). It costs ``len(alphas) * n_splits + 1`` fits.

    Parameters
    ----------
    alphas : sequence of float in (0, 1), default (1e-6, 1e-4, 1e-3, 1e-2, 0.05, 0.2)
        Family-wise levels tried (``FloatingFStepwise(alpha=...)``).
    n_splits : int, default 5
        Number of contiguous blocks.
    gap : int, optional
        Rows left out on each side of a test block. Defaults to the
        Newey-West bandwidth of the record (5 rows for 400, 7 for 2,000): the
        residuals' correlation length the robust F-ratios assume.
    selection : {"min", "1se"}, default "min"
        ``"min"``: the level with the smallest cross-validation error.
        ``"1se"``: the smallest level (sparsest models) whose error is within
        one standard error of that minimum. On the drop-in benchmark's
        records (5 seeds) "min" recovered the exact support in 101 of 120
        fits, "1se" in 90: the sparser choice drops weak true terms.
    estimator : FloatingFStepwise, optional
        Template whose other parameters are kept (default
        ``FloatingFStepwise()``); its ``alpha`` is replaced.

    Attributes
    ----------
    alpha_ : float
        The chosen level.
    cv_errors_ : ndarray (len(alphas), n_splits)
        Held-out normalised squared error of each level and block.
    best_estimator_ : FloatingFStepwise
        The optimizer refitted on all rows at ``alpha_`` (its ``anova_``,
        ``steps_`` and ``summary()`` describe the final model).
    coef_, intercept_, ind_ : ndarray
        Those of ``best_estimator_``.
    history_ : list of ndarray
        ``best_estimator_.history_``.

    Notes
    -----
    Rows must be in time order (pysindy passes them so); with several
    trajectories stacked, a block may straddle two of them, which is
    harmless. ``sample_weight`` weights both the fits and the held-out errors.
    """

    # LinearRegression's tags read ``positive``; coefficients are unconstrained.
    positive = False

    def __init__(
        self,
        alphas=DEFAULT_ALPHAS,
        n_splits=5,
        gap=None,
        selection="min",
        estimator=None,
    ):
        self.alphas = alphas
        self.n_splits = n_splits
        self.gap = gap
        self.selection = selection
        self.estimator = estimator

    def set_params(self, **params):
        """Set parameters (scikit-learn API); returns ``self``."""
        super(BaseOptimizer, self).set_params(**params)
        return self

    def _check_params(self, n_rows: int):
        alphas = np.asarray(self.alphas, dtype=float)
        if alphas.ndim != 1 or alphas.size == 0:
            raise ValueError(
                f"alphas must be a non-empty sequence, got {self.alphas!r}"
            )
        if np.any(~(alphas > 0) | ~(alphas < 1)):
            raise ValueError(f"alphas must lie strictly between 0 and 1, got {alphas}")
        if isinstance(self.n_splits, bool) or not isinstance(
            self.n_splits, numbers.Integral
        ):
            raise InvalidParameterError(
                f"n_splits must be an integer, got {self.n_splits!r}"
            )
        if self.n_splits < 2:
            raise ValueError(f"n_splits must be >= 2, got {self.n_splits}")
        gap = newey_west_lags(n_rows) if self.gap is None else self.gap
        if isinstance(gap, bool) or not isinstance(gap, numbers.Integral) or gap < 0:
            raise ValueError(f"gap must be a non-negative integer, got {gap!r}")
        if n_rows // self.n_splits <= 2 * gap + 2:
            raise ValueError(
                f"{n_rows} rows are too few for n_splits={self.n_splits} blocks "
                f"with gap={gap} rows on each side"
            )
        if self.selection not in ("1se", "min"):
            raise ValueError(
                f"selection must be '1se' or 'min', got {self.selection!r}"
            )
        template = FloatingFStepwise() if self.estimator is None else self.estimator
        if not isinstance(template, FloatingFStepwise):
            raise InvalidParameterError(
                f"estimator must be a FloatingFStepwise, got {type(template).__name__}"
            )
        if template.f_enter is not None or template.alpha_enter is not None:
            raise InvalidParameterError(
                "estimator uses the classic rule (f_enter or alpha_enter); the "
                "alpha this cross-validates belongs to the default rule"
            )
        return np.sort(alphas), int(gap), template

    def _reduce(self, x, y, **kwargs):
        """Not used: :meth:`fit` does the whole work."""
        raise NotImplementedError("FloatingFStepwiseCV.fit does not call _reduce")

    def fit(self, x_, y, sample_weight=None, feature_names=None, target_names=None):
        """Choose ``alpha`` by blocked cross-validation and refit on all rows.

        Parameters are those of :meth:`FloatingFStepwise.fit`.

        Returns
        -------
        self
        """
        x, y, w, _ = check_data(x_, y, sample_weight)
        alphas, gap, template = self._check_params(x.shape[0])
        scale = np.average(
            (y - np.average(y, axis=0, weights=w)) ** 2, axis=0, weights=w
        )
        scale = np.where(scale > 0, scale, 1.0)
        errors = np.zeros((alphas.size, self.n_splits))
        for b, (train, test) in enumerate(
            blocked_folds(x.shape[0], self.n_splits, gap)
        ):
            for i, alpha in enumerate(alphas):
                opt = clone(template).set_params(alpha=float(alpha))
                opt.fit(x[train], y[train], sample_weight=w[train])
                resid = (opt.predict(x[test]) - y[test]) ** 2 / scale
                errors[i, b] = float(np.average(resid.mean(axis=1), weights=w[test]))
        mean = errors.mean(axis=1)
        best = int(np.argmin(mean))
        if self.selection == "1se":
            se = errors[best].std(ddof=1) / np.sqrt(self.n_splits)
            best = int(np.flatnonzero(mean <= mean[best] + se)[0])
        self.alphas_ = alphas
        self.cv_errors_ = errors
        self.alpha_ = float(alphas[best])
        self.best_estimator_ = clone(template).set_params(alpha=self.alpha_)
        self.best_estimator_.fit(
            x,
            y,
            sample_weight=w,
            feature_names=feature_names,
            target_names=target_names,
        )
        for name in ("coef_", "intercept_", "ind_", "history_", "n_features_in_"):
            setattr(self, name, getattr(self.best_estimator_, name))
        return self

    def predict(self, x):
        """Prediction of the refitted model (see :meth:`FloatingFStepwise.predict`)."""
        check_is_fitted(self, "best_estimator_")
        return self.best_estimator_.predict(x)

    def summary(self, feature_names=None, target_names=None, target=None):
        """The refitted model's summary, preceded by the cross-validation table."""
        check_is_fitted(self, "best_estimator_")
        text = self.best_estimator_.summary(feature_names, target_names, target)
        rows = [
            f"  alpha = {a:<8g} held-out error {m:.4g} (+- {s:.2g})"
            + ("   <- chosen" if a == self.alpha_ else "")
            for a, m, s in zip(
                self.alphas_,
                self.cv_errors_.mean(axis=1),
                self.cv_errors_.std(axis=1, ddof=1) / np.sqrt(self.n_splits),
                strict=True,
            )
        ]
        title = (
            f"FloatingFStepwiseCV: {self.n_splits} contiguous blocks, "
            f"selection '{self.selection}'"
        )
        head = title + "\n" + "\n".join(rows) + "\n\n"
        page = (
            f"<p><b>{html.escape(title)}</b></p><pre>{html.escape(chr(10).join(rows))}"
            "</pre>\n" + text.as_html()
        )
        return type(text)(head + str(text), page, text.tables, text.steps)
