"""Whole figures of a study: one per view, or all views in one.

:func:`save_figures` writes the four PNGs the command line leaves in its
output folder (``states.png``, ``model_error.png``, ``gain.png``,
``stepwise_history.png``); :func:`plot_discovery` (``Discovery.plot``)
draws every view in one figure.
"""

from __future__ import annotations

from pathlib import Path

from ._base import legend_outside, pyplot
from .gain import gain_table, plot_gain
from .history import MAX_ROWS, history_rows, plot_stepwise_history
from .model_error import plot_model_error
from .states import plot_states

__all__ = [
    "states_figure",
    "model_error_figure",
    "gain_figure",
    "history_figure",
    "plot_discovery",
    "save_figures",
]

WIDTH = 10.0  # inches, every figure


def _history_height(res) -> list:
    """Inches per history panel: one row per step (at most MAX_ROWS)."""
    rows = [r for r in history_rows(res) if r[1]] or [("", [])]
    return [0.9 + 0.24 * min(len(steps), MAX_ROWS) for _, steps in rows]


def states_figure(res, x_true=None):
    """Measurements, MME estimate, assumed and extended simulations."""
    plt = pyplot()
    n = len(res.state_names)
    fig, axes = plt.subplots(
        n,
        1,
        figsize=(WIDTH, 2.2 * n + 0.9),
        sharex=True,
        squeeze=False,
        layout="constrained",
    )
    plot_states(res, axes[:, 0], x_true=x_true)
    legend_outside(fig, *axes[0, 0].get_legend_handles_labels())
    fig.suptitle("States: the measurements and both models' simulations", fontsize=11)
    return fig


def model_error_figure(res, d_true=None):
    """MME's ``d(t)`` and the identified correction, per error state."""
    plt = pyplot()
    q = len(res.error_states)
    fig, axes = plt.subplots(
        q,
        1,
        figsize=(WIDTH, 2.3 * q + 0.9),
        sharex=True,
        squeeze=False,
        layout="constrained",
    )
    plot_model_error(res, axes[:, 0], d_true=d_true)
    handles, labels = [], []
    for ax in axes[:, 0]:
        h, lab = ax.get_legend_handles_labels()
        handles += h
        labels += lab
    legend_outside(fig, handles, labels)
    fig.suptitle(
        "What the assumed model misses: d(t) and the correction found", fontsize=11
    )
    return fig


def gain_figure(res):
    """The gain panel (simulation RMSE, assumed vs extended vs noise)."""
    plt = pyplot()
    n_rows = len(gain_table(res.gain))
    fig, ax = plt.subplots(
        figsize=(max(8.5, 1.6 * n_rows + 5.0), 4.6), layout="constrained"
    )
    plot_gain(res, ax)
    handles, labels = ax.get_legend_handles_labels()
    legend_outside(fig, handles, labels, loc="outside lower center", ncol=3)
    return fig


def history_figure(res):
    """The stepwise history, one panel per error state."""
    plt = pyplot()
    heights = _history_height(res)
    targets = [name for name, steps in history_rows(res) if steps] or [None]
    fig, axes = plt.subplots(
        len(heights),
        1,
        figsize=(WIDTH, sum(heights) + 0.3),
        squeeze=False,
        height_ratios=heights,
        layout="constrained",
    )
    handles, labels = [], []
    for ax, target in zip(axes[:, 0], targets):
        plot_stepwise_history(res, ax, target=target)
        h, lab = ax.get_legend_handles_labels()
        handles += h
        labels += lab
    legend_outside(fig, handles, labels)
    return fig


def plot_discovery(res, x_true=None, d_true=None, path=None):
    """Every view of the study in one figure; saved to ``path`` when given.

    Parameters
    ----------
    res : Discovery
    x_true, d_true : ndarray (n_samples, n_states), optional
        True states and model error, drawn when known.
    path : str or Path, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = pyplot()
    n, q = len(res.state_names), len(res.error_states)
    hist = _history_height(res)
    heights = [2.2 * n + 0.5, 2.2 * q + 0.5, 3.4, sum(hist) + 0.3]
    fig = plt.figure(figsize=(WIDTH, sum(heights)), layout="constrained")
    parts = fig.subfigures(4, 1, height_ratios=heights)
    axes = parts[0].subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    plot_states(res, axes, x_true=x_true)
    legend_outside(parts[0], *axes[0].get_legend_handles_labels())
    axes = parts[1].subplots(q, 1, sharex=True, squeeze=False)[:, 0]
    plot_model_error(res, axes, d_true=d_true)
    legend_outside(parts[1], *axes[0].get_legend_handles_labels())
    ax = parts[2].subplots()
    plot_gain(res, ax)
    legend_outside(parts[2], *ax.get_legend_handles_labels())
    targets = [name for name, steps in history_rows(res) if steps] or [None]
    axes = parts[3].subplots(len(hist), 1, squeeze=False, height_ratios=hist)[:, 0]
    for ax, target in zip(axes, targets):
        plot_stepwise_history(res, ax, target=target)
    legend_outside(parts[3], *axes[0].get_legend_handles_labels())
    fig.suptitle("pysindy-mme: what the assumed model gets wrong, the fix, the gain")
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig


def save_figures(res, out, x_true=None, d_true=None, dpi=110) -> list:
    """Write the four figures of a study into the folder ``out``.

    Returns
    -------
    list of Path
        ``states.png``, ``model_error.png``, ``gain.png``,
        ``stepwise_history.png``.
    """
    plt = pyplot()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    figures = {
        "states.png": lambda: states_figure(res, x_true),
        "model_error.png": lambda: model_error_figure(res, d_true),
        "gain.png": lambda: gain_figure(res),
        "stepwise_history.png": lambda: history_figure(res),
    }
    written = []
    for name, make in figures.items():
        fig = make()
        fig.savefig(out / name, dpi=dpi)
        plt.close(fig)
        written.append(out / name)
    return written
