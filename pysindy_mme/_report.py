"""Plain-text report of a Discovery: what is wrong, the cause, the fix, the gain."""

from __future__ import annotations

import numpy as np

__all__ = ["format_discovery", "format_table"]


def format_table(header, rows, indent="  ") -> str:
    """Left-aligned text table; numbers are formatted by the caller."""
    cells = [list(map(str, header))] + [list(map(str, r)) for r in rows]
    widths = [max(len(row[j]) for row in cells) for j in range(len(header))]
    lines = []
    for k, row in enumerate(cells):
        lines.append(indent + "  ".join(c.ljust(w) for c, w in zip(row, widths)))
        if k == 0:
            lines.append(indent + "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _p(p: float) -> str:
    if not np.isfinite(p):
        return "n/a"
    return "< 1e-300" if p == 0 else (f"{p:.3g}" if p >= 1e-4 else f"{p:.1e}")


def format_discovery(res) -> str:
    out = []
    add = out.append
    t = res.t
    add("pysindy-mme discovery report")
    add("=" * 28)
    add(
        f"Data: {t.size} samples over t = {t[0]:.4g} .. {t[-1]:.4g}; measured: "
        f"{', '.join(res.channel_names)}; states: {', '.join(res.state_names)}"
        + (f"; inputs: {', '.join(res.input_names)}" if res.input_names else "")
    )
    noise = ", ".join(f"{v:.3g}" for v in np.diag(res.noise_cov))
    add(f"Measurement noise variance: {noise}")
    add("")

    # ---- 1. what is wrong ----
    add("1. What the assumed model gets wrong")
    add("-" * 36)
    resid = res.y - res.assumed_simulation[:, res.measured]
    rows = []
    for j, name in enumerate(res.channel_names):
        r = resid[:, j]
        worst = int(np.nanargmax(np.abs(r))) if np.any(np.isfinite(r)) else 0
        rows.append(
            [
                name,
                f"{res.gain.rmse_assumed[j]:.4g}",
                f"{res.gain.noise_floor[j]:.4g}",
                f"{res.gain.rmse_assumed[j] / res.gain.noise_floor[j]:.3g}x",
                f"{r[worst]:+.3g} at t = {t[worst]:.3g}",
            ]
        )
    add("Simulation of the assumed model (initial state fitted) against the data:")
    add(format_table(["channel", "RMSE", "noise", "RMSE/noise", "largest error"], rows))
    verdict = (
        "the data CONTRADICT the assumed model"
        if res.consistency_p_value < res.alpha
        else "the data are consistent with the assumed model"
    )
    add(
        f"Consistency test: chi2 = {res.consistency_chi2:.4g} on "
        f"{res.consistency_dof} dof, p = {_p(res.consistency_p_value)} -> {verdict} "
        f"(alpha = {res.alpha})."
    )
    ratio = ", ".join(f"{v:.3f}" for v in np.atleast_1d(res.mme.covariance_ratio_))
    add(
        f"MME estimate of the model error d(t): W = {_fmt_w(res.mme.W_)}, "
        f"measurement-minus-estimate covariance / noise = {ratio}."
    )
    rows = [
        [
            name,
            f"{s['rms_d']:.4g}",
            f"{s['rms_dynamics']:.4g}",
            f"{100 * s['share']:.1f}%",
        ]
        for name, s in res.d_summary.items()
    ]
    add(format_table(["state", "rms d(t)", "rms dx/dt", "share missed"], rows))
    add("")

    # ---- 2. the cause ----
    add("2. The cause")
    add("-" * 12)
    for state, terms in res.terms.items():
        if not terms:
            add(
                f"{state}': no significant correction - the assumed equation is "
                "consistent with the data."
            )
        else:
            add(f"{state}' misses: {_terms_text(terms)}")
    if res.term_estimates:
        rows = [
            [
                te.state,
                te.feature,
                f"{te.coefficient:+.4f}",
                f"[{te.ci_low:+.4f}, {te.ci_high:+.4f}]",
                f"{te.regression_coefficient:+.4f}",
                "n/a" if not np.isfinite(te.partial_f) else f"{te.partial_f:.4g}",
                _p(te.p_value),
            ]
            for te in res.term_estimates
        ]
        add(
            format_table(
                [
                    "eq.",
                    "term",
                    "coef (refit)",
                    "95% CI",
                    "coef (d regr.)",
                    "partial F",
                    "p",
                ],
                rows,
            )
        )
    if res.pruned_terms:
        add(
            "Proposed by the regression of d(t) but not confirmed against the "
            f"measurements (alpha = {res.alpha}): {', '.join(res.pruned_terms)}."
        )
    if np.isfinite(res.correction_p_value):
        add(
            "F-test of the extended against the assumed model: p = "
            f"{_p(res.correction_p_value)}."
        )
    summary = getattr(res.optimizer, "summary", None)
    if callable(summary):
        add("")
        add("Stepwise regression of d(t) (ANOVA per error state):")
        try:
            text = summary(
                feature_names=res.library_feature_names,
                target_names=[res.state_names[i] for i in res.error_states],
            )
        except TypeError:
            text = summary()
        add(text.rstrip())
    add("")

    # ---- 3. the extended model ----
    add("3. The extended model")
    add("-" * 21)
    for name, eq in zip(res.state_names, res.extended_model.equations()):
        add(f"({name})' = {eq}")
    add("")

    # ---- 4. the gain ----
    add("4. The gain")
    add("-" * 11)
    g = res.gain
    rows = []
    for j, name in enumerate(g.channel_names):
        row = [
            name,
            f"{g.rmse_assumed[j]:.4g}",
            f"{g.rmse_extended[j]:.4g}",
            f"{g.ratio[j]:.3g}x",
            f"{g.noise_floor[j]:.4g}",
        ]
        if g.validation_rmse_assumed is not None:
            row += [
                f"{g.validation_rmse_assumed[j]:.4g}",
                f"{g.validation_rmse_extended[j]:.4g}",
                f"{g.validation_ratio[j]:.3g}x",
            ]
        rows.append(row)
    header = ["channel", "RMSE assumed", "RMSE extended", "gain", "noise floor"]
    if g.validation_rmse_assumed is not None:
        header += ["valid. assumed", "valid. extended", "valid. gain"]
    add("Simulation RMSE against the measurements (noise floor = perfect model):")
    add(format_table(header, rows))
    if res.warnings:
        add("")
        add("Warnings: " + "; ".join(res.warnings))
    return "\n".join(out) + "\n"


def _fmt_w(w) -> str:
    w = np.asarray(w, dtype=float)
    if w.size == 1:
        return f"{float(w.ravel()[0]):.4g}"
    return np.array2string(w, precision=4)


def _terms_text(terms: dict) -> str:
    parts = []
    for k, (name, c) in enumerate(terms.items()):
        sign = "-" if c < 0 else ("+" if k else "")
        sep = " " if k else ""
        parts.append(
            f"{sep}{sign}{' ' if k else ''}{abs(c):.4f}"
            + ("" if name == "1" else f" {name}")
        )
    return "".join(parts)
