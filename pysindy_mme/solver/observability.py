"""Which states the measurements cannot see.

Two checks: :func:`unobservable_states` is structural (from the sparsity of
the model's Jacobian and of the measurement, before any solve) and names the
states for the user; :func:`unobservable_directions` is numerical (from the
linearisation that made a KKT system look singular) and names the
initial-state directions no measurement determines.
"""

from __future__ import annotations

import numpy as np

__all__ = ["unobservable_states", "unobservable_directions"]


def unobservable_directions(A, H, mask, labels=None, max_steps: int = 1000):
    """The initial-state directions no measurement sees, as text.

    Stacks ``H_k Phi(k, 0)`` (the linearised sensitivity of the k-th
    measurement to ``x_0``, with the model error held at zero) over the
    first ``max_steps`` samples (so a state first seen later than that
    would be reported; the check is only consulted when the KKT system
    looks singular) and returns the right singular vectors with negligible
    singular values, each written as ``+1 x0 -1 x1``; ``[]`` if there are
    none, ``None`` if nothing is measured there. ``Phi`` is renormalised
    at every step: only the directions matter, and an unstable model
    would otherwise overflow it.
    """
    n = A.shape[1]
    K = min(A.shape[0] + 1, max_steps)
    P = np.empty((K, n, n))
    P[0] = np.eye(n)
    for k in range(1, K):
        Pk = A[k - 1] @ P[k - 1]
        size = float(np.max(np.abs(Pk)))
        if not (np.isfinite(size) and size > 0):
            K = k
            break
        P[k] = Pk / size
    P = P[:K]
    O = np.einsum("ai,kij->kaj", H, P) if H.ndim == 2 else H[:K] @ P
    O = O[mask[:K]]  # (observed values, n)
    if O.shape[0] == 0:
        return None
    if not np.isfinite(O).all():
        return []
    try:
        # R of a QR first: the SVD of a tall O only needs its n x n factor
        if O.shape[0] > n:
            O = np.linalg.qr(O, mode="r")
        _, sv, vt = np.linalg.svd(O, full_matrices=True)
    except np.linalg.LinAlgError:
        return []
    sv = np.concatenate([sv, np.zeros(n - sv.size)])
    null = vt[sv <= 1e-8 * max(sv.max(), 1e-300)]
    parts = []
    for v in null:
        v = v / np.max(np.abs(v))
        v = v * np.sign(v[np.flatnonzero(np.abs(v) > 1e-6)[0]])  # first is +
        names = labels or [f"x{j}" for j in range(n)]
        terms = [f"{c:+.3g} {names[j]}" for j, c in enumerate(v) if abs(c) > 1e-6]
        parts.append(" ".join(terms))
    return parts


def unobservable_states(
    model,
    x,
    t,
    u,
    measurement_pattern,
    n_points: int = 40,
    seed: int = 0,
    unit=None,
):
    """States that cannot influence any measurement (structural check).

    A state is seen if a measured quantity depends on it directly, or if it
    drives (through a nonzero entry of ``df/dx``) a state that is seen. An
    entry counts as nonzero above ``1e-10`` times the largest entry of its
    row (its equation). The pattern is the union over a few samples of the
    initial trajectory and random perturbations of them, so that a
    derivative that happens to vanish on the initial guess (e.g.
    ``d(x1 x2)/dx1`` at ``x2 = 0``) is not mistaken for a structural zero.

    ``unit`` (one per state, the solver's internal units) makes the
    comparison within an equation unit-free: the entries of a row have
    different units (``df_j/dx_i`` per unit of ``x_i``), so they are compared
    as ``|df_j/dx_i| unit_i / unit_j``; a state in kN next to one in mm
    would otherwise look disconnected. It also sets the perturbation of a
    state that is zero along ``x``.

    Returns
    -------
    list of int
        Indices of the states that no measurement can see.
    """
    x = np.asarray(x, dtype=float)
    n = x.shape[1]
    rng = np.random.default_rng(seed)
    idx = np.unique(np.linspace(0, x.shape[0] - 1, min(n_points, x.shape[0])))
    idx = idx.astype(int)
    xs = x[idx]
    ts = np.asarray(t, dtype=float)[idx]
    us = None
    if u is not None:
        us = (
            np.asarray(u(ts), dtype=float).reshape(ts.size, -1)
            if callable(u)
            else np.asarray(u)[idx]
        )
    scale = np.maximum(np.std(x, axis=0), 0.1 * np.max(np.abs(x), axis=0))
    fill = 1.0 if unit is None else np.asarray(unit, dtype=float)
    scale = np.where(scale > 0, scale, fill)
    ratio = 1.0
    if unit is not None:  # |df_j/dx_i| in units of unit_j / unit_i
        unit = np.asarray(unit, dtype=float)
        ratio = unit[None, None, :] / unit[None, :, None]
    pattern = np.zeros((n, n), dtype=bool)
    for trial in range(3):
        pts = xs if trial == 0 else xs + scale * rng.standard_normal(xs.shape)
        with np.errstate(all="ignore"):
            jac = model.jacobian(pts, ts, us)
        finite = np.isfinite(jac)
        mag = np.where(finite, np.abs(jac) * ratio, 0.0)
        # Relative to the largest entry of the same equation (row): one
        # threshold for the whole Jacobian would erase a coupling of 1 next
        # to a stiff -1e11 elsewhere (a model in the wrong units), and the
        # error would wrongly blame observability.
        row_max = np.maximum(mag.max(axis=-1, keepdims=True), np.finfo(float).tiny)
        pattern |= (mag > 1e-10 * row_max).any(axis=0)
    seen = np.asarray(measurement_pattern, dtype=bool).any(axis=0)
    changed = True
    while changed:
        # state i is seen if it drives a seen state j: df_j/dx_i != 0
        new = seen | (pattern[seen, :].any(axis=0))
        changed = bool((new != seen).any())
        seen = new
    return [int(i) for i in np.flatnonzero(~seen)]
