"""Study settings chosen on the training record alone.

A setting that changes the answer (how the input acts between samples, for
one) must be chosen without the test data, or the test score is no longer a
test. :func:`choose_input_hold` splits the user's record into a fit part and a
held-out last stretch, runs :func:`discover` on the fit part once per
candidate, runs each extended model free on the held-out stretch (the
benchmarks' protocol: the initial state from the stretch's first ``window``
samples, the error over the rest) and keeps the candidate with the smallest
error. Nothing outside the given record is read.
"""

from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass, field

import numpy as np
from sklearn.base import clone

from ..core import validation as val
from ..core.integrate import HOLDS
from ..core.tables import sig
from ..differentiation import MME
from ..exceptions import DivergenceError
from .study import discover

__all__ = ["HoldChoice", "choose_input_hold"]


@dataclass
class HoldChoice:
    """The answer of :func:`choose_input_hold`.

    Attributes
    ----------
    hold : str
        The chosen hold: the smallest ``score`` (the first of ``holds`` on a tie).
    holds : tuple of str
        The candidates, in the order tried.
    rmse : dict
        ``{hold: ndarray (n_measured,)}``: the extended model's free-run RMSE
        on the held-out stretch, per measured channel (``inf`` for a run or a
        study that diverged).
    assumed_rmse : dict
        The same for the assumed model (its parameters fitted by that study).
    score : dict
        ``{hold: float}``: the criterion, the mean over channels of the RMSE
        divided by the channel's standard deviation on the held-out stretch
        (with one channel, the order of the RMSE itself).
    studies : dict
        ``{hold: Discovery or None}``: each study on the fit part (None when it
        diverged; ``failures`` says why).
    failures : dict
        ``{hold: message}`` for the studies that raised :class:`DivergenceError`.
    n_fit, n_held_out, window : int
        Samples in the fit part, in the held-out stretch, and the stretch's
        leading samples used only to settle the initial state.
    """

    hold: str
    holds: tuple
    rmse: dict
    assumed_rmse: dict
    score: dict
    studies: dict = field(repr=False)
    failures: dict
    n_fit: int
    n_held_out: int
    window: int

    def table(self, scale: float = 1.0, unit: str = "") -> str:
        """A Markdown table ``| hold | training held-out RMSE |``, one row per
        candidate (the chosen one marked); RMSEs multiplied by ``scale`` and
        labelled with ``unit`` (``table(1e3, "mV")`` for volts in mV)."""
        label = "training held-out RMSE" + (f" ({unit})" if unit else "")
        lines = [f"| hold | {label} |", "|---|---:|"]
        for hold in self.holds:
            cells = ", ".join(sig(scale * v, 3) for v in self.rmse[hold])
            if hold in self.failures:
                cells = "diverged"
            mark = " (chosen)" if hold == self.hold else ""
            lines.append(f"| {hold}{mark} | {cells} |")
        return "\n".join(lines)

    def __str__(self) -> str:
        return (
            f"Input hold chosen on the training record: fitted on its first "
            f"{self.n_fit} samples, scored by free runs on the last "
            f"{self.n_held_out} (the first {self.window} of them settle the "
            f"initial state).\n{self.table()}\nChosen: {self.hold}"
        )


def _held_out_count(held_out, n: int, window: int) -> int:
    if isinstance(held_out, bool) or not isinstance(held_out, numbers.Real):
        raise TypeError(f"held_out must be a fraction or a count, got {held_out!r}")
    if isinstance(held_out, numbers.Integral):
        count = int(held_out)
    else:
        if not 0.0 < float(held_out) < 1.0:
            raise ValueError(
                f"held_out as a fraction must lie strictly between 0 and 1, "
                f"got {held_out}"
            )
        count = int(round(float(held_out) * n))
    if count < window + 2 or n - count < window + 2:
        raise ValueError(
            f"held_out = {held_out} leaves {count} held-out and {n - count} fit "
            f"samples of {n}; each part needs at least window + 2 = {window + 2}"
        )
    return count


def choose_input_hold(
    y,
    t,
    u,
    holds=HOLDS,
    *,
    held_out=0.25,
    window=50,
    **discover_options,
) -> HoldChoice:
    """Choose ``discover``'s ``input_hold`` by held-out free runs on ``y`` alone.

    The record is cut in two: the fit part (the leading samples) and the
    held-out stretch (the last ``held_out`` of them). For each candidate
    hold, :func:`discover` runs on the fit part with ``discover_options`` and
    that hold; its extended model then runs free on the held-out stretch
    (:meth:`Discovery.validate`: the initial state fitted to the stretch's
    first ``window`` samples, the RMSE over the rest). The hold with the
    smallest error wins. Use a training record: the choice is then made
    without any test data.

    Parameters
    ----------
    y : array-like (n_samples, n_measured) or (n_samples,)
    t : array-like (n_samples,) or float
        Sample times (or the time step).
    u : array-like (n_samples, n_inputs) or (n_samples,)
        The known inputs on the sample grid.
    holds : sequence of str, default all that ``discover`` accepts
        Candidates among ``"linear"``, ``"zoh"`` and ``"cubic"``.
    held_out : float in (0, 1) or int, default 0.25
        The held-out stretch: a fraction of the record or a number of samples.
    window : int, default 50
        Leading samples of the held-out stretch used to settle the initial
        state (not scored).
    **discover_options
        Everything else :func:`discover` takes (``assumed_model``,
        ``n_states``, ``options``, ...), except ``validation`` (the held-out
        stretch plays its part); an ``mme=MME(...)`` gets each candidate's
        ``input_hold`` (the choice). Warnings of
        the candidate studies are silenced; the studies are kept in the
        result.

    Returns
    -------
    HoldChoice
        The chosen ``hold``, the table (``table()``), the RMSEs and scores.

    Raises
    ------
    DivergenceError
        No candidate gave a finite held-out error.
    """
    for key in ("input_hold", "validation"):
        if key in discover_options:
            raise TypeError(
                f"choose_input_hold does not take {key}= (the hold is what it "
                "chooses; the held-out stretch of y is its validation record)"
            )
    estimator = discover_options.pop("mme", None)
    if estimator is not None and getattr(estimator, "input_hold", "linear") != "linear":
        raise TypeError(
            "choose_input_hold does not take input_hold (in mme=MME(...)): the "
            "hold is what it chooses"
        )
    if isinstance(holds, str):
        holds = (holds,)
    holds = tuple(holds)
    if not holds or any(h not in HOLDS for h in holds) or len(set(holds)) != len(holds):
        raise ValueError(f"holds must be distinct names among {HOLDS}, got {holds!r}")
    if isinstance(window, bool) or not isinstance(window, numbers.Integral):
        raise TypeError(f"window must be an integer, got {window!r}")
    if window < 1:
        raise ValueError(f"window must be at least 1, got {window}")
    y = val.as_float_array(y, "y", ndim=(1, 2), allow_nan=True)
    if y.ndim == 1:
        y = y[:, None]
    n = y.shape[0]
    t = val.check_time(t, n, "t")
    if u is None:
        raise TypeError("u is required: the hold says how the inputs act")
    u = val.as_float_array(u, "u", ndim=(1, 2))
    if u.ndim == 1:
        u = u[:, None]
    if u.shape[0] != n:
        raise ValueError(f"u has {u.shape[0]} samples but y has {n}")
    n_held = _held_out_count(held_out, n, int(window))
    n_fit = n - n_held
    fit, held = slice(0, n_fit), slice(n_fit, n)
    spread = np.nanstd(y[held][int(window) :], axis=0)
    spread = np.where(spread > 0, spread, 1.0)

    rmse, assumed, score, studies, failures = {}, {}, {}, {}, {}
    for hold in holds:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = discover(
                    y[fit],
                    t[fit],
                    u=u[fit],
                    **{**discover_options, "mme": _with_hold(estimator, hold)},
                )
                runs = res.validate(y[held], t[held], u[held], window=int(window))
        except DivergenceError as exc:
            studies[hold], failures[hold] = None, str(exc)
            rmse[hold] = assumed[hold] = np.full(y.shape[1], np.inf)
            score[hold] = np.inf
            continue
        studies[hold] = res
        rmse[hold] = np.asarray(runs["extended"].rmse, dtype=float)
        assumed[hold] = np.asarray(runs["assumed"].rmse, dtype=float)
        score[hold] = float(np.mean(rmse[hold] / spread))
    finite = [h for h in holds if np.isfinite(score[h])]
    if not finite:
        raise DivergenceError(
            "no input hold gave a finite held-out error: "
            + "; ".join(
                f"{h}: {failures.get(h, 'the free run diverged')}" for h in holds
            )
        )
    chosen = min(finite, key=lambda h: score[h])  # min keeps the first on a tie
    return HoldChoice(
        hold=chosen,
        holds=holds,
        rmse=rmse,
        assumed_rmse=assumed,
        score=score,
        studies=studies,
        failures=failures,
        n_fit=n_fit,
        n_held_out=n_held,
        window=int(window),
    )


def _with_hold(estimator, hold):
    """The user's MME settings (or the defaults) with ``input_hold=hold``."""
    if estimator is None:
        return MME(input_hold=hold)
    return clone(estimator).set_params(input_hold=hold)
