"""The command line's bad-input table: slips, each of which must print a
message that names the option (or file and line) and what to do.

Errors end with exit code 2, one line ``pysindy-mme: error: ...`` and no
output folder. Every slip runs with the tripwires of ``bad_input_support.py``
in place (the checks come before any solver), except the few marked
``in_solver``, which fail inside MME's first integration on purpose.
``tests/test_bad_input_coverage.py`` checks this table under its own names
(``SLIPS``, ``test_command_line_slip_is_named``).

Warnings are printed as ``pysindy-mme: warning: ...`` lines.
"""

import contextlib
import io
import re
from dataclasses import dataclass, field

import numpy as np
import pytest
from cli_support import MODEL_FILE, base_args, run, write_user_files

from pysindy_mme.cli import main

ENTRY_POINT = "command line"


def _line_of(text, needle):
    """1-based line number of ``needle`` in ``text``."""
    return next(k for k, line in enumerate(text.splitlines(), 1) if needle in line)


@dataclass(frozen=True)
class Slip:
    id: str
    changes: dict = field(default_factory=dict)  # option -> value (None: drop)
    phrases: tuple = ()  # each must appear in the message
    csv_text: str | None = None
    files: dict = field(default_factory=dict)  # extra files written to tmp
    data_file: str | None = None  # replaces data.csv in the command
    in_solver: bool = False  # fails inside a solver on purpose: no tripwires


BROKEN_AT_IMPORT = "import numpy as np\nraise RuntimeError('broken on import')\n"
SYNTAX_ERROR = "import numpy as np\n\ndef f(x, t)\n    return x\n"
WRONG_SHAPE = "def f(x, t):\n    return x[:, :1]\n"
EXPLODES = """import numpy as np


def f(x, t):
    return np.column_stack([x[:, 1] + 1e8 * x[:, 0] ** 2, np.zeros(len(x))])
"""
HEADER = "time,position\n"

SLIPS = [
    Slip(
        "missing data file",
        data_file="nope.csv",
        phrases=("data file", "nope.csv does not exist", "first argument"),
    ),
    Slip(
        "measured column not in the CSV",
        {"states": "position,speed", "measured": "speed", "error_states": "speed"},
        ("--measured: column 'speed' is not in the CSV", "use a column name"),
    ),
    Slip(
        "time column not in the CSV",
        {"time": "clock"},
        ("--time: column 'clock' is not in the CSV", "--rate HZ"),
    ),
    Slip(
        "non-numeric cell",
        csv_text="time,position\n0,1.0\n0.1,abc\n0.2,1.0\n",
        phrases=("line 3, column 'position': 'abc' is not a number", "leave a cell"),
    ),
    Slip(
        "model file with a syntax error",
        {"model": "{tmp}/bad_syntax.py:f"},
        ("bad_syntax.py:3: SyntaxError", "fix the file given to --model"),
        files={"bad_syntax.py": SYNTAX_ERROR},
    ),
    Slip(
        "model file raising at import",
        {"model": "{tmp}/broken.py:f"},
        (
            "broken.py:2: RuntimeError: broken on import",
            "fix the file given to --model",
        ),
        files={"broken.py": BROKEN_AT_IMPORT},
    ),
    Slip(
        "model raising on its first evaluation",
        {"model": "{tmp}/model.py:divides"},
        (f"model.py:{_line_of(MODEL_FILE, '1 / 0')}:", "ZeroDivisionError", "--model"),
    ),
    Slip(
        "model raising during the study",
        {"model": "{tmp}/model.py:fails_later"},
        (
            f"model.py:{_line_of(MODEL_FILE, 'lookup table')}: RuntimeError: lookup "
            "table out of range",
            "raised by the model given to --model during the study",
        ),
    ),
    Slip(
        "unknown library",
        {"library": "fourier"},
        ("--library: invalid choice: 'fourier'", "use poly, power, or FILE.py:NAME"),
    ),
    Slip(
        "library file naming a model, not a library",
        {"library": "{tmp}/model.py:f"},
        ("--library: 'f' in", "is not a pysindy feature library"),
    ),
    Slip(
        "train rows not a range",
        {"train_rows": "10-20"},
        ("--train-rows: '10-20' is not a row range", "e.g. --train-rows 0:1000"),
    ),
    Slip(
        "train rows beyond the CSV",
        {"train_rows": "0:5000"},
        ("--train-rows 0:5000: the CSV has only 801 data rows",),
    ),
    Slip(
        "validation rows overlapping the training rows",
        {"validation_rows": "600:"},
        (
            "--validation-rows 600: overlaps the training rows 0:801",
            "--train-rows 0:600",
        ),
    ),
    Slip(
        "validation window without validation rows",
        {"validation_window": "30"},
        ("--validation-window needs --validation-rows",),
    ),
    Slip(
        "rate given with a time column",
        {"rate": "40"},
        ("--rate and --time both given", "not both"),
    ),
    Slip("rate zero", {"rate": "0", "time": None}, ("--rate must be > 0",)),
    Slip(
        "unknown input column",
        {"inputs": "force", "model": "{tmp}/model.py:with_input"},
        ("--inputs: column 'force' is not in the CSV",),
    ),
    Slip(
        "model takes an input but no --inputs",
        {"model": "{tmp}/model.py:with_input"},
        ("--model: with_input takes an input u", "--inputs"),
    ),
    Slip(
        "error state not a state",
        {"error_states": "acceleration"},
        ("--error-states: 'acceleration' is not one of --states",),
    ),
    Slip(
        "measured name not a state",
        {"measured": "speed"},
        ("--measured: 'speed' is not one of --states",),
    ),
    Slip(
        "parameters without values",
        {"parameters": "k,c", "model": "{tmp}/model.py:g"},
        ("--parameters: 'k' has no value", "e.g. --parameters k=1.0,c=0.1"),
    ),
    Slip(
        "parameter bounds out of order",
        {"parameters": "k=1.0:2:0,c=0.1", "model": "{tmp}/model.py:g"},
        ("--parameters: k: the lower bound 2 must be below the upper bound 0",),
    ),
    Slip(
        "parameter bounds with one missing field",
        {"parameters": "k=1.0:0,c=0.1", "model": "{tmp}/model.py:g"},
        ("--parameters: k=1.0:0 must be GUESS or GUESS:LOWER:UPPER",),
    ),
    Slip(
        "parameters for a model that takes none",
        {"parameters": "k=1.0"},
        ("--parameters: the model f must take (x, t, u, p)",),
    ),
    Slip(
        "grey-box model without --parameters",
        {"model": "{tmp}/model.py:g"},
        ("--model: g takes 4 arguments", "--parameters NAME=VALUE"),
    ),
    Slip(
        "noise variance not a number",
        {"noise_variance": "loud"},
        ("--noise-variance must be a number or 'auto'",),
    ),
    Slip(
        "noise variance negative",
        {"noise_variance": "-1"},
        ("noise_variance must be finite and > 0", "(option --noise-variance)"),
    ),
    Slip(
        "model spec without a function",
        {"model": "{tmp}/model.py"},
        ("--model must look like FILE.py:FUNCTION", "e.g. --model my_model.py:f"),
    ),
    Slip(
        "model function missing",
        {"model": "{tmp}/model.py:h"},
        ("--model:", "defines no function 'h'", "it defines"),
    ),
    Slip("degree zero", {"degree": "0"}, ("--degree must be >= 1",)),
    Slip(
        "input hold unknown",
        {"input_hold": "spline"},
        ("--input-hold must be one of linear, zoh",),
    ),
    Slip(
        "error model unknown",
        {"error_model": "smooth"},
        ("--error-model must be one of white, random_walk", "got 'smooth'"),
    ),
    Slip("states repeated", {"states": "position,position"}, ("--states repeats",)),
    Slip(
        "model file does not exist",
        {"model": "{tmp}/missing.py:f"},
        ("--model: file {tmp}/missing.py does not exist",),
    ),
    Slip(
        "model name is not a function",
        {"model": "{tmp}/model.py:NOT_A_FUNCTION"},
        ("--model: 'NOT_A_FUNCTION' in {tmp}/model.py is not callable",),
    ),
    Slip(
        "model returns the wrong shape",
        {"model": "{tmp}/wrong_shape.py:f"},
        ("assumed_model returned an array of shape", "(option --model)"),
        files={"wrong_shape.py": WRONG_SHAPE},
    ),
    Slip(
        "ragged CSV row",
        csv_text=HEADER + "0,1.0\n0.1,2.0,3.0\n",
        phrases=("data.csv: line 3 has 3 fields but the header has 2",),
    ),
    Slip(
        "CSV with a header only",
        csv_text=HEADER,
        phrases=("{tmp}/data.csv: needs a header row and at least one data row",),
    ),
    Slip(
        "missing time value",
        csv_text=HEADER + "0,1.0\n,2.0\n0.2,1.5\n",
        phrases=("--time: column 'time' has missing values",),
    ),
    Slip(
        "record shorter than the library",
        csv_text=HEADER + "".join(f"{0.1 * k},{np.cos(0.1 * k)}\n" for k in range(6)),
        phrases=("at least 12 samples are needed",),
    ),
    Slip(
        "model that blows up",
        {"model": "{tmp}/explodes.py:f"},
        ("blows up within one sample interval", "--model"),
        files={"explodes.py": EXPLODES},
        in_solver=True,
    ),
]


def _params(slips):
    return [pytest.param(slip, id=slip.id) for slip in slips]


@pytest.mark.parametrize("slip", _params(s for s in SLIPS if not s.in_solver))
def test_command_line_slip_is_named(tmp_path, slip, no_long_computation):
    assert_slip_is_named(tmp_path, slip)


@pytest.mark.parametrize("slip", _params(s for s in SLIPS if s.in_solver))
def test_slip_found_inside_a_solver_is_named(tmp_path, slip):
    assert_slip_is_named(tmp_path, slip)


def assert_slip_is_named(tmp_path, slip):
    """Exit code 2, one error line with the slip's phrases, nothing written."""
    csv, model, _ = write_user_files(tmp_path)
    if slip.csv_text is not None:
        csv.write_text(slip.csv_text)
    for name, text in slip.files.items():
        (tmp_path / name).write_text(text)
    if slip.data_file:
        csv = tmp_path / slip.data_file
    out = tmp_path / "never"
    changes = {
        k: (None if v is None else v.replace("{tmp}", str(tmp_path)))
        for k, v in slip.changes.items()
    }
    result = run(base_args(csv, model, out, **changes))
    assert result.code == 2, result
    lines = result.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pysindy-mme: error: "), lines
    for phrase in slip.phrases:
        phrase = phrase.replace("{tmp}", str(tmp_path))
        assert phrase in lines[0], (phrase, lines[0])
    # it names what to fix: an option, or the file (and line) of the user's input
    assert re.search(r"--[a-z]|\.py:\d+:|data file|: line \d+", lines[0]) or (
        f"{csv}: " in lines[0]
    ), lines[0]
    assert "Traceback" not in result.err
    assert not out.exists(), "bad input must not write anything"


def test_the_table_covers_at_least_twelve_slips():
    assert len(SLIPS) >= 12
    assert len({slip.id for slip in SLIPS}) == len(SLIPS), "slip ids must be unique"
    # all but a few run under the tripwires
    assert sum(not slip.in_solver for slip in SLIPS) >= 12


# ------------------------------------------------------------------ warnings


class Stop(BaseException):
    """Raised by the stand-in for discover: the command got that far."""


def _until_discover(argv, monkeypatch):
    """Standard error up to the call of discover, and discover's keywords."""
    import pysindy_mme.discovery as discovery

    captured = {}

    def stand_in(*args, **kwargs):
        captured.update(kwargs)
        raise Stop

    monkeypatch.setattr(discovery, "discover", stand_in)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        with pytest.raises(Stop):
            main([str(a) for a in argv])
    return err.getvalue(), captured


@pytest.mark.parametrize(
    "error_states, warned",
    [(None, True), ("position,velocity", True), ("velocity", False)],
)
def test_error_state_that_cannot_be_told_apart_is_warned_about(
    tmp_path, monkeypatch, error_states, warned
):
    """Only the position is measured; the velocity is seen only through
    position' = velocity, so an error allowed in position' competes with it."""
    csv, model, _ = write_user_files(tmp_path)
    argv = base_args(csv, model, tmp_path / "o", error_states=error_states)
    text, kwargs = _until_discover(argv, monkeypatch)
    phrase = "cannot tell an error in position' from one in velocity'"
    assert (phrase in text) == warned, text
    if warned:
        assert text.startswith("pysindy-mme: warning: --error-states:")
        assert "leave it out: --error-states velocity" in text
        assert kwargs["error_states"] == [0, 1]
    else:
        assert kwargs["error_states"] == [1]


def test_both_states_measured_is_not_warned_about(tmp_path, monkeypatch):
    csv, model, data = write_user_files(tmp_path)
    rows = ["time,position,velocity"] + [
        f"{t:.6f},{a:.6f},{b:.6f}" for t, (a, b) in zip(data.t, data.x)
    ]
    csv.write_text("\n".join(rows) + "\n")
    argv = base_args(csv, model, tmp_path / "o", measured=None, error_states=None)
    text, kwargs = _until_discover(argv, monkeypatch)
    assert "--error-states" not in text
    assert kwargs["measured"] == [0, 1] and kwargs["error_states"] == [0, 1]


def test_standard_deviation_given_as_variance_is_named(tmp_path):
    """The record's noise variance is 0.01 (sd 0.1); the user typed 0.1."""
    csv, model, _ = write_user_files(tmp_path)
    out = tmp_path / "out"
    result = run(base_args(csv, model, out, noise_variance="0.1"))
    assert result.code == 0, result.err
    hints = [ln for ln in result.err.splitlines() if "standard deviation" in ln]
    assert len(hints) == 1, result.err
    hint = hints[0]
    assert hint.startswith("pysindy-mme: warning: --noise-variance 0.1:")
    assert "Was 0.1 the standard deviation?" in hint
    assert "--noise-variance 0.01" in hint
    # (test_cli.py::test_discover_command_on_user_csv: the right variance, 0.01,
    # gives no such hint)


def test_noise_hint_threshold_against_a_direct_computation():
    """noise_hints fires exactly when the fit RMSE is below half the noise sd."""
    from types import SimpleNamespace

    from pysindy_mme.cli.checks import noise_hints

    def result(rmse, sd):
        gain = SimpleNamespace(
            channel_names=["a", "b"],
            noise_floor=np.array(sd, dtype=float),
            rmse_extended=np.array(rmse, dtype=float),
        )
        return SimpleNamespace(gain=gain)

    assert noise_hints(result([0.1, 0.2], [0.1, 0.3]), "0.01") == []
    hints = noise_hints(result([0.049, 0.2], [0.1, 0.3]), "0.01,0.09")
    assert len(hints) == 1 and " a " in hints[0]
    auto = noise_hints(result([0.1, np.inf], [0.3, 0.3]), "auto")
    assert len(auto) == 1 and "took signal for noise" in auto[0]
