"""What :func:`discover` returns: the step records and what they add up to."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial

import numpy as np

from ..core.relaxation import overflow_columns_of
from ..exceptions import NotSavedError
from .estimates import ParameterEstimate
from .extended_at import extended_model_at
from .report import format_discovery

__all__ = ["Discovery", "SavedDiscovery"]


@dataclass
class Discovery:
    """What :func:`discover` found. ``print(result)`` tells the story.

    The study's five steps each leave a record: ``assumed`` (step 1, the
    assumed model's output-error fit and consistency test), ``estimate``
    (step 2, MME), ``proposals`` (step 3, the regression of ``d(t)``),
    ``confirmation`` (step 4, the output-error selection) and ``gain``
    (step 5). The attributes below are read off them.

    Attributes
    ----------
    terms : dict
        ``{state name: {feature name: coefficient}}`` for every error state;
        an empty inner dict means no significant correction for that state.
    term_estimates : list of TermEstimate
    extended_model : ExtendedModel
        Assumed model + fitted correction.
    gain : Gain
    consistency_p_value : float
        Chi-square test of the assumed model against the data (its initial
        state fitted): small means the data contradict the assumed model.
    correction_p_value : float
        F-test of the extended model against the assumed one (NaN when no
        term was kept).
    mme : MME
        The fitted estimator (``smoothed_x_``, ``d_``, ``W_``, ...).
    optimizer : fitted optimizer
        The regression of ``d`` (``anova_``, ``steps_``, ``summary()``).
    conclusion : str
        One of ``"explained"``, ``"partly explained"``, ``"not explained"``,
        ``"consistent"``, ``"inconclusive"``, derived from the evidence (see
        :mod:`pysindy_mme.discovery.conclusion` for what each requires).
    verdict : str
        The conclusion as one sentence (the report's first lines).
    reasons : list of str
        Why: each a short sentence naming the number that decided it.
    advice : list of str
        What to try when the conclusion is short of "explained".
    trade_offs : list of TradeOff
        Combinations of fitted quantities the data do not determine.
    clipped : Clipping
        Readings of the fitting record on a sensor's limits (per channel
        and side: level, count, mask; see
        :mod:`pysindy_mme.core.sensors`); left out of the fits and RMSEs
        unless ``clipped="keep"``. ``validation_clipped``: the same for the
        validation record (None without one). A clipped stretch at the start
        or end of a record is cut (``study.clipped_cut``,
        ``study.validation_clipped_cut``): ``t``, ``y`` and these masks are
        the rows between.
    readings : ndarray
        The fitting record as the sensors reported it (``y`` has NaN at the
        censored readings).
    smoothing : str
        How the kinks of non-smooth kept terms were integrated, and the
        check that their smoothing width does not change the result (empty
        without such terms; a width that matters is a warning instead).
    kink_misfit : float or None
        Where the extended model misses its record by more than the noise
        and has smoothed kinks: its misfit beyond the noise refitted with the
        kinks at half the width (and twice the RK4 steps), as a share of its
        misfit (RMSE-like). Well below 1 (at most 0.7), most of the misfit is
        the integration of the smoothed kinks; near 1, an effect the library
        lacks. None where not measured.
    memory : list of MemoryEvidence
        Per error state, how well the present states and inputs predict the
        assumed model's error ``d(t)``, and how much better their history
        does (:mod:`pysindy_mme.discovery.memory`); ``suspected`` marks a
        likely missing state, named in the reasons and the advice.
    warnings : list of str
    """

    study: object
    assumed: object
    estimate: object
    proposals: object
    confirmation: object
    gain: object
    extended_model: object
    terms: dict
    term_estimates: list
    verdict: str
    warnings: list = field(default_factory=list)
    extended_fit: object | None = None
    substeps: int = 1
    conclusion: str = "inconclusive"
    reasons: list = field(default_factory=list)
    advice: list = field(default_factory=list)
    trade_offs: list = field(default_factory=list)
    smoothing: str = ""
    memory: list = field(default_factory=list)
    kink_misfit: float | None = None

    # ----------------------------------------------------- read off the steps
    t = property(lambda self: self.study.t)
    y = property(lambda self: self.study.y)
    u = property(lambda self: self.study.u)
    state_names = property(lambda self: self.study.state_names)
    input_names = property(lambda self: self.study.input_names)
    channel_names = property(lambda self: self.study.channel_names)
    measured = property(lambda self: self.study.measured)
    error_states = property(lambda self: self.study.error_states)
    noise_cov = property(lambda self: self.study.noise_cov)
    alpha = property(lambda self: self.study.alpha)
    mme = property(lambda self: self.estimate.mme)
    d_summary = property(lambda self: self.estimate.summary)
    optimizer = property(lambda self: self.proposals.optimizer)
    library_feature_names = property(lambda self: self.proposals.feature_names)
    regression_coef = property(lambda self: self.proposals.coefficients)
    assumed_fit = property(lambda self: self.assumed.fit)
    consistency_chi2 = property(lambda self: self.assumed.chi2)
    consistency_dof = property(lambda self: self.assumed.dof)
    consistency_p_value = property(lambda self: self.assumed.p_value)
    correction_p_value = property(lambda self: self.confirmation.correction_p_value)
    clipped = property(lambda self: self.study.clipped)
    validation_clipped = property(lambda self: self.study.validation_clipped)

    @property
    def readings(self) -> np.ndarray:
        """The fitting record as reported, clipped readings included."""
        readings = self.study.readings
        return self.study.y if readings is None else readings

    @property
    def assumed_simulation(self) -> np.ndarray:
        """The assumed model's free run from its fitted initial state."""
        return self.gain.in_sample_runs["assumed"].x

    @property
    def extended_simulation(self) -> np.ndarray:
        """The extended model's free run from its fitted initial state."""
        return self.gain.in_sample_runs["extended"].x

    # ---------------------------------------------- statsmodels' names
    @property
    def _final_fit(self):
        return self.extended_fit or self.assumed.fit

    @property
    def param_names(self) -> list:
        """Names of :attr:`params`: the grey-box parameters, the kept terms
        (``"x1^3 in x2'"``), the measurement offsets (``offsets=True``)."""
        fit = self._final_fit
        names = list(self.study.parameter_names)
        names += [f"{te.feature} in {te.state}'" for te in self.term_estimates]
        if fit.n_offsets:
            names += [f"offset of {name}" for name in self.study.channel_names]
        return names

    @property
    def params(self) -> np.ndarray:
        """Every fitted constant of the final model (statsmodels' ``params``):
        parameters, term coefficients, offsets, in :attr:`param_names` order."""
        return np.array(self._final_fit.theta, dtype=float)

    @property
    def bse(self) -> np.ndarray:
        """Standard errors of :attr:`params` (NaN where undefined: a parameter
        held on its bound, an unidentified direction)."""
        se = np.array(self._final_fit.std_errors, dtype=float)
        return np.where(se > 0, se, np.nan)

    @property
    def df_resid(self) -> int:
        """Residual degrees of freedom of the final fit."""
        return int(self._final_fit.dof)

    @property
    def nobs(self) -> int:
        """Measurements fitted (censored and missing readings left out)."""
        return int(self._final_fit.n_residuals)

    @property
    def tvalues(self) -> np.ndarray:
        """``params / bse``."""
        with np.errstate(all="ignore"):
            return self.params / self.bse

    @property
    def pvalues(self) -> np.ndarray:
        """Two-sided p-values of :attr:`tvalues` (Student t, :attr:`df_resid`)."""
        from scipy import stats

        return 2.0 * stats.t.sf(np.abs(self.tvalues), self.df_resid)

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """Confidence intervals of :attr:`params` at level ``1 - alpha``,
        shape ``(k, 2)`` (the report's are ``alpha = 0.05``)."""
        if not 0.0 < float(alpha) < 1.0:
            raise ValueError(f"alpha must lie strictly between 0 and 1, got {alpha!r}")
        ci = np.array(self._final_fit.confidence_intervals(1.0 - float(alpha)))
        ci[~np.isfinite(self.bse)] = np.nan
        return ci

    @property
    def parameters(self) -> dict:
        """``{name: ParameterEstimate}`` of the assumed model's parameters."""
        names = self.study.parameter_names
        if not names:
            return {}
        fit = self.extended_fit or self.assumed.fit
        ci = fit.confidence_intervals()
        se = fit.std_errors
        bounds = self.study.parameter_bounds
        gauge = self.study.parameter_gauge
        out = {}
        for k, name in enumerate(names):
            out[name] = ParameterEstimate(
                name=name,
                initial=float(self.study.parameter_init[k]),
                assumed_fit=float(self.assumed.fit.physical[k]),
                value=float(fit.physical[k]),
                std_error=float(se[k]) if se[k] > 0 else float("nan"),
                ci_low=float(ci[k, 0]),
                ci_high=float(ci[k, 1]),
                lower=float(bounds[k, 0]) if len(bounds) else -np.inf,
                upper=float(bounds[k, 1]) if len(bounds) else np.inf,
                at_bound=bool(fit.at_bound[k]) and not gauge[k],
                gauge=bool(gauge[k]),
            )
        return out

    @property
    def offsets(self) -> np.ndarray | None:
        """Fitted constant offset per measured channel (``offsets=True``)."""
        if not self.study.offsets:
            return None
        return (self.extended_fit or self.assumed.fit).offsets

    @property
    def walls(self) -> list:
        """The overflow terms that ended as walls: one dict per wall, with the
        ``state`` held below ``level``, the wall's ``coefficient`` (on its
        limit ``-WALL_DECAY / dt``, see :mod:`~pysindy_mme.solver.output_error`:
        the data say only that the excess goes within a fraction of a
        sample) and ``routes``, ``{state: fraction}`` of the excess each
        other equation's term of the same column takes (its coefficient over
        the wall's magnitude)."""
        fit = self.extended_fit
        if fit is None or not np.any(fit.at_wall):
            return []
        # the library's own declaration (a loaded result keeps it: StoredLibrary)
        columns = overflow_columns_of(self.proposals.library)
        a = fit.n_physical
        out = []
        for k in np.flatnonzero(fit.at_wall):
            i, c = fit.slots[k]
            coef = float(fit.theta[a + k])
            routes = {
                self.state_names[j]: float(fit.theta[a + m]) / abs(coef)
                for m, (j, cc) in enumerate(fit.slots)
                if cc == c and j != i
            }
            out.append(
                dict(
                    state=self.state_names[i],
                    term=self.proposals.name(c),
                    level=float(columns[c][1]) if c in columns else float("nan"),
                    coefficient=coef,
                    routes=routes,
                )
            )
        return out

    @property
    def candidate_terms(self) -> dict:
        return self.proposals.candidate_terms(self.state_names)

    @property
    def pruned_terms(self) -> list:
        def describe(slot):
            i, c = slot
            return f"{self.state_names[i]}: {self.proposals.name(c)}"

        # a term tried, dropped and taken back later is in the model, not "not kept"
        kept = set(self.confirmation.slots)
        return [
            f"{describe(s)} ({why})"
            for s, why in self.confirmation.rejected
            if tuple(s) not in kept
        ]

    def validate(self, y, t, u=None, window: int | None = None, protocol=None) -> dict:
        """Both models on another record, by a validation protocol.

        By default the benchmarks' free run (the study's record protocol,
        :class:`~pysindy_mme.protocols.LeadingWindow` unless the study was
        given another): each model's initial state is fitted to the first
        ``window`` samples (default: the study's ``validation_window``),
        then it runs free over the whole record; the RMSE is taken over the
        samples after the window (a run that diverges has none: ``inf``,
        and ``diverged_at``). Clipped readings are censored as in the study
        (``clipped``), and a clipped stretch at either end of the record is
        cut: the runs then cover the samples between.

        Parameters
        ----------
        y : array-like (n_samples, n_measured); t : array-like (n_samples,)
        u : array-like (n_samples, n_inputs), optional
        window : int, optional
            Leading samples the initial states are fitted to.
        protocol : ValidationProtocol, optional
            How to run and score the models on the record, for example
            ``KStepAhead(10)`` (:mod:`pysindy_mme.protocols`).

        Returns
        -------
        dict
            ``{"assumed": FreeRun, "extended": FreeRun}`` (``x0``, ``x``,
            ``rmse`` per channel, ``diverged_at``; where the extended run
            misses by more than 1.5x the noise, its ``uncertainty``: whether
            that miss is the uncertainty of its coefficients and start,
            :class:`~pysindy_mme.protocols.RunUncertainty`).
        """
        from ..protocols import ValidationProtocol
        from ..protocols.base import check_window
        from .inputs import check_record

        if protocol is None:
            protocol = self.study.validation_protocol
            default_window = self.study.validation_window
        else:
            default_window = getattr(protocol, "window", None)
        if not isinstance(protocol, ValidationProtocol):
            raise TypeError(
                "protocol must be a validation protocol (pysindy_mme.protocols: "
                f"LeadingWindow(), KStepAhead(k)), got {protocol!r}"
            )
        protocol._check()
        window = check_window(default_window if window is None else window)
        record = check_record(self.study, y, t, u, "y")
        models = {
            "assumed": self.study.model_at(self.assumed.fit.physical),
            "extended": self.extended_model,
        }
        runs = protocol.score(
            self.study, models, self.proposals.evaluate, self.substeps, record, window
        )
        protocol.measure_uncertainty(
            self.study,
            runs,
            models,
            self._coefficient_draws(),
            self.proposals.evaluate,
            self.substeps,
            record,
        )
        return runs

    def _coefficient_draws(self) -> dict | None:
        """The extended model at its coefficients moved one standard error
        along each eigenvector of their covariance, made when a run's
        ``uncertainty`` is measured (:mod:`~pysindy_mme.protocols.uncertainty`);
        None without terms."""
        from ..protocols.uncertainty import coefficient_draws

        fit = self.confirmation.fit
        if fit is None or not fit.slots:
            return None
        x_hat = np.asarray(self.mme.smoothed_x_, dtype=float)

        def build(at):
            return extended_model_at(
                self.study, self.proposals, at, x_hat, self.substeps
            )

        return {"extended": partial(coefficient_draws, fit, build)}

    @property
    def found_correction(self) -> bool:
        return any(self.terms.values())

    @property
    def assumed_output(self) -> np.ndarray:
        """The assumed model's free run as the sensors see it (``(N, m)``:
        the measurement applied to :attr:`assumed_simulation`, no offsets)."""
        measure = self.study.measurement
        x = self.assumed_simulation
        return measure(x) if callable(measure) else x @ np.asarray(measure).T

    @property
    def extended_correction(self) -> np.ndarray:
        """The extended model's correction along its own free run (``(N, n)``;
        along MME's estimate where that run is not finite): what the model
        error figure draws against ``d(t)``."""
        x = self.extended_simulation
        if x is None or not np.all(np.isfinite(x)):
            x = self.mme.smoothed_x_
        with np.errstate(all="ignore"):
            return np.asarray(self.extended_model.correction(x, self.u), dtype=float)

    def __str__(self) -> str:
        return format_discovery(self)

    def summary(self):
        """The study in tables, in statsmodels' style.

        Returns
        -------
        Summary
            ``str()`` gives text, ``as_html()`` HTML (a notebook shows it),
            ``as_latex()`` LaTeX; ``tables`` are
            :class:`~pysindy_mme.core.tables.SimpleTable` of the values
            (``table.to_frame()`` with pandas). ``print(result)`` remains the
            full report.
        """
        from .summary import discovery_summary

        return discovery_summary(self)

    def _repr_html_(self) -> str:
        return self.summary().as_html()

    def to_frame(self, table: str = "terms"):
        """A table of the result as a ``pandas.DataFrame`` (needs pandas).

        Parameters
        ----------
        table : {"terms", "parameters", "gain"}
            ``"terms"``: one row per kept term, indexed by ``(state,
            feature)``, the columns of :class:`TermEstimate`;
            ``"parameters"``: one row per grey-box parameter, indexed by
            ``name``, the columns of :class:`ParameterEstimate` and
            ``change``; ``"gain"``: one row per measured channel, the
            in-sample and validation RMSEs, gains and the noise floor.

        Returns
        -------
        pandas.DataFrame
        """
        from ..core.tables import require_pandas
        from .summary import TABLES, columns, records

        rows = records(self, table)
        pd = require_pandas()
        return pd.DataFrame(rows, columns=columns(table)).set_index(TABLES[table])

    def save(self, path) -> None:
        """Write the result to ``path`` (a ``.npz`` file, no pickle inside).

        The file holds what the report, :meth:`summary`, the tables and
        :meth:`plot` need (format: :mod:`pysindy_mme.discovery.storage`), not
        the user's code: :meth:`load` it anywhere pysindy-mme is installed.
        """
        from .storage import save

        save(self, path)

    @classmethod
    def load(cls, path, assumed_model=None) -> Discovery:
        """A result saved by :meth:`save`.

        Parameters
        ----------
        path : str or Path
        assumed_model : callable, optional
            The assumed model the study ran with (for a grey box, ``f(x, t,
            u, p)``: the fitted parameters are in the file). Without it the
            loaded result reports, tabulates and plots, but its extended
            model cannot simulate (:class:`~pysindy_mme.NotSavedError`).

        Returns
        -------
        Discovery
            With the stored numbers; what needs the user's code or the
            fitted estimators (``validate``, ``mme.fit``, ...) raises
            :class:`~pysindy_mme.NotSavedError` naming what is missing.
        """
        from .storage import load

        return load(path, SavedDiscovery, assumed_model=assumed_model)

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
        from ..plotting import plot_discovery

        return plot_discovery(self, x_true=x_true, d_true=d_true, path=path)

    def to_dict(self) -> dict:
        """Plain-Python summary (JSON-serialisable) for saving."""

        def plain(v):
            v = float(v)
            return v if np.isfinite(v) else None

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
                "chi2": plain(self.consistency_chi2),
                "dof": self.consistency_dof,
                "p_value": plain(self.consistency_p_value),
            },
            "model_error": self.d_summary,
            "candidate_terms": self.candidate_terms,
            "pruned_terms": list(self.pruned_terms),
            "correction_p_value": plain(self.correction_p_value),
            "terms": self.terms,
            "term_estimates": [
                {
                    k: (plain(v) if isinstance(v, float) else v)
                    for k, v in vars(te).items()
                }
                for te in self.term_estimates
            ],
            "conclusion": self.conclusion,
            "verdict": self.verdict,
            "reasons": list(self.reasons),
            "advice": list(self.advice),
            "trade_offs": [str(t) for t in self.trade_offs],
            "parameters": {
                k: {
                    f: (plain(v) if isinstance(v, float) else v)
                    for f, v in vars(pe).items()
                }
                for k, pe in self.parameters.items()
            },
            "clipped": _clipped_dict(self.study),
            "extended_model": self.extended_model.equations(),
            "gain": self.gain.to_dict(),
            "warnings": list(self.warnings),
        }


def _clipped_dict(study) -> dict:
    """The clipping findings of both records, JSON-ready."""

    def findings(clipping):
        if clipping is None:
            return []
        return [
            {
                "channel": study.channel_names[c.channel],
                "side": c.side,
                "level": float(c.level),
                "count": int(c.count),
                "share": float(c.share),
                "longest_run": int(c.longest_run),
                "given": bool(c.given),
            }
            for c in clipping
        ]

    option = study.clipped_option
    return {
        "option": option if isinstance(option, str) else [list(r) for r in option],
        "censored": bool(study.censored),
        "fitting_record": findings(study.clipped),
        "validation_record": findings(study.validation_clipped),
        "cut": {
            "fitting_record": list(study.clipped_cut),
            "validation_record": list(study.validation_clipped_cut),
        },
    }


class SavedDiscovery(Discovery):
    """A :class:`Discovery` loaded from a file (:meth:`Discovery.load`).

    Reports, tables and plots as the original did; what needs the user's
    code raises :class:`~pysindy_mme.NotSavedError` (module docstring).
    ``saved`` holds the file's ``path``, ``version``, ``package_version``
    and the ``report`` as it was printed when saved.
    """

    @property
    def assumed_output(self) -> np.ndarray:
        return self.saved["assumed_output"]

    @property
    def extended_correction(self) -> np.ndarray:
        return self.saved["extended_correction"]

    def validate(self, y, t, u=None, window=None, protocol=None):
        raise NotSavedError(
            "validate() refits both models on another record, which needs the "
            "fitted MME estimator and the library, not saved: run discover() "
            "again (with validation=) for a new record"
        )
