"""FloatingFStepwise: the estimator (parameters, validation, fit, final fit).

:class:`FloatingFStepwise` is a pysindy optimizer. For every target (every
equation) it screens the library (:mod:`.screening`), selects library
functions one at a time by partial F-ratios (:mod:`.selection`, Kolodziej &
Mook, section III) under an entry/removal rule (:mod:`.rules`: by default
Newey-West robust F-ratios, :mod:`.robust`, at a Bonferroni level) over an
incremental QR state (:mod:`.incremental_qr`), and describes the chosen
model by a direct least-squares fit and its ANOVA table (:mod:`.final_fit`,
:mod:`.anova`).

No refit per candidate: an addition costs one pass over the library; a tall,
narrow library is selected from moments of two passes (:mod:`.moments`).

Units: partial F-ratios do not depend on the scale of a column or of the
target, but sums of squares of values near ``1e+-154`` overflow or underflow.
Every library column and every target is therefore multiplied by a power of
two that brings its largest magnitude into ``[0.5, 1)`` (exact in floating
point, applied on the fly: the library is still not copied), so that data in
any units select the same terms; coefficients are converted back at the end.
"""

from __future__ import annotations

import numpy as np
from pysindy.optimizers import BaseOptimizer
from sklearn.utils.validation import check_is_fitted

from ._checks import DEFAULT_ALPHA, DEFAULT_FLOAT_RATIO, check_params
from ._interface import (
    EstimatorInterface,
    array_ndim,
    warn_constant_lost,
    warn_cycle,
    warn_excluded,
    warn_not_settled,
)
from ._numeric import scaled_target
from .design import check_fit_inputs
from .errors_in_variables import corrected_or_as_given
from .final_fit import final_fit
from .gram import selection_state
from .partial import target_groups
from .preparation import prepare_library
from .rules import PAPER_F, PAPER_RATIO
from .screening import Screen
from .selection import history_row, select_target
from .summary import build_summary

__all__ = ["FloatingFStepwise"]


class FloatingFStepwise(EstimatorInterface, BaseOptimizer):
    """Stepwise regression on partial F-ratios, as a pysindy optimizer.

    ``ps.SINDy(optimizer=FloatingFStepwise())``. Each target (equation) gets
    its own support, chosen one function at a time by partial F-ratios
    (Draper & Smith's stepwise regression, Kolodziej & Mook section III).

    The default rule, in two sentences: a function enters (or stays) when its
    Newey-West robust partial F-ratio, which does not count autocorrelated
    residual samples as independent evidence, reaches the Bonferroni critical
    value for the number of candidates outside the model at family-wise level
    ``alpha``; of the candidates that reach it, the one that lowers the
    residual sum of squares most enters. Where the residual this leaves is
    smooth (lag-1 autocorrelation above 0.9, as with MME's estimate of the
    model error), the selection is redone with the paper's rule (``F* = 10``
    and its floating Phase II), which was designed for that case. (Terms that
    matter only together, whose parts no forward step admits alone, are
    caught by a joint test of the candidates Phase I left out: if they are jointly
    significant, all enter and the rule removes them one at a time; the
    result is kept only if it is relevantly better than the forward model,
    since with many rows a derivative's systematic error is significant
    too; ``joint_tests_``.)

    :meth:`paper` gives the paper's rule for every target.

    Parameters
    ----------
    f_enter : float, optional
        A fixed threshold on the classic partial F-ratio (the paper's ``F*``;
        the paper uses 10). Giving it selects the classic rule: no robust
        F-ratios, no multiplicity correction. Use it to reproduce the paper
        or a textbook stepwise regression.
    f_remove : float, optional
        Removal threshold of the classic rule; defaults to ``f_enter`` and must
        not exceed it (the selection could cycle). Requires ``f_enter``.
    alpha_enter, alpha_remove : float in (0, 1), optional
        Per-test significance levels of the classic rule (MATLAB's
        ``stepwisefit``): thresholds ``scipy.stats.f.ppf(1 - alpha, 1,
        dof_E)`` at the current residual degrees of freedom (of the enlarged
        model for entry, of the current model for removal). ``alpha_remove``
        defaults to ``max(alpha_enter, 0.10)`` and must be ``>= alpha_enter``.
        Exclusive with ``f_enter``.
    floating : {"auto", True, False}, default "auto"
        Phase II, the paper's floating threshold. ``"auto"`` uses it only for
        targets whose Phase I residual has lag-1 autocorrelation above 0.9
        (``phase_one_lag1_``, ``phase_two_``): under the default rule such a
        target is selected again with the paper's rule; under ``f_enter`` or
        ``alpha_enter`` Phase II continues from the Phase I model. True: always
        (the paper); False: never. Phase II removes true functions whose
        partial F-ratio is small next to the strongest one (Lorenz's ``-x2``
        in ``x2'``, a light damping): it suits one dominant effect plus
        corrections (MME's model error), not multi-scale dynamics.
    float_ratio : float, default 10.0
        Phase II threshold = largest classic partial F-ratio in the model
        divided by this (the paper: one order of magnitude). Must be ``>= 1``.
    alpha : float in (0, 1), default 0.01
        Family-wise level of the default rule (used when neither ``f_enter``
        nor ``alpha_enter`` is given): in each step, the chance that any false
        function enters is at most ``alpha``. Lower it for fewer false terms,
        raise it (0.05) to keep weak terms at high noise; the Bonferroni
        threshold grows only with the logarithm of the library size (about
        F = 11 for 20 candidates, 16 for 500, 21 for 5,000).
    autocorrelation : {"newey-west", None}, default "newey-west"
        Statistic of the default rule. ``"newey-west"``: robust partial
        F-ratios (Bartlett kernel, ``floor(4 (n / 100)**(2/9))`` lags; see
        :mod:`pysindy_mme.optimizers.robust`), valid for autocorrelated and
        heteroscedastic residuals, such as those of smoothed finite-difference
        derivatives; it needs rows in time order (see ``time_ordered``).
        None: classic partial F-ratios (independent residuals of equal
        variance).
    time_ordered : {"auto", True, False}, default "auto"
        Whether consecutive rows are neighbours in time, as the Newey-West
        variance and ``floating="auto"`` (which reads the residual's lag-1
        autocorrelation) assume. They are not with pysindy's
        ``WeakPDELibrary`` (integrals over overlapping windows at random
        centres), shuffled rows or bootstrap samples (``EnsembleOptimizer``).
        ``"auto"``: in time order unless the median lag-1 autocorrelation of
        the library columns is below 0.3 (near 1 along a trajectory, near 0
        in a random order; under 20 rows: as given). Out of time order
        (``rows_in_time_order_`` False) the default rule uses the ordinary
        test (classic partial F-ratios, same Bonferroni level) and, with
        ``floating="auto"``, Phase II: the dependence between such rows
        cannot be seen, so the F-ratios' scale is uncalibrated (a weak
        library's grow with its number of windows), which Phase II's
        relative threshold does not depend on. ``floating=False`` for truly
        independent rows; ``time_ordered=True`` keeps the robust test.
    errors_in_variables : {"auto", False}, default "auto"
        Correct the statistics for noise in the library's inputs, which at a
        few per cent lets false terms fit better than the true model
        (:mod:`pysindy_mme.optimizers.errors_in_variables`). ``"auto"``: for a
        polynomial library of states measured with white noise, rows in
        time order (found from the values, ``errors_in_variables_`` says
        whether and why not). False: the library as given (states that are
        estimates, not measurements, such as MME's).
    max_iter : int, default 1000
        Maximum number of additions plus removals per target. Reaching it
        raises a ``ConvergenceWarning`` and sets ``converged_`` to False.
    drop_insignificant_constant : bool, default True
        The constant is always in the regression while functions are selected
        and is never a candidate. At the end, if its partial F-ratio (robust
        under the default rule, compared with the single-test level
        ``alpha``; classic under the classic rule, compared with the removal
        threshold) is too small, the selected functions are refit through the
        origin and the intercept reported as 0, so that dynamics without a
        constant print without a ``1`` term. ``anova_`` still describes the
        fit with intercept (the paper's Table II has an Intercept row).
    fit_intercept : bool, default False
        The constant where the library has no constant column (with one,
        e.g. pysindy's ``"1"``, that column carries it in ``coef_``). False,
        pysindy's convention (``SINDy.print``, ``equations``,
        ``coefficients`` and ``EnsembleOptimizer`` read ``coef_`` only):
        selection still has the constant in the regression, but ``coef_`` is
        refit through the origin and ``intercept_`` is 0, so the printed
        model is the one that predicts (as with STLSQ); a
        ``ConstantNotInLibraryWarning`` says when the constant was
        significant. True: ``intercept_`` holds it
        (scikit-learn's meaning, for use outside ``SINDy``).
    tolerance : float, default 1e-8
        Collinearity tolerance: a candidate whose residual after projecting
        out the model is below ``tolerance`` times its centred norm cannot
        enter. Also used to set aside columns collinear with the constant or
        with an earlier column before selection starts.
    max_report : int, default 10
        Number of strongest functions not in the model listed in ``anova_``
        and :meth:`summary`.
    normalize_columns, copy_X, unbias : bool
        pysindy's ``BaseOptimizer`` parameters, honoured by construction, so
        either value gives the same fit: partial F-ratios and least squares
        are invariant to column scale (``normalize_columns``), the input is
        never modified (``copy_X``), and the coefficients are always ordinary
        least squares on the support, with no shrinkage to remove
        (``unbias``). A value that is not a bool raises.
    initial_guess : None
        pysindy's ``BaseOptimizer`` parameter, kept so that pysindy's
        wrappers (``EnsembleOptimizer``) can read it; anything but None raises
        a ``ValueError``: selection always starts from the constant-only model.

    Attributes
    ----------
    coef_ : ndarray (n_targets, n_features)
        Least-squares coefficients on the selected functions (zero elsewhere).
        If the library has a constant column (e.g. pysindy's ``"1"``), the
        intercept is carried by it.
    intercept_ : ndarray (n_targets,)
        0, unless the library has no constant column and ``fit_intercept`` is
        True: then the fitted constant (0 where it was dropped).
    ind_ : ndarray of bool (n_targets, n_features)
        The support of each target.
    Theta_ : ndarray (n_samples, n_features)
        The library matrix that was fitted (a float view of ``x``, not a copy,
        unless rows that are all NaN were dropped).
    history_ : list of ndarray
        ``coef_`` after each step (pysindy's meaning), starting from zeros.
    errors_in_variables_ : dict
        ``applied``, ``reason`` (why not), ``base_columns``,
        ``noise_variance`` and each target's ``routes`` (a list of these
        with ``partial_out``).
    anova_ : list of :class:`~pysindy_mme.optimizers.AnovaTable`
        Final ANOVA table of each target (with intercept). Under the default
        rule it also holds the robust partial F-ratios, the Bonferroni-
        adjusted p-values (``adjusted_p_values``), the residual's lag-1
        autocorrelation and its effective number of observations.
    steps_ : list of list of :class:`Step`
        The additions and removals of each target, in order, with the
        statistic and threshold that decided each.
    n_iter_ : ndarray of int (n_targets,)
        Steps taken per target.
    phase_two_ : ndarray of bool (n_targets,)
        Whether Phase II ran for each target (under the default rule with
        ``floating="auto"``: whether the paper's rule was applied).
    phase_one_lag1_ : ndarray (n_targets,)
        Lag-1 autocorrelation of the residual at the end of Phase I (what
        ``floating="auto"`` decides on).
    joint_tests_ : list of (dict or None)
        Per target, the joint test of the candidates Phase I left out under
        the default rule (``{"n", "f", "p", "restart"}``, and after a
        restart ``"effect"`` and ``"kept"``; None where it did not apply).
        ``restart``: they were jointly significant, so all were added (steps
        with ``joint=True``) and removed again one at a time by the rule,
        which finds terms that matter only together. ``kept``: the forward
        model explained less than 80 % of the target's variance, or the
        restarted model is relevantly better (no more terms and a smaller
        residual, or Cohen's f^2 per extra term ``effect`` at least 0.15);
        otherwise the selection went back to the forward model.
    converged_ : bool
        False if some target hit ``max_iter``.
    cycle_detected_ : bool
        True if some target returned to a model already visited in the same
        phase (a cycle); a :class:`StepwiseCycleWarning` was raised and the
        selection stopped at the model of the cycle with the largest overall
        F-ratio.
    intercept_dropped_ : ndarray of bool (n_targets,)
        Whether the constant was dropped (``drop_insignificant_constant``, or
        no constant column and ``fit_intercept=False``).
    rows_in_time_order_ : bool
        Whether the rows were taken to be in time order (``time_ordered``);
        where False, the default rule used the ordinary test.
    excluded_ : dict
        ``{column index: reason}`` for columns that can never be selected:
        non-finite values, all zero, constant (a second constant column),
        collinear with the constant, duplicate of / collinear with an earlier
        column, values too large (``|x| * n_samples > 2**1000``) or too small
        (``max |x| < 2**-960``) for double precision. They are listed in one
        :class:`ExcludedFeaturesWarning` per fit.
    constant_feature_ : int or None
        The library column that carries the intercept, if any.
    n_partialled_ : ndarray of int (n_targets,)
        Independent ``partial_out`` columns projected out of each target
        (0 without ``partial_out``).
    feature_names_, target_names_ : list of str or None
        Names given to :meth:`fit` (pysindy does not pass them: see
        :meth:`summary`).
    n_features_in_ : int

    Notes
    -----
    The selection rule is one documented set of parameters; the first that
    applies chooses it, and a parameter the chosen rule would not read raises
    a ``ValueError`` rather than being ignored:

    ==============================  =========================================
    rule                            parameters
    ==============================  =========================================
    default (family-wise)           ``alpha``, ``autocorrelation``,
                                    ``time_ordered``
    classic, fixed thresholds       ``f_enter``, ``f_remove`` (no ``alpha``)
    classic, per-test levels        ``alpha_enter``, ``alpha_remove`` (no
                                    ``alpha``)
    Phase II (any rule)             ``floating``, ``float_ratio`` (no
                                    ``float_ratio`` with ``floating=False``)
    ==============================  =========================================

    Which rule to use. The default wins the drop-in benchmark
    (``benchmarks/bench_dropin.py``: nine systems, three noise levels, 20
    seeds, against pysindy's optimizers at their defaults and tuned by
    cross-validation). Use :meth:`paper` to reproduce the paper, and
    ``f_enter``/``alpha_enter`` for a textbook stepwise regression.

    ``sample_weight`` are frequency weights for every sum of squares and the
    coefficients: a fit with integer weights has the coefficients of a fit on
    rows repeated by their weights, and under the classic rule the same
    steps. The robust F-ratios treat a row of weight ``w`` as one observation
    whose score is ``w`` times larger (repeated rows would be perfectly
    correlated neighbours, no independent evidence), so multiplying all
    weights by a constant changes nothing. Rows of weight 0 are ignored.

    Rows whose library values or targets are all NaN (the end points of
    ``FiniteDifference(drop_endpoints=True)``) are dropped, as pysindy's
    ``BaseOptimizer.fit`` drops them; other non-finite targets, complex and
    sparse input are errors. A bad parameter value raises a ``ValueError``
    naming it (:class:`~._checks.InvalidParameterError`, also a TypeError).

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

    def __init__(
        self,
        f_enter=None,
        f_remove=None,
        alpha_enter=None,
        alpha_remove=None,
        floating="auto",
        float_ratio=DEFAULT_FLOAT_RATIO,
        alpha=DEFAULT_ALPHA,
        autocorrelation="newey-west",
        time_ordered="auto",
        errors_in_variables="auto",
        max_iter=1000,
        drop_insignificant_constant=True,
        fit_intercept=False,
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
        self.alpha = alpha
        self.autocorrelation = autocorrelation
        self.time_ordered = time_ordered
        self.errors_in_variables = errors_in_variables
        self.max_iter = max_iter
        self.drop_insignificant_constant = drop_insignificant_constant
        self.fit_intercept = fit_intercept
        self.tolerance = tolerance
        self.max_report = max_report
        self.normalize_columns = normalize_columns
        self.copy_X = copy_X
        self.initial_guess = initial_guess
        self.unbias = unbias

    @classmethod
    def paper(cls, **kwargs):
        """The paper's modified stepwise regression (Kolodziej & Mook).

        ``FloatingFStepwise(f_enter=10, floating=True, float_ratio=10,
        errors_in_variables=False)``: classic partial F-ratios against
        ``F* = 10``, then Phase II always, on the library as given (the
        paper regresses MME's model-error estimate on its smoothed states).
        Other parameters (``max_report``, ...) may be given as keywords.
        """
        params = dict(
            f_enter=PAPER_F,
            floating=True,
            float_ratio=PAPER_RATIO,
            errors_in_variables=False,
        )
        params.update(kwargs)
        return cls(**params)

    def set_params(self, **params):
        """Set parameters (scikit-learn API); returns ``self``."""
        super(BaseOptimizer, self).set_params(**params)
        return self

    # --------------------------------------------------------------------- fit
    def _reduce(self, x, y, **kwargs):
        """Not used: :meth:`fit` does the whole work (it needs the raw weights)."""
        raise NotImplementedError("FloatingFStepwise.fit does not call _reduce")

    def fit(
        self,
        x_,
        y,
        sample_weight=None,
        feature_names=None,
        target_names=None,
        partial_out=None,
    ):
        """Select the functions of each target and fit them by least squares.

        Parameters
        ----------
        x_ : array-like, StreamedDesign or dask.array (n_samples, n_features)
            The library (pysindy's Theta; streamed: read by column blocks,
            never whole). Non-finite columns are set aside, not an error.
        y : array-like (n_samples,) or (n_samples, n_targets)
            Targets (time derivatives); must be finite.
        sample_weight : float or array-like (n_samples,), optional
            Non-negative frequency weights.
        feature_names : sequence of str, optional
            Names of the library columns (used by ``steps_`` and :meth:`summary`).
        target_names : sequence of str, optional
            Names of the targets.
        partial_out : list of array-like (n_samples, k_t) or None, optional
            One entry per target: regressors every model of that target
            holds, fitted but not selected or reported (a grey-box model's
            parameter sensitivities). The selection runs on the library and
            target with their weighted projection on these columns removed
            (Frisch-Waugh-Lovell: the coefficients are those of the joint
            regression); see :mod:`pysindy_mme.optimizers.partial`. Needs an
            in-memory library; each target is then screened on its own.

        Returns
        -------
        self
        """
        params = check_params(self)
        # predict's shape follows y's (scikit-learn's convention); coef_ 2-D
        y_ndim = array_ndim(y)
        x, y, w, feature_names, nuisance = check_fit_inputs(
            x_, y, sample_weight, feature_names, target_names, partial_out
        )
        self._y_ndim = y_ndim
        self.feature_names_ = None if feature_names is None else list(feature_names)
        self.target_names_ = None if target_names is None else list(target_names)
        self.n_features_in_ = n_features = x.shape[1]
        self.Theta_ = x
        if not np.all(w > 0):
            x, y, w, nuisance = _positive_rows(x, y, w, nuisance)

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
        self.phase_two_ = np.zeros(n_targets, dtype=bool)
        self.phase_one_lag1_ = np.zeros(n_targets)
        self.joint_tests_ = [None] * n_targets
        self.n_partialled_ = np.zeros(n_targets, dtype=int)
        self.excluded_ = {}
        corrections = []
        self._routes = []
        lost = []
        for g, (xg, yg, targets, rank) in enumerate(target_groups(x, y, w, nuisance)):
            self.n_partialled_[targets] = rank
            # the rows' time order is read on the first library only
            order = self.time_ordered if g == 0 else self.rows_in_time_order_
            screen, rule, moments, self.rows_in_time_order_, correction = (
                prepare_library(
                    xg, yg, w, params, self.autocorrelation, order, rank == 0
                )
            )
            corrections.append(correction.as_dict())
            self.excluded_.update(screen.excluded)
            self.constant_feature_ = screen.carrier
            for local, t in enumerate(targets):
                joint = (x, y[:, t], nuisance[t]) if rank else None
                coef[t], intercept[t], significant_lost = self._fit_target(
                    xg, yg[:, local], w, screen, rule, t, coef, moments, local, joint
                )
                self.history_.append(coef.copy())
                if significant_lost:
                    lost.append(self._target_name(t))
        if len(corrections) == 1:
            corrections[0]["routes"] = tuple(self._routes)
        self.errors_in_variables_ = (
            corrections[0] if len(corrections) == 1 else corrections
        )
        if self.excluded_:
            warn_excluded(self.excluded_, self._name)
        if lost:
            warn_constant_lost(lost)
        self.coef_ = coef
        self.intercept_ = intercept
        self.ind_ = coef != 0
        return self

    def _name(self, j: int) -> str:
        names = getattr(self, "feature_names_", None)
        return str(names[j]) if names is not None else f"f{j}"

    def _target_name(self, t: int) -> str:
        names = getattr(self, "target_names_", None)
        return f"{names[t]}'" if names is not None else f"target {t}"

    def _select(self, make_state, rule, coef, target: int):
        """:func:`~.selection.select_target` with this estimator's settings."""
        return select_target(
            make_state,
            rule,
            coef,
            target,
            floating=self.floating,
            float_ratio=float(self.float_ratio),
            max_iter=self.max_iter,
            name=self._name,
            time_ordered=self.rows_in_time_order_,
        )

    def _fit_target(
        self, x, y, w, screen: Screen, rule, target, coef, moments, local, joint=None
    ):
        """Select and fit one target (``target`` among all, ``local`` in the
        ``moments``; ``joint``: see :func:`final_fit`): its row and intercept."""
        n_eff = float(w.sum())
        sw = np.sqrt(w)
        y_scale, yt = scaled_target(y)  # in units of its largest magnitude

        def make_state(moments=moments):
            return selection_state(
                moments, local, x, sw, yt * sw, screen, n_eff, self.tolerance, y_scale
            )

        (state, result, steps_history, rule), route = corrected_or_as_given(
            self._select(make_state, rule, coef, target),
            moments,
            lambda: self._select(lambda: make_state(None), rule, coef, target),
            make_state,
            lambda state: history_row(coef, target, state),
            self._name,
        )
        self._routes += [route] if route else []
        self.history_ += steps_history
        if result.cycle is not None:
            self.cycle_detected_ = True
            warn_cycle(target, result.cycle)
        if not result.converged:
            self.converged_ = False
            warn_not_settled(target, self.max_iter)
        self.steps_.append(result.steps)
        self.n_iter_[target] = len(result.steps)
        self.phase_two_[target] = result.phase_two
        self.phase_one_lag1_[target] = result.phase_one_lag1
        self.joint_tests_[target] = result.joint
        row, icpt, table, dropped, significant_lost = final_fit(
            state,
            x,
            yt,
            w,
            screen,
            tolerance=float(self.tolerance),
            max_report=self.max_report,
            rule=rule,
            drop_constant=self.drop_insignificant_constant,
            fit_intercept=bool(self.fit_intercept),
            joint=joint,
        )
        self.anova_.append(table)
        self.intercept_dropped_[target] = dropped
        return row, icpt, significant_lost

    # ----------------------------------------------------------------- summary
    def summary(self, feature_names=None, target_names=None, target=None):
        """ANOVA tables (the paper's Table II) and step histories.

        ``feature_names`` (e.g. ``model.get_feature_names()``) and
        ``target_names`` (e.g. ``model.feature_names``) default to those
        given to :meth:`fit`; ``target`` selects one target. Returns a
        :class:`StepwiseSummary`: a ``str`` with ``as_text``, ``as_html``,
        ``_repr_html_`` and the per-target ``AnovaTable`` objects in
        ``tables``.
        """
        check_is_fitted(self, "coef_")
        return build_summary(self, feature_names, target_names, target)


def _positive_rows(x, y, w, nuisance):
    """The rows of positive weight (rows of weight 0 are ignored)."""
    keep = w > 0
    nuisance = None if nuisance is None else [n[keep] for n in nuisance]
    return x[keep], y[keep], w[keep], nuisance
