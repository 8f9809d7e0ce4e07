"""The stepwise history, one row per step (after the paper's Fig. 4).

Each step of :class:`FloatingFStepwise` is one row, read top to bottom:
its label on the left ("3. add x1^2 x2"), its partial F as a marker (an
up-triangle for an addition, a down-triangle for a removal) on a log
scale, and the threshold it was tested against as a black tick. Rows of
Phase II (the floating threshold) are shaded. One row per step means the
labels never overlap, however many steps there are.
"""

from __future__ import annotations

import textwrap

import numpy as np

__all__ = ["plot_stepwise_history", "history_rows", "MAX_ROWS"]

#: steps drawn per error state; longer histories show their first rows
MAX_ROWS = 60

_MARK = {
    "add": dict(marker="^", color="#1a9850", label="term added (partial F)"),
    "remove": dict(marker="v", color="#d73027", label="term removed (partial F)"),
}


def history_rows(res) -> list:
    """``[(target name, steps)]`` for every error state the optimizer fitted."""
    steps_per_target = getattr(res.optimizer, "steps_", None) or []
    rows = []
    for k, steps in enumerate(steps_per_target):
        if k < len(res.error_states):
            rows.append((res.state_names[res.error_states[k]], list(steps)))
    return rows


def _name(res, step):
    names = res.library_feature_names
    if 0 <= step.feature < len(names):
        return names[step.feature]
    return getattr(step, "name", f"f{step.feature}")


def _final_terms(res, steps) -> list:
    """Names of the terms in the model after the last step, in order of entry."""
    model = []
    for s in steps:
        name = _name(res, s)
        if s.action == "add" and name not in model:
            model.append(name)
        elif s.action == "remove" and name in model:
            model.remove(name)
    return model


def _final_text(terms, limit=10, width=72) -> str:
    """The final model for the title: at most ``limit`` names, wrapped."""
    if not terms:
        return "no term"
    text = ", ".join(terms[:limit])
    if len(terms) > limit:
        text += f" and {len(terms) - limit} more"
    return textwrap.fill(text, width)


def plot_stepwise_history(res, ax, target=None):
    """Draw the steps of one error state (``target``, default the first).

    Parameters
    ----------
    res : Discovery
    ax : matplotlib Axes
    target : str, optional
        Name of the error state; default the first with a history.
    """
    rows = history_rows(res)
    if target is not None:
        rows = [r for r in rows if r[0] == target]
    rows = [r for r in rows if r[1]]
    if not rows:
        ax.text(
            0.5,
            0.5,
            "no stepwise history (the optimizer is not "
            "FloatingFStepwise, or it took no step)",
            ha="center",
            va="center",
            transform=ax.transAxes,
            fontsize=9,
        )
        ax.set_axis_off()
        return
    name, steps = rows[0]
    shown = steps[:MAX_ROWS]
    y = np.arange(len(shown))
    f = np.array([s.partial_f for s in shown], dtype=float)
    thr = np.array([s.threshold for s in shown], dtype=float)
    for k, s in enumerate(shown):
        if s.phase == 2:
            ax.axhspan(k - 0.5, k + 0.5, color="0.92", zorder=0, lw=0)
    for action, style in _MARK.items():
        sel = np.array([s.action == action for s in shown])
        if np.any(sel):
            ax.scatter(f[sel], y[sel], s=42, zorder=3, **style)
    ax.scatter(
        thr,
        y,
        marker="|",
        s=160,
        color="black",
        lw=1.5,
        zorder=2,
        label="threshold of the step",
    )
    ax.hlines(y, np.minimum(f, thr), np.maximum(f, thr), color="0.6", lw=0.8, zorder=1)
    labels = [f"{s.iteration}. {s.action} {_name(res, s)}" for s in shown]
    ax.set_yticks(y, labels, fontsize=8)
    ax.set_ylim(len(shown) - 0.5, -0.5)
    ax.set_xscale("log")
    ax.set_xlabel("partial F (log scale)")
    more = f"; first {MAX_ROWS} of {len(steps)} steps" if len(steps) > MAX_ROWS else ""
    phase2 = any(s.phase == 2 for s in shown)
    shade = "; shaded: Phase II (floating threshold)" if phase2 else ""
    final = _final_text(_final_terms(res, steps))
    ax.set_title(
        f"stepwise regression of d in {name}'{shade}{more}\nfinal model: {final}",
        fontsize=9,
        loc="left",
    )
    ax.grid(axis="x", alpha=0.25, lw=0.5, which="both")
