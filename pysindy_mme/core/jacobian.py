"""Central-difference Jacobians of row-wise maps (every row at once).

Its own module because both the model wrapper (``model.py``) and the
integrator (``integrate.py``) use it, and neither should import the other
for it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["column_scale", "rowwise_jacobian"]


def column_scale(x) -> np.ndarray:
    """Each column's RMS over its finite rows (1 where that is 0 or there
    are none): the typical size of each variable, the floor of
    :func:`rowwise_jacobian`'s steps."""
    x = np.atleast_2d(np.asarray(x, dtype=float))
    with np.errstate(all="ignore"):
        scale = np.sqrt(np.nanmean(np.where(np.isfinite(x), x, np.nan) ** 2, axis=0))
    return np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)


def rowwise_jacobian(func, x, rel_step: float | None = None, scale=None) -> np.ndarray:
    """Central-difference Jacobian of a row-wise map, for every row at once.

    ``func`` maps ``x`` of shape ``(n_rows, n)`` to ``(n_rows, n_out)`` row by
    row; the result has shape ``(n_rows, n_out, n)`` and costs ``2 n`` calls.
    Steps are ``rel_step * max(|x|, scale)`` (default ``eps**(1/3)``, the
    optimum for central differences). ``scale`` (a number or one per column)
    is each variable's typical size, the floor of the step where ``x`` is
    near zero; by default each column's RMS over the rows (1 for a column of
    zeros). A fixed floor of 1 would make the step depend on the units of
    ``x``: 1e-6 m is 0.1 % of a displacement of 1e-3 m and nothing next to
    a force of 50 N. A caller whose ``x`` is already scaled (the solver's
    internal units) passes ``scale=1``. Non-finite differences are returned
    as they are.
    """
    x = np.atleast_2d(np.asarray(x, dtype=float))
    rel_step = np.cbrt(np.finfo(float).eps) if rel_step is None else rel_step
    if scale is None:
        scale = column_scale(x)
    h = rel_step * np.maximum(np.abs(x), scale)
    out = None
    for j in range(x.shape[1]):
        xp, xm = x.copy(), x.copy()
        xp[:, j] += h[:, j]
        xm[:, j] -= h[:, j]
        with np.errstate(all="ignore"):
            diff = np.asarray(func(xp), dtype=float) - func(xm)
            if out is None:
                out = np.empty(diff.shape + (x.shape[1],))
            # output by output into its place: each division then runs over
            # the rows (dividing the (rows, n_out) difference by a column
            # broadcast along a last axis of 2-5 is several times slower)
            two_h = 2.0 * h[:, j]
            for i in range(diff.shape[1]):
                np.divide(diff[:, i], two_h, out=out[:, i, j])
    if out is None:  # no variables
        out = np.empty(np.shape(func(x)) + (0,))
    return out
