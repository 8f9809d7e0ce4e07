"""What every figure shares: the matplotlib import, one style per series, legends.

Each series keeps one look in every figure, so a reader learns it once:
measurements are grey dots, the truth (when known) a thin black line, the
assumed model a dashed orange line, MME's estimate a thin blue line, and the
extended model a thick green line drawn last, on top of everything else.
Legends sit outside the axes, so they never hide data.
"""

from __future__ import annotations

import os

import numpy as np

#: line / marker style of each series, shared by all figures
STYLE = {
    "measured": dict(ls="none", marker=".", ms=3.0, color="0.55", alpha=0.7, zorder=1),
    "truth": dict(color="black", lw=0.9, zorder=2),
    "assumed": dict(color="#e66100", ls=(0, (5, 2.5)), lw=1.5, zorder=3),
    "estimate": dict(color="#1f77b4", lw=1.0, alpha=0.9, zorder=4),
    "extended": dict(color="#1a9850", lw=2.4, alpha=0.7, zorder=6),
    "correction": dict(color="#1a9850", lw=2.4, alpha=0.7, zorder=6),
}

#: legend labels of the series
LABEL = {
    "measured": "measured",
    "truth": "truth",
    "assumed": "assumed model (simulated)",
    "estimate": "MME estimate",
    "extended": "extended model (simulated)",
    "correction": "identified correction",
}


def pyplot():
    """``matplotlib.pyplot``, on the Agg backend when there is no display."""
    try:
        import matplotlib

        backend = matplotlib.get_backend().lower()
        interactive = backend not in ("agg", "pdf", "svg", "ps", "cairo")
        if interactive and not os.environ.get("DISPLAY") and os.name != "nt":
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(
            "plotting needs matplotlib: pip install 'pysindy-mme[plot]'"
        ) from exc
    return plt


def legend_outside(fig_or_ax, handles=None, labels=None, **kwargs):
    """A legend to the right of the axes (or figure), outside the data area."""
    if handles is None:
        handles, labels = fig_or_ax.get_legend_handles_labels()
    unique = {}
    for h, lab in zip(handles, labels):
        unique.setdefault(lab, h)
    if not unique:
        return None
    options = dict(fontsize=8, frameon=False)
    options.update(kwargs)
    if hasattr(fig_or_ax, "add_subplot"):  # a figure or subfigure
        options.setdefault("loc", "outside right upper")
        return fig_or_ax.legend(list(unique.values()), list(unique.keys()), **options)
    return fig_or_ax.legend(
        list(unique.values()),
        list(unique.keys()),
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        borderaxespad=0.0,
        **options,
    )


def finite_range(*arrays):
    """``(lo, hi)`` over the finite values of ``arrays`` (None if there are none)."""
    values = [np.asarray(a, dtype=float).ravel() for a in arrays if a is not None]
    values = [v[np.isfinite(v)] for v in values]
    values = [v for v in values if v.size]
    if not values:
        return None
    allv = np.concatenate(values)
    return float(allv.min()), float(allv.max())


def padded(lo: float, hi: float, pad: float = 0.08):
    """``(lo, hi)`` widened by ``pad`` of the span (a unit span when flat)."""
    span = hi - lo
    if not span > 0:
        span = max(abs(hi), 1.0)
    return lo - pad * span, hi + pad * span
