"""The advice for a doubtful grey-box parameter names the user's parameter.

A verdict that says "try parameters={'M': (90.0, 50.0, 200.0)}" on a model
whose parameters are a1, b, a2, a3 sends the user after a parameter they do
not have (it was the advice on every model until session 10). The advice is
written from the study's own parameters: a bound that keeps the sign of a
parameter that changed sign, bounds within ``RUNAWAY_FACTOR`` of the guess
for one that ran away, the user's own bounds kept.
"""

from __future__ import annotations

import ast
from types import SimpleNamespace

import numpy as np

from pysindy_mme.discovery.conclusion import RUNAWAY_FACTOR
from pysindy_mme.discovery.study import _parameter_doubts


def _study(names, init, bounds=None, gauge=None):
    n = len(names)
    return SimpleNamespace(
        parameter_names=list(names),
        parameter_init=np.asarray(init, float),
        parameter_bounds=np.asarray(
            bounds if bounds is not None else [(-np.inf, np.inf)] * n, float
        ),
        parameter_gauge=np.asarray(gauge if gauge is not None else [False] * n),
    )


def _fit(values, at_bound=None):
    n = len(values)
    return SimpleNamespace(
        physical=np.asarray(values, float),
        at_bound=np.asarray(at_bound if at_bound is not None else [False] * n),
    )


def _spec(advice: str) -> dict:
    """The ``parameters={...}`` dict the advice writes, parsed as Python."""
    start = advice.index("parameters={") + len("parameters=")
    depth = 0
    for end in range(start, len(advice)):
        depth += {"{": 1, "}": -1}.get(advice[end], 0)
        if depth == 0:
            return ast.literal_eval(advice[start : end + 1])
    raise AssertionError(f"unbalanced braces in {advice!r}")


def test_a_sign_change_is_advised_a_bound_at_zero_in_its_own_name():
    study = _study(["a1", "b", "a2", "a3"], [0.03, 0.05, 0.03, 0.03])
    sentences, advice = _parameter_doubts(study, _fit([0.04, 0.05, 0.041, -0.0087]))
    assert sentences == ["a3 changed sign: 0.03 guessed, -0.0087 fitted"]
    assert _spec(advice) == {"a3": (0.03, 0, None)}
    assert "'M'" not in advice


def test_a_negative_guess_keeps_its_sign_from_above():
    study = _study(["c"], [-2.0])
    _, advice = _parameter_doubts(study, _fit([0.5]))
    assert _spec(advice) == {"c": (-2.0, None, 0)}


def test_a_runaway_is_bounded_around_its_guess_within_the_users_bounds():
    study = _study(["k", "m"], [1.0, 90.0], bounds=[(0.5, np.inf), (0.0, np.inf)])
    sentences, advice = _parameter_doubts(study, _fit([1.1, 4.7e4]))
    assert len(sentences) == 1 and sentences[0].startswith("m moved from the guess 90")
    guess, lower, upper = _spec(advice)["m"]
    assert (guess, lower, upper) == (90.0, 90.0 / RUNAWAY_FACTOR, 90.0 * RUNAWAY_FACTOR)
    # the user's own lower bound is kept when it is tighter
    study = _study(["m"], [90.0], bounds=[(50.0, np.inf)])
    _, advice = _parameter_doubts(study, _fit([1e4]))
    assert _spec(advice)["m"] == (90.0, 50.0, 900.0)


def test_several_doubts_in_one_dict_and_bounds_named():
    study = _study(
        ["a", "b", "c"], [1.0, 2.0, 3.0], bounds=[(-9, 9), (0, 2.5), (-9, 9)]
    )
    sentences, advice = _parameter_doubts(
        study, _fit([-1.0, 2.5, 300.0], at_bound=[False, True, False])
    )
    assert len(sentences) == 3
    assert set(_spec(advice)) == {"a", "c"}
    assert "checking the bound of b" in advice


def test_gauges_and_quiet_parameters_give_no_advice():
    study = _study(["a", "b"], [1.0, 2.0], gauge=[True, False])
    sentences, advice = _parameter_doubts(study, _fit([-5.0, 2.2]))
    assert sentences == [] and advice is None


def test_the_command_line_form_parses_to_the_same_bounds():
    from pysindy_mme.cli.arguments import parse_parameters

    study = _study(
        ["a1", "a3", "m"], [0.03, 0.03, 90.0], bounds=[(-1, 1), (-1, 1), (0, 500)]
    )
    _, advice = _parameter_doubts(study, _fit([0.03, -0.0087, 4.7e4]))
    flags = advice.split("command line: --parameters ", 1)[1].split(",...)", 1)[0]
    assert parse_parameters(flags) == _spec(advice)
