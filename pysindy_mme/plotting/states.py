"""The states: measurements, MME estimate, assumed and extended simulations.

One panel per state. The extended model is drawn last and thickest, so the
answer of the study is the line on top; the assumed model is dashed. The
vertical range follows the data and the estimates: an assumed model that
runs far away is clipped (its label says so) instead of squashing the rest.
"""

from __future__ import annotations

import numpy as np

from ._base import LABEL, STYLE, finite_range, padded

__all__ = ["plot_states"]


def _measured_column(res, i):
    """Column of ``res.y`` that measures state ``i`` directly, or None."""
    measured = res.measured
    if measured is None:
        return None
    measured = [int(k) for k in measured]
    return measured.index(i) if i in measured else None


def plot_states(res, axes, x_true=None):
    """One panel per state of a :class:`~pysindy_mme.Discovery`.

    Parameters
    ----------
    res : Discovery
    axes : sequence of matplotlib Axes, one per state
    x_true : ndarray (n_samples, n_states), optional
        Noise-free states, drawn when known (simulated data).

    With fitted measurement offsets (``discover(..., offsets=True)``) the
    measurements are drawn with their offset removed, on the states' scale.
    """
    t = res.t
    x_hat = np.asarray(res.mme.smoothed_x_, dtype=float)
    x_ext = np.asarray(res.extended_simulation, dtype=float)
    x_ass = np.asarray(res.assumed_simulation, dtype=float)
    same = x_ext is x_ass or np.array_equal(x_ext, x_ass, equal_nan=True)
    offsets = getattr(res, "offsets", None)
    for i, ax in enumerate(axes):
        name = res.state_names[i]
        j = _measured_column(res, i)
        y = None if j is None else res.y[:, j]
        label = LABEL["measured"]
        if y is not None and offsets is not None:  # the states, not the sensors
            y = y - offsets[j]
            label = "measured - fitted offset"
        truth = None if x_true is None else np.asarray(x_true)[:, i]
        if y is not None:
            ax.plot(t, y, label=label, **STYLE["measured"])
        if truth is not None:
            ax.plot(t, truth, label=LABEL["truth"], **STYLE["truth"])
        ax.plot(t, x_hat[:, i], label=LABEL["estimate"], **STYLE["estimate"])
        rng = finite_range(y, truth, x_hat[:, i], x_ext[:, i])
        lo, hi = padded(*rng) if rng else (-1.0, 1.0)
        a = x_ass[:, i]
        clipped = bool(np.any(np.isfinite(a) & ((a < lo) | (a > hi))))
        label = LABEL["assumed"] + (" - leaves the range" if clipped else "")
        ax.plot(t, a, label=label, **STYLE["assumed"])
        if not same:
            ax.plot(t, x_ext[:, i], label=LABEL["extended"], **STYLE["extended"])
        ax.set_ylim(lo, hi)
        ax.set_xlim(t[0], t[-1])
        ax.set_ylabel(name)
        seen = "measured" if j is not None else "not measured"
        ax.set_title(f"{name} ({seen})", fontsize=9, loc="left")
        ax.grid(alpha=0.25, lw=0.5)
    if same and len(axes):
        axes[0].text(
            0.99,
            0.02,
            "no correction found: the extended model is the assumed one",
            transform=axes[0].transAxes,
            ha="right",
            va="bottom",
            fontsize=8,
        )
    if len(axes):
        axes[-1].set_xlabel("t")
