"""Overflow terms integrated exactly: an operator split of RK4.

An overflow column ``over(h, L) = max(h - L, 0)`` of a state ``h`` is linear
in ``h``'s excess ``e = h - L`` above the level. In ``h``'s own equation, with
coefficient ``a``, it is a relaxation ``e' = a e``, and in the equation of
another state ``j``, with coefficient ``c_j``, it routes that excess
(``h_j' = c_j e``): a tank that spills over its rim into the tank below.
A fit of a tank that cannot rise above its rim drives ``-a`` towards
infinity (the rim is the limit of ever stiffer walls), and RK4 on the whole
right-hand side then needs a step below ``2.8 / |a|``: the fit stops joining
its own trajectory long before the wall is stiff enough.

Here the overflow part is split off and solved exactly over each step,
``e(h) = e0 exp(a h)`` and ``h_j(h) = h_j0 + c_j e0 h phi1(a h)`` with
``phi1(z) = (exp(z) - 1) / z``, around the RK4 step of the rest (Strang
splitting: half a step of overflow, the RK4 step, half a step of overflow).
Away from the level the step is RK4 itself; above it the split is second
order for a soft wall and first order while a stiff wall holds the state at
the level (the rest of the right-hand side is evaluated a little above it
within each step, as in a catch-up projection).
It is stable for every ``a <= 0``: an infinitely stiff wall is a clamp at
the level with the excess routed, as a real rim behaves. The derivatives of
the split map are exact, so Gauss-Newton sees the Jacobian of the discrete
map it solves (:func:`~pysindy_mme.core.integrate.rk4_flow`).

Several overflow columns of one state are split one after another (first
order in their interaction, which only matters while the state is above two
levels at once).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Overflows", "overflow_columns_of", "split_form"]


def split_form(rhs):
    """``(rhs, split)``: the right-hand side an integrator should step with
    RK4 and the part it should solve exactly (None if there is none).

    A model whose call gives its whole right-hand side but which has
    overflow terms (an :class:`~pysindy_mme.ExtendedModel`) offers its
    split form through ``split_form()``; a bare right-hand side that already
    lacks them carries ``split``.
    """
    form = getattr(rhs, "split_form", None)
    if callable(form):
        bare = form()
        if bare is not None:
            return bare, bare.split
    return rhs, getattr(rhs, "split", None)


def overflow_columns_of(features) -> dict:
    """``{column: (variable, level)}`` of the overflow columns ``features``
    declares (its ``overflow_columns()``), or ``{}``."""
    own = getattr(features, "overflow_columns", None)
    return dict(own()) if callable(own) else {}


def _phi1(z):
    """``(exp(z) - 1) / z`` and its derivative, stable near ``z = 0``."""
    small = np.abs(z) < 1e-4
    zz = np.where(small, 1.0, z)
    with np.errstate(over="ignore", invalid="ignore"):
        e = np.exp(z)
        p = np.where(small, 1.0 + z / 2.0 + z * z / 6.0, np.expm1(zz) / zz)
        dp = np.where(
            small, 0.5 + z / 3.0 + z * z / 8.0, (e * (zz - 1.0) + 1.0) / (zz * zz)
        )
    return e, p, dp


@dataclass(frozen=True)
class _Overflow:
    """One overflow column: ``variable``'s excess over ``level``; ``rate``
    the coefficient position in ``variable``'s own equation (or None);
    ``routes`` ``((state, position), ...)`` in the other equations."""

    variable: int
    level: float
    rate: int | None
    routes: tuple


class Overflows:
    """The overflow terms of a model, split off its right-hand side.

    Parameters
    ----------
    slots : sequence of (state, column)
        The model's terms; those on an overflow column of a state are taken
        out of the right-hand side (:attr:`positions`) and solved here.
    overflow_columns : dict
        ``{column: (variable, level)}`` (see :func:`overflow_columns_of`).
    n_states : int
        Only columns of a state variable (``variable < n_states``) are split:
        an input's overflow is a function of time, not a relaxation.
    """

    def __init__(self, slots, overflow_columns, n_states):
        by_column = {}
        for k, (i, c) in enumerate(slots):
            found = overflow_columns.get(int(c))
            if found is None or not 0 <= int(found[0]) < n_states:
                continue
            by_column.setdefault(int(c), []).append((int(i), k))
        items = []
        for c, members in sorted(by_column.items()):
            var, level = overflow_columns[c]
            rate = next((k for i, k in members if i == var), None)
            routes = tuple((i, k) for i, k in members if i != var)
            items.append(_Overflow(int(var), float(level), rate, routes))
        self.items = tuple(items)
        self.positions = frozenset(
            k for item in items for k in ([item.rate] if item.rate is not None else [])
        ) | frozenset(k for item in items for _, k in item.routes)

    def __bool__(self) -> bool:
        return bool(self.items)

    def bound(self, coefs, column_of=None):
        """``split(X, D, h)`` for :func:`~pysindy_mme.core.integrate.rk4_flow`
        at fixed coefficients ``coefs``."""
        return _Bound(self, np.asarray(coefs, dtype=float), column_of)

    def step(self, X, h, coefs, D=None, column_of=None):
        """Advance ``X`` (K, n) by ``h`` ((K, 1) or a scalar) under the overflow
        terms alone, exactly; ``coefs`` the model's term coefficients.

        With ``D`` (K, n, n_cols), ``dX / d(start, parameters)``, also its
        update: ``column_of(position)`` is the column of ``D`` that holds the
        coefficient at ``position`` (None: ``D`` has no parameter columns, the
        coefficients are fixed). Returns ``(X, D)``: new arrays where a state
        is above a level, the inputs themselves where none is (most steps).
        """
        h = np.broadcast_to(np.asarray(h, dtype=float).reshape(-1), (X.shape[0],))
        copied = False
        for item in self.items:
            v = item.variable
            e0 = X[:, v] - item.level
            on = e0 > 0.0
            if not np.any(on):
                continue
            if not copied:  # the caller's arrays are never written to
                X = np.array(X, dtype=float)
                D = None if D is None else np.array(D, dtype=float)
                copied = True
            a = 0.0 if item.rate is None else float(coefs[item.rate])
            hh, ee = h[on], e0[on]
            E, p1, dp1 = _phi1(a * hh)
            dv_old = None if D is None else D[on, v, :].copy()
            for j, k in item.routes:
                c = float(coefs[k])
                X[on, j] += c * ee * hh * p1
                if D is not None:
                    D[on, j, :] += (c * hh * p1)[:, None] * dv_old
                    if column_of is not None:
                        D[on, j, column_of(k)] += ee * hh * p1
                    if column_of is not None and item.rate is not None:
                        D[on, j, column_of(item.rate)] += c * ee * hh * hh * dp1
            if item.rate is not None:
                X[on, v] = item.level + ee * E
                if D is not None:
                    D[on, v, :] = E[:, None] * dv_old
                    if column_of is not None:
                        D[on, v, column_of(item.rate)] += ee * hh * E
        return X, D


class _Bound:
    """:meth:`Overflows.step` at fixed coefficients (a class, not a closure:
    a model holding it pickles)."""

    def __init__(self, overflows, coefs, column_of):
        self.overflows, self.coefs, self.column_of = overflows, coefs, column_of

    def __call__(self, X, D, h):
        return self.overflows.step(X, h, self.coefs, D, self.column_of)
