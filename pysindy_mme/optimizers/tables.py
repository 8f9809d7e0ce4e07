"""Text and HTML layout of the optimizer's tables (ANOVA, step history).

Formatting only: the numbers come from :class:`~.anova.AnovaTable` and
:class:`~.selection.Step`. Text is laid out like the paper's Table II; HTML
carries the same rows for notebooks. (To be merged into the package's one
table formatter, ``pysindy_mme/core/tables.py``.)
"""

from __future__ import annotations

import html

import numpy as np

__all__ = [
    "anova_html",
    "anova_text",
    "format_number",
    "steps_html",
    "steps_text",
]


def format_number(v) -> str:
    """Four significant digits, switching to exponent form for extremes."""
    v = float(v)
    if not np.isfinite(v):
        return str(v)
    if v == int(v) and abs(v) < 1e7:
        return str(int(v))
    if v != 0 and (abs(v) >= 1e6 or abs(v) < 1e-3):
        return f"{v:.4g}"
    return f"{v:.5g}"


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
    return lines


def _in_model_rows(table, name):
    rows = [
        (name(j), c, se, f, p)
        for j, c, se, f, p in zip(
            table.features,
            table.coefficients,
            table.std_errors,
            table.partial_f,
            table.p_values,
            strict=True,
        )
    ]
    if table.has_intercept:
        rows.append(
            (
                "(intercept)",
                table.intercept,
                table.intercept_std_error,
                table.intercept_partial_f,
                table.intercept_p_value,
            )
        )
    return rows


def _out_rows(table, name):
    return [
        (name(j), f, p)
        for j, f, p in zip(
            table.out_features, table.out_partial_f, table.out_p_values, strict=True
        )
    ]


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
        f"{'partial F':>12}{'p-value':>12}",
    ]
    for label, c, se, f, p in _in_model_rows(table, name):
        lines.append(f"  {label:<20}{_num(c, 14)}{_num(se)}{_num(f)}{_num(p)}")
    if not table.features and not table.has_intercept:
        lines.append("  (none)")
    lines += ["", "  Functions not in the model (strongest)"]
    out = _out_rows(table, name)
    if out:
        lines.append(f"  {'function':<20}{'partial F':>14}{'p-value':>12}")
        lines += [f"  {label:<20}{_num(f, 14)}{_num(p)}" for label, f, p in out]
    else:
        lines.append("  (none assessed)")
    return "\n".join(lines)


def _html_table(header, rows, caption=None) -> str:
    esc = html.escape
    out = ['<table class="simpletable">']
    if caption:
        out.append(f"<caption>{esc(caption)}</caption>")
    out.append("<tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr>")
    for row in rows:
        cells = []
        for v in row:
            if v is None:
                cells.append("<td></td>")
            elif isinstance(v, str):
                cells.append(f"<td>{esc(v)}</td>")
            else:
                cells.append(f'<td style="text-align:right">{format_number(v)}</td>')
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


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
    parts.append(
        _html_table(
            ["function", "coefficient", "std error", "partial F", "p-value"],
            _in_model_rows(table, name),
            caption="Functions in the model",
        )
    )
    out = _out_rows(table, name)
    parts.append(
        _html_table(
            ["function", "partial F", "p-value"],
            out if out else [("(none assessed)", None, None)],
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
