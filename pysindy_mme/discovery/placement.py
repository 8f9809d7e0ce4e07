"""Where the model error goes when the user does not say: not on kinematics.

An equation that only says a state is the rate of another (``q' = v``,
``theta' = omega``) is a definition, not a model: nothing is missing from
it. An error placed there is also indistinguishable from one in the
equation it integrates (``q'' = v' + d_q'``: any smooth ``d_q`` acts like a
force ``d_q'``), so with errors on both MME spreads the effect over the two
and the regression of either finds nothing. With ``error_states`` omitted,
the study therefore places the model error on every equation except such
kinematic identities (on all of them when every equation is one).

The identity is checked by evaluating the assumed model at random states
(around the measured data's scale) and inputs: ``f_i(x, t, u) == x_j`` to
rounding at every probe.
"""

from __future__ import annotations

import numpy as np

__all__ = ["kinematic_identities", "default_error_states"]

#: random probes of the model: an identity must hold at every one
N_PROBES = 16


def kinematic_identities(model, n_states, t, u=None, scale=None, seed=0) -> dict:
    """``{i: j}`` for every equation ``x_i' = x_j`` of ``model``.

    Parameters
    ----------
    model : callable ``(x (K, n), t (K,), u (K, m) or None) -> (K, n)``
    n_states : int
    t : ndarray (N,)
        Sample times (probe times are drawn from them).
    u : ndarray (N, m) or None
        Inputs on the sample grid (probe inputs are rows of it).
    scale : ndarray (n,), optional
        Typical size of each state (default 1).
    """
    rng = np.random.default_rng(seed)
    scale = np.ones(n_states) if scale is None else np.asarray(scale, float)
    x = rng.standard_normal((N_PROBES, n_states)) * scale
    rows = rng.integers(0, len(t), N_PROBES)
    uu = None if u is None else np.asarray(u, float)[rows]
    try:
        with np.errstate(all="ignore"):
            f = np.asarray(model(x, np.asarray(t, float)[rows], uu), dtype=float)
    except Exception:  # noqa: BLE001 - a model that cannot be probed keeps all
        return {}
    if f.shape != x.shape or not np.all(np.isfinite(f)):
        return {}
    out = {}
    for i in range(n_states):
        for j in range(n_states):
            if j != i and np.allclose(f[:, i], x[:, j], rtol=1e-12, atol=0.0):
                out[i] = j
                break
    return out


def default_error_states(model, n_states, t, u, scale, state_names):
    """``(error_states, note)``: every equation but the kinematic identities.

    ``note`` is empty when nothing was left out, else one sentence for the
    report saying which equations were left out and why.
    """
    identities = kinematic_identities(model, n_states, t, u, scale)
    keep = [i for i in range(n_states) if i not in identities]
    if not identities or not keep:
        return list(range(n_states)), ""
    shown = ", ".join(
        f"{state_names[i]}' = {state_names[j]}" for i, j in sorted(identities.items())
    )
    note = (
        f"{', '.join(state_names[i] for i in keep)}' (error_states omitted: "
        f"{shown} is a kinematic identity, where an error would only blur the "
        "one in the equation it integrates)"
    )
    return keep, note
