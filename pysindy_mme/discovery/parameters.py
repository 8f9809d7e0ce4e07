"""Grey-box parameters: an initial guess and optional bounds.

``discover(..., parameters={...})`` takes, per parameter name, a number (the
guess, unbounded), a tuple ``(guess, lower, upper)`` with ``None`` for a
missing bound, or a :class:`Parameter`. :func:`parameter_spec` turns any of
them into ``(guess, lower, upper)`` floats (``-inf`` / ``inf`` for no bound)
or raises an error that names the parameter.

The bounds form a closed box: a fitted value may end on a bound (the output
error fit then reports the parameter as ``at_bound``), so a guess on a bound
is accepted too; the assumed model is evaluated at the guess first, so it
must be defined there (a mass bounded below by 0 must not start at 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Parameter", "parameter_spec"]


def _number(value, what: str) -> float:
    """``value`` as a float, or a TypeError saying ``what`` must be a number."""
    # bool converts to a float, but True as a mass is a slip, not a number;
    # so is a string that happens to parse
    if not isinstance(value, (bool, str, bytes)) and np.ndim(value) == 0:
        try:
            return float(value)
        except (TypeError, ValueError):
            pass
    raise TypeError(f"{what} must be a number, got {value!r}")


def _bound(value, none: float, what: str) -> float:
    """A bound as a float (``none`` for None)."""
    if value is None:
        return none
    try:
        return _number(value, what)
    except TypeError:
        raise TypeError(f"{what} must be a number or None, got {value!r}") from None


def _checked(value, lower, upper, where: str, guess: str) -> tuple:
    """``(guess, lower, upper)`` floats, checked.

    ``where`` starts the messages about the bounds, ``guess`` names the guess
    in its own (``parameters: k must be finite``).
    """
    value = _number(value, guess)
    if not np.isfinite(value):
        raise ValueError(f"{guess} must be finite, got {value!r}")
    lo = _bound(lower, -np.inf, f"{where}: the lower bound")
    hi = _bound(upper, np.inf, f"{where}: the upper bound")
    if np.isnan(lo) or np.isnan(hi):
        raise ValueError(f"{where}: a bound is NaN; use None for no bound")
    if not lo < hi:
        raise ValueError(
            f"{where}: the lower bound {lo:g} must be below the upper bound {hi:g}"
        )
    if not lo <= value <= hi:
        raise ValueError(
            f"{where}: the guess {value:g} is outside its bounds [{lo:g}, {hi:g}]"
        )
    return value, lo, hi


@dataclass(frozen=True)
class Parameter:
    """An unknown parameter of the assumed model: its guess and bounds.

    Checked when it is made (``lower < upper``, a finite guess in
    ``[lower, upper]``); the fitted value never leaves ``[lower, upper]``.

    Parameters
    ----------
    value : float
        Initial guess (finite). It may lie on a bound, where the assumed
        model must then be defined (it is evaluated there first).
    lower, upper : float or None
        Bounds; None (or an infinite value) for none.

    Examples
    --------
    >>> Parameter(90.0, lower=1.0)
    Parameter(value=90.0, lower=1.0, upper=None)
    """

    value: float
    lower: float | None = None
    upper: float | None = None

    def __post_init__(self):
        guess, lo, hi = _checked(
            self.value, self.lower, self.upper, "Parameter", "Parameter: the guess"
        )
        # frozen: store the checked floats (None kept for a missing bound)
        object.__setattr__(self, "value", guess)
        object.__setattr__(self, "lower", None if self.lower is None else lo)
        object.__setattr__(self, "upper", None if self.upper is None else hi)

    @property
    def bounds(self) -> tuple:
        """``(lower, upper)`` as floats, ``-inf`` / ``inf`` where unbounded."""
        lo = -np.inf if self.lower is None else self.lower
        hi = np.inf if self.upper is None else self.upper
        return float(lo), float(hi)


def parameter_spec(name: str, spec) -> tuple:
    """``(guess, lower, upper)`` of one entry of ``parameters=``, checked.

    ``spec`` is a number, a tuple (or list) ``(guess, lower, upper)`` with
    None for a missing bound, or a :class:`Parameter`. Errors name the
    parameter (``parameters: M: ...``).
    """
    where = f"parameters: {name}"
    if isinstance(spec, Parameter):
        return (spec.value, *spec.bounds)
    if isinstance(spec, (tuple, list)):
        if len(spec) != 3:
            raise ValueError(
                f"{where} must be a number, (guess, lower, upper) or "
                f"Parameter(guess, lower, upper); got {len(spec)} values {spec!r}"
            )
        return _checked(*spec, where, f"{where}: the guess")
    try:
        guess = _number(spec, where)
    except TypeError:
        raise TypeError(
            f"{where} must be a number, (guess, lower, upper) or "
            f"Parameter(guess, lower, upper); got {spec!r}"
        ) from None
    return _checked(guess, None, None, where, where)
