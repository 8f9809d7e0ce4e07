"""Step 3: propose correction terms by regressing ``d(t)`` on the library.

The library is evaluated on MME's state estimate (and the inputs); the
optimizer (:class:`~pysindy_mme.FloatingFStepwise` by default) regresses the
model error of each error state on it. Its terms are *proposals*: the
output-error confirmation (step 4) settles them on the measurements.
"""

from __future__ import annotations

import copy
import inspect
from dataclasses import dataclass

import numpy as np
from sklearn.base import clone

from ..core.features import SelectedFeatures
from ..core.libraries import fresh_library
from ..core.relaxation import overflow_columns_of
from ..optimizers import FloatingFStepwise
from ..optimizers.partial import project_out

__all__ = ["Proposals", "propose_terms"]


class LibraryColumns:
    """Columns of a fitted library at any points; ``constant`` is a column of ones.

    ``columns(z, cols)`` evaluates, ``columns.gradient(z, cols)`` differentiates
    (``(n_rows, len(cols), n_vars)``): what an output-error model needs of its
    correction terms.
    """

    def __init__(self, features: SelectedFeatures, constant: int):
        self.features, self.constant = features, constant

    def _split(self, columns):
        lib = [int(c) for c in columns if c != self.constant]
        where = [k for k, c in enumerate(columns) if c != self.constant]
        return lib, where

    def __call__(self, z, columns):
        lib, where = self._split(columns)
        values = self.features(z, lib) if lib else np.zeros((len(z), 0))
        if len(lib) == len(columns):
            return values
        out = np.ones((len(z), len(columns)))
        out[:, where] = values
        return out

    def overflow_columns(self) -> dict:
        """``{column: (variable, level)}`` of the overflow columns."""
        return overflow_columns_of(self.features)

    def gradient(self, z, columns):
        lib, where = self._split(columns)
        if len(lib) == len(columns):
            # no constant among them: the library's gradient as it is (the
            # integrators call this at every RK4 stage; a copy into a zeroed
            # array was 30 % of its cost at 10^6 samples)
            return self.features.gradient(z, lib)
        out = np.zeros((len(z), len(columns), z.shape[1]))
        if lib:
            out[:, where] = self.features.gradient(z, lib)
        return out


@dataclass
class Proposals:
    """What the regression of ``d(t)`` proposes.

    Attributes
    ----------
    library : fitted pysindy feature library
    feature_names : list of str
        Names of the library's columns.
    features : SelectedFeatures
        Fast evaluation of any library column at new points.
    optimizer : fitted optimizer
    coefficients : ndarray (n_states, n_features)
        Regression coefficients (rows of non-error states are zero).
    intercepts : ndarray (n_states,)
        The optimizer's own constant (when the library has none).
    slots : list of (state, column)
        Proposed terms, strongest evidence first per state; column
        ``n_features`` stands for the optimizer's intercept (see
        :attr:`constant_column`).
    start_values : list of float
        Their regression coefficients.
    candidates : list of (state, column)
        Every library function the confirmation may add (finite columns of
        every error state, plus a constant when the library has none).
    singular : dict
        ``{column: reason}``: library functions that are not finite, or
        singular, along the estimated trajectory. Simulating a model with
        them is ill-posed: they are neither proposed nor offered.
    nonsmooth : dict
        ``{column: reason}``: functions that jump where the trajectory
        crosses zero (``sign(v)``). Allowed (friction is real), but reported:
        RK4 loses accuracy at the jumps.
    rejected : list of (slot, reason)
        Proposals set aside before confirmation (singular functions).
    """

    library: object
    feature_names: list
    features: SelectedFeatures
    optimizer: object
    coefficients: np.ndarray
    intercepts: np.ndarray
    slots: list
    start_values: list
    candidates: list
    singular: dict
    nonsmooth: dict
    rejected: list

    @property
    def constant_column(self) -> int:
        """The slot column that stands for a constant outside the library."""
        return len(self.feature_names)

    def name(self, column: int) -> str:
        return "1" if column == self.constant_column else self.feature_names[column]

    @property
    def evaluate(self) -> LibraryColumns:
        """Library columns (the constant slot included), with their gradient."""
        return LibraryColumns(self.features, self.constant_column)

    def candidate_terms(self, state_names) -> dict:
        """``{state: {feature: regression coefficient}}`` of the proposals."""
        out = {}
        for (i, c), v in zip(self.slots, self.start_values):
            out.setdefault(state_names[i], {})[self.name(c)] = float(v)
        return out


def _accepts_names(optimizer) -> bool:
    """Whether ``optimizer.fit`` takes ``feature_names`` (FloatingFStepwise)."""
    try:
        return "feature_names" in inspect.signature(optimizer.fit).parameters
    except (TypeError, ValueError):
        return False


def _entry_order(opt, target, coef_row, theta):
    """Columns of ``coef_row``'s support, strongest evidence first.

    For FloatingFStepwise the order of their last entry in ``steps_``; for
    other optimizers the size of the standardised coefficient.
    """
    support = [int(j) for j in np.flatnonzero(coef_row)]
    steps = getattr(opt, "steps_", None)
    if steps:
        entered = {}
        for step in steps[target]:
            if step.action == "add":
                entered[int(step.feature)] = step.iteration
        return sorted(support, key=lambda j: (entered.get(j, np.inf), j))
    with np.errstate(all="ignore"):
        scale = np.nanstd(theta[:, support], axis=0) if support else []
    strength = [abs(coef_row[j]) * s for j, s in zip(support, scale)]
    return [support[k] for k in np.argsort(strength)[::-1]]


def flag_library_columns(theta, z=None, columns=None):
    """Library functions unfit for simulation along the estimated trajectory.

    Non-finite values (a division by a state that reaches zero) and a range
    so wide it is a singularity in all but name (``max |f| > 1e6 median
    |f|``) make a function *singular*. A function is *not smooth* when it
    jumps (``sign(v)`` where ``v`` crosses zero): its increment between two
    samples differs from what its own gradient predicts (the trapezoid rule
    along the step, exact for quadratics, ``O(step^3)`` for smooth
    functions) by more than half the function's whole range. (A smooth
    function of a fast, coarsely sampled signal is not flagged: its
    increments are large but predicted.) ``columns`` (a
    :class:`LibraryColumns`) and ``z`` (the points of ``theta``) give the
    gradients; without them only singularities are looked for.

    Returns ``(singular, nonsmooth)``, two ``{column: reason}`` dicts.
    """
    flags, nonsmooth = {}, {}
    with np.errstate(all="ignore"):
        for j in range(theta.shape[1]):
            col = theta[:, j]
            if not np.all(np.isfinite(col)):
                flags[j] = "not finite along the estimated trajectory (singular)"
                continue
            mag = np.abs(col)
            med = float(np.median(mag))
            if med > 0 and float(mag.max()) > 1e6 * med:
                flags[j] = (
                    f"singular along the estimated trajectory (largest value "
                    f"{mag.max():.3g}, typical {med:.3g})"
                )
                continue
            span = float(np.ptp(col))
            if columns is None or z is None or span == 0 or col.size < 3:
                continue
            grad = columns.gradient(z, [j])[:, 0, :]
            predicted = 0.5 * np.einsum(
                "kv,kv->k", grad[1:] + grad[:-1], np.diff(z, axis=0)
            )
            miss = np.abs(np.diff(col) - predicted)
            if np.all(np.isfinite(miss)) and float(miss.max()) > 0.5 * span:
                if med > 0 and float(mag.max()) > 30 * med:
                    # it jumps through infinity: a pole the trajectory crosses
                    flags[j] = (
                        "singular: it jumps through very large values (largest "
                        f"{mag.max():.3g}, typical {med:.3g}) where the trajectory "
                        "crosses a pole"
                    )
                else:
                    nonsmooth[j] = (
                        "not smooth: it jumps between samples (as sign(v) does)"
                    )
    return flags, nonsmooth


def _given_columns(study, sensitivities):
    """Per error state, the sensitivities of the parameters the study re-fits
    (gauges are held) that move that equation; None when there are none."""
    if sensitivities is None:
        return None
    free = ~np.asarray(study.parameter_gauge, dtype=bool)
    given = []
    for i in study.error_states:
        cols = sensitivities[:, i, free]
        cols = cols[:, np.any(cols != 0, axis=0)]
        given.append(cols if cols.shape[1] else None)
    return given if any(g is not None for g in given) else None


def _fit_each(opt, theta, d, given):
    """Any pysindy optimizer, given the columns: fitted once per error state on
    the projected library and target; one copy holds the stacked ``coef_``."""
    fitted = []
    for k in range(d.shape[1]):
        one = clone(opt)
        cols = given[k] if given[k] is not None else np.zeros((len(d), 0))
        # through the origin (pysindy's optimizers): the columns as given
        x_p, y_p, _ = project_out(theta, d[:, [k]], cols, np.ones(len(d)), False)
        fitted.append(one.fit(x_p, y_p))
    stacked = copy.deepcopy(fitted[0])
    stacked.coef_ = np.vstack([np.asarray(f.coef_).reshape(1, -1) for f in fitted])
    if hasattr(stacked, "intercept_"):
        stacked.intercept_ = np.concatenate(
            [np.ravel(getattr(f, "intercept_", 0.0))[:1] for f in fitted]
        )
    return stacked


def propose_terms(study, x_hat, d_hat, sensitivities=None) -> Proposals:
    """Regress ``d_hat`` of the error states on the library at ``x_hat``.

    With grey-box parameters, ``sensitivities`` (``df/dp`` along ``x_hat``,
    :func:`~.steps.parameter_sensitivities`) are regressors every model of
    an equation holds: the confirmation re-fits the parameters with the new
    terms, so a term is proposed for what the parameters cannot explain.
    ``d_hat`` was estimated at the current parameters; without this, a
    missing ``-sqrt(h)`` beside the model's ``-a h`` (whose ``a`` then
    absorbs part of it) is explained by look-alikes that bend the other way.
    ``FloatingFStepwise`` takes them as ``partial_out``; another optimizer is
    fitted once per equation on the library and ``d`` with them projected
    out (Frisch-Waugh-Lovell).
    """
    z_hat = x_hat if study.u is None else np.hstack([x_hat, study.u])
    library = fresh_library(study.library).fit(z_hat)
    with np.errstate(all="ignore"):
        theta = np.asarray(library.transform(z_hat))
    names = list(library.get_feature_names(study.feature_names))
    opt = clone(study.optimizer)
    if isinstance(opt, FloatingFStepwise):
        # The study proposes the constant as a term of its own (the
        # ``constant_column`` slot) when the library has no constant column.
        opt.set_params(fit_intercept=True)
    es = study.error_states
    targets = [study.state_names[i] for i in es]
    given = _given_columns(study, sensitivities)
    if given is not None and not isinstance(opt, FloatingFStepwise):
        opt = _fit_each(opt, theta, d_hat[:, es], given)
    elif _accepts_names(opt):
        extra = {} if given is None else {"partial_out": given}
        opt.fit(theta, d_hat[:, es], feature_names=names, target_names=targets, **extra)
    else:
        opt.fit(theta, d_hat[:, es])
    if getattr(opt, "Theta_", None) is not None:
        # pysindy's optimizers keep their design matrix; the study's copy
        # need not (it is the library at MME's states, rebuilt from them at
        # will): on a long record it was 80 bytes per sample of a cubic
        # library in two states, held through every later step
        opt.Theta_ = None
    n = study.n_states
    coef = np.zeros((n, theta.shape[1]))
    coef[es] = np.asarray(opt.coef_).reshape(es.size, -1)
    intercept = np.zeros(n)
    intercept[es] = np.broadcast_to(
        np.asarray(getattr(opt, "intercept_", 0.0), dtype=float), (es.size,)
    )
    const = theta.shape[1]
    features = SelectedFeatures(
        library, study.feature_names, range(theta.shape[1]), z_hat
    )
    singular, nonsmooth = flag_library_columns(
        theta, z_hat, LibraryColumns(features, theta.shape[1])
    )
    slots, start, rejected = [], [], []
    for k, i in enumerate(es):
        for j in _entry_order(opt, k, coef[i], theta):
            if j in singular:
                rejected.append(((int(i), int(j)), singular[j]))
                continue
            slots.append((int(i), int(j)))
            start.append(float(coef[i, j]))
        if intercept[i] != 0:
            slots.append((int(i), const))
            start.append(float(intercept[i]))
    usable = [j for j in range(theta.shape[1]) if j not in singular]
    has_constant = any(np.ptp(theta[:, j]) == 0 and theta[0, j] != 0 for j in usable)
    candidates = [
        (int(i), j) for i in es for j in usable + ([] if has_constant else [const])
    ]
    return Proposals(
        library=library,
        feature_names=names,
        features=features,
        optimizer=opt,
        coefficients=coef,
        intercepts=intercept,
        slots=slots,
        start_values=start,
        candidates=candidates,
        singular=singular,
        nonsmooth=nonsmooth,
        rejected=rejected,
    )
