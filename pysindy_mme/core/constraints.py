"""Declarative parameter constraints: one check per parameter, one message.

An estimator lists what each of its parameters may be in one table
(scikit-learn's ``_parameter_constraints`` is the model; ours is not named
so, since scikit-learn's own checks would read it with its own types)::

    PARAMETER_CONSTRAINTS = {
        "alpha": [Interval(0.0, 1.0, closed="neither")],
        "floating": [Boolean(), Options("auto")],
        "f_enter": [None, Interval(0.0, None, closed="neither")],
    }

and :func:`check_parameters` checks them all before any work: a value is
accepted if it meets any constraint of its list (``None`` in the list admits
None); otherwise a ``ValueError`` (``TypeError`` when no constraint accepts
the value's kind) whose message starts with the parameter's name and lists
what is allowed. Rules that tie two parameters together (``f_remove <=
f_enter``) stay with the estimator: a table cannot say them.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

__all__ = ["Boolean", "Integer", "Interval", "Options", "check_parameters"]


def _is_bool(value) -> bool:
    return isinstance(value, (bool, np.bool_))


def _is_real(value) -> bool:
    return isinstance(value, numbers.Real) and not _is_bool(value)


@dataclass(frozen=True)
class Interval:
    """A finite real number in an interval; ``None`` for an open end.

    ``closed``: "both", "left", "right" or "neither" (which ends belong).
    """

    low: float | None
    high: float | None
    closed: str = "both"

    def kind_matches(self, value) -> bool:
        return _is_real(value)

    def accepts(self, value) -> bool:
        if not self.kind_matches(value) or not math.isfinite(float(value)):
            return False
        value = float(value)
        left = self.closed in ("both", "left")
        right = self.closed in ("both", "right")
        if self.low is not None and (
            value < self.low or (not left and value == self.low)
        ):
            return False
        if self.high is not None and (
            value > self.high or (not right and value == self.high)
        ):
            return False
        return True

    def describe(self) -> str:
        left = self.closed in ("both", "left")
        right = self.closed in ("both", "right")
        low, high = self.low, self.high
        if low is not None and high is not None and left == right:
            where = "strictly between" if not left else "between"
            return f"a finite number {where} {low:g} and {high:g}"
        parts = []
        if low is not None:
            parts.append(f"{'>=' if left else '>'} {low:g}")
        if high is not None:
            parts.append(f"{'<=' if right else '<'} {high:g}")
        return "a finite number" + (" " + " and ".join(parts) if parts else "")


@dataclass(frozen=True)
class Integer:
    """An integer (not a bool) of at least ``low``."""

    low: int | None = None

    def kind_matches(self, value) -> bool:
        return isinstance(value, numbers.Integral) and not _is_bool(value)

    def accepts(self, value) -> bool:
        return self.kind_matches(value) and (self.low is None or value >= self.low)

    def describe(self) -> str:
        return "an integer" + ("" if self.low is None else f" >= {self.low}")


@dataclass(frozen=True)
class Boolean:
    """True or False (numpy's bools included)."""

    def kind_matches(self, value) -> bool:
        return _is_bool(value)

    def accepts(self, value) -> bool:
        return _is_bool(value)

    def describe(self) -> str:
        return "True or False"


class Options:
    """One of a few fixed values (strings compared by equality)."""

    def __init__(self, *values):
        self.values = tuple(values)

    def kind_matches(self, value) -> bool:
        return any(type(value) is type(v) for v in self.values)

    def accepts(self, value) -> bool:
        return any(type(value) is type(v) and value == v for v in self.values)

    def describe(self) -> str:
        words = [repr(v) for v in self.values]
        return (
            words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]
        )


def _either(words) -> str:
    """'a', 'a or b', 'a, b or c'."""
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]


def _allowed(constraints) -> str:
    return _either(["None" if c is None else c.describe() for c in constraints])


def check_parameter(name: str, value, constraints) -> None:
    """Raise unless ``value`` meets one of ``constraints`` (see the module)."""
    if value is None and None in constraints:
        return
    rules = [c for c in constraints if c is not None]
    if any(c.accepts(value) for c in rules):
        return
    error = ValueError if any(c.kind_matches(value) for c in rules) else TypeError
    raise error(f"{name} must be {_allowed(constraints)}, got {value!r}")


def check_parameters(estimator, constraints: dict) -> None:
    """Check every parameter of ``estimator`` listed in ``constraints``."""
    for name, allowed in constraints.items():
        check_parameter(name, getattr(estimator, name), allowed)
