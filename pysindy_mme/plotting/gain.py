"""The gain at a glance: simulation RMSE per channel, assumed vs extended.

For each measured channel, two pairs of bars on a log scale - the fitting
record (in-sample) and, when a validation record was given, the validation
record (free run) - with the noise floor (what a perfect model reaches) as
a black line across them and the gain written above each pair. A model
without a finite RMSE (its free run diverged) gets a hatched bar marked
"diverged" instead of a number.
"""

from __future__ import annotations

import numpy as np

from ..core.tables import sig
from ._base import STYLE

__all__ = ["plot_gain", "gain_table"]


def gain_table(gain) -> list:
    """``[(channel, record, rmse_assumed, rmse_extended, noise)]`` rows."""
    rows = []
    for j, name in enumerate(gain.channel_names):
        noise = float(gain.noise_floor[j])
        rows.append(
            (name, "in-sample", gain.rmse_assumed[j], gain.rmse_extended[j], noise)
        )
        if gain.validation_rmse_assumed is not None:
            rows.append(
                (
                    name,
                    "validation",
                    gain.validation_rmse_assumed[j],
                    gain.validation_rmse_extended[j],
                    noise,
                )
            )
    return rows


def _bar(ax, x, value, top, style, label):
    """One bar; a hatched full-height bar marked 'diverged' if not finite."""
    value = float(value)
    if np.isfinite(value):
        ax.bar(x, value, width=0.36, color=style["color"], label=label, zorder=3)
        ax.text(x, value * 1.08, sig(value, 3), ha="center", va="bottom", fontsize=7)
    else:
        ax.bar(
            x,
            top,
            width=0.36,
            color="white",
            edgecolor=style["color"],
            hatch="///",
            label=label,
            zorder=3,
        )
        ax.text(x, top / 3, "diverged", rotation=90, ha="center", fontsize=7)


def plot_gain(res_or_gain, ax):
    """Bar chart of the gain (a :class:`Discovery` or its ``gain``)."""
    gain = getattr(res_or_gain, "gain", res_or_gain)
    rows = gain_table(gain)
    values = np.array([[r[2], r[3], r[4]] for r in rows], dtype=float)
    finite = values[np.isfinite(values) & (values > 0)]
    lo = float(finite.min()) if finite.size else 1e-3
    hi = float(finite.max()) if finite.size else 1.0
    top = hi * 6.0
    labels = []
    for k, (name, record, ra, re, noise) in enumerate(rows):
        _bar(ax, k - 0.19, ra, top, STYLE["assumed"], "assumed model")
        _bar(ax, k + 0.19, re, top, STYLE["extended"], "extended model")
        ax.hlines(
            noise,
            k - 0.45,
            k + 0.45,
            color="black",
            lw=1.6,
            zorder=4,
            label="noise floor (a perfect model)",
        )
        ratio = float(ra) / float(re) if np.isfinite(ra) and np.isfinite(re) else np.nan
        text = f"gain {sig(ratio, 3)}x" if np.isfinite(ratio) else "gain n/a"
        ax.text(
            k, top * 1.15, text, ha="center", va="bottom", fontsize=9, fontweight="bold"
        )
        labels.append(f"{name}\n{record}")
    ax.set_yscale("log")
    ax.set_ylim(lo / 3.0, top * 3.0)
    ax.set_xticks(range(len(rows)), labels, fontsize=8)
    ax.set_xlim(-0.6, len(rows) - 0.4)
    ax.set_ylabel("simulation RMSE")
    window = gain.validation_window
    method = getattr(gain, "validation_method", None) or (
        f"initial state from the first {window} samples, then a free run"
    )
    ax.set_xlabel(
        f"in-sample: each model fitted to this record; validation: {method}"
        if gain.validation_rmse_assumed is not None
        else "in-sample: each model fitted to this record (no validation record given)",
        fontsize=8,
    )
    ax.set_title(
        "Gain: simulation RMSE against the measurements (lower is better)",
        fontsize=10,
        loc="left",
    )
    ax.grid(axis="y", alpha=0.25, lw=0.5, which="both")
