"""choose_input_hold: the input hold chosen on the training record alone.

Simulated records where the right answer is known: a damped oscillator
``x'' = -x - 0.2 x' + u``, its position measured with noise of standard
deviation 1e-3, the assumed model exact, driven at 4 Hz by

- a smooth input (two sines): cubic interpolation between samples is nearly
  exact, linear interpolation cuts the curvature, a zero-order hold lags;
- a staircase (random levels, each held for one sample, as a DAC does):
  the zero-order hold is exact;
- a ramp between random levels (each segment joins two samples): linear
  interpolation is exact, cubics overshoot at the corners.

Each case must choose its own hold, with the winner's held-out error at the
noise level; the table printed is the table the choice was made from.
"""

from __future__ import annotations

import re

import numpy as np
import pysindy as ps
import pytest
from bad_input_support import Bad, assert_raises_as_documented, params

from pysindy_mme import MME, StudyOptions
from pysindy_mme.core.model import simulate_model
from pysindy_mme.discovery import choices
from pysindy_mme.discovery.choices import HoldChoice, choose_input_hold
from pysindy_mme.exceptions import DivergenceError

RATE = 4.0  # Hz: coarse for the inputs below
NOISE_SD = 1e-3
LEVELS = np.random.default_rng(1).standard_normal(400)


def oscillator(x, t, u):
    return np.column_stack([x[:, 1], -x[:, 0] - 0.2 * x[:, 1] + u[:, 0]])


def smooth(t):
    t = np.asarray(t, dtype=float)
    return (np.sin(1.7 * t) + 0.8 * np.sin(2.9 * t + 0.5))[..., None]


def staircase(t):
    k = np.floor(np.asarray(t, dtype=float) * RATE + 1e-9).astype(int)
    return LEVELS[np.clip(k, 0, LEVELS.size - 1)][..., None]


def ramps(t):
    grid = np.arange(LEVELS.size) / RATE
    return np.interp(np.asarray(t, dtype=float), grid, LEVELS)[..., None]


def record(u_of_t, seed=0, t_end=60.0):
    """``(y, t, u)``: the oscillator driven by the exact ``u(t)``; ``u`` its samples."""
    t = np.arange(int(round(t_end * RATE)) + 1) / RATE
    x = simulate_model(oscillator, (0.0, 0.0), t, u_of_t, n_states=2, rtol=1e-10)
    rng = np.random.default_rng(seed)
    y = x[:, :1] + NOISE_SD * rng.standard_normal((t.size, 1))
    return y, t, u_of_t(t)


OPTIONS = dict(
    assumed_model=oscillator,
    n_states=2,
    measured=[0],
    noise_variance=NOISE_SD**2,
    error_states=[1],
    feature_library=ps.PolynomialLibrary(degree=2),
    options=StudyOptions(feature_names=["x", "v", "u"]),
)


def _table_rows(text):
    """``{hold: rmse}`` and the marked hold, read back from the printed table."""
    rows, marked = {}, None
    for hold, mark, value in re.findall(
        r"^\| (\w+)( \(chosen\))? \| (\S+) \|$", text, re.M
    ):
        rows[hold] = float(value)
        if mark:
            marked = hold
    return rows, marked


@pytest.mark.parametrize(
    "u_of_t, right", [(smooth, "cubic"), (staircase, "zoh"), (ramps, "linear")]
)
@pytest.mark.parametrize("seed", [0, 1])
def test_each_input_chooses_its_own_hold(u_of_t, right, seed):
    y, t, u = record(u_of_t, seed)
    choice = choose_input_hold(y, t, u, window=10, **OPTIONS)
    assert isinstance(choice, HoldChoice)
    assert choice.hold == right, choice.score
    assert choice.holds == ("linear", "zoh", "cubic")
    assert choice.n_fit + choice.n_held_out == t.size
    assert choice.n_held_out == round(0.25 * t.size) and choice.window == 10
    # the winner simulates the held-out stretch to the noise level, every
    # other hold at least 1.5 times worse
    best = float(choice.rmse[right][0])
    assert best < 1.5 * NOISE_SD, choice.rmse
    for hold in choice.holds:
        if hold != right:
            assert choice.rmse[hold][0] > 1.5 * best, choice.rmse
    # what is printed is what was chosen from
    rows, marked = _table_rows(choice.table())
    assert set(rows) == set(choice.holds) and marked == right
    assert min(rows, key=rows.get) == right
    assert "Chosen: " + right in str(choice)
    # the studies were run on the fit part with their hold
    for hold, res in choice.studies.items():
        assert res.study.inputs.hold == hold
        assert res.study.t.size == choice.n_fit


def test_table_scales_and_names_the_unit():
    y, t, u = record(smooth)
    choice = choose_input_hold(
        y, t, u, holds=("linear", "cubic"), held_out=60, window=10, **OPTIONS
    )
    assert choice.holds == ("linear", "cubic") and choice.n_held_out == 60
    text = choice.table(1e3, "mV")
    assert "| hold | training held-out RMSE (mV) |" in text
    rows, _ = _table_rows(text)
    assert rows["cubic"] == pytest.approx(1e3 * choice.rmse["cubic"][0], rel=1e-2)


def test_a_diverging_study_loses_and_all_diverging_raises(monkeypatch):
    y, t, u = record(smooth)
    real = choices.discover

    def fragile(*args, mme, **kwargs):
        if mme.input_hold == "cubic":
            raise DivergenceError("the model blew up")
        return real(*args, mme=mme, **kwargs)

    monkeypatch.setattr(choices, "discover", fragile)
    choice = choose_input_hold(y, t, u, window=10, **OPTIONS)
    assert choice.hold == "linear"  # cubic would have won, but diverged
    assert choice.studies["cubic"] is None
    assert "blew up" in choice.failures["cubic"]
    assert "| cubic | diverged |" in choice.table()

    def broken(*args, **kwargs):
        raise DivergenceError("the model blew up")

    monkeypatch.setattr(choices, "discover", broken)
    with pytest.raises(DivergenceError, match="no input hold gave a finite"):
        choose_input_hold(y, t, u, window=10, **OPTIONS)


_Y, _T, _U = record(smooth, t_end=20.0)


def _call(**changes):
    arguments = dict(y=_Y, t=_T, u=_U, window=10, **OPTIONS)
    arguments.update(changes)
    y, t, u = arguments.pop("y"), arguments.pop("t"), arguments.pop("u")
    return lambda tmp_path: choose_input_hold(y, t, u, **arguments)


BAD_INPUTS = [
    Bad(
        "hold given",
        _call(mme=MME(input_hold="cubic")),
        TypeError,
        "does not take input_hold",
    ),
    Bad("validation given", _call(validation=(_Y, _T, _U)), TypeError, "validation"),
    Bad("unknown hold", _call(holds=("quadratic",)), ValueError, "holds must be"),
    Bad("no hold", _call(holds=()), ValueError, "holds must be"),
    Bad("hold twice", _call(holds=("zoh", "zoh")), ValueError, "distinct"),
    Bad("fraction 0", _call(held_out=0.0), ValueError, "strictly between"),
    Bad("fraction 1.5", _call(held_out=1.5), ValueError, "strictly between"),
    Bad("held_out text", _call(held_out="25%"), TypeError, "fraction or a count"),
    Bad("stretch too short", _call(held_out=11), ValueError, "window \\+ 2"),
    Bad("fit too short", _call(held_out=_T.size - 5), ValueError, "window \\+ 2"),
    Bad("window 0", _call(window=0), ValueError, "at least 1"),
    Bad("window float", _call(window=5.0), TypeError, "integer"),
    Bad("u missing", _call(u=None), TypeError, "u is required"),
    Bad("u short", _call(u=_U[:-1]), ValueError, "u has"),
    Bad("t short", _call(t=_T[:-1]), ValueError, "entries"),
    Bad(
        "y with inf", _call(y=np.where(_T[:, None] > 3, np.inf, _Y)), ValueError, "inf"
    ),
]


@pytest.mark.parametrize("case", params(BAD_INPUTS))
def test_bad_input(case, tmp_path, no_long_computation):
    assert_raises_as_documented(case, tmp_path)
