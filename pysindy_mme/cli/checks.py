"""Slips the command line can see that the study alone cannot name.

* :func:`confounded_error_states` (before the study): an error in the
  equation of a measured state competes with the errors of states that reach
  the measurements only through it. With only the position measured and
  errors allowed in both ``position'`` and ``velocity'``, any missing force
  can be explained as a velocity error *or* as a position-rate error: the
  data cannot tell them apart, only MME's weight decides, and the
  regression may put a spring force into ``position'``. Found from the
  structure of the model's Jacobian at points spread over the data.
* :func:`noise_hints` (after the study): the extended model fits far below
  the stated noise - usually a standard deviation given as a variance, or an
  'auto' estimate that took signal for noise.
"""

from __future__ import annotations

import numpy as np

from ..core.jacobian import rowwise_jacobian
from ..core.model import as_model_function
from ..core.tables import sig

__all__ = ["confounded_error_states", "influence_pattern", "noise_hints"]


def influence_pattern(f, n_states, y, measured, u=None, n_points=40, seed=0):
    """``P[a, b]``: state ``b`` enters ``a``'s equation somewhere near the data.

    The Jacobian of ``f`` by central differences at ``n_points`` states:
    measured states from random data rows, the others drawn at the scale of
    the data (their values are unknown before the study).
    """
    rng = np.random.default_rng(seed)
    model = as_model_function(f, n_states)
    rows = np.flatnonzero(np.all(np.isfinite(y), axis=1))
    if rows.size == 0:
        return None
    pick = rng.choice(rows, size=min(n_points, rows.size), replace=False)
    scale = float(np.nanstd(y)) or 1.0
    x = rng.normal(0.0, scale, (pick.size, n_states))
    x[:, measured] = y[pick]
    tt = np.zeros(pick.size)
    uu = None if u is None else np.asarray(u, dtype=float)[pick]
    try:
        jac = rowwise_jacobian(lambda z: np.asarray(model.unchecked()(z, tt, uu)), x)
    except Exception:  # the study reports a broken model properly
        return None
    jac = np.where(np.isfinite(jac), np.abs(jac), 0.0)
    return np.max(jac, axis=0) > 1e-9 * max(float(np.max(jac)), 1e-300)


def _reaches(pattern, start, blocked):
    """States whose equations ``start`` influences, not passing ``blocked``."""
    seen, todo = {start}, [start]
    while todo:
        b = todo.pop()
        for a in np.flatnonzero(pattern[:, b]):
            a = int(a)
            if a not in seen and a != blocked:
                seen.add(a)
                todo.append(a)
    return seen - {start}


def confounded_error_states(pattern, measured, error_states) -> list:
    """``[(i, [j, ...])]``: measured error state ``i`` and the error states
    ``j`` that reach the measurements only through ``i``'s equation."""
    if pattern is None:
        return []
    measured = set(measured)
    out = []
    for i in error_states:
        if i not in measured:
            continue
        hidden = []
        for j in error_states:
            if j == i or j in measured:
                continue
            via_i = i in _reaches(pattern, j, blocked=-1)
            other = _reaches(pattern, j, blocked=i) & (measured - {i})
            if via_i and not other:
                hidden.append(j)
        if hidden:
            out.append((i, hidden))
    return out


def error_state_warnings(request) -> list:
    """Warnings about ``--error-states`` (one line each)."""
    kw = request.kwargs
    if kw.get("error_states") is None:  # the hidden states only: none measured
        return []
    f = kw["assumed_model"]
    if request.parameters:
        values = dict(request.parameters)

        def f(x, t, u, _f=f):
            return _f(x, t, u, values)

    pattern = influence_pattern(f, kw["n_states"], request.y, kw["measured"], request.u)
    names = request.states
    notes = []
    for i, hidden in confounded_error_states(
        pattern, kw["measured"], kw["error_states"]
    ):
        others = [names[k] for k in kw["error_states"] if k != i]
        seen_via = ", ".join(f"{names[j]}'" for j in hidden)
        notes.append(
            f"--error-states: {names[i]} is measured and {seen_via} reach(es) the "
            f"measurements only through {names[i]}', so the data cannot tell an "
            f"error in {names[i]}' from one in {seen_via}; the study may split the "
            f"missing effect between them. If {names[i]}' is exact (a definition "
            f"such as position' = velocity), leave it out: --error-states "
            f"{','.join(others)}"
        )
    return notes


def noise_hints(result, noise_text: str, factor: float = 0.5) -> list:
    """A hint per channel whose extended fit lies far below the noise floor.

    A correct model's residuals have RMSE close to the noise standard
    deviation (``sqrt(1 - p/N)`` of it with ``p`` fitted numbers); below
    ``factor`` of it the stated noise is almost surely too large.
    """
    gain = result.gain
    hints = []
    auto = str(noise_text).strip().lower() == "auto"
    for j, name in enumerate(gain.channel_names):
        sd, fit = float(gain.noise_floor[j]), float(gain.rmse_extended[j])
        if not (np.isfinite(fit) and np.isfinite(sd) and fit < factor * sd):
            continue
        if auto:
            hints.append(
                f"--noise-variance auto estimated the noise sd of {name} as "
                f"{sig(sd, 3)}, but the extended model fits it to an RMSE of "
                f"{sig(fit, 3)}: the estimate took signal for noise. Give "
                f"--noise-variance (the variance, sd squared) if you know it, e.g. "
                f"--noise-variance {sig(fit**2, 2)}"
            )
        else:
            var = sd**2
            hints.append(
                f"--noise-variance {sig(var, 3)}: the extended model fits {name} to "
                f"an RMSE of {sig(fit, 3)}, far below the noise sd {sig(sd, 3)} this "
                f"variance implies. Was {sig(var, 3)} the standard deviation? Then "
                f"give its square, --noise-variance {sig(var**2, 3)}, and run again "
                "(too large a noise variance hides effects)"
            )
    return hints
