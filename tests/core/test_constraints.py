"""Declarative parameter constraints: one check per parameter, one message."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from pysindy_mme.core.constraints import (
    Boolean,
    Integer,
    Interval,
    Options,
    check_parameter,
)
from pysindy_mme.optimizers import FloatingFStepwise
from pysindy_mme.optimizers._checks import PARAMETER_CONSTRAINTS


@pytest.mark.parametrize(
    "constraint, good, bad",
    [
        (Interval(0.0, 1.0, closed="neither"), [1e-9, 0.5, 1 - 1e-9], [0, 1, -1]),
        (Interval(0.0, 1.0, closed="both"), [0, 0.5, 1], [-1e-12, 1.0000001]),
        (Interval(1.0, None, closed="left"), [1, 1e300], [0.999, np.inf, np.nan]),
        (Interval(None, 0.0, closed="neither"), [-1e-300, -5], [0, 3]),
        (Integer(1), [1, np.int64(7)], [0, -3]),
        (Boolean(), [True, False, np.bool_(True)], []),
        (Options("auto", "off"), ["auto", "off"], ["Auto", "on"]),
    ],
)
def test_each_constraint_accepts_exactly_its_values(constraint, good, bad):
    for value in good:
        check_parameter("p", value, [constraint])
    for value in bad:
        with pytest.raises(ValueError, match=r"^p must be .*, got "):
            check_parameter("p", value, [constraint])


@pytest.mark.parametrize(
    "value, constraints",
    [
        ("0.5", [Interval(0.0, 1.0)]),  # a string that parses is still a slip
        (True, [Interval(0.0, 1.0)]),  # so is a bool for a number
        (1.0, [Integer(1)]),
        (1, [Boolean()]),
        (None, [Boolean()]),
        (0.5, [Options("auto")]),
    ],
)
def test_a_value_of_the_wrong_kind_is_a_type_error(value, constraints):
    with pytest.raises(TypeError, match=r"^p must be "):
        check_parameter("p", value, constraints)


def test_the_message_lists_every_alternative():
    allowed = [None, Boolean(), Options("auto")]
    check_parameter("p", None, allowed)
    with pytest.raises(ValueError) as err:
        check_parameter("p", "sometimes", allowed)
    assert str(err.value) == "p must be None, True or False or 'auto', got 'sometimes'"


def test_every_stepwise_parameter_has_one_declared_check():
    """The table covers the constructor (initial_guess: its own check, with the
    reason), and each entry's message starts with the parameter's name."""
    names = set(inspect.signature(FloatingFStepwise).parameters)
    assert set(PARAMETER_CONSTRAINTS) == names - {"initial_guess"}
    for name in PARAMETER_CONSTRAINTS:
        with pytest.raises(ValueError, match=rf"^{name} must be "):
            FloatingFStepwise(**{name: "bogus"}).fit(np.eye(3), np.ones(3))
