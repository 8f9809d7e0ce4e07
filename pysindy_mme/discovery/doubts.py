"""When the numbers are doubtful: which quantities, and what to try.

A solver that stopped early, or data that cannot tell two terms apart, does
not spoil every coefficient alike. The covariance of the final output-error
fit (the same factorisation the tests use) says which ones: a quantity whose
relative standard error is large is the least determined by the data and the
most moved by an unconverged fit; two terms whose estimates are almost
perfectly correlated trade off against each other (look-alikes, such as
``x`` and ``x^3`` on a small amplitude). The notes name them and say what
would help, so that a user does not only learn that a solver stopped.
"""

from __future__ import annotations

import numpy as np

from ..core.tables import sig

__all__ = ["correlated_pairs", "doubt_notes", "generalisation_note", "stop_reason"]

# A 95 % interval that reaches within half the value of zero: 1.96 * se > |v| / 2.
WEAK_RELATIVE_SE = 0.25
# Estimates this correlated cannot be told apart by the data.
LOOK_ALIKE_CORRELATION = 0.98
MAX_NAMED = 4
# Two estimates each within this relative standard error (a 95 % interval
# within +-10 % of the value) are each determined, however correlated: on a
# long record of a limit cycle the period pins one combination a thousand
# times better than the other, and the correlation of two precise estimates
# goes to -1.000 (Van der Pol over 2,500 s: standard errors 0.06 % of the
# values), which says nothing against either value
PRECISE_RELATIVE_SE = 0.05
# A model that fits its own record to the noise but misses the validation
# record by this factor of the noise floor has learnt that record, not the system.
VALIDATION_EXCESS = 1.5
IN_SAMPLE_AT_NOISE = 1.2


def doubt_notes(fit, names) -> list:
    """Notes on a final fit: non-convergence, undetermined and look-alike terms.

    Parameters
    ----------
    fit : OutputErrorFit
        The extended model's output-error fit.
    names : list of str
        A name for each of ``fit``'s physical parameters and correction terms,
        in the order of ``fit.theta`` (offsets excluded).
    """
    k = len(names)
    theta = np.asarray(fit.theta[:k], dtype=float)
    cov = np.asarray(fit.covariance[:k, :k], dtype=float)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = se / np.abs(theta)
    # a parameter held (on a bound, or at its guess as a gauge) is fixed, not
    # undetermined: the conclusion names it apart
    held = np.zeros(k, dtype=bool)
    flags = np.asarray(getattr(fit, "held", held), dtype=bool)[:k]
    held[: flags.size] = flags
    undetermined = ~np.isfinite(rel) & ~held
    weak = np.isfinite(rel) & (rel > WEAK_RELATIVE_SE)
    pairs = correlated_pairs(cov, names, undetermined, values=theta)

    notes = []
    if not fit.converged:
        notes.append(_not_converged(fit, names, rel, undetermined, pairs))
    elif weak.any():
        listed = _by_doubt(names, rel, weak)
        notes.append(
            f"the data hardly determine {listed}: their values are uncertain; a "
            "longer record, or an input that excites them, would pin them down"
        )
    if undetermined.any():
        notes.append(
            "some coefficients of the extended model are not determined by the "
            f"data ({_join([names[j] for j in np.flatnonzero(undetermined)])}: "
            "standard errors reported as n/a); remove one of each group of "
            "look-alike functions from the library, or fix a parameter"
        )
    for a, b, r in pairs:
        notes.append(
            f"{a} and {b} can hardly be told apart in these data (correlation "
            f"of their estimates {r:+.3f}): their sum is determined, not each "
            "value; offer the library only one of them, or a record of larger "
            "amplitude"
        )
    return notes


def generalisation_note(gain, names, channel_names) -> str | None:
    """A note when the extended model fits its record to the noise but not the
    validation record: the terms may be look-alikes of the true ones."""
    if gain.validation_rmse_extended is None or not names:
        return None
    fit = np.asarray(gain.rmse_extended, dtype=float)
    valid = np.asarray(gain.validation_rmse_extended, dtype=float)
    floor = np.asarray(gain.noise_floor, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        excess = valid / floor
    bad = (
        np.isfinite(excess)
        & (excess > VALIDATION_EXCESS)
        & (fit <= IN_SAMPLE_AT_NOISE * floor)
    )
    if not bad.any():
        return None
    where = _join(
        [f"{channel_names[j]} {sig(excess[j], 2)}x" for j in np.flatnonzero(bad)]
    )
    return (
        "the extended model fits this record to the noise but misses the "
        f"validation record by more (RMSE over the noise floor: {where}): its "
        f"terms ({_join(names[:MAX_NAMED])}"
        f"{' ...' if len(names) > MAX_NAMED else ''}) may be look-alikes of the "
        "missing effect that fit this record only; try a smaller library (fewer "
        "look-alike functions), a longer record, or fitting on a record that "
        "spans the validation record's amplitudes"
    )


def stop_reason(fit) -> str:
    """Why a fit stopped, worded so that it never contradicts ``converged``.

    The solver may call its own iteration converged while the fit is not
    (a trial step blew the model up, the intervals do not join): the text
    then says the iteration *stopped*, not that it converged.
    """
    message = str(fit.message)
    if not fit.converged and message.startswith("converged"):
        message = "the iteration stopped" + message[len("converged") :]
    return message


def _not_converged(fit, names, rel, undetermined, pairs) -> str:
    text = (
        "the output-error refit of the extended model did not converge "
        f"({stop_reason(fit)}); its coefficients may be inaccurate"
    )
    doubtful = np.isfinite(rel) & ~undetermined
    if doubtful.any():
        text += ", most of all the least determined ones: " + _by_doubt(
            names, rel, doubtful
        )
    tips = []
    if pairs or undetermined.any():
        tips.append("a library without look-alikes of these terms")
    tips += [
        "a noise_variance checked against the sensor (too small a value makes "
        "every mismatch significant)",
        "the assumed model's uncertain constants as parameters= (grey box)",
        "a shorter stretch of the record first (--train-rows on the command line) "
        "to see whether the terms hold",
    ]
    return text + ". Try: " + "; ".join(tips)


def _by_doubt(names, rel, mask) -> str:
    """Names with their relative standard error, least determined first."""
    order = [j for j in np.argsort(-np.where(mask, rel, -np.inf)) if mask[j]]
    shown = [f"{names[j]} (se {sig(100 * rel[j], 2)} %)" for j in order[:MAX_NAMED]]
    more = len(order) - MAX_NAMED
    return _join(shown) + (f" and {more} more" if more > 0 else "")


def correlated_pairs(
    cov,
    names,
    undetermined,
    limit=LOOK_ALIKE_CORRELATION,
    most=MAX_NAMED,
    values=None,
) -> list:
    """(name, name, correlation) of estimate pairs beyond ``limit``, the most
    correlated first (``most`` of them; None: all).

    ``values``: the estimates; given, a pair whose two estimates are each
    within ``PRECISE_RELATIVE_SE`` of their value is not one (the data
    determine each, see :data:`PRECISE_RELATIVE_SE`)."""
    ok = np.flatnonzero(~undetermined & (np.diag(cov) > 0))
    if ok.size < 2:
        return []
    sub = cov[np.ix_(ok, ok)]
    d = np.sqrt(np.diag(sub))
    corr = sub / np.outer(d, d)
    precise = np.zeros(ok.size, dtype=bool)
    if values is not None:
        v = np.abs(np.asarray(values, dtype=float)[ok])
        with np.errstate(divide="ignore", invalid="ignore"):
            precise = d <= PRECISE_RELATIVE_SE * v
    pairs = []
    for a in range(ok.size):
        for b in range(a + 1, ok.size):
            if abs(corr[a, b]) > limit and not (precise[a] and precise[b]):
                pairs.append((names[ok[a]], names[ok[b]], float(corr[a, b])))
    pairs.sort(key=lambda p: -abs(p[2]))
    return pairs if most is None else pairs[:most]


def _join(items) -> str:
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]
