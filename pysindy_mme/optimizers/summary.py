"""The summary of a fitted :class:`FloatingFStepwise`: tables as text and HTML.

:func:`build_summary` assembles, per target, the final model's ANOVA table
(the paper's Table II) and the step history into a :class:`StepwiseSummary`.
"""

from __future__ import annotations

import html
import numbers

import numpy as np

from .rules import PAPER_F
from .selection import AUTO_LAG1, JOINT_MIN_EFFECT
from .tables import anova_html, anova_text, steps_html, steps_text

__all__ = ["StepwiseSummary", "build_summary", "rule_description"]


def _plural(count: int, word: str) -> str:
    return f"{count} {word}" + ("" if count == 1 else "s")


class StepwiseSummary(str):
    """The summary of a fitted :class:`FloatingFStepwise`, in statsmodels' style.

    It *is* the text (a ``str`` subclass), so ``print(summary)``, ``in``,
    ``==`` and string methods work as on the plain text; notebooks call
    :meth:`_repr_html_` and show the same tables as HTML.

    Attributes
    ----------
    tables : list of AnovaTable
        The final ANOVA table of each target shown.
    steps : list of list of Step
        The step history of each target shown.
    """

    def __new__(cls, text, html_text="", tables=(), steps=()):
        obj = super().__new__(cls, text)
        obj._html = html_text
        obj.tables = list(tables)
        obj.steps = list(steps)
        return obj

    def __repr__(self) -> str:
        # The text itself, not a quoted string: an interactive console shows
        # the tables when the summary is the value of an expression.
        return str(self)

    def __str__(self) -> str:
        return str.__str__(self)

    def __reduce__(self):
        return (StepwiseSummary, (str(self), self._html, self.tables, self.steps))

    def as_text(self) -> str:
        """The summary as plain text (what ``print`` shows)."""
        return str(self)

    def as_html(self) -> str:
        """The summary as HTML tables."""
        return self._html

    def _repr_html_(self) -> str:
        return self._html


def rule_description(opt) -> str:
    """The selection rule of a fitted optimizer in one line (the summary's first)."""
    if opt.f_enter is not None:
        f_remove = opt.f_enter if opt.f_remove is None else opt.f_remove
        rule = f"F_enter = {opt.f_enter:g}, F_remove = {f_remove:g}"
    elif opt.alpha_enter is not None:
        a_rem = (
            max(opt.alpha_enter, 0.10) if opt.alpha_remove is None else opt.alpha_remove
        )
        rule = f"alpha_enter = {opt.alpha_enter:g}, alpha_remove = {a_rem:g}"
    default_rule = opt.f_enter is None and opt.alpha_enter is None
    in_order = getattr(opt, "rows_in_time_order_", True)
    if default_rule:
        stat = (
            "classic"
            if opt.autocorrelation is None or not in_order
            else "Newey-West robust"
        )
        rule = (
            f"family-wise alpha = {opt.alpha:g} (Bonferroni over the "
            f"candidates outside the model), {stat} partial F"
        )
        if not in_order:
            rule += " (rows not in time order: the ordinary test)"
            if opt.floating == "auto":
                return (
                    f"FloatingFStepwise: {rule}, Phase II floating ratio "
                    f"{opt.float_ratio:g} (auto, rows not in time order)"
                )
    engaged = ", ".join(str(t) for t in np.flatnonzero(opt.phase_two_))
    if opt.floating == "auto" and default_rule and opt.autocorrelation:
        rule += (
            f"; where the Phase I residual's lag-1 autocorrelation is > "
            f"{AUTO_LAG1:g} the paper's rule (F* = {PAPER_F:g}, Phase II "
            f"floating ratio {opt.float_ratio:g}) is applied instead: "
            f"target(s) {engaged or 'none'}"
        )
    elif opt.floating == "auto":
        rule += (
            f", Phase II auto (floating ratio {opt.float_ratio:g} when the "
            f"Phase I residual's lag-1 autocorrelation > {AUTO_LAG1:g}; "
            f"engaged on target(s): {engaged or 'none'})"
        )
    elif opt.floating:
        rule += f", Phase II floating ratio = {opt.float_ratio:g}"
    else:
        rule += ", Phase II off"
    return f"FloatingFStepwise: {rule}"


def _labels(opt, feature_names, target_names, target):
    """(feature_names, target labels, targets to show), validated."""
    n_targets, n_features = opt.coef_.shape
    if feature_names is None:
        feature_names = opt.feature_names_
    if feature_names is not None and len(feature_names) != n_features:
        raise ValueError(
            f"feature_names has {len(feature_names)} names but the library has "
            f"{n_features} columns"
        )
    if target_names is None:
        target_names = opt.target_names_
    if target_names is not None:
        if len(target_names) != n_targets:
            raise ValueError(
                f"target_names has {len(target_names)} names but there are "
                f"{n_targets} targets"
            )
        labels = [f"({name})'" for name in target_names]
    else:
        labels = [f"target {t}" for t in range(n_targets)]
    if target is None:
        targets = list(range(n_targets))
    else:
        if not isinstance(target, numbers.Integral) or not 0 <= target < n_targets:
            raise ValueError(f"target must be an index in [0, {n_targets - 1}]")
        targets = [int(target)]
    return feature_names, labels, targets


def _errors_in_variables_line(opt, name) -> str:
    """Whether the statistics were corrected for a noisy library, and why not
    (only where it could have been: a polynomial library, or rows out of
    time order; nothing for a small or non-polynomial library, or when off)."""
    info = getattr(opt, "errors_in_variables_", None)
    if not isinstance(info, dict):
        return ""
    if not info["applied"]:
        if info["base_columns"] or info["reason"] == "rows not in time order":
            return f"Errors in variables: not corrected ({info['reason']})."
        return ""
    noise = ", ".join(
        f"{name(j)} {v:.3g}"
        for j, v in zip(info["base_columns"], info["noise_variance"], strict=True)
    )
    return (
        "Errors in variables: statistics corrected for the noise of the library's "
        f"base columns (variances: {noise})."
    )


def _notes(opt, t) -> list:
    """Plain-text notes under a target's ANOVA table."""
    notes = []
    info = getattr(opt, "errors_in_variables_", None)
    routes = info.get("routes", ()) if isinstance(info, dict) else ()
    if t < len(routes):
        notes.append(f"  Note: errors in variables: the model {_ROUTES(routes[t])}.")
    table = opt.anova_[t]
    no_column = getattr(opt, "constant_feature_", 0) is None
    if opt.intercept_dropped_[t] and no_column and not opt.fit_intercept:
        notes.append(
            "  Note: the library has no constant column and fit_intercept is "
            "False: coef_ is refit through the origin (pysindy's convention)."
        )
    elif opt.intercept_dropped_[t] and table.robust:
        notes.append(
            "  Note: the intercept's robust partial F "
            f"({table.intercept_robust_partial_f:.4g}) is below the single-test "
            f"threshold at alpha = {opt.alpha:g}; coef_ is refit through the origin."
        )
    elif opt.intercept_dropped_[t]:
        notes.append(
            "  Note: the intercept's partial F "
            f"({table.intercept_partial_f:.4g}) is below the removal "
            "threshold; coef_ is refit through the origin."
        )
    partialled = getattr(opt, "n_partialled_", None)
    if partialled is not None and partialled[t]:
        notes.append(
            f"  Note: partial_out: {_plural(int(partialled[t]), 'column')} "
            "projected out of the library and the target first (every model "
            "holds them; the F-ratios' degrees of freedom are not reduced by "
            "them)."
        )
    joint = (getattr(opt, "joint_tests_", None) or [None] * (t + 1))[t]
    if joint is not None:
        outcome = (
            "jointly significant: all were added (with the joint F), then removed "
            "one at a time by the rule"
            if joint["restart"]
            else "not jointly significant"
        )
        if joint["restart"] and not joint.get("kept", True):
            outcome += (
                f"; not relevant (forward R^2 >= 0.8 and f^2 per extra term "
                f"{joint['effect']:.2g} < {JOINT_MIN_EFFECT:g}): back to the "
                "forward model"
            )
        notes.append(
            f"  Joint test of the {joint['n']} candidates Phase I left out: "
            f"F = {joint['f']:.4g}, p = {joint['p']:.2g}: {outcome}."
        )
    if table.robust:
        notes.append(
            "  Phase I compares robust partial F-ratios (Newey-West) with the "
            "Bonferroni threshold; adj. p = p x candidates; Phase II "
            "(if engaged) compares classic ones."
        )
    return notes


def _warnings(opt) -> list:
    out = []
    if not opt.converged_:
        out.append("\nWARNING: max_iter was reached; the selection did not settle.")
    if opt.cycle_detected_:
        out.append("\nWARNING: a cycle was detected; the selection stopped there.")
    return out


def _ROUTES(route: str) -> str:  # noqa: N802 - reads as a phrase
    """A target's errors-in-variables route, in words."""
    words = {
        "both": "is the same on the corrected and the given library",
        "corrected": "is the corrected selection's",
        "as given": (
            "is the selection's on the library as given (coefficients corrected)"
        ),
        "as given (the target shares the library's noise)": (
            "is fitted as given (the target shares the library's noise)"
        ),
        "corrected, the model as given indefinite": (
            "is the corrected selection's (the selection on the library as "
            "given has columns collinear to within the noise: it cannot be "
            "fitted in the corrected metric)"
        ),
    }
    base, _, then = route.partition(", then ")
    text = words.get(base, base)
    return text + (f", then {then}" if then else "")


def build_summary(opt, feature_names=None, target_names=None, target=None):
    """The :class:`StepwiseSummary` of a fitted optimizer (see its ``summary``)."""
    feature_names, labels, targets = _labels(opt, feature_names, target_names, target)

    def name(j):
        return str(feature_names[j]) if feature_names is not None else f"f{j}"

    rule = rule_description(opt)
    text = [rule]
    page = [f"<p><b>{html.escape(rule)}</b></p>"]
    correction = _errors_in_variables_line(opt, name)
    if correction:
        text.append(correction)
        page.append(f"<p>{html.escape(correction)}</p>")
    if opt.excluded_:
        text.append("Library columns set aside (never selected):")
        text += [f"  {name(j)}: {why}" for j, why in opt.excluded_.items()]
        page.append("<p>Library columns set aside (never selected):</p><ul>")
        page += [
            f"<li>{html.escape(name(j))}: {html.escape(why)}</li>"
            for j, why in opt.excluded_.items()
        ]
        page.append("</ul>")
    for t in targets:
        table = opt.anova_[t]
        title = (
            f"=== {labels[t]}: final model ANOVA table "
            f"({_plural(len(opt.steps_[t]), 'step')}, n = {table.n:g}) ==="
        )
        notes = _notes(opt, t)
        text += ["", anova_text(table, feature_names, title=title)]
        text += notes
        text += [""] + steps_text(opt.steps_[t], feature_names)
        page.append(anova_html(table, feature_names, title=title))
        page += [f"<p>{html.escape(note.strip())}</p>" for note in notes]
        page.append(steps_html(opt.steps_[t], feature_names))
    warns = _warnings(opt)
    text += warns
    page += [f"<p><b>{html.escape(w.strip())}</b></p>" for w in warns]
    return StepwiseSummary(
        "\n".join(text),
        "\n".join(page),
        tables=[opt.anova_[t] for t in targets],
        steps=[opt.steps_[t] for t in targets],
    )
