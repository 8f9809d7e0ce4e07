"""Text and HTML layout of the optimizer's tables (ANOVA, step history).

Formatting only: the numbers come from :class:`~.anova.AnovaTable` and
:class:`~.selection.Step`. Text is laid out like the paper's Table II; HTML
carries the same rows for notebooks. Numbers and HTML come from the
package's one formatter, ``pysindy_mme/core/tables.py``; only the layout of
these particular tables lives here.
"""

from __future__ import annotations

import html

import numpy as np

from ..core.tables import html_table, statistic

__all__ = [
    "anova_html",
    "anova_text",
    "format_number",
    "steps_html",
    "steps_text",
]


def format_number(v) -> str:
    """Table II style numbers (:func:`pysindy_mme.core.tables.statistic`);
    ``inf`` (an exact fit's F) as itself, NaN (not defined) as ``n/a``."""
    v = float(v)
    if np.isnan(v):
        return "n/a"
    return str(v) if not np.isfinite(v) else statistic(v)


def _namer(feature_names):
    def name(j):
        if feature_names is not None and j < len(feature_names):
            return str(feature_names[j])
        return f"f{j}"

    return name


def _num(v, width=12):
    return f"{format_number(v):>{width}}"


def _anova_rows(table):
    """(source, dof, SS, MS, F, p) rows of the analysis of variance."""
    return [
        (
            "Due to regression",
            table.dof_regression,
            table.ss_regression,
            table.ms_regression,
            table.f_ratio,
            table.p_value,
        ),
        (
            "Deviation about regression",
            table.dof_residual,
            table.ss_residual,
            table.ms_residual,
            None,
            None,
        ),
        ("Total", table.dof_total, table.ss_total, None, None, None),
    ]


def _header_lines(table):
    lines = [
        ("Coefficient of determination", format_number(table.r2)),
        ("Multiple corr. coefficient", format_number(table.multiple_r)),
        ("Variance of estimate", format_number(table.variance_of_estimate)),
        ("Std error of estimate", format_number(table.std_error_of_estimate)),
    ]
    if table.has_intercept:
        lines.append(("Intercept", format_number(table.intercept)))
    else:
        lines.append(("Intercept", "none (through the origin)"))
    if table.robust:
        lines += [
            ("Residual lag-1 autocorr.", format_number(table.lag1_autocorrelation)),
            ("Effective observations", format_number(round(table.effective_n, 1))),
            ("Newey-West lags", str(table.hac_lags)),
            ("Candidates (Bonferroni)", str(table.n_candidates)),
        ]
    return lines


def _in_model_rows(table, name):
    """(name, coefficient, std error, partial F, p[, robust F, adjusted p]) rows."""
    cols = [table.coefficients, table.std_errors, table.partial_f, table.p_values]
    if table.robust:
        cols += [table.robust_partial_f, table.adjusted_p_values]
    rows = [(name(j),) + tuple(v) for j, *v in zip(table.features, *cols, strict=True)]
    if table.has_intercept:
        row = (
            "(intercept)",
            table.intercept,
            table.intercept_std_error,
            table.intercept_partial_f,
            table.intercept_p_value,
        )
        if table.robust:
            # The constant is one prespecified test: no Bonferroni factor.
            row += (table.intercept_robust_partial_f, None)
        rows.append(row)
    return rows


def _out_rows(table, name):
    """(name, partial F, p[, robust F, adjusted p]) rows."""
    cols = [table.out_partial_f, table.out_p_values]
    if table.robust:
        cols += [table.out_robust_partial_f, table.out_adjusted_p_values]
    return [
        (name(j),) + tuple(v) for j, *v in zip(table.out_features, *cols, strict=True)
    ]


def _robust_header(table) -> str:
    return f"{'robust F':>12}{'adj. p':>12}" if table.robust else ""


def _cells(values, width=12) -> str:
    return "".join(" " * width if v is None else _num(v, width) for v in values)


def anova_text(table, feature_names=None, title=None) -> str:
    """An :class:`~.anova.AnovaTable` as text, laid out like the paper's Table II."""
    name = _namer(feature_names)
    lines = [] if title is None else [title]
    lines += [f"  {label:<30}{value}" for label, value in _header_lines(table)]
    lines += [
        "",
        f"  {'Source of variation':<26}{'dof':>8}{'SS':>12}{'MS':>12}"
        f"{'F-ratio':>12}{'p-value':>12}",
    ]
    for source, dof, ss, ms, f, p in _anova_rows(table):
        cells = "".join(_num(v) for v in (ss, ms, f, p) if v is not None)
        lines.append(f"  {source:<26}{format_number(dof):>8}{cells}")
    lines += [
        "",
        "  Functions in the model",
        f"  {'function':<20}{'coefficient':>14}{'std error':>12}"
        f"{'partial F':>12}{'p-value':>12}{_robust_header(table)}",
    ]
    for label, c, *rest in _in_model_rows(table, name):
        lines.append(f"  {label:<20}{_num(c, 14)}{_cells(rest)}".rstrip())
    if not table.features and not table.has_intercept:
        lines.append("  (none)")
    lines += ["", "  Functions not in the model (strongest)"]
    out = _out_rows(table, name)
    if out:
        lines.append(
            f"  {'function':<20}{'partial F':>14}{'p-value':>12}{_robust_header(table)}"
        )
        lines += [
            f"  {label:<20}{_num(f, 14)}{_cells(rest)}" for label, f, *rest in out
        ]
    else:
        lines.append("  (none assessed)")
    return "\n".join(lines)


def _html_table(header, rows, caption=None) -> str:
    return html_table(header, rows, caption, number=format_number)


def anova_html(table, feature_names=None, title=None) -> str:
    """The same tables as :func:`anova_text`, as HTML."""
    name = _namer(feature_names)
    parts = [] if title is None else [f"<h4>{html.escape(title)}</h4>"]
    parts.append(_html_table(["", ""], _header_lines(table)))
    parts.append(
        _html_table(
            ["Source of variation", "dof", "SS", "MS", "F-ratio", "p-value"],
            _anova_rows(table),
        )
    )
    robust = ["robust F", "adj. p"] if table.robust else []
    parts.append(
        _html_table(
            ["function", "coefficient", "std error", "partial F", "p-value"] + robust,
            _in_model_rows(table, name),
            caption="Functions in the model",
        )
    )
    out = _out_rows(table, name)
    header = ["function", "partial F", "p-value"] + robust
    parts.append(
        _html_table(
            header,
            out if out else [("(none assessed)",) + (None,) * (len(header) - 1)],
            caption="Functions not in the model (strongest)",
        )
    )
    return "\n".join(parts)


def _step_rows(steps, name):
    return [
        (
            s.iteration,
            s.phase,
            s.action,
            name(s.feature),
            s.partial_f,
            s.threshold,
            s.n_terms,
        )
        for s in steps
    ]


def steps_text(steps, feature_names=None) -> list:
    """Lines of the step history (indented by two spaces)."""
    name = _namer(feature_names)
    lines = ["  Step history"]
    if not steps:
        return lines + ["  (no function entered)"]
    lines.append(
        f"  {'iter':>4} {'phase':>5} {'action':<7}{'function':<20}"
        f"{'partial F':>12}{'threshold':>12}{'terms':>7}"
    )
    for it, phase, action, label, f, thr, terms in _step_rows(steps, name):
        lines.append(
            f"  {it:>4} {phase:>5} {action:<7}{label:<20}{f:>12.5g}{thr:>12.5g}"
            f"{terms:>7}"
        )
    return lines


def steps_html(steps, feature_names=None) -> str:
    """The step history as an HTML table."""
    name = _namer(feature_names)
    rows = [
        (str(it), str(phase), action, label, f, thr, str(terms))
        for it, phase, action, label, f, thr, terms in _step_rows(steps, name)
    ]
    return _html_table(
        ["iter", "phase", "action", "function", "partial F", "threshold", "terms"],
        rows if rows else [("(no function entered)",) + (None,) * 6],
        caption="Step history",
    )
