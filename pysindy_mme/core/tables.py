"""The one table formatter: numbers by significant digits, text and HTML tables.

Every report of the package lays out its tables here, so numbers look the
same everywhere: significant digits (never fixed decimals, which print a
coefficient of 4e-4 as 0.000), ``n/a`` for a statistic that is not finite
or not determined, p-values that say ``< 1e-300`` instead of 0.
"""

from __future__ import annotations

import html

import numpy as np

__all__ = ["sig", "signed", "statistic", "p_value", "text_table", "html_table"]


def sig(value, digits: int = 4) -> str:
    """``value`` to ``digits`` significant digits; ``n/a`` if not finite."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    if not np.isfinite(v):
        return "n/a"
    if v == 0:
        return "0"
    return f"{v:.{digits}g}"


def signed(value, digits: int = 4) -> str:
    """Like :func:`sig` with an explicit sign (``+0.5``, ``-3.2e-05``)."""
    text = sig(value, digits)
    return text if text in ("n/a", "0") or text.startswith("-") else "+" + text


def statistic(value) -> str:
    """A table entry of the paper's Table II style: whole numbers (degrees of
    freedom, counts) as integers, others to five significant digits, exponent
    form beyond ``1e6`` and below ``1e-3``; ``n/a`` if not finite."""
    v = float(value)
    if not np.isfinite(v):
        return "n/a"
    if v == int(v) and abs(v) < 1e7:
        return str(int(v))
    if v != 0 and (abs(v) >= 1e6 or abs(v) < 1e-3):
        return f"{v:.4g}"
    return f"{v:.5g}"


def p_value(p) -> str:
    """A p-value: ``n/a``, ``< 1e-300`` or two significant digits."""
    try:
        p = float(p)
    except (TypeError, ValueError):
        return "n/a"
    if not np.isfinite(p):
        return "n/a"
    if p <= 1e-300:
        return "< 1e-300"
    return f"{p:.2g}"


def text_table(header, rows, indent: str = "  ") -> str:
    """Left-aligned text table of already formatted cells."""
    cells = [list(map(str, header))] + [list(map(str, r)) for r in rows]
    widths = [max(len(row[j]) for row in cells) for j in range(len(header))]
    lines = []
    for k, row in enumerate(cells):
        lines.append(indent + "  ".join(c.ljust(w) for c, w in zip(row, widths)))
        if k == 0:
            lines.append(indent + "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def html_table(header, rows, caption: str | None = None, number=None) -> str:
    """An HTML table; numbers (not strings) right-aligned, formatted by
    ``number`` (default: :func:`sig` to five digits); ``None`` cells empty."""
    number = number or (lambda v: sig(v, 5))
    esc = html.escape
    out = ['<table class="simpletable">']
    if caption:
        out.append(f"<caption>{esc(caption)}</caption>")
    out.append("<tr>" + "".join(f"<th>{esc(str(h))}</th>" for h in header) + "</tr>")
    for row in rows:
        cells = []
        for v in row:
            if v is None:
                cells.append("<td></td>")
            elif isinstance(v, str):
                cells.append(f"<td>{esc(v)}</td>")
            else:
                cells.append(f'<td style="text-align:right">{number(v)}</td>')
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)
