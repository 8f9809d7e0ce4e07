"""Plain-text report of a Discovery: what is wrong, the cause, the fix, the gain.

Numbers are printed by significant digits (:mod:`pysindy_mme.core.tables`);
a statistic that is not finite or not determined prints as ``n/a``; the
consistency test, the correction test and the text share one verdict.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..core.tables import p_value, sig, signed, text_table
from ..solver.output_error import WALL_DECAY
from .run_sensitivity import spread_from

__all__ = ["format_discovery"]


def _header(res) -> list:
    t = res.t
    noise = ", ".join(sig(v, 3) for v in np.diag(res.noise_cov))
    source = res.study.noise_description or "stated by the user"
    inputs = f"; inputs: {', '.join(res.input_names)}" if res.input_names else ""
    study = res.study
    if study.n_records > 1:
        spans = ", ".join(
            f"{sig(t[p.start])} .. {sig(t[p.stop - 1])}" for p in study.record_slices
        )
        data = (
            f"Data: {study.n_records} records, "
            f"{' + '.join(str(k) for k in study.record_sizes)} samples (t = {spans}; "
            "each its own initial state, shared parameters and correction)"
        )
    else:
        data = f"Data: {t.size} samples over t = {sig(t[0])} .. {sig(t[-1])}"
    out = [
        "pysindy-mme discovery report",
        "=" * 28,
        f"{data}; measured: "
        f"{', '.join(res.channel_names)}; states: {', '.join(res.state_names)}"
        + inputs,
        f"Measurement noise variance: {noise} ({source})",
    ]
    out += _clipped_lines(res)
    placement = res.study.error_states_note
    if placement:
        out.append(f"Model error placed on: {placement}")
    out += [f"Conclusion: {res.conclusion}", f"Verdict: {res.verdict}."]
    if res.reasons:
        out.append("Why:")
        out += [f"- {r}" for r in res.reasons]
    if res.advice:
        out.append("What to try:")
        out += [f"- {a}" for a in res.advice]
    return out + [""]


def _clipped_lines(res) -> list:
    """``y2: 47 samples (4.6 %) sit on the sensor's ceiling 10: treated as
    censored (left out of the fit)``, per clipped channel and side; and the
    clipped stretches cut from the ends of a record."""
    study = res.study
    validation = study.validation
    records = [
        ("", study.clipped, study.clipped_cut, study.t),
        (
            "validation record, ",
            study.validation_clipped,
            study.validation_clipped_cut,
            None if validation is None else validation[1],
        ),
    ]
    treated = (
        "treated as censored (left out of the fit)"
        if study.censored
        else "fitted as readings (clipped='keep')"
    )
    out = []
    for where, found, cut, t in records:
        for c in found or ():
            given = c.given and not isinstance(study.clipped_option, str)
            on = "at or beyond" if given else "on"
            out.append(
                f"Clipped: {where}{res.channel_names[c.channel]}: {c.count} samples "
                f"({sig(100 * c.share, 2)} %) sit {on} the sensor's {c.side} "
                f"{sig(c.level)}{' (given)' if given else ''}: {treated}"
            )
        if any(cut):
            ends = [f"{w} {k}" for w, k in zip(("first", "last"), cut) if k]
            record = "the validation record" if where else "the record"
            out.append(
                f"Clipped: {record}'s {' and '.join(ends)} samples are all on the "
                f"sensor's limits, with no reading after them to anchor a fit: "
                f"cut, the study runs on the {t.size} samples between (t = "
                f"{sig(t[0])} .. {sig(t[-1])})"
            )
    return out


def _what_is_wrong(res) -> list:
    out = ["1. What the assumed model gets wrong", "-" * 36]
    g = res.gain
    resid = res.y - res.assumed_output
    rows = []
    for j, name in enumerate(res.channel_names):
        r = resid[:, j]
        finite = np.isfinite(r)
        worst = (
            int(np.nanargmax(np.abs(np.where(finite, r, np.nan))))
            if finite.any()
            else 0
        )
        rows.append(
            [
                name,
                sig(g.rmse_assumed[j]),
                sig(g.noise_floor[j]),
                sig(g.rmse_assumed[j] / g.noise_floor[j], 3) + "x",
                f"{signed(r[worst], 3)} at t = {sig(res.t[worst], 3)}",
            ]
        )
    converged = "" if res.assumed.fit.converged else " (its fit did NOT converge)"
    out.append(
        "Free run of the assumed model from its fitted initial state against the "
        f"data{converged}:"
    )
    out.append(
        text_table(["channel", "RMSE", "noise", "RMSE/noise", "largest error"], rows)
    )
    contradicted = res.consistency_p_value < res.alpha
    verdict = (
        "the data CONTRADICT the assumed model"
        if contradicted
        else "the data are consistent with the assumed model"
    )
    out.append(
        f"Consistency test: chi2 = {sig(res.consistency_chi2)} on "
        f"{res.consistency_dof} dof ({res.assumed.fit.n_residuals} residuals less "
        f"{res.study.n_states * res.study.n_records} initial states), "
        f"p = {p_value(res.consistency_p_value)} -> {verdict} (alpha = {res.alpha})."
    )
    ratio = ", ".join(sig(v, 4) for v in np.atleast_1d(res.mme.covariance_ratio_))
    w = np.asarray(res.mme.W_, dtype=float)
    w_text = (
        sig(float(w.ravel()[0])) if w.size == 1 else np.array2string(w, precision=4)
    )
    out.append(
        f"MME estimate of the model error d(t): W = {w_text}, "
        f"measurement-minus-estimate covariance / noise = {ratio}."
    )
    rows = [
        [name, sig(s["rms_d"]), sig(s["rms_dynamics"]), f"{sig(100 * s['share'], 3)}%"]
        for name, s in res.d_summary.items()
    ]
    out.append(text_table(["state", "rms d(t)", "rms dx/dt", "share missed"], rows))
    if res.memory:
        names = res.study.state_names
        rows = [
            [
                names[m.state],
                f"{sig(100 * max(m.r2_static, 0.0), 3)}%",
                f"{sig(100 * max(m.r2_history, 0.0), 3)}%",
                str(m.lag),
                _null_cell(m),
                "LIKELY MISSING STATE" if m.suspected else "no",
            ]
            for m in res.memory
        ]
        out.append(
            "Memory of d(t) (cross-validated share predicted by the present states "
            "and inputs, and with the states `lag` samples earlier too; where a "
            "state is suspected, what the history adds on a record simulated from "
            "the model found, which has none):"
        )
        out.append(
            text_table(
                ["state", "present", "with history", "lag", "null record", "memory"],
                rows,
            )
        )
    return out + [""]


def _terms_text(terms: dict) -> str:
    parts = []
    for k, (name, c) in enumerate(terms.items()):
        value = sig(abs(c))
        sign = "-" if c < 0 else ("+" if k else "")
        body = value + ("" if name == "1" else f" {name}")
        parts.append(f"{sign} {body}" if k else f"{sign}{body}")
    return " ".join(parts)


def _parameters(res) -> list:
    if not res.parameters:
        return []
    rows = [
        [
            name,
            sig(pe.initial),
            sig(pe.assumed_fit),
            sig(pe.value),
            f"[{sig(pe.ci_low)}, {sig(pe.ci_high)}]",
            f"{signed(100 * pe.change, 3)}%",
        ]
        for name, pe in res.parameters.items()
    ]
    gauges = [
        f"Gauge: {pe.name} = {sig(pe.initial)} is held at its guess, not fitted "
        "(fixed: the scale is not determined by the data). " + _gauge_reason(res, name)
        for name, pe in res.parameters.items()
        if pe.gauge
    ]
    return [
        "Parameters of the assumed model, fitted to the measurements (not "
        "missing effects):",
        text_table(
            [
                "parameter",
                "guess",
                "fit (assumed)",
                "fit (extended)",
                "95% CI",
                "change",
            ],
            rows,
        ),
    ] + gauges


def _gauge_reason(res, name) -> str:
    """Why ``name`` is a gauge: the trade-off it fixes, as found at the guesses."""
    for trade in getattr(res.study, "gauges", ()):
        if trade.gauge == name:
            text = str(replace(trade, gauge=""))
            return text[0].upper() + text[1:] + "."
    return ""


def _offsets(res) -> list:
    if res.offsets is None:
        return []
    fit = res.extended_fit or res.assumed.fit
    k0 = fit.n_physical + len(fit.slots)
    ci = fit.confidence_intervals()[k0:]
    parts = [
        f"{name} {signed(o)} [{signed(lo)}, {signed(hi)}]"
        for name, o, (lo, hi) in zip(res.channel_names, res.offsets, ci)
    ]
    return ["Measurement offsets (fitted, 95% CI): " + "; ".join(parts)]


def _cause(res) -> list:
    out = ["2. The cause", "-" * 12] + _parameters(res) + _offsets(res)
    contradicted = res.consistency_p_value < res.alpha
    for state, terms in res.terms.items():
        if terms:
            out.append(f"{state}' misses: {_terms_text(terms)}")
        elif contradicted and not res.found_correction:
            out.append(
                f"{state}': no library term explains the misfit - the library lacks "
                "the effect."
            )
        elif contradicted:
            out.append(f"{state}': no term kept in this equation.")
        else:
            out.append(
                f"{state}': no significant correction - the assumed equation is "
                "consistent with the data."
            )
    if res.term_estimates:
        rows = [
            [
                te.state,
                te.feature,
                signed(te.coefficient),
                f"[{signed(te.ci_low)}, {signed(te.ci_high)}]",
                sig(te.std_error, 3),
                f"{sig(100 * te.share_of_correction, 3)}%",
                f"{sig(100 * te.share_of_dynamics, 3)}%",
                signed(te.regression_coefficient),
                sig(te.partial_f),
                p_value(te.p_value),
            ]
            for te in res.term_estimates
        ]
        header = [
            "eq.",
            "term",
            "coef (fit)",
            "95% CI",
            "std err",
            "of corr.",
            "of dx/dt",
            "coef (d regr.)",
            "partial F",
            "p",
        ]
        out.append(text_table(header, rows))
        out.append(
            "(coef (fit): fitted to the measurements; 'of corr.' / 'of dx/dt': RMS "
            "size of the term over that of the correction / of the equation.)"
        )
    out += wall_lines(res)
    if res.pruned_terms:
        out.append(
            "Proposed or tried but not kept (alpha = "
            f"{res.alpha}): {'; '.join(res.pruned_terms)}."
        )
    if np.isfinite(res.correction_p_value):
        out.append(
            "F-test of the extended against the assumed model: p = "
            f"{p_value(res.correction_p_value)}."
        )
    text = optimizer_summary(res)
    if text is not None:
        out += ["", "Stepwise regression of d(t) (ANOVA per error state):"]
        out.append(str(text).rstrip())
    return out + [""]


def wall_lines(res) -> list:
    """``Wall: h1 stays at or below 14 ...`` per overflow term that ended
    on its wall limit (:attr:`Discovery.walls`)."""
    out = []
    for w in res.walls:
        routed = "; ".join(
            f"{sig(100 * f, 3)} % of the excess flows into {state} ({w['term']} "
            f"in {state}')"
            for state, f in w["routes"].items()
        )
        out.append(
            f"Wall: {w['state']} stays at or below {sig(w['level'])} ({w['term']} "
            f"in {w['state']}' is on its limit {sig(w['coefficient'])}, "
            f"{WALL_DECAY:g} over the sample interval: the excess goes within a "
            "fraction of a sample, so the data say it is a wall, not how stiff)"
            + (f"; {routed}" if routed else "; the excess leaves the system")
            + "."
            + _gauged_level(res, w["state"])
        )
    return out


def _gauged_level(res, state) -> str:
    """`` The level is in the scale ...``: where a gauge fixes the scale of the
    unmeasured ``state``, a level read on it is in that scale, not in the
    state's own units (the cascaded tanks: ``b`` held at its guess 0.05
    against the plant's 0.036 puts the rim at 10 V at 14 in the estimate)."""
    study = getattr(res, "study", None)
    trades = list(getattr(study, "gauges", ()) or ()) + list(res.trade_offs or ())
    for trade in trades:
        if getattr(trade, "gauge", "") and state in (trade.hidden_states or ()):
            return (
                f" The level is in the scale of {state} that the gauge sets "
                f"({trade.gauge} held at its guess: {state} is not measured and "
                f"its scale is not determined), not in {state}'s own units: it "
                "moves with the gauge's true value"
            ) + "."
    return ""


def optimizer_summary(res):
    """The optimizer's own summary of the regression of ``d(t)``, or None."""
    summary = getattr(res.optimizer, "summary", None)
    if not callable(summary):
        return None
    try:
        return summary(
            feature_names=res.library_feature_names,
            target_names=[res.state_names[i] for i in res.error_states],
        )
    except TypeError:
        return summary()


def _gain(res) -> list:
    out = ["4. The gain", "-" * 11]
    g = res.gain
    validation = g.validation_rmse_assumed is not None
    # "*": a model's out-of-sample run its start's estimate spreads beyond
    # the noise (explained below the table)
    spread = {m: spread_from(g, m) for m in ("assumed", "extended")}
    star = {m: "*" if when is not None else "" for m, when in spread.items()}
    # and an in-sample run that rounding sets (named below the table)
    rounded = {m: "*" if m in g.rounding_set else "" for m in ("assumed", "extended")}
    rows = []
    for j, name in enumerate(g.channel_names):
        row = [
            name,
            sig(g.rmse_assumed[j]) + rounded["assumed"],
            sig(g.rmse_extended[j]) + rounded["extended"],
            sig(g.ratio[j], 3) + "x" + ("*" if g.rounding_set else ""),
            sig(g.noise_floor[j]),
        ]
        if validation:
            row += [
                sig(g.validation_rmse_assumed[j]) + star["assumed"],
                sig(g.validation_rmse_extended[j]) + star["extended"],
                sig(g.validation_ratio[j], 3)
                + "x"
                + ("*" if any(star.values()) else ""),
            ]
        rows.append(row)
    header = ["channel", "RMSE assumed", "RMSE extended", "gain (in-sample)", "noise"]
    if validation:
        header += ["valid. assumed", "valid. extended", "valid. gain"]
    out.append("Free-run RMSE against the measurements (noise = a perfect model):")
    out.append(text_table(header, rows))
    if res.study.censored and (res.clipped or res.validation_clipped):
        out.append(
            "Clipped readings are left out of every RMSE: a reading on the sensor's "
            "limit says only that the value is at or beyond it."
        )
    if res.study.n_records > 1:
        out.append(
            f"In-sample: each model run free over each of the {res.study.n_records} "
            "records from that record's initial state of its fit to them, the RMSE "
            "pooled over the records (the extended model's terms were chosen on "
            "them)."
        )
    else:
        out.append(
            "In-sample: each model run free over this record from the initial state "
            "of its fit to it (the extended model's terms were chosen on it)."
        )
    unconverged = [name for name, ok in g.converged.items() if not ok]
    if unconverged:
        out.append(
            f"NOT CONVERGED: the fit of the {' and the '.join(unconverged)} model "
            "did not converge; its numbers are a free run of an unsettled fit."
        )
    for name, when in g.rounding_set.items():
        out.append(
            f"* SET BY ROUNDING: the {name} model's in-sample run from t = {when:.6g} "
            "on (see the notes); its RMSE and the gain over it are one run's among "
            "many the model allows within rounding, not the model's."
        )
    if validation:
        source = g.validation_source or "the validation record"
        method = g.validation_method or (
            f"initial state from its first {g.validation_window} samples, then a "
            "free run; RMSE over the rest."
        )
        out.append(f"Out of sample ('valid.'): {source}; {method}")
        for m, when in spread.items():
            if when is not None:
                out.append(
                    f"* SPREAD BY ITS START: from t = {when:.6g} on, the {m} "
                    "model's run there is spread by more than the noise by the "
                    "standard error of its initial state (carried along the run): "
                    "its RMSE there can measure that estimate as much as the model."
                )
        runs = g.validation_runs or {}
        out_run = runs.get("extended")
        uncertainty = None if out_run is None else out_run.uncertainty
        if uncertainty is not None:
            out.append(
                "Beyond the noise out of sample, the extended model: "
                f"{uncertainty.sentence()}; {uncertainty.directions} coefficient "
                "direction(s) run one standard error away, the start's (and "
                "offsets') covariance carried along."
            )
    return out


def format_discovery(res) -> str:
    out = _header(res) + _what_is_wrong(res) + _cause(res)
    out += ["3. The extended model", "-" * 21]
    for name, eq in zip(res.state_names, res.extended_model.equations()):
        out.append(f"({name})' = {eq}")
    if res.smoothing:
        out.append(f"Kinks: {res.smoothing}.")
    out.append("")
    out += _gain(res)
    if res.warnings:
        out += ["", "Warnings:"] + [f"- {w}" for w in res.warnings]
    return "\n".join(out) + "\n"


def _null_cell(m) -> str:
    """The history's gain on the null record against the data's (or ``-``)."""
    null = getattr(m, "null_gain", None)
    if null is None:
        return "-"
    return f"+{sig(100 * max(null, 0.0), 2)}% (data +{sig(100 * m.history_gain, 2)}%)"
