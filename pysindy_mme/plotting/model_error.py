"""The model error ``d(t)`` MME estimated, and the correction that explains it.

One panel per error state. The identified correction (the extended model's
extra terms, evaluated along its own fitted trajectory) is the thick green
line on top; MME's ``d(t)`` is thinner, and the true model error is drawn
when known.
"""

from __future__ import annotations

import numpy as np

from ._base import LABEL, STYLE, finite_range, padded

__all__ = ["plot_model_error", "identified_correction"]


def identified_correction(res) -> np.ndarray:
    """The extended model's correction along its fitted trajectory.

    Falls back to MME's state estimate when no extended fit exists (then the
    correction is zero anyway).
    """
    return np.asarray(res.extended_correction, dtype=float)


def plot_model_error(res, axes, d_true=None):
    """One panel per error state: MME's ``d(t)`` and the identified correction.

    Parameters
    ----------
    res : Discovery
    axes : sequence of matplotlib Axes, one per error state
    d_true : ndarray (n_samples, n_states), optional
        The true model error, drawn when known.
    """
    t = res.t
    d_hat = np.asarray(res.mme.d_, dtype=float)
    corr = identified_correction(res)
    for ax, i in zip(axes, res.error_states):
        name = res.state_names[i]
        truth = None if d_true is None else np.asarray(d_true)[:, i]
        if truth is not None:
            ax.plot(t, truth, label="true model error", **STYLE["truth"])
        ax.plot(t, d_hat[:, i], label="MME estimate d(t)", **STYLE["estimate"])
        found = bool(np.any(corr[:, i] != 0))
        if found:
            ax.plot(t, corr[:, i], label=LABEL["correction"], **STYLE["correction"])
        ax.axhline(0.0, color="0.6", lw=0.6, zorder=0)
        rng = finite_range(d_hat[:, i], truth, corr[:, i])
        if rng:
            ax.set_ylim(*padded(*rng))
        ax.set_xlim(t[0], t[-1])
        ax.set_ylabel(f"d in {name}'")
        terms = res.terms.get(name, {})
        what = f"{len(terms)} term(s) found" if terms else "no term found"
        ax.set_title(f"model error in {name}' ({what})", fontsize=9, loc="left")
        ax.grid(alpha=0.25, lw=0.5)
    if len(axes):
        axes[-1].set_xlabel("t")
