"""The study: what the assumed model gets wrong, why, the fix, and the gain.

``discover`` chains the pieces one way, as in the paper's Fig. 1:

1. output-error fit of the *assumed* model (initial state only) -> how far its
   simulation is from the data, and a chi-square test of consistency;
2. :class:`~pysindy_mme.MME` -> full state estimate and model error ``d(t)``;
3. stepwise regression of ``d`` on a library of the estimated states
   (:class:`~pysindy_mme.FloatingFStepwise` by default) -> candidate terms;
4. output-error refit of the extended model against the measurements
   themselves (removes the shrinkage bias of ``d``), pruning terms whose
   refitted coefficient is not significant, and an F-test of the extended
   against the assumed model (false discoveries are as bad as misses);
5. the gain: simulation error of both models against the measurements, on
   the fitting data and on validation data.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import stats
from sklearn.base import clone

from ._confirm import Confirmation, confirm_terms, make_problem_factory
from ._output_error import OutputErrorProblem, OutputErrorResult
from ._report import format_discovery
from .core import validation as val
from .core.features import SelectedFeatures
from .core.model import as_model_function, rowwise_jacobian
from .differentiation import MME, noise_covariance
from .exceptions import DiscoveryWarning
from .extended import ExtendedModel
from .stepwise import FloatingFStepwise

__all__ = ["discover", "Discovery", "ExtendedModel", "Gain", "TermEstimate"]


@dataclass(frozen=True)
class TermEstimate:
    """One identified correction term.

    Attributes
    ----------
    state : str
        The equation it corrects (``state``').
    feature : str
        Library feature name.
    coefficient : float
        Refitted coefficient (output error against the measurements).
    regression_coefficient : float
        Coefficient from the stepwise regression of ``d(t)`` (biased to 0).
    std_error : float
    ci_low, ci_high : float
        95 % confidence interval of ``coefficient``.
    partial_f : float
        Partial F-ratio in the stepwise regression (NaN for other optimizers).
    p_value : float
        Wald test of ``coefficient`` in the output-error refit.
    """

    state: str
    feature: str
    coefficient: float
    regression_coefficient: float
    std_error: float
    ci_low: float
    ci_high: float
    partial_f: float
    p_value: float


@dataclass
class Gain:
    """How much closer to the measurements the extended model simulates.

    RMSE per measured channel of the simulated measurement against the data
    (both models with their own best-fit initial state), the ratio
    assumed / extended, and the noise floor ``sqrt(R_jj)`` that a perfect
    model would reach.
    """

    channel_names: list
    rmse_assumed: np.ndarray
    rmse_extended: np.ndarray
    noise_floor: np.ndarray
    validation_rmse_assumed: np.ndarray | None = None
    validation_rmse_extended: np.ndarray | None = None

    @property
    def ratio(self) -> np.ndarray:
        return self.rmse_assumed / self.rmse_extended

    @property
    def validation_ratio(self) -> np.ndarray | None:
        if self.validation_rmse_assumed is None:
            return None
        return self.validation_rmse_assumed / self.validation_rmse_extended

    def to_dict(self) -> dict:
        out = {
            "channels": list(self.channel_names),
            "rmse_assumed": self.rmse_assumed.tolist(),
            "rmse_extended": self.rmse_extended.tolist(),
            "ratio": self.ratio.tolist(),
            "noise_floor": self.noise_floor.tolist(),
        }
        if self.validation_rmse_assumed is not None:
            out["validation_rmse_assumed"] = self.validation_rmse_assumed.tolist()
            out["validation_rmse_extended"] = self.validation_rmse_extended.tolist()
            out["validation_ratio"] = self.validation_ratio.tolist()
        return out


@dataclass
class Discovery:
    """What :func:`discover` found. ``print(result)`` tells the story.

    Attributes
    ----------
    terms : dict
        ``{state name: {feature name: coefficient}}`` for every error state;
        an empty inner dict means no significant correction for that state.
    term_estimates : list of TermEstimate
        The same terms with regression coefficient, CI, partial F, p-value.
    extended_model : ExtendedModel
        Assumed model + refitted correction.
    gain : Gain
    consistency_p_value : float
        Chi-square test of the assumed model against the data (its initial
        state fitted): small means the data contradict the assumed model.
    correction_p_value : float
        F-test of the extended model against the assumed one (NaN when the
        regression proposed no term).
    mme : MME
        The fitted estimator (``smoothed_x_``, ``d_``, ``W_``,
        ``covariance_ratio_``).
    optimizer : fitted optimizer
        The regression of ``d`` (``anova_``, ``steps_``, ``summary()`` for
        FloatingFStepwise).
    """

    t: np.ndarray
    y: np.ndarray
    u: np.ndarray | None
    state_names: list
    input_names: list
    channel_names: list
    measured: np.ndarray | None
    error_states: np.ndarray
    noise_cov: np.ndarray
    alpha: float
    mme: object
    optimizer: object
    library_feature_names: list
    regression_coef: np.ndarray
    assumed_fit: OutputErrorResult
    assumed_simulation: np.ndarray
    consistency_chi2: float
    consistency_dof: int
    consistency_p_value: float
    candidate_terms: dict
    pruned_terms: list
    extended_fit: OutputErrorResult | None
    extended_simulation: np.ndarray
    extended_model: ExtendedModel
    correction_p_value: float
    terms: dict
    term_estimates: list
    gain: Gain
    d_summary: dict
    warnings: list = field(default_factory=list)

    @property
    def found_correction(self) -> bool:
        return any(self.terms.values())

    def __str__(self) -> str:
        return format_discovery(self)

    def summary(self) -> str:
        return str(self)

    def plot(self, x_true=None, d_true=None, path=None):
        """Draw the study (needs matplotlib: ``pip install pysindy-mme[plot]``).

        Parameters
        ----------
        x_true, d_true : ndarray (n_samples, n_states), optional
            True states / model error, drawn for comparison when known.
        path : str or Path, optional
            Save the figure there.

        Returns
        -------
        matplotlib.figure.Figure
        """
        from .plotting import plot_discovery

        return plot_discovery(self, x_true=x_true, d_true=d_true, path=path)

    def to_dict(self) -> dict:
        """Plain-Python summary (JSON-serialisable) for saving."""
        return {
            "state_names": list(self.state_names),
            "input_names": list(self.input_names),
            "channels": list(self.channel_names),
            "error_states": [self.state_names[i] for i in self.error_states],
            "n_samples": int(self.t.size),
            "noise_covariance": self.noise_cov.tolist(),
            "W": np.asarray(self.mme.W_).tolist(),
            "covariance_ratio": np.asarray(self.mme.covariance_ratio_).tolist(),
            "consistency": {
                "chi2": self.consistency_chi2,
                "dof": self.consistency_dof,
                "p_value": self.consistency_p_value,
            },
            "model_error": self.d_summary,
            "candidate_terms": self.candidate_terms,
            "pruned_terms": list(self.pruned_terms),
            "correction_p_value": self.correction_p_value,
            "terms": self.terms,
            "term_estimates": [vars(te) for te in self.term_estimates],
            "extended_model": self.extended_model.equations(),
            "gain": self.gain.to_dict(),
            "warnings": list(self.warnings),
        }


# --------------------------------------------------------------------------- #
# input handling


def _check_library(feature_library):
    if feature_library is None:
        import pysindy as ps

        return ps.PolynomialLibrary(degree=3)
    if not (hasattr(feature_library, "fit") and hasattr(feature_library, "transform")):
        raise TypeError(
            "feature_library must be a pysindy feature library, got "
            f"{type(feature_library).__name__}"
        )
    return feature_library


def _check_optimizer(optimizer):
    if optimizer is None:
        return FloatingFStepwise()
    if not (hasattr(optimizer, "fit") and hasattr(optimizer, "get_params")):
        raise TypeError(
            f"optimizer must be a pysindy optimizer, got {type(optimizer).__name__}"
        )
    return optimizer


def _check_validation(validation, m, n_inputs):
    if validation is None:
        return None
    if not isinstance(validation, (tuple, list)) or len(validation) not in (2, 3):
        raise TypeError("validation must be a tuple (y, t) or (y, t, u)")
    y_v = val.as_float_array(validation[0], "validation y", ndim=(1, 2), allow_nan=True)
    if y_v.ndim == 1:
        y_v = y_v[:, None]
    if y_v.shape[1] != m:
        raise ValueError(
            f"validation y has {y_v.shape[1]} columns but {m} channels are measured"
        )
    t_v = val.check_time(validation[1], y_v.shape[0], "validation t")
    u_v = None
    if n_inputs:
        if len(validation) != 3:
            raise ValueError("validation must be (y, t, u): the model has inputs")
        u_v = val.as_float_array(validation[2], "validation u", ndim=(1, 2))
        u_v = u_v.reshape(y_v.shape[0], -1)
    return y_v, t_v, u_v


# --------------------------------------------------------------------------- #
# the study


def discover(
    y,
    t,
    *,
    assumed_model,
    n_states,
    measured=None,
    noise_variance,
    error_states=None,
    feature_library=None,
    optimizer=None,
    feature_names=None,
    u=None,
    validation=None,
    W="auto",
    error_model="white",
    alpha=0.01,
    refit=True,
    assumed_equations=None,
):
    """Find what an assumed model gets wrong, name the cause, fix it, measure it.

    Parameters
    ----------
    y : array-like (n_samples, n_measured)
        Noisy measurements of the states listed in ``measured``; NaN marks a
        missing sample.
    t : array-like (n_samples,) or float
        Strictly increasing sample times (or the time step).
    assumed_model : callable, pysindy model or ExtendedModel
        The user's simulation model ``f(x, t)`` or ``f(x, t, u)``, vectorised.
    n_states : int
    measured : sequence of int, optional
        Measured state indices (default: all states).
    noise_variance : float, array (n_measured,) or (n_measured, n_measured), or "auto"
        Measurement noise (co)variance. "auto" estimates it from the data.
    error_states : sequence of int, optional
        States whose equation may be wrong (default: all).
    feature_library : pysindy feature library, optional
        Candidate functions of the states (and inputs); default
        ``PolynomialLibrary(degree=3)``.
    optimizer : pysindy optimizer, optional
        Default :class:`FloatingFStepwise` ``()``.
    feature_names : list of str, optional
        Names of the states followed by the inputs (default ``x0, x1, ...``
        and ``u0, ...``).
    u : array-like (n_samples, n_inputs), optional
        Known inputs on the sample grid.
    validation : tuple (y, t) or (y, t, u), optional
        Another record, used only to measure the gain.
    W : "auto", "ml" or positive number
        MME weight (see :class:`MME`).
    error_model : {"white", "random_walk"}
        MME's prior on the model error (see :class:`MME`).
    alpha : float
        Significance level of the tests (consistency, term pruning, F-test of
        the extended model against the assumed one).
    refit : bool
        Refit the identified coefficients by output error (recommended).
    assumed_equations : list of str, optional
        Text of the assumed right-hand sides for the printed equations.

    Returns
    -------
    Discovery
    """
    # ---- validate everything before any long computation ----
    if isinstance(n_states, bool) or not isinstance(n_states, (int, np.integer)):
        raise TypeError(f"n_states must be a positive integer, got {n_states!r}")
    if n_states < 1:
        raise ValueError(f"n_states must be a positive integer, got {n_states}")
    n_states = int(n_states)
    y = val.as_float_array(y, "y", ndim=(1, 2), allow_nan=True)
    if y.ndim == 1:
        y = y[:, None]
    n_samples = y.shape[0]
    t = val.check_time(t, n_samples, "t")
    measured_idx = (
        np.arange(n_states)
        if measured is None
        else val.check_indices(measured, n_states, "measured")
    )
    m = measured_idx.size
    if y.shape[1] != m:
        raise ValueError(
            f"y has {y.shape[1]} columns but measured names {m} states "
            f"({measured_idx.tolist()})"
        )
    if np.all(np.isnan(y)):
        raise ValueError("y contains no finite measurement")
    error_idx = (
        np.arange(n_states)
        if error_states is None
        else val.check_indices(error_states, n_states, "error_states")
    )
    alpha = val.check_probability(alpha, "alpha")
    if not isinstance(refit, (bool, np.bool_)):
        raise TypeError(f"refit must be True or False, got {refit!r}")
    if u is not None:
        u = val.as_float_array(u, "u", ndim=(1, 2))
        if u.ndim == 1:
            u = u[:, None]
        if u.shape[0] != n_samples:
            raise ValueError(f"u has {u.shape[0]} rows but y has {n_samples} samples")
    n_inputs = 0 if u is None else u.shape[1]
    if feature_names is None:
        feature_names = [f"x{i}" for i in range(n_states)] + [
            f"u{i}" for i in range(n_inputs)
        ]
    feature_names = [str(n) for n in feature_names]
    if len(feature_names) != n_states + n_inputs:
        raise ValueError(
            f"feature_names has {len(feature_names)} names but there are {n_states} "
            f"states and {n_inputs} inputs"
        )
    if len(set(feature_names)) != len(feature_names):
        raise ValueError(f"feature_names repeats a name: {feature_names}")
    state_names = feature_names[:n_states]
    input_names = feature_names[n_states:]
    library = _check_library(feature_library)
    optimizer = _check_optimizer(optimizer)
    if isinstance(noise_variance, str):
        if noise_variance != "auto":
            raise ValueError(
                f"noise_variance must be a number, an array or 'auto', got "
                f"{noise_variance!r}"
            )
        noise_cov = None
    else:
        noise_cov = noise_covariance(noise_variance, m)
    validation = _check_validation(validation, m, n_inputs)
    if assumed_equations is not None and len(assumed_equations) != n_states:
        raise ValueError(
            f"assumed_equations has {len(assumed_equations)} entries, expected "
            f"{n_states}"
        )
    f = as_model_function(assumed_model, n_states)
    # The library size bounds what a record can support: fail now, not after MME.
    probe = np.zeros((min(n_samples, 8), n_states + n_inputs)) + 0.5
    n_features = np.asarray(clone(library).fit(probe).transform(probe)).shape[1]
    n_finite = int(np.sum(np.all(np.isfinite(y), axis=1)))
    needed = n_features + 2
    if n_finite < needed:
        raise ValueError(
            f"y has {n_finite} complete samples but the feature library has "
            f"{n_features} terms: at least {needed} samples are needed"
        )

    notes = []
    # ---- 2. MME: states and model error ----
    mme = MME(
        assumed_model=f,
        n_states=n_states,
        measured=measured_idx.tolist(),
        noise_variance="auto" if noise_cov is None else noise_cov,
        error_states=error_idx.tolist(),
        W=W,
        error_model=error_model,
        u=u,
    )
    mme(y, t)
    if noise_cov is None:
        noise_cov = np.asarray(mme.noise_variance_)  # (m, m), estimated
    if not mme.converged_:
        notes.append("MME did not converge; the state estimate may be poor")
    x_hat = np.asarray(mme.smoothed_x_)
    d_hat = np.asarray(mme.d_)

    # ---- 1. the assumed model against the data ----
    def measure(x):
        return x[..., measured_idx]

    f_fast = f.unchecked()  # validated by MME's first evaluation

    def base_rhs(x, s, us):
        tt = np.full(x.shape[0], s)
        uu = None if us is None else np.tile(us, (x.shape[0], 1))
        return np.asarray(f_fast(x, tt, uu), dtype=float)

    # ---- 3. stepwise regression of d on the library ----
    z_hat = x_hat if u is None else np.hstack([x_hat, u])
    library = clone(library).fit(z_hat)
    with np.errstate(all="ignore"):
        theta = np.asarray(library.transform(z_hat))
    lib_names = list(library.get_feature_names(feature_names))
    opt = clone(optimizer)
    target_names = [state_names[i] for i in error_idx]
    if _accepts_names(opt):
        opt.fit(
            theta,
            d_hat[:, error_idx],
            feature_names=lib_names,
            target_names=target_names,
        )
    else:
        opt.fit(theta, d_hat[:, error_idx])
    reg_coef = np.zeros((n_states, theta.shape[1]))
    reg_coef[error_idx] = np.asarray(opt.coef_).reshape(error_idx.size, -1)
    reg_intercept = np.zeros(n_states)
    reg_intercept[error_idx] = np.broadcast_to(
        np.asarray(getattr(opt, "intercept_", 0.0), dtype=float), (error_idx.size,)
    )
    candidate_terms = {
        state_names[i]: {
            lib_names[j]: float(reg_coef[i, j]) for j in np.flatnonzero(reg_coef[i])
        }
        for i in error_idx
    }
    for i in error_idx:
        if reg_intercept[i] != 0:
            candidate_terms[state_names[i]]["1"] = float(reg_intercept[i])

    # Slots are (state, library column); column n_lib stands for the
    # optimizer's own intercept (a constant the library does not have).
    n_lib = theta.shape[1]
    const_col = n_lib
    proposals, start = [], []
    for k_target, i in enumerate(error_idx):
        for j in _entry_order(opt, k_target, reg_coef[i], theta):
            proposals.append((int(i), int(j)))
            start.append(float(reg_coef[i, j]))
        if reg_intercept[i] != 0:
            proposals.append((int(i), const_col))
            start.append(float(reg_intercept[i]))
    selected = SelectedFeatures(library, feature_names, range(n_lib), z_hat)

    def features(z, cols):
        lib_cols = [k for k in cols if k != const_col]
        th = selected(z, lib_cols)
        if const_col in cols:
            th = np.insert(th, list(cols).index(const_col), 1.0, axis=1)
        return th

    # Every finite library function of every error state may be added by the
    # forward search in output-error space (a constant too, if the library
    # has none).
    finite_cols = [int(j) for j in np.flatnonzero(np.all(np.isfinite(theta), axis=0))]
    has_constant = any(
        np.ptp(theta[:, j]) == 0 and theta[0, j] != 0 for j in finite_cols
    )
    library_candidates = [
        (int(i), j)
        for i in error_idx
        for j in finite_cols + ([] if has_constant else [const_col])
    ]

    # The refits integrate with fixed-step RK4: enough substeps per sample
    # interval to resolve the fastest time scale of the regression model.
    substeps = _rk4_substeps(f, features, reg_coef, x_hat, t, u)
    make_problem = make_problem_factory(
        base_rhs, features, n_states, measure, y, t, u, noise_cov, substeps
    )
    assumed_fit = make_problem([]).fit(x_hat[0])
    assumed_sim = make_problem([])._simulate(assumed_fit.params[None])[0]
    n_res = assumed_fit.n_residuals
    chi2_dof = max(n_res - n_states, 1)
    chi2_p = float(stats.chi2.sf(assumed_fit.cost, chi2_dof))

    # ---- 4. confirm the proposals against the measurements ----
    def describe(slot):
        i, k = slot
        return f"{state_names[i]}: {'1' if k == const_col else lib_names[k]}"

    if refit and proposals:
        confirmation = confirm_terms(
            make_problem,
            proposals,
            start,
            assumed_fit,
            n_states,
            alpha,
            describe,
            library_candidates=library_candidates,
            f_rows=f,
            x0_start=x_hat[0],
        )
    else:
        # No refit: keep the regression's terms and values as they are.
        fixed = make_problem(proposals)
        params0 = np.concatenate([assumed_fit.params, start])
        confirmation = Confirmation(
            list(proposals), _evaluate_only(fixed, params0) if proposals else None
        )
    final_slots = confirmation.slots
    extended_fit = confirmation.fit
    if not assumed_fit.converged:
        notes.append(
            "the output-error fit of the assumed model did not converge "
            f"({assumed_fit.message})"
        )
    if extended_fit is not None:
        dof_e = max(extended_fit.n_residuals - extended_fit.params.size, 1)
        p_e = float(stats.chi2.sf(extended_fit.cost, dof_e))
        if p_e < alpha:
            notes.append(
                "the extended model still does not fit the data to the noise level "
                f"(chi2 = {extended_fit.cost:.4g} on {dof_e} dof, p = {p_e:.2g}): "
                "the library may lack the missing effect, the noise variance may be "
                "too small, or the search stopped in a local optimum"
            )
    if refit and extended_fit is not None and not extended_fit.converged:
        notes.append(
            "the output-error refit of the extended model did not converge "
            f"({extended_fit.message}); its coefficients may be inaccurate"
        )
    final_coef = (
        np.array([]) if extended_fit is None else extended_fit.params[n_states:]
    )
    pruned = [f"{describe(s)} ({why})" for s, why in confirmation.rejected]
    correction_p = confirmation.correction_p_value

    # ---- the extended model ----
    coef = np.zeros((n_states, theta.shape[1]))
    intercept = np.zeros(n_states)
    for (i, k), c in zip(final_slots, final_coef):
        if k == const_col:
            intercept[i] = c
        else:
            coef[i, k] = c
    extended = ExtendedModel(
        f,
        library,
        coef,
        state_names,
        input_names,
        intercept=intercept,
        assumed_equations=assumed_equations,
        z_reference=z_hat,
    )
    if extended_fit is not None:
        extended_sim = make_problem(final_slots)._simulate(extended_fit.params[None])[0]
    else:
        extended_sim = assumed_sim

    # ---- terms with their statistics ----
    terms = {state_names[i]: {} for i in error_idx}
    estimates = []
    if extended_fit is not None:
        ci = extended_fit.confidence_intervals()[n_states:]
        se = extended_fit.std_errors[n_states:]
        dof = max(extended_fit.n_residuals - extended_fit.params.size, 1)
        for s, (i, k) in enumerate(final_slots):
            fname = "1" if k == const_col else lib_names[k]
            c = float(final_coef[s])
            terms[state_names[i]][fname] = c
            reg_c = reg_intercept[i] if k == const_col else reg_coef[i, k]
            estimates.append(
                TermEstimate(
                    state=state_names[i],
                    feature=fname,
                    coefficient=c,
                    regression_coefficient=float(reg_c),
                    std_error=float(se[s]),
                    ci_low=float(ci[s, 0]),
                    ci_high=float(ci[s, 1]),
                    partial_f=_partial_f(
                        opt,
                        list(error_idx).index(i),
                        None if k == const_col else k,
                    ),
                    p_value=float(2 * stats.t.sf(abs(c / se[s]), dof))
                    if se[s] > 0
                    else 0.0,
                )
            )

    # ---- 5. the gain ----
    noise_floor = np.sqrt(np.diag(noise_cov))
    rmse_a = _rmse(y, measure(assumed_sim))
    rmse_e = _rmse(y, measure(extended_sim))
    channel_names = [state_names[i] for i in measured_idx]
    gain = Gain(channel_names, rmse_a, rmse_e, noise_floor)
    if validation is not None:
        y_v, t_v, u_v = validation
        # Only the initial state is fitted on validation data, starting from
        # an MME estimate of that record's state.
        mme_v = clone(mme).set_params(u=u_v, noise_variance=noise_cov)
        mme_v(y_v, t_v)
        x0_guess = np.asarray(mme_v.smoothed_x_)[0]
        rmse_v = []
        for slots_v, coefs_v in (([], np.array([])), (final_slots, final_coef)):
            problem_v = OutputErrorProblem(
                base_rhs,
                features,
                slots_v,
                n_states,
                measure,
                y_v,
                t_v,
                u_v,
                noise_cov,
                substeps=substeps,
                held_coefficients=coefs_v,
            )
            x0_v = problem_v.fit(x0_guess).params
            sim_v = problem_v._simulate(x0_v[None])[0]
            rmse_v.append(_rmse(y_v, measure(sim_v)))
        gain.validation_rmse_assumed, gain.validation_rmse_extended = rmse_v

    # ---- what d(t) says ----
    f_hat = f(x_hat, t, u)
    d_summary = {}
    for i in error_idx:
        rms_d = float(np.sqrt(np.mean(d_hat[:, i] ** 2)))
        rms_total = float(np.sqrt(np.mean((f_hat[:, i] + d_hat[:, i]) ** 2)))
        d_summary[state_names[i]] = {
            "rms_d": rms_d,
            "rms_dynamics": rms_total,
            "share": rms_d / rms_total if rms_total > 0 else float("nan"),
        }

    for note in notes:
        warnings.warn(note, DiscoveryWarning, stacklevel=2)
    return Discovery(
        t=t,
        y=y,
        u=u,
        state_names=state_names,
        input_names=input_names,
        channel_names=channel_names,
        measured=measured_idx,
        error_states=error_idx,
        noise_cov=noise_cov,
        alpha=alpha,
        mme=mme,
        optimizer=opt,
        library_feature_names=lib_names,
        regression_coef=reg_coef,
        assumed_fit=assumed_fit,
        assumed_simulation=assumed_sim,
        consistency_chi2=float(assumed_fit.cost),
        consistency_dof=int(chi2_dof),
        consistency_p_value=chi2_p,
        candidate_terms=candidate_terms,
        pruned_terms=pruned,
        extended_fit=extended_fit,
        extended_simulation=extended_sim,
        extended_model=extended,
        correction_p_value=correction_p,
        terms=terms,
        term_estimates=estimates,
        gain=gain,
        d_summary=d_summary,
        warnings=notes,
    )


# --------------------------------------------------------------------------- #
# small helpers


def _accepts_names(optimizer) -> bool:
    """Whether ``optimizer.fit`` takes ``feature_names`` (FloatingFStepwise)."""
    import inspect

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


def _rk4_substeps(f, features, reg_coef, x_hat, t, u):
    """RK4 steps per interval so that ``h * spectral radius <= 0.5``.

    The spectral radius of the Jacobian of the regression model (assumed model
    plus proposed correction) along the MME trajectory sets the fastest time
    scale; RK4 is accurate to ~1e-5 relative per step at ``h rho = 0.5``.
    """
    stride = max(1, x_hat.shape[0] // 200)  # a sample of points is enough
    xs, ts = x_hat[::stride], t[::stride]
    us = None if u is None else u[::stride]
    columns = [int(j) for j in np.flatnonzero(np.any(reg_coef != 0, axis=0))]

    def model(x):
        out = f(x, ts, us)
        if columns:
            z = x if us is None else np.hstack([x, us])
            out = out + features(z, columns) @ reg_coef[:, columns].T
        return out

    jac = rowwise_jacobian(model, xs, rel_step=1e-6)
    jac[~np.isfinite(jac)] = 0.0
    rho = float(np.max(np.abs(np.linalg.eigvals(jac)))) if xs.size else 0.0
    dt = float(np.max(np.diff(t)))
    return int(min(50, max(1, np.ceil(dt * rho / 0.5))))


def _partial_f(opt, target, column):
    """Partial F of ``column`` in the stepwise model of ``target`` (NaN if none)."""
    tables = getattr(opt, "anova_", None)
    if tables is None or column is None:
        return float("nan")
    table = tables[target]
    support = list(np.asarray(getattr(table, "features", ())))
    partial = np.asarray(getattr(table, "partial_f", []))
    if column in support and len(partial) == len(support):
        return float(partial[support.index(column)])
    return float("nan")


def _rmse(y, y_hat):
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.nanmean((y - y_hat) ** 2, axis=0))


def _evaluate_only(problem, params):
    """An OutputErrorResult at fixed parameters (no optimisation)."""
    r = problem.residuals_batch(params[None])[0]
    cost = float(r @ r) if np.all(np.isfinite(r)) else np.inf
    cov = np.full((params.size, params.size), np.nan)
    return OutputErrorResult(params, cov, cost, cost, r.size, False, "not refitted")
