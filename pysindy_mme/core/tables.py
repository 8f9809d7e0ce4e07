"""The one table formatter: numbers by significant digits, text and HTML tables.

Every report of the package lays out its tables here, so numbers look the
same everywhere: significant digits (never fixed decimals, which print a
coefficient of 4e-4 as 0.000), ``n/a`` for a statistic that is not finite
or not determined, p-values that say ``< 1e-300`` instead of 0.

:class:`SimpleTable` and :class:`Summary` are the results tables in
statsmodels' style (``statsmodels.iolib``): a table keeps its values and
their formatting apart, and shows itself as text (``str``), HTML
(``as_html``, and ``_repr_html_`` for a notebook), LaTeX (``as_latex``) or a
pandas ``DataFrame`` of the values (``to_frame``); a summary is a titled
list of them with notes.
"""

from __future__ import annotations

import html

import numpy as np

__all__ = [
    "sig",
    "signed",
    "statistic",
    "p_value",
    "text_table",
    "html_table",
    "latex_escape",
    "SimpleTable",
    "Summary",
    "require_pandas",
]


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


_LATEX_SPECIAL = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
    "|": r"\textbar{}",
    "<": r"\textless{}",
    ">": r"\textgreater{}",
}


def latex_escape(text) -> str:
    """``text`` with LaTeX's special characters escaped."""
    return "".join(_LATEX_SPECIAL.get(ch, ch) for ch in str(text))


def require_pandas():
    """``pandas``, or an ImportError that says how to install it."""
    try:
        import pandas
    except ImportError as exc:
        raise ImportError(
            "data frames need pandas, an optional dependency: "
            "pip install 'pysindy-mme[pandas]'"
        ) from exc
    return pandas


class SimpleTable:
    """A table of values with a title, shown as text, HTML or LaTeX.

    Parameters
    ----------
    header : sequence of str
        Column titles.
    rows : sequence of sequences
        The values (numbers, strings, None for an empty cell).
    title : str, optional
    formats : dict, optional
        ``{column title: callable(value) -> str}``; other numbers are shown
        by :func:`sig` to four significant digits, None as an empty cell.

    Attributes
    ----------
    header, rows, title
        As given (``rows`` as lists).
    """

    def __init__(self, header, rows, title: str | None = None, formats=None):
        self.header = [str(h) for h in header]
        self.rows = [list(r) for r in rows]
        self.title = title
        self.formats = dict(formats or {})
        for r in self.rows:
            if len(r) != len(self.header):
                raise ValueError(
                    f"a row of table {title!r} has {len(r)} cells for "
                    f"{len(self.header)} columns"
                )

    def _cell(self, column: str, value) -> str:
        if value is None:
            return ""
        fmt = self.formats.get(column)
        if fmt is not None:
            return fmt(value)
        if isinstance(value, str):
            return value
        if isinstance(value, (bool, np.bool_)):
            return "yes" if value else "no"
        return sig(value)

    def cells(self) -> list:
        """The rows as formatted strings (what every view shows)."""
        return [[self._cell(h, v) for h, v in zip(self.header, r)] for r in self.rows]

    def as_text(self) -> str:
        """The title over a left-aligned text table."""
        body = text_table(self.header, self.cells(), indent="")
        if not self.title:
            return body
        width = max(len(line) for line in body.splitlines())
        return f"{self.title}\n{'=' * max(width, len(self.title))}\n{body}"

    def __str__(self) -> str:
        return self.as_text()

    def __repr__(self) -> str:
        return self.as_text()

    def __len__(self) -> int:
        return len(self.rows)

    def as_html(self) -> str:
        """An HTML ``<table class="simpletable">`` with the title as caption."""
        esc = html.escape
        out = ['<table class="simpletable">']
        if self.title:
            out.append(f"<caption>{esc(self.title)}</caption>")
        out.append(
            "<tr>" + "".join(f"<th>{esc(h)}</th>" for h in self.header) + "</tr>"
        )
        for raw, row in zip(self.rows, self.cells()):
            tds = []
            for v, text in zip(raw, row):
                number = v is not None and not isinstance(v, (str, bool, np.bool_))
                align = ' style="text-align:right"' if number else ""
                tds.append(f"<td{align}>{esc(text)}</td>")
            out.append("<tr>" + "".join(tds) + "</tr>")
        out.append("</table>")
        return "\n".join(out)

    def _repr_html_(self) -> str:
        return self.as_html()

    def as_latex(self) -> str:
        """A LaTeX ``table`` (the title as caption) around a ``tabular`` with
        booktabs rules (``\\usepackage{booktabs}``), numbers right-aligned."""
        numeric = [
            all(
                v is None or not isinstance(v, (str, bool, np.bool_))
                for v in (r[j] for r in self.rows)
            )
            and bool(self.rows)
            for j in range(len(self.header))
        ]
        spec = "".join("r" if n else "l" for n in numeric)
        out = ["\\begin{table}[ht]", "\\centering"]
        if self.title:
            out.append(f"\\caption{{{latex_escape(self.title)}}}")
        out += [
            f"\\begin{{tabular}}{{{spec}}}",
            "\\toprule",
            " & ".join(latex_escape(h) for h in self.header) + r" \\",
            "\\midrule",
        ]
        out += [" & ".join(latex_escape(c) for c in r) + r" \\" for r in self.cells()]
        out += ["\\bottomrule", "\\end{tabular}", "\\end{table}"]
        return "\n".join(out)

    def to_frame(self):
        """The values as a ``pandas.DataFrame`` (needs pandas)."""
        pd = require_pandas()
        return pd.DataFrame(self.rows, columns=self.header)


class Summary:
    """Tables and notes under a title, in statsmodels' ``Summary`` style.

    ``str(summary)`` (or :meth:`as_text`) is the text, :meth:`as_html` the
    same as HTML (what a notebook shows: ``_repr_html_``), :meth:`as_latex`
    LaTeX tabulars.

    Attributes
    ----------
    title : str
    tables : list of SimpleTable
    notes : list of str
        Lines shown after the tables.
    """

    def __init__(self, title: str, tables=(), notes=()):
        self.title = title
        self.tables = list(tables)
        self.notes = list(notes)

    def table(self, title: str) -> SimpleTable:
        """The table with this title (KeyError naming the titles if none)."""
        for t in self.tables:
            if t.title == title:
                return t
        raise KeyError(
            f"no table {title!r}; the tables are {[t.title for t in self.tables]}"
        )

    def as_text(self) -> str:
        parts = [self.title, "=" * len(self.title), ""]
        for t in self.tables:
            parts += [t.as_text(), ""]
        parts += self.notes
        return "\n".join(parts).rstrip() + "\n"

    def __str__(self) -> str:
        return self.as_text()

    def __repr__(self) -> str:
        return self.as_text()

    def as_html(self) -> str:
        esc = html.escape
        out = [f"<h4>{esc(self.title)}</h4>"]
        out += [t.as_html() for t in self.tables]
        if self.notes:
            out.append("<ul>" + "".join(f"<li>{esc(n)}</li>" for n in self.notes))
            out[-1] += "</ul>"
        return "\n".join(out)

    def _repr_html_(self) -> str:
        return self.as_html()

    def as_latex(self) -> str:
        out = [f"% {self.title}"]
        for t in self.tables:
            out += [t.as_latex(), ""]
        out += [f"% {n}" for n in self.notes]
        return "\n".join(out).rstrip() + "\n"
