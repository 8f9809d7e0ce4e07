"""Physical effects: the columns of :class:`~pysindy_mme.PhysicsLibrary`.

Real machines are not polynomials: a slide sticks, a valve saturates, a tank
drains through an orifice. Each effect below is one such mechanism, named as
an engineer names it and acting on one variable (a column index or a name),
so that a regression over a :class:`~pysindy_mme.PhysicsLibrary` answers in
the engineer's terms ("Coulomb friction of 1.9 N on v") rather than as a
polynomial that imitates a kink. Worked examples, one per effect (``q``
position, ``v`` velocity, ``u`` input, ``h1`` a tank level)::

    from pysindy_mme import PhysicsLibrary
    from pysindy_mme.feature_library import (Coulomb, DeadZone, Overflow,
        Saturation, SmoothCoulomb, Stribeck, Torricelli, ViscousSplit)

Coulomb friction
    A slide on a dry rail: ``m v' = u - Fc sign(v) - b v``. Column ``sign(v)``
    (coefficient ``-Fc/m``; ``sign(0) = 0``: at rest no friction is assumed)::

        PhysicsLibrary([Coulomb("v")], names=["q", "v", "u"])

Smooth Coulomb friction
    The same friction with a continuous transition of width ``w``,
    ``tanh(v/w)``, for integrators and fits that need a derivative at
    ``v = 0``; take ``w`` below the speeds the record resolves. Column
    ``tanh(v/0.001)``::

        PhysicsLibrary([SmoothCoulomb("v", 0.001)], names=["q", "v", "u"])

Stribeck friction
    Breakaway friction above the sliding one: ``F = Fc sign(v) + (Fs - Fc)
    sign(v) exp(-(v/vs)^2) + b v``. The effect is the decaying part only, so
    the library ``Coulomb + Stribeck`` (+ a linear term) spans the whole
    curve. Column ``sign(v) exp(-(v/0.01)^2)``::

        PhysicsLibrary([Coulomb("v"), Stribeck("v", 0.01)], names=["q", "v", "u"])

Direction-dependent viscous friction
    A damper stiffer in rebound than in compression: ``F = -c_up max(v, 0)
    - c_down min(v, 0)``. Columns ``v+`` and ``v-`` (their sum is ``v``)::

        PhysicsLibrary([ViscousSplit("v")], names=["q", "v", "u"])

Saturation
    An amplifier with a current limit: ``m v' = k clip(u, -L, L)``. With
    ``L`` unknown, give candidates and let the regression choose; columns
    ``sat(u, 1)``, ``sat(u, 2)``, ``sat(u, 5)``::

        PhysicsLibrary([Saturation("u", [1, 2, 5])], names=["q", "v", "u"])

Dead zone
    A valve or a worn gear that does nothing for ``|u| < w`` and then follows
    ``u`` shifted by ``w``: ``dz(u, w) = u - clip(u, -w, w)``. Column
    ``dz(u, 0.1)``::

        PhysicsLibrary([DeadZone("u", 0.1)], names=["q", "v", "u"])

Torricelli outflow
    A tank draining through an orifice: ``A h1' = q_in - a sqrt(2 g h1)``.
    Column ``sqrt(h1+)``, ``sqrt(max(h1, 0))``: an empty tank has no
    outflow (and a slightly negative estimate of ``h1`` gives no NaN)::

        PhysicsLibrary([Torricelli("h1")], names=["h1", "h2", "q_in"])

Overflow
    A tank spilling over a weir at height 10: ``A h1' = q_in - c max(h1 -
    10, 0)``. Column ``over(h1, 10)``; several candidate heights as for
    ``Saturation``::

        PhysicsLibrary([Overflow("h1", 10)], names=["h1", "h2", "q_in"])

    When ``h1`` is a state, the column in ``h1``'s own equation is a
    relaxation of the excess above the level, and in another state's
    equation it routes that excess there (a tank spilling into the one
    below: ``over(h1, 10)`` in ``h2'`` with a positive coefficient). Every
    integrator of the package solves these terms exactly around each RK4
    step (:mod:`~pysindy_mme.core.relaxation`), so a coefficient of any size
    is stable: a rim the level cannot pass is the limit of a large negative
    coefficient, which the study's fits bound at ``-10 / dt`` (``dt`` the
    sample interval: the excess relaxes with a time constant of a tenth of
    a sample, a clamp as far as the data can tell) and report as a wall.

Offset
    A constant force (gravity along an incline, a sensor's bias) is no effect
    class: ``PhysicsLibrary(..., include_bias=True)`` adds the column ``1``.

Backlash is deliberately missing. The output of a gear with play depends on
where the gear was, not only on where the input is now: it has memory, so it
is a state, not a function of the present state, and no library column can
express it. Model it as a hidden state (an extra state of the assumed model,
see the hidden-states docs) instead.

Every effect says whether it is non-smooth (``nonsmooth``: a kink or a jump,
true for all but :class:`SmoothCoulomb`) and gives, per column, its value,
its exact derivative and a switching function whose zeros are the kinks (so
a simulator can locate them). Derivatives at a kink are the one-sided ones
from above (``d max(x, 0)/dx = 1`` at ``x = 0``), except Torricelli's, which
is infinite there and set to 0 (``sqrt(max(x, 0))`` for ``x <= 0``).
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

__all__ = [
    "Effect",
    "Coulomb",
    "SmoothCoulomb",
    "Stribeck",
    "ViscousSplit",
    "Saturation",
    "DeadZone",
    "Torricelli",
    "Overflow",
]


# Smoothing. Every kink below is a step (sign) or a ramp (max(s, 0)) of a
# switching variable; with a width w > 0 the step becomes tanh(s/w) and the
# ramp w log(1 + e^(s/w)) (softplus), which differ from the exact ones by at
# most w log 2 and only within a few w of the switch. Integrators with
# exact sensitivities need this: a jump in the right-hand side makes the
# flow over a step discontinuous in its start state, so a Gauss-Newton fit
# of a trajectory through it has no consistent linearisation. w = 0 is the
# exact effect.


def _step(s, w):
    return np.sign(s) if w == 0 else np.tanh(s / w)


def _dstep(s, w):
    return np.zeros(np.shape(s)) if w == 0 else (1.0 - np.tanh(s / w) ** 2) / w


def _ramp(s, w):
    return np.maximum(s, 0.0) if w == 0 else w * np.logaddexp(0.0, s / w)


def _dramp(s, w):
    # one-sided from above at the kink (d max(s, 0)/ds = 1 at s = 0)
    return (s >= 0).astype(float) if w == 0 else 0.5 * (1.0 + np.tanh(0.5 * s / w))


def _where(effect) -> str:
    return f"({type(effect).__name__} on {effect.variable!r})"


def _check_variable(effect) -> None:
    value = effect.variable
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(
            f"variable must be a column index (int) or a name (str), got {value!r} "
            f"({type(effect).__name__})"
        )
    if isinstance(value, numbers.Integral):
        if value < 0:
            raise ValueError(
                f"variable must be a column index >= 0, got {value} "
                f"({type(effect).__name__})"
            )
        object.__setattr__(effect, "variable", int(value))
    elif isinstance(value, str):
        if not value.strip():
            raise ValueError(
                f"variable must be a non-empty name ({type(effect).__name__})"
            )
    else:
        raise TypeError(
            f"variable must be a column index (int) or a name (str), got {value!r} "
            f"({type(effect).__name__})"
        )


def _real(value, name: str, effect) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number {_where(effect)}, got {value!r}")
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"{name} must be finite {_where(effect)}, got {value}")
    return value


def _positive(value, name: str, effect) -> float:
    value = _real(value, name, effect)
    if value <= 0:
        raise ValueError(f"{name} must be positive {_where(effect)}, got {value:g}")
    return value


def _levels(effect, name: str, positive: bool) -> None:
    """Normalise ``effect.<name>`` (a number or a sequence) to a tuple of floats."""
    value = getattr(effect, name)
    if isinstance(value, (str, bytes)):
        raise TypeError(
            f"{name} must be a number or a sequence of numbers {_where(effect)}, "
            f"got {value!r}"
        )
    items = list(value) if isinstance(value, Iterable) else [value]
    if not items:
        raise ValueError(f"{name} must not be empty {_where(effect)}")
    check = _positive if positive else _real
    out = tuple(check(item, name, effect) for item in items)
    if len(set(out)) != len(out):
        raise ValueError(f"{name} contains duplicates {_where(effect)}: {out}")
    # frozen dataclass: the normalised value is set once, here
    object.__setattr__(effect, name, out)


@dataclass(frozen=True)
class Effect:
    """Base class: one physical effect on one variable, giving library columns.

    Subclasses are frozen dataclasses (hashable, picklable, compared by
    value). The library calls the methods below with ``x``, the 1-D array of
    the effect's variable, and ``k``, the column within the effect.

    Parameters
    ----------
    variable : int or str
        The variable the effect acts on: a column index of the library's
        input (states, then inputs) or a name (resolved against the
        library's ``names`` or pysindy's ``input_features``).
    """

    variable: int | str

    _NONSMOOTH = True

    def __post_init__(self):
        _check_variable(self)

    @property
    def nonsmooth(self) -> bool:
        """Whether the columns have a kink or a jump (a switching surface)."""
        return self._NONSMOOTH

    @property
    def n_columns(self) -> int:
        return 1

    def column_name(self, var: str, k: int) -> str:  # pragma: no cover - abstract
        raise NotImplementedError

    def value(self, x: np.ndarray, k: int, width: float = 0.0) -> np.ndarray:
        """Column ``k`` at ``x``; smoothed over ``width`` when it is > 0."""
        raise NotImplementedError  # pragma: no cover

    def derivative(self, x: np.ndarray, k: int, width: float = 0.0) -> np.ndarray:
        """``d value / dx`` (exact, or of the smoothed column)."""
        raise NotImplementedError  # pragma: no cover

    def switching(self, x: np.ndarray, k: int) -> np.ndarray:
        """A function of ``x`` that changes sign exactly at the kinks.

        ``x`` itself unless the effect says otherwise; smooth effects return
        ones (no switch).
        """
        return np.array(x, dtype=float) if self._NONSMOOTH else np.ones(len(x))


@dataclass(frozen=True)
class Coulomb(Effect):
    """Coulomb friction: ``sign(x)`` (``sign(0) = 0``), column ``sign(x)``."""

    def column_name(self, var, k):
        return f"sign({var})"

    def value(self, x, k, width=0.0):
        return _step(x, width)

    def derivative(self, x, k, width=0.0):
        return _dstep(x, width)  # exact: a jump at 0, flat elsewhere


@dataclass(frozen=True)
class SmoothCoulomb(Effect):
    """Coulomb friction smoothed over ``width``: ``tanh(x/width)``.

    Parameters
    ----------
    variable : int or str
    width : float, > 0
        Speed of the transition; column ``tanh(x/width)`` (``%g``).
    """

    width: float
    _NONSMOOTH = False

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "width", _positive(self.width, "width", self))

    def column_name(self, var, k):
        return f"tanh({var}/{self.width:g})"

    def value(self, x, k, width=0.0):
        return np.tanh(x / self.width)  # smooth already: width is ignored

    def derivative(self, x, k, width=0.0):
        return (1.0 - np.tanh(x / self.width) ** 2) / self.width


@dataclass(frozen=True)
class Stribeck(Effect):
    """Stribeck (breakaway) friction: ``sign(x) exp(-(x/velocity)^2)``.

    Parameters
    ----------
    variable : int or str
    velocity : float, > 0
        Stribeck velocity; column ``sign(x) exp(-(x/velocity)^2)`` (``%g``).
    """

    velocity: float

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "velocity", _positive(self.velocity, "velocity", self))

    def column_name(self, var, k):
        return f"sign({var}) exp(-({var}/{self.velocity:g})^2)"

    def value(self, x, k, width=0.0):
        return _step(x, width) * np.exp(-((x / self.velocity) ** 2))

    def derivative(self, x, k, width=0.0):
        # d/dx [step(x) e^(-(x/c)^2)] = (step' - 2 x step / c^2) e^(-(x/c)^2);
        # exact: -2 |x| / c^2 e^(-(x/c)^2), 0 at the jump
        c = self.velocity
        bump = np.exp(-((x / c) ** 2))
        return (_dstep(x, width) - 2.0 * x * _step(x, width) / c**2) * bump


@dataclass(frozen=True)
class ViscousSplit(Effect):
    """Direction-dependent viscous friction: ``max(x, 0)``, ``min(x, 0)``.

    Two columns, ``x+`` and ``x-``; a different coefficient on each is a
    damper that differs between the two directions.
    """

    @property
    def n_columns(self) -> int:
        return 2

    def column_name(self, var, k):
        return f"{var}+" if k == 0 else f"{var}-"

    def value(self, x, k, width=0.0):
        up = _ramp(x, width)
        return up if k == 0 else x - up  # the two always sum to x

    def derivative(self, x, k, width=0.0):
        up = _dramp(x, width)  # from above at the kink: the two sum to 1
        return up if k == 0 else 1.0 - up


@dataclass(frozen=True)
class Saturation(Effect):
    """Saturation at ``+-L``: ``clip(x, -L, L)``, one column per level.

    Parameters
    ----------
    variable : int or str
    levels : float or sequence of float, each > 0
        Candidate limits ``L``; columns ``sat(x, L)`` (``%g``). Stored as a
        tuple of floats.
    """

    levels: float | tuple

    def __post_init__(self):
        super().__post_init__()
        _levels(self, "levels", positive=True)

    @property
    def n_columns(self) -> int:
        return len(self.levels)

    def column_name(self, var, k):
        return f"sat({var}, {self.levels[k]:g})"

    def value(self, x, k, width=0.0):
        level = self.levels[k]
        if width == 0:
            return np.clip(x, -level, level)
        return x - _ramp(x - level, width) + _ramp(-x - level, width)

    def derivative(self, x, k, width=0.0):
        level = self.levels[k]
        if width == 0:
            return ((x >= -level) & (x < level)).astype(float)
        return 1.0 - _dramp(x - level, width) - _dramp(-x - level, width)

    def switching(self, x, k):
        return np.abs(x) - self.levels[k]  # > 0 where saturated


@dataclass(frozen=True)
class DeadZone(Effect):
    """Dead zone of half-width ``w``: ``x - w`` above, ``x + w`` below, else 0.

    Parameters
    ----------
    variable : int or str
    widths : float or sequence of float, each > 0
        Candidate half-widths ``w``; columns ``dz(x, w)`` (``%g``). Stored as
        a tuple of floats.
    """

    widths: float | tuple

    def __post_init__(self):
        super().__post_init__()
        _levels(self, "widths", positive=True)

    @property
    def n_columns(self) -> int:
        return len(self.widths)

    def column_name(self, var, k):
        return f"dz({var}, {self.widths[k]:g})"

    def value(self, x, k, width=0.0):
        half = self.widths[k]
        if width == 0:
            return x - np.clip(x, -half, half)
        return _ramp(x - half, width) - _ramp(-x - half, width)

    def derivative(self, x, k, width=0.0):
        half = self.widths[k]
        if width == 0:
            return ((x >= half) | (x < -half)).astype(float)
        return _dramp(x - half, width) + _dramp(-x - half, width)

    def switching(self, x, k):
        return np.abs(x) - self.widths[k]  # > 0 outside the dead zone


@dataclass(frozen=True)
class Torricelli(Effect):
    """Torricelli outflow: ``sqrt(max(x, 0))``, column ``sqrt(x+)``.

    Its derivative ``1 / (2 sqrt(x))`` is infinite at 0; it is set to 0 for
    ``x <= 0`` (an empty tank) so that gradients stay finite.
    """

    def column_name(self, var, k):
        return f"sqrt({var}+)"

    def value(self, x, k, width=0.0):
        return np.sqrt(_ramp(x, width))

    def derivative(self, x, k, width=0.0):
        out = np.zeros(len(x))
        level = _ramp(x, width)
        full = level > 0  # smoothed: everywhere, with a finite slope at 0
        out[full] = 0.5 / np.sqrt(level[full]) * _dramp(x[full], width)
        return out


@dataclass(frozen=True)
class Overflow(Effect):
    """Overflow above a level: ``max(x - L, 0)``, one column per level.

    Parameters
    ----------
    variable : int or str
    levels : float or sequence of float
        Candidate heights ``L`` (any sign); columns ``over(x, L)`` (``%g``).
        Stored as a tuple of floats.
    """

    levels: float | tuple

    def __post_init__(self):
        super().__post_init__()
        _levels(self, "levels", positive=False)

    @property
    def n_columns(self) -> int:
        return len(self.levels)

    def column_name(self, var, k):
        return f"over({var}, {self.levels[k]:g})"

    def value(self, x, k, width=0.0):
        return _ramp(x - self.levels[k], width)

    def derivative(self, x, k, width=0.0):
        return _dramp(x - self.levels[k], width)

    def switching(self, x, k):
        return x - self.levels[k]
