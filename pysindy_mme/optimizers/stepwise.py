"""FloatingFStepwise: the estimator (parameters, validation, fit, final fit).

:class:`FloatingFStepwise` is a pysindy optimizer. For every target (every
equation) it screens the library (:mod:`.screening`), selects library
functions one at a time by partial F-ratios (:mod:`.selection`, Kolodziej &
Mook, section III) over an incremental QR state (:mod:`.incremental_qr`), and
describes the chosen model by a direct least-squares fit and its ANOVA table
(:mod:`.anova`).

The selection never refits the model per candidate: adding a function costs
one pass over the library (``O(n_samples * n_candidates)``), removing one
``O(n_samples * k^2 + k^2 * n_candidates)`` for ``k`` functions in the model.
The library is never copied.

Units: partial F-ratios do not depend on the scale of a column or of the
target, but sums of squares of values near ``1e+-154`` overflow or underflow.
Every library column and every target is therefore multiplied by a power of
two that brings its largest magnitude into ``[0.5, 1)`` (exact in floating
point, applied on the fly: the library is still not copied), so that data in
any units select the same terms; coefficients are converted back at the end.
"""

from __future__ import annotations

import numbers
import warnings

import numpy as np
from pysindy.optimizers import BaseOptimizer
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils.validation import check_is_fitted

from ..core.validation import check_positive_number, check_probability
from ..exceptions import ExcludedFeaturesWarning, StepwiseCycleWarning
from ._numeric import pow2_scale
from .anova import f_critical
from .final_fit import final_fit
from .incremental_qr import IncrementalQR
from .screening import Screen, screen_columns
from .selection import select
from .summary import build_summary

__all__ = ["FloatingFStepwise"]


class FloatingFStepwise(BaseOptimizer):
    """Stepwise regression on partial F-ratios with a floating threshold.

    The modified stepwise regression (MSR) of Kolodziej & Mook as a pysindy
    optimizer: ``ps.SINDy(optimizer=FloatingFStepwise())``. Each target
    (equation) gets its own support. Phase I is Draper & Smith's stepwise
    regression with fixed thresholds; Phase II (``floating=True``) raises the
    threshold to the largest partial F-ratio in the model divided by
    ``float_ratio`` and removes the functions below it, one at a time.

    Parameters
    ----------
    f_enter : float, default 10.0
        Partial F-ratio a candidate needs to enter (the paper's ``F*``).
    f_remove : float, optional
        A function in the model whose partial F-ratio falls below this leaves.
        Defaults to ``f_enter``; must not exceed it (the selection could cycle).
    alpha_enter, alpha_remove : float in (0, 1), optional
        Significance levels. When ``alpha_enter`` is given they replace
        ``f_enter``/``f_remove``: the thresholds become
        ``scipy.stats.f.ppf(1 - alpha, 1, dof_E)`` at the current residual
        degrees of freedom (as MATLAB's ``stepwisefit``): ``dof_E`` of the
        enlarged model for entry, of the current model for removal.
        ``alpha_remove`` defaults to ``max(alpha_enter, 0.10)`` (MATLAB's
        default) and must be ``>= alpha_enter``.
    floating : bool, default True
        Run Phase II.
    float_ratio : float, default 10.0
        Phase II threshold = largest partial F-ratio in the model divided by
        this (the paper: one order of magnitude). Must be ``>= 1``.
    max_iter : int, default 1000
        Maximum number of additions plus removals per target. Reaching it
        raises a ``ConvergenceWarning`` and sets ``converged_`` to False.
    drop_insignificant_constant : bool, default True
        The constant is always in the regression while functions are selected
        and is never a candidate. At the end, if its partial F-ratio (its
        ``t**2``) is below the removal threshold, the selected functions are
        refit through the origin and the intercept reported as 0, so that
        dynamics without a constant term print without a ``1`` term and
        supports can be compared exactly. ``anova_`` still describes the fit
        with intercept (the paper's Table II has an Intercept row).
    tolerance : float, default 1e-8
        Collinearity tolerance: a candidate whose residual after projecting
        out the model is below ``tolerance`` times its centred norm cannot
        enter. Also used to set aside columns collinear with the constant or
        with an earlier column before selection starts.
    max_report : int, default 10
        Number of strongest functions not in the model listed in ``anova_``
        and :meth:`summary`.
    normalize_columns, copy_X, initial_guess, unbias
        Accepted for compatibility with pysindy's ``BaseOptimizer`` and
        ignored: selection by partial F-ratios is invariant to column scale,
        the input is never modified, selection always starts from the
        constant-only model (a non-None ``initial_guess`` raises a warning),
        and coefficients are already ordinary least squares on the support.

    Attributes
    ----------
    coef_ : ndarray (n_targets, n_features)
        Least-squares coefficients on the selected functions (zero elsewhere).
        If the library has a constant column (e.g. pysindy's ``"1"``), the
        intercept is carried by it; otherwise by ``intercept_``.
    intercept_ : ndarray (n_targets,)
        The fitted constant when the library has no constant column (0 when it
        has one, or when the constant was dropped).
    ind_ : ndarray of bool (n_targets, n_features)
        The support of each target.
    Theta_ : ndarray (n_samples, n_features)
        The library matrix that was fitted (a float view of ``x``, not a copy).
    history_ : list of ndarray
        ``coef_`` after each step (pysindy's meaning), starting from zeros.
    anova_ : list of :class:`~pysindy_mme.optimizers.AnovaTable`
        Final ANOVA table of each target (with intercept).
    steps_ : list of list of :class:`Step`
        The additions and removals of each target, in order.
    n_iter_ : ndarray of int (n_targets,)
        Steps taken per target.
    converged_ : bool
        False if some target hit ``max_iter``.
    cycle_detected_ : bool
        True if some target returned to a model already visited in the same
        phase (a cycle); a :class:`StepwiseCycleWarning` was raised and the
        selection stopped at the model of the cycle with the largest overall
        F-ratio.
    intercept_dropped_ : ndarray of bool (n_targets,)
        Whether the constant was dropped (``drop_insignificant_constant``).
    excluded_ : dict
        ``{column index: reason}`` for columns that can never be selected:
        non-finite values, all zero, constant (a second constant column),
        collinear with the constant, duplicate of / collinear with an earlier
        column, values too large (``|x| * n_samples > 2**1000``) or too small
        (``max |x| < 2**-960``) for double precision. They are listed in one
        :class:`ExcludedFeaturesWarning` per fit.
    constant_feature_ : int or None
        The library column that carries the intercept, if any.
    feature_names_, target_names_ : list of str or None
        Names given to :meth:`fit` (pysindy does not pass them: see
        :meth:`summary`).
    n_features_in_ : int

    Notes
    -----
    ``sample_weight`` are frequency weights: the number of observations in the
    degrees of freedom is ``sum(sample_weight)``, so a fit with integer weights
    equals a fit on rows repeated by their weights. Rows of weight 0 are
    ignored.

    The target must be finite: unlike pysindy's own optimizers, rows with NaN
    targets (e.g. the end points of ``FiniteDifference(drop_endpoints=True)``)
    are an error rather than silently dropped.

    Phase II compares partial F-ratios with the strongest one, so a true term
    whose contribution is small next to the others (Lorenz's ``-x2`` in
    ``x2'``, a light damping) is removed with the default ``float_ratio=10``;
    raise ``float_ratio`` or set ``floating=False`` for such multi-scale
    dynamics (see ``tests/test_stepwise_vs_stlsq.py``).

    A target reproduced to rounding level (relative residual ``< 1e-12``,
    noise-free data) takes no further functions, Phase II does not rank the
    (then meaningless) partial F-ratios, and the constant is dropped only if
    the fit stays exact without it.

    Inside ``ps.SINDy`` the optimizer does not see the feature names; print
    the ANOVA tables with
    ``model.optimizer.summary(model.get_feature_names(), model.feature_names)``.

    Examples
    --------
    >>> import pysindy as ps
    >>> model = ps.SINDy(optimizer=FloatingFStepwise(),
    ...                  feature_library=ps.PolynomialLibrary(degree=3))
    >>> model.fit(x, t=t)  # doctest: +SKIP
    >>> print(model.optimizer.summary(model.get_feature_names(),
    ...                               model.feature_names))  # doctest: +SKIP
    """

    # LinearRegression's tags read ``positive``; coefficients are unconstrained.
    positive = False

    def __init__(
        self,
        f_enter=10.0,
        f_remove=None,
        alpha_enter=None,
        alpha_remove=None,
        floating=True,
        float_ratio=10.0,
        max_iter=1000,
        drop_insignificant_constant=True,
        tolerance=1e-8,
        max_report=10,
        normalize_columns=False,
        copy_X=True,
        initial_guess=None,
        unbias=False,
    ):
        # Parameters are only stored here (scikit-learn convention); fit
        # validates them. BaseOptimizer.__init__ is not called because it
        # validates and reshapes.
        self.f_enter = f_enter
        self.f_remove = f_remove
        self.alpha_enter = alpha_enter
        self.alpha_remove = alpha_remove
        self.floating = floating
        self.float_ratio = float_ratio
        self.max_iter = max_iter
        self.drop_insignificant_constant = drop_insignificant_constant
        self.tolerance = tolerance
        self.max_report = max_report
        self.normalize_columns = normalize_columns
        self.copy_X = copy_X
        self.initial_guess = initial_guess
        self.unbias = unbias

    def set_params(self, **params):
        """Set parameters (scikit-learn API); returns ``self``."""
        super(BaseOptimizer, self).set_params(**params)
        return self

    # ------------------------------------------------------------------ checks
    def _validate_params(self) -> dict:
        f_enter = check_positive_number(self.f_enter, "f_enter")
        if self.f_remove is None:
            f_remove = f_enter
        else:
            f_remove = check_positive_number(self.f_remove, "f_remove")
            if f_remove > f_enter:
                raise ValueError(
                    f"f_remove ({f_remove}) must not exceed f_enter ({f_enter}): "
                    "a function could enter and leave forever"
                )
        alpha_enter = alpha_remove = None
        if self.alpha_enter is not None:
            alpha_enter = check_probability(self.alpha_enter, "alpha_enter")
            if self.alpha_remove is None:
                alpha_remove = max(alpha_enter, 0.10)
            else:
                alpha_remove = check_probability(self.alpha_remove, "alpha_remove")
                if alpha_remove < alpha_enter:
                    raise ValueError(
                        f"alpha_remove ({alpha_remove}) must be >= alpha_enter "
                        f"({alpha_enter}): a function could enter and leave forever"
                    )
        elif self.alpha_remove is not None:
            raise ValueError(
                "alpha_remove requires alpha_enter (significance levels replace "
                "f_enter/f_remove only when alpha_enter is given)"
            )
        for name in ("floating", "drop_insignificant_constant"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise TypeError(
                    f"{name} must be True or False, got {getattr(self, name)!r}"
                )
        float_ratio = check_positive_number(
            self.float_ratio, "float_ratio", minimum=1.0, strict=False
        )
        for name, minimum in (("max_iter", 1), ("max_report", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Integral):
                raise TypeError(f"{name} must be an integer, got {value!r}")
            if value < minimum:
                raise ValueError(f"{name} must be >= {minimum}, got {value}")
        tolerance = check_positive_number(self.tolerance, "tolerance")
        if tolerance >= 1:
            raise ValueError(f"tolerance must be < 1, got {tolerance}")
        return dict(
            f_enter=f_enter,
            f_remove=f_remove,
            alpha_enter=alpha_enter,
            alpha_remove=alpha_remove,
            float_ratio=float_ratio,
            tolerance=tolerance,
        )

    @staticmethod
    def _validate_data(x, y, sample_weight):
        try:
            x = np.asarray(x, dtype=float)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"x must be a numeric array: {exc}") from None
        if x.ndim != 2:
            raise ValueError(
                f"x must be 2-D (n_samples, n_features), got shape {x.shape}"
            )
        if x.shape[1] == 0:
            raise ValueError("x has no columns (the library is empty)")
        try:
            y = np.array(y, dtype=float)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"y must be a numeric array: {exc}") from None
        if y.ndim == 1:
            y = y.reshape(-1, 1)
        if y.ndim != 2:
            raise ValueError(f"y must be 1-D or 2-D, got shape {y.shape}")
        if y.shape[0] != x.shape[0]:
            raise ValueError(
                f"y has {y.shape[0]} rows but x has {x.shape[0]}: they must "
                "have one row per sample"
            )
        bad = ~np.isfinite(y)
        if np.any(bad):
            row, col = np.argwhere(bad)[0]
            kind = "NaN" if np.isnan(y[row, col]) else "inf"
            raise ValueError(
                f"y (the target) contains {kind} (first at row {row}, column "
                f"{col}); remove those samples first (e.g. the NaN end points "
                "of FiniteDifference(drop_endpoints=True))"
            )
        n = x.shape[0]
        if sample_weight is None:
            w = np.ones(n)
        else:
            try:
                w = np.asarray(sample_weight, dtype=float)
            except (TypeError, ValueError) as exc:
                raise TypeError(f"sample_weight must be numeric: {exc}") from None
            if w.ndim == 0:
                w = np.full(n, float(w))
            if w.ndim != 1 or w.shape[0] != n:
                raise ValueError(
                    f"sample_weight must have one entry per sample ({n}), got "
                    f"shape {w.shape}"
                )
            if not np.all(np.isfinite(w)):
                raise ValueError("sample_weight contains NaN or inf")
            if np.any(w < 0):
                raise ValueError(
                    f"sample_weight must be non-negative, got {w.min()} "
                    f"(at index {int(np.argmin(w))})"
                )
        n_eff = float(w.sum())
        if n_eff < 2:
            raise ValueError(
                f"need at least 2 observations (sum of sample_weight), got {n_eff:g}"
            )
        return x, y, w

    def _thresholds(self, k: int, n_eff: float, p: dict):
        """(entry, removal) thresholds for a model with ``k`` functions."""
        if p["alpha_enter"] is None:
            return p["f_enter"], p["f_remove"]
        return (
            float(f_critical(p["alpha_enter"], n_eff - k - 2)),
            float(f_critical(p["alpha_remove"], n_eff - k - 1)),
        )

    # --------------------------------------------------------------------- fit
    def _reduce(self, x, y, **kwargs):
        """Not used: :meth:`fit` does the whole work (it needs the raw weights)."""
        raise NotImplementedError("FloatingFStepwise.fit does not call _reduce")

    def fit(self, x_, y, sample_weight=None, feature_names=None, target_names=None):
        """Select the functions of each target and fit them by least squares.

        Parameters
        ----------
        x_ : array-like (n_samples, n_features)
            The library (pysindy's Theta). Columns with non-finite values are
            set aside, not an error.
        y : array-like (n_samples,) or (n_samples, n_targets)
            Targets (time derivatives); must be finite.
        sample_weight : float or array-like (n_samples,), optional
            Non-negative frequency weights.
        feature_names : sequence of str, optional
            Names of the library columns (used by ``steps_`` and :meth:`summary`).
        target_names : sequence of str, optional
            Names of the targets.

        Returns
        -------
        self
        """
        params = self._validate_params()
        x, y, w = self._validate_data(x_, y, sample_weight)
        n_features = x.shape[1]
        for label, names, size, what in (
            ("feature_names", feature_names, n_features, "x has"),
            ("target_names", target_names, y.shape[1], "y has"),
        ):
            if names is not None and len(names) != size:
                raise ValueError(
                    f"{label} has {len(names)} names but {what} {size} columns"
                )
        if self.initial_guess is not None:
            warnings.warn(
                "FloatingFStepwise ignores initial_guess: selection always "
                "starts from the constant-only model",
                UserWarning,
                stacklevel=2,
            )
        self.feature_names_ = None if feature_names is None else list(feature_names)
        self.target_names_ = None if target_names is None else list(target_names)
        self.n_features_in_ = n_features
        self.Theta_ = x

        keep = w > 0
        if not np.all(keep):
            x, y, w = x[keep], y[keep], w[keep]
        screen = screen_columns(x, np.sqrt(w), float(w.sum()), params["tolerance"])
        self.excluded_ = screen.excluded
        self.constant_feature_ = screen.carrier
        if screen.excluded:
            listed = "; ".join(
                f"{self._name(j)}: {why}" for j, why in screen.excluded.items()
            )
            warnings.warn(
                f"{len(screen.excluded)} library column(s) can never be selected "
                f"({listed})",
                ExcludedFeaturesWarning,
                stacklevel=2,
            )

        n_targets = y.shape[1]
        coef = np.zeros((n_targets, n_features))
        intercept = np.zeros(n_targets)
        self.history_ = [coef.copy()]
        self.anova_ = []
        self.steps_ = []
        self.n_iter_ = np.zeros(n_targets, dtype=int)
        self.intercept_dropped_ = np.zeros(n_targets, dtype=bool)
        self.converged_ = True
        self.cycle_detected_ = False
        for t in range(n_targets):
            coef[t], intercept[t] = self._fit_target(
                x, y[:, t], w, screen, params, t, coef
            )
            self.history_.append(coef.copy())
        self.coef_ = coef
        self.intercept_ = intercept
        self.ind_ = coef != 0
        return self

    def _name(self, j: int) -> str:
        names = getattr(self, "feature_names_", None)
        return str(names[j]) if names is not None else f"f{j}"

    def _fit_target(self, x, y, w, screen: Screen, params, target: int, coef):
        """Select and fit one target; returns its coefficient row and intercept."""
        n_eff = float(w.sum())
        sw = np.sqrt(w)
        # The target in units of its largest magnitude (an exact power of two):
        # squares can then neither overflow nor underflow.
        y_scale = float(pow2_scale(np.max(np.abs(y), initial=0.0)))
        yt = y * y_scale
        state = IncrementalQR(
            x, sw, yt * sw, screen, n_eff, params["tolerance"], y_unit=1.0 / y_scale
        )

        def record(state):
            current = coef.copy()
            current[target] = state.coefficient_row()
            self.history_.append(current)

        result = select(
            state,
            lambda k: self._thresholds(k, n_eff, params),
            self.floating,
            params["float_ratio"],
            self.max_iter,
            self._name,
            on_step=record,
        )
        if result.cycle is not None:
            self.cycle_detected_ = True
            c = result.cycle
            warnings.warn(
                f"FloatingFStepwise returned to a model it had already visited "
                f"(target {target}, phase {c['phase']}, iteration {c['iteration']}): "
                f"a cycle of {c['length']} models; stopping at the one with the "
                "largest overall F-ratio",
                StepwiseCycleWarning,
                stacklevel=3,
            )
        if not result.converged:
            self.converged_ = False
            warnings.warn(
                f"FloatingFStepwise reached max_iter={self.max_iter} on target "
                f"{target} before the selection settled; the last model is kept",
                ConvergenceWarning,
                stacklevel=3,
            )
        self.steps_.append(result.steps)
        self.n_iter_[target] = len(result.steps)
        _, remove_thr = self._thresholds(state.k, n_eff, params)
        row, icpt, table, dropped = final_fit(
            state,
            x,
            yt,
            w,
            screen,
            tolerance=params["tolerance"],
            max_report=self.max_report,
            remove_threshold=remove_thr,
            drop_constant=self.drop_insignificant_constant,
        )
        self.anova_.append(table)
        self.intercept_dropped_[target] = dropped
        return row, icpt

    # ----------------------------------------------------------------- predict
    def predict(self, x):
        """``x @ coef_.T + intercept_``, reading only the columns in use.

        Columns with zero coefficients are not read, so non-finite values in
        set-aside library columns do not spoil predictions.
        """
        check_is_fitted(self, "coef_")
        x = np.asarray(x, dtype=float)
        if x.ndim != 2 or x.shape[1] != self.coef_.shape[1]:
            raise ValueError(
                f"x must have shape (n_samples, {self.coef_.shape[1]}), got {x.shape}"
            )
        used = np.flatnonzero(np.any(self.coef_ != 0, axis=0))
        return x[:, used] @ self.coef_[:, used].T + self.intercept_

    # ----------------------------------------------------------------- summary
    def _rule_description(self) -> str:
        """The selection rule in one line (the summary's first line)."""
        if self.alpha_enter is None:
            f_remove = self.f_enter if self.f_remove is None else self.f_remove
            rule = f"F_enter = {self.f_enter:g}, F_remove = {f_remove:g}"
        else:
            a_rem = (
                max(self.alpha_enter, 0.10)
                if self.alpha_remove is None
                else self.alpha_remove
            )
            rule = f"alpha_enter = {self.alpha_enter:g}, alpha_remove = {a_rem:g}"
        if self.floating:
            rule += f", Phase II floating ratio = {self.float_ratio:g}"
        else:
            rule += ", Phase II off"
        return f"FloatingFStepwise: {rule}"

    def summary(self, feature_names=None, target_names=None, target=None):
        """ANOVA tables (the paper's Table II) and step histories.

        Parameters
        ----------
        feature_names : sequence of str, optional
            Library column names, e.g. ``model.get_feature_names()``. Defaults
            to the names given to :meth:`fit`, else ``f0, f1, ...``.
        target_names : sequence of str, optional
            Target names, e.g. ``model.feature_names`` (shown as ``x0'``...).
            Defaults to the names given to :meth:`fit`, else ``target 0``...
        target : int, optional
            Only this target.

        Returns
        -------
        StepwiseSummary
            The text (a ``str``: ``print`` it, search it, compare it) with
            :meth:`~StepwiseSummary.as_text`, :meth:`~StepwiseSummary.as_html`
            and ``_repr_html_`` (notebooks show the tables), and the
            per-target :class:`~pysindy_mme.optimizers.AnovaTable` objects in
            ``tables``.
        """
        check_is_fitted(self, "coef_")
        return build_summary(self, feature_names, target_names, target)
