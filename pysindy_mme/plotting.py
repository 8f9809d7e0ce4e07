"""Figures of a discovery study (matplotlib is an optional dependency).

Three views, after the paper's Figs. 2-4: the states (measurements, MME
estimate, assumed and extended simulations), the model error ``d(t)`` against
the identified correction, and the stepwise history of partial F-ratios.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "plot_discovery",
    "plot_states",
    "plot_model_error",
    "plot_stepwise_history",
]


def _pyplot():
    try:
        import matplotlib

        if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "ps"):
            import os

            if not os.environ.get("DISPLAY"):
                matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(
            "plotting needs matplotlib: pip install 'pysindy-mme[plot]'"
        ) from exc
    return plt


def plot_states(res, axes, x_true=None):
    """One panel per state: data, MME estimate, assumed and extended simulations."""
    t = res.t
    x_hat = np.asarray(res.mme.smoothed_x_)
    for i, ax in enumerate(axes):
        name = res.state_names[i]
        if i in list(res.measured):
            j = list(res.measured).index(i)
            ax.plot(t, res.y[:, j], ".", ms=2.5, color="0.6", label="measured")
        if x_true is not None:
            ax.plot(t, x_true[:, i], color="k", lw=1.0, label="truth")
        ax.plot(
            t,
            res.assumed_simulation[:, i],
            "--",
            color="tab:red",
            lw=1.2,
            label="assumed model",
        )
        ax.plot(t, x_hat[:, i], color="tab:blue", lw=1.2, label="MME estimate")
        ax.plot(
            t,
            res.extended_simulation[:, i],
            ":",
            color="tab:green",
            lw=1.8,
            label="extended model",
        )
        state = "measured" if i in list(res.measured) else "not measured"
        ax.set_ylabel(name)
        ax.set_title(f"{name} ({state})", fontsize=9, loc="left")
        finite = x_hat[:, i][np.isfinite(x_hat[:, i])]
        if finite.size:
            lo, hi = finite.min(), finite.max()
            pad = 0.6 * (hi - lo + 1e-12)
            ax.set_ylim(lo - pad, hi + pad)
    axes[0].legend(fontsize=7, ncol=5, loc="upper right")
    axes[-1].set_xlabel("t")


def plot_model_error(res, axes, d_true=None):
    """One panel per error state: MME ``d(t)`` and the identified correction."""
    t = res.t
    x_hat = np.asarray(res.mme.smoothed_x_)
    d_hat = np.asarray(res.mme.d_)
    corr = res.extended_model.correction(x_hat, res.u)
    for ax, i in zip(axes, res.error_states):
        name = res.state_names[i]
        if d_true is not None:
            ax.plot(t, d_true[:, i], color="k", lw=1.0, label="true model error")
        ax.plot(t, d_hat[:, i], color="tab:blue", lw=1.2, label="MME estimate d(t)")
        ax.plot(
            t,
            corr[:, i],
            "--",
            color="tab:green",
            lw=1.5,
            label="identified correction",
        )
        ax.set_ylabel(f"d ({name}')")
        ax.set_title(f"model error in {name}'", fontsize=9, loc="left")
        ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("t")


def plot_stepwise_history(res, ax):
    """Partial F of each step and the threshold, per iteration (paper's Fig. 4)."""
    steps_per_target = getattr(res.optimizer, "steps_", None)
    if not steps_per_target:
        ax.text(
            0.5,
            0.5,
            "no stepwise history (optimizer is not FloatingFStepwise)",
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
        return
    markers = {"add": "^", "remove": "v"}
    for k, steps in enumerate(steps_per_target):
        target = res.state_names[res.error_states[k]]
        if not steps:
            continue
        it = np.array([s.iteration for s in steps])
        f = np.array([s.partial_f for s in steps], dtype=float)
        thr = np.array([s.threshold for s in steps], dtype=float)
        ax.step(it, thr, where="mid", lw=1.0, label=f"threshold ({target}')")
        for action, marker in markers.items():
            sel = np.array([s.action == action for s in steps])
            if np.any(sel):
                ax.scatter(
                    it[sel], f[sel], marker=marker, s=30, label=f"{action} ({target}')"
                )
        for s in steps:
            name = res.library_feature_names[s.feature]
            ax.annotate(
                name,
                (s.iteration, s.partial_f),
                fontsize=6,
                xytext=(2, 3),
                textcoords="offset points",
            )
        phase2 = [s.iteration for s in steps if s.phase == 2]
        if phase2:
            ax.axvline(min(phase2) - 0.5, color="0.5", ls=":", lw=1)
    ax.set_yscale("log")
    ax.set_xlabel("iteration")
    ax.set_ylabel("partial F")
    ax.set_title(
        "stepwise history (dotted line: Phase II begins)", fontsize=9, loc="left"
    )
    ax.legend(fontsize=7)


def plot_discovery(res, x_true=None, d_true=None, path=None):
    """All three views in one figure; saved to ``path`` when given."""
    plt = _pyplot()
    n = len(res.state_names)
    q = len(res.error_states)
    rows = n + q + 1
    fig, axes = plt.subplots(rows, 1, figsize=(9, 2.3 * rows + 0.6))
    axes = np.atleast_1d(axes)
    plot_states(res, axes[:n], x_true=x_true)
    plot_model_error(res, axes[n : n + q], d_true=d_true)
    plot_stepwise_history(res, axes[-1])
    fig.suptitle("pysindy-mme: assumed model, model error and its explanation")
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig
