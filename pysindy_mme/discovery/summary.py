"""A Discovery's numbers as tables: its summary, and data frames of them.

:func:`discovery_summary` (``Discovery.summary()``) lays the study out in
statsmodels' style (:class:`~pysindy_mme.core.tables.Summary`): the study at
a glance, the identified terms, the grey-box parameters, the gain and the
model error, each a :class:`~pysindy_mme.core.tables.SimpleTable` of values
(text with ``str``, HTML in a notebook, LaTeX), then the verdict, the
extended model and the warnings. :func:`records` gives the terms, the
parameters and the gain as one dict per row under the attribute names of
:class:`~.result.TermEstimate`, :class:`~.result.ParameterEstimate` and
:class:`~.gain.Gain` (``Discovery.to_frame`` makes a pandas frame of them).

Everything here reads the result's own attributes, never the user's model:
a result loaded from a file (:mod:`.storage`) has the same summary.
"""

from __future__ import annotations

import numpy as np

from ..core.tables import SimpleTable, Summary, p_value, sig
from .report import wall_lines

__all__ = ["discovery_summary", "records", "columns", "TABLES"]

#: what :func:`records` (and ``Discovery.to_frame``) can lay out, with the
#: columns that index each table
TABLES = {
    "terms": ["state", "feature"],
    "parameters": ["name"],
    "gain": ["channel"],
}


def _percent(value) -> str:
    return f"{sig(100 * float(value), 3)}%"


def _ratio(value) -> str:
    return f"{sig(value, 3)}x"


def _overview(res) -> SimpleTable:
    t = res.t
    study = res.study
    noise = ", ".join(sig(v, 3) for v in np.diag(res.noise_cov))
    rows = [
        ["conclusion", res.conclusion],
        ["samples", f"{t.size} over t = {sig(t[0])} .. {sig(t[-1])}"],
        ["records", study.n_records],
        ["states", ", ".join(res.state_names)],
        ["measured", ", ".join(res.channel_names)],
        ["inputs", ", ".join(res.input_names) or "none"],
        ["error states", ", ".join(res.state_names[i] for i in res.error_states)],
        ["noise variance", f"{noise} ({study.noise_description or 'stated'})"],
        ["alpha", res.alpha],
        ["consistency chi2", res.consistency_chi2],
        ["consistency dof", res.consistency_dof],
        ["consistency p", p_value(res.consistency_p_value)],
        ["terms kept", len(res.term_estimates)],
        ["correction F-test p", p_value(res.correction_p_value)],
    ]
    return SimpleTable(["quantity", "value"], rows, title="Study")


def _terms(res) -> SimpleTable:
    header = [
        "eq.",
        "term",
        "coef",
        "std err",
        "ci low",
        "ci high",
        "p",
        "of corr.",
        "of dx/dt",
        "coef (d regr.)",
        "partial F",
    ]
    rows = [
        [
            te.state,
            te.feature,
            te.coefficient,
            te.std_error,
            te.ci_low,
            te.ci_high,
            te.p_value,
            te.share_of_correction,
            te.share_of_dynamics,
            te.regression_coefficient,
            te.partial_f,
        ]
        for te in res.term_estimates
    ]
    formats = {"p": p_value, "of corr.": _percent, "of dx/dt": _percent}
    return SimpleTable(header, rows, title="Identified terms (95% CI)", formats=formats)


def _parameters(res) -> SimpleTable | None:
    if not res.parameters:
        return None
    header = [
        "parameter",
        "guess",
        "fit (assumed)",
        "fit (extended)",
        "std err",
        "ci low",
        "ci high",
        "change",
        "at bound",
    ]
    rows = [
        [
            name,
            pe.initial,
            pe.assumed_fit,
            pe.value,
            pe.std_error,
            pe.ci_low,
            pe.ci_high,
            pe.change,
            pe.at_bound,
        ]
        for name, pe in res.parameters.items()
    ]
    formats = {"change": _percent}
    return SimpleTable(
        header, rows, title="Parameters of the assumed model", formats=formats
    )


def _gain(res) -> SimpleTable:
    g = res.gain
    validation = g.validation_rmse_assumed is not None
    header = ["channel", "RMSE assumed", "RMSE extended", "gain", "noise"]
    if validation:
        header += ["valid. assumed", "valid. extended", "valid. gain"]
    rows = []
    for j, name in enumerate(g.channel_names):
        row = [
            name,
            g.rmse_assumed[j],
            g.rmse_extended[j],
            g.ratio[j],
            g.noise_floor[j],
        ]
        if validation:
            row += [
                g.validation_rmse_assumed[j],
                g.validation_rmse_extended[j],
                g.validation_ratio[j],
            ]
        rows.append(row)
    formats = {"gain": _ratio, "valid. gain": _ratio}
    return SimpleTable(header, rows, title="Gain: free-run RMSE", formats=formats)


def _model_error(res) -> SimpleTable:
    rows = [
        [name, s["rms_d"], s["rms_dynamics"], s["share"]]
        for name, s in res.d_summary.items()
    ]
    return SimpleTable(
        ["state", "rms d(t)", "rms dx/dt", "share missed"],
        rows,
        title="Model error d(t) (MME)",
        formats={"share missed": _percent},
    )


def discovery_summary(res) -> Summary:
    """The summary of a :class:`~.result.Discovery` (module docstring)."""
    tables = [_overview(res), _terms(res)]
    params = _parameters(res)
    if params is not None:
        tables.append(params)
    tables += [_gain(res), _model_error(res)]
    notes = [f"Verdict: {res.verdict}."]
    notes += [
        f"({name})' = {eq}"
        for name, eq in zip(res.state_names, res.extended_model.equations())
    ]
    notes += wall_lines(res)
    notes += [f"Warning: {w}" for w in res.warnings]
    return Summary("pysindy-mme discovery", tables, notes)


def columns(table: str) -> list:
    """The columns of :func:`records`' rows for ``table`` (also when empty)."""
    from dataclasses import fields

    from .estimates import ParameterEstimate, TermEstimate

    if table == "terms":
        return [f.name for f in fields(TermEstimate)]
    if table == "parameters":
        return [f.name for f in fields(ParameterEstimate)] + ["change"]
    if table == "gain":
        return list(_GAIN_COLUMNS)
    raise ValueError(f"table must be one of {sorted(TABLES)}, got {table!r}")


_GAIN_COLUMNS = [
    "channel",
    "rmse_assumed",
    "rmse_extended",
    "gain",
    "noise_floor",
    "validation_rmse_assumed",
    "validation_rmse_extended",
    "validation_gain",
]


def records(res, table: str) -> list:
    """``table``'s rows as dicts (``"terms"``, ``"parameters"``, ``"gain"``)."""
    if table == "terms":
        return [dict(vars(te)) for te in res.term_estimates]
    if table == "parameters":
        return [{**vars(pe), "change": pe.change} for pe in res.parameters.values()]
    if table == "gain":
        return _gain_records(res.gain)
    raise ValueError(f"table must be one of {sorted(TABLES)}, got {table!r}")


def _gain_records(g) -> list:
    validation = g.validation_rmse_assumed is not None
    out = []
    for j, name in enumerate(g.channel_names):
        row = {
            "channel": name,
            "rmse_assumed": float(g.rmse_assumed[j]),
            "rmse_extended": float(g.rmse_extended[j]),
            "gain": float(g.ratio[j]),
            "noise_floor": float(g.noise_floor[j]),
        }
        nan = float("nan")
        row["validation_rmse_assumed"] = (
            float(g.validation_rmse_assumed[j]) if validation else nan
        )
        row["validation_rmse_extended"] = (
            float(g.validation_rmse_extended[j]) if validation else nan
        )
        row["validation_gain"] = float(g.validation_ratio[j]) if validation else nan
        out.append(row)
    return out
