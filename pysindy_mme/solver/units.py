"""The solver's internal units, and the model as the solver sees it.

The KKT pivots mix ``R^-1`` (state rows) with ``h W^-1`` (multiplier rows),
and finite differences, merit functions and convergence tests compare
numbers across states, so the solver works in units in which every state is
of the same order. Each state ``i`` has its own unit ``s_i``
(:func:`state_units`) and each measured channel ``j`` its noise standard
deviation ``sy_j`` (:func:`channel_units`); :class:`Dynamics` is the model
in those units, with its Jacobians.

The units are *equivariant*: a change of the user's units of state ``i`` by
a factor ``c_i`` (metres to millimetres, say) changes ``s_i`` by the same
``c_i``, so the problem the solver sees, and with it every step,
tolerance and finite-difference increment, is the same whatever units the
data and the model are written in (a property test: the same study in two
unit systems gives the same terms and the same physical RMSE). One scalar
unit for all states was not enough: a displacement of 1e-3 m next to a
force of 50 N (or a velocity of 1e2 mm/s next to 1e-3 m) spread the pivots
over the ratio of the scales squared, and an unmeasured state's
finite-difference step was relative to the wrong scale.
"""

from __future__ import annotations

import numpy as np

from ..core.jacobian import rowwise_jacobian
from ..core.model import ModelFunction

__all__ = ["Dynamics", "channel_units", "internal_unit", "state_units"]

# Sample points of the trajectory at which the model's Jacobian is read to
# set the units of the unmeasured states (a sample is enough for a scale).
_UNIT_POINTS = 200
# A coupling ``df_j/dx_i`` counts (carries a unit from state j to state i)
# when a difference step in ``x_i`` moves ``f_j`` by more than this fraction
# of ``f_j``: below it is rounding (about 1e-16) magnified by the difference.
_COUPLING = 1e-12


def internal_unit(R) -> float:
    """One unit for everything: a power of two near the noise's std. dev.

    With ``R / s^2`` of order one the KKT pivots of the state rows
    (``~ R^-1``) and of the multiplier rows (``~ h W^-1 ~ R`` at the
    reference weight) are of order one together, whatever the data's units.
    The fallback of :func:`state_units` for a state it cannot place.
    """
    sd = float(np.sqrt(np.mean(np.diag(np.atleast_2d(R)))))
    return float(np.ldexp(1.0, int(np.round(np.log2(sd)))))


def channel_units(R) -> np.ndarray:
    """Each measured channel's unit: its noise standard deviation ``sqrt(R_jj)``.

    Exactly the standard deviation (no rounding to a power of two), so that
    it scales exactly with the channel's units: the internal data ``y / sy``
    are then the same in any unit system, to rounding.
    """
    return np.sqrt(np.diag(np.atleast_2d(np.asarray(R, dtype=float))))


def state_units(model, x, t, u, theta, H, sy, h, fallback) -> np.ndarray:
    """Each state's internal unit ``s_i`` (user units), from the data's noise.

    * A state a channel measures (``H_ji != 0``): the noise sd the channel
      gives it, ``sy_j / |H_ji|`` (the finest over channels), so that a
      measured state is resolved to about one unit.
    * Any other state through the model: if it drives a placed state ``j``
      (``J_ji = df_j/dx_i != 0``), one unit of it moves ``x_j`` by about
      ``s_j`` within the model's own time scale ``1 / omega``:
      ``s_i = s_j omega / |J_ji|`` (the finest over the states it drives),
      placed in rounds outwards from the measured states. ``omega`` is the
      median spectral radius of ``J`` along the trajectory (a rate, the same
      in any units: the eigenvalues of ``D J D^-1`` are those of ``J``), at
      most ``1 / sample interval``; when it is slower than the record (or
      zero: a chain of integrators), ``1 / sqrt(duration * interval)``. For
      a velocity under a measured position this is the noise sd times the
      oscillation's frequency: every state is then of the same order in
      internal units.
    * A state neither measured nor driving a placed one (unobservable, or
      coupled only through states that are zero along ``x``): ``fallback``.

    Under a change of the user's units ``x -> D x`` (``D`` diagonal), ``H ->
    Dy H D^-1``, ``sy -> Dy sy`` and ``J -> D J D^-1``, so ``s -> D s``.
    The Jacobian is taken by finite differences in provisional internal
    units (the measured states' units, the others' RMS along ``x``), so its
    steps follow the same rule; a state that is zero all along ``x`` (no
    estimate yet) is stepped further, 1e4 times at a time, until the step
    moves the equations beyond rounding.

    Parameters
    ----------
    model : ModelFunction or ParametricModel
    x : ndarray (N, n)
        A trajectory in user units (the starting trajectory).
    t, u : sample times (N,) and inputs on the grid (N, m_u) or None
    theta : ndarray (p,)
        The model's parameters (empty without).
    H : ndarray (m, n) or (N, m, n)
        The measurement's Jacobian in user units.
    sy : ndarray (m,)
        The channels' units (:func:`channel_units`).
    h : ndarray (N - 1,)
        Sample intervals (0 across a break between records).
    fallback : float
        The unit of a state that cannot be placed.
    """
    x = np.nan_to_num(np.asarray(x, dtype=float), posinf=0.0, neginf=0.0)
    n = x.shape[1]
    Habs = np.abs(np.asarray(H, dtype=float))
    if Habs.ndim == 3:
        Habs = np.sqrt(np.mean(Habs**2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        direct = np.where(Habs > 0, sy[:, None] / np.where(Habs > 0, Habs, 1.0), np.inf)
    s = direct.min(axis=0) if direct.size else np.full(n, np.inf)
    s = np.where(np.isfinite(s) & (s > 0), s, np.inf)
    if np.all(np.isfinite(s)):
        return s
    idx = np.unique(np.linspace(0, x.shape[0] - 1, min(_UNIT_POINTS, x.shape[0])))
    idx = idx.astype(int)
    rms = np.sqrt(np.mean(x[idx] ** 2, axis=0))
    prov = np.where(np.isfinite(s), s, np.where(rms > 0, rms, fallback))
    z = x[idx] / prov
    try:
        with np.errstate(all="ignore"):
            dyn = Dynamics(model, prov)
            uu = None if u is None else np.asarray(u, dtype=float)[idx]
            J = np.asarray(dyn.jacobian(z, t[idx], uu, theta), dtype=float)
            f = np.asarray(dyn(z, t[idx], uu, theta), dtype=float)
    except Exception:  # a model that fails here fails its own checks next
        return np.where(np.isfinite(s), s, fallback)
    J = np.where(np.isfinite(J), J, 0.0)
    f = np.where(np.isfinite(f), f, 0.0)
    fsize = np.sqrt(np.mean(f**2, axis=0))
    # A coupling is real when the difference step in x_i moves f_j by more
    # than rounding of f_j could (a structural zero differences to exactly
    # 0). Not relative to the row's largest entry: the entries of a row
    # have different units, and a force of 50 N next to 1e-3 m would hide
    # a real coupling.
    step = np.cbrt(np.finfo(float).eps) * np.maximum(np.abs(z), 1.0)
    hcol = np.sqrt(np.mean(step**2, axis=0))

    def coupled_to(column, h_i):  # (n,): the equations x_i moves
        return np.sqrt(np.mean(column**2, axis=0)) * h_i > _COUPLING * fsize

    # A state that is zero all along x (unmeasured, before any estimate)
    # has no scale of its own to step by, and the fallback may be far too
    # small a step to move the equations beyond rounding (a force in kN
    # next to a displacement in mm): larger steps, 1e4 times at a time,
    # until one does (exact for a linear coupling, the slope over the step
    # for a nonlinear one).
    for i in np.flatnonzero(~np.isfinite(s) & (rms == 0)):
        if coupled_to(J[:, :, i], hcol[i]).any():
            continue
        for k in range(1, 9):
            delta = hcol[i] * 10.0 ** (4 * k)
            zp, zm = z.copy(), z.copy()
            zp[:, i] += delta
            zm[:, i] -= delta
            try:
                with np.errstate(all="ignore"):
                    df = dyn(zp, t[idx], uu, theta) - dyn(zm, t[idx], uu, theta)
                    df = np.asarray(df, dtype=float) / (2.0 * delta)
            except Exception:
                break
            if not np.all(np.isfinite(df)):
                break
            if coupled_to(df, delta).any():
                J[:, :, i], hcol[i] = df, delta
                break
    size = np.sqrt(np.mean(J**2, axis=0))  # (n, n): equation j, state i
    coupled = size * hcol[None, :] > _COUPLING * fsize[:, None]
    with np.errstate(all="ignore"):
        radius = np.max(np.abs(np.linalg.eigvals(J)), axis=1)
    steps = h[h > 0]
    if not steps.size:
        return np.where(np.isfinite(s), s, fallback)
    lo, hi = 1.0 / float(steps.sum()), 1.0 / float(np.mean(steps))
    # a rate slower than the record (or none: a chain of integrators) says
    # nothing about a state's scale: then the record's middle time scale
    omega = float(np.median(radius)) if radius.size else 0.0
    omega = min(omega, hi) if omega >= lo else float(np.sqrt(lo * hi))
    # |df_j/dx_i| in user units: J_int[j, i] = J_user[j, i] s_i / s_j
    rate = size * prov[:, None] / prov[None, :]
    for _ in range(n):
        placed = np.isfinite(s)
        with np.errstate(divide="ignore", invalid="ignore"):
            cand = np.where(
                coupled & placed[:, None],
                s[:, None] * omega / np.where(rate > 0, rate, np.nan),
                np.inf,
            )
        cand = np.where(np.isfinite(cand) & (cand > 0), cand, np.inf).min(axis=0)
        new = ~placed & np.isfinite(cand)
        if not new.any():
            break
        s = np.where(new, cand, s)
    return np.where(np.isfinite(s), s, fallback)


#: columns up to which :func:`_scale` goes column by column
_BY_COLUMN = 16


def _scale(a, unit, op=np.multiply):
    """``op(a, unit)`` for ``a (K, n)`` and one unit per column (``np.divide``
    for ``a / unit``): the same numbers, column by column.

    numpy runs its inner loop over the last axis; with 2-5 states that loop
    is a few elements long and the broadcast costs 5-7x an operation over
    the rows (0.10 ms against 0.015 for 32,768 rows of two states). The
    integrators convert units at every RK4 stage and finite-difference
    step.
    """
    a = np.asarray(a, dtype=float)
    n = unit.shape[0]
    if a.ndim != 2 or a.shape[1] != n or n > _BY_COLUMN:
        return op(a, unit)
    out = np.empty(a.shape)
    for j in range(n):
        op(a[:, j], unit[j], out=out[:, j])
    return out


class Dynamics:
    """The model in internal units: ``f_s(z, theta) = S^-1 f(S z, theta)``.

    ``S = diag(unit)``, one unit per state (a scalar is broadcast). Wraps a
    :class:`ModelFunction` (no parameters) or a
    :class:`~pysindy_mme.core.model.ParametricModel`. Finite-difference
    Jacobians step in ``z`` (``max(|z|, 1)`` times a relative step: one
    internal unit is about one noise sd of the state, whatever the user's
    units: ``scale=1``); a model with its own Jacobian keeps it
    (``d f_s / dz = S^-1 J(S z) S``).
    """

    def __init__(self, model, unit):
        self.model = model
        self.n = model.n_states
        self.unit = np.broadcast_to(np.asarray(unit, dtype=float), (self.n,)).copy()
        self._last = (None, None)  # (z, S z): the same z gives the same array
        self.p = int(getattr(model, "n_params", 0))
        self.parametric = hasattr(model, "param_jacobian")
        own = type(model).jacobian is not ModelFunction.jacobian
        self._own_jacobian = isinstance(model, ModelFunction) and own
        # A model with its model error as extra states (``augments``, see
        # :class:`~.error_models.AugmentedModel`: ``base``, ``es``, ``rate``):
        # the base model's block by finite differences in internal units
        # (its own Jacobian steps in the user's units), the d blocks exact
        self._augmented = None
        if getattr(model, "augments", False):
            nb = model.n_base
            self._augmented = (Dynamics(model.base, self.unit[:nb]), nb, model.es)

    def _user(self, z):
        """``S z``, the same array object for the same ``z`` (so the model can
        reuse what it computed at that point)."""
        if self._last[0] is not z:
            self._last = (z, _scale(z, self.unit))
        return self._last[1]

    def _to_internal(self, J):
        """A Jacobian ``df/dx`` in user units as ``d f_s / dz = S^-1 J S``."""
        return J * (self.unit[None, None, :] / self.unit[None, :, None])

    def __call__(self, z, t, u, theta):
        if self.parametric:
            return _scale(self.model(self._user(z), t, u, theta), self.unit, np.divide)
        return _scale(self.model(_scale(z, self.unit), t, u), self.unit, np.divide)

    def jacobian(self, z, t, u, theta):
        if self._augmented is not None:
            base, nb, es = self._augmented
            J = np.zeros((z.shape[0], self.n, self.n))
            J[:, :nb, :nb] = base.jacobian(z[:, :nb], t, u, theta)
            cols = nb + np.arange(es.size)
            J[:, es, cols] = self.unit[cols] / self.unit[es]  # x_es' += d
            sd = self.unit[cols]  # d' = F d + w: S_d^-1 F S_d
            J[:, nb:, nb:] = self.model.rate * (sd[None, :] / sd[:, None])
            return J
        if self._own_jacobian:
            return self._to_internal(self.model.jacobian(z * self.unit, t, u))
        s = self.unit
        if self.parametric and self.model.has_exact_correction_jacobian:
            # finite differences of the assumed model only (steps in z); the
            # correction's Jacobian is exact: S^-1 c'(S z) S
            base = rowwise_jacobian(
                lambda zz: _scale(
                    self.model.base_part(_scale(zz, s), t, u, theta), s, np.divide
                ),
                z,
                scale=1.0,
            )
            # added into the fresh array in place, already in internal units
            return self.model.correction_jacobian(
                self._user(z), u, theta, out=base, unit=s
            )
        return rowwise_jacobian(lambda zz: self(zz, t, u, theta), z, scale=1.0)

    def split_at(self, theta, first_column=None):
        """The model's overflow terms at ``theta`` as ``split(Z, D, h)`` in
        internal units (see :meth:`ParametricModel.split_at`), or None."""
        own = getattr(self.model, "split_at", None)
        inner = own(theta, first_column) if callable(own) else None
        return None if inner is None else _InternalSplit(inner, self.unit)

    def param_jacobian(self, z, t, u, theta):
        if not self.p:
            return np.zeros((z.shape[0], self.n, 0))
        dfdp = self.model.param_jacobian(self._user(z), t, u, theta)
        return dfdp / self.unit[None, :, None]


class _InternalSplit:
    """A split ``(X, D, h)`` in user units, applied to internal units: the
    rows of ``Z`` and ``D`` are scaled by the state units and back."""

    def __init__(self, inner, unit):
        self.inner, self.unit = inner, unit

    def __call__(self, Z, D, h):
        s = self.unit
        X, DX = self.inner(Z * s, None if D is None else D * s[None, :, None], h)
        return X / s, (None if DX is None else DX / s[None, :, None])
