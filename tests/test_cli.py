"""The command line: the demo, a user's CSV and model, and bad input."""

import numpy as np
import pytest

from pysindy_mme.cli import main
from pysindy_mme.systems import duffing

MODEL_FILE = '''
import numpy as np

def f(x, t):
    """Linear damped oscillator: the user's model of a Duffing oscillator."""
    return np.column_stack([x[:, 1], -x[:, 0] - 0.1 * x[:, 1]])

NOT_A_FUNCTION = 3
'''


@pytest.fixture
def user_files(tmp_path):
    data = duffing().measure(0)
    csv = tmp_path / "data.csv"
    rows = ["time,position"] + [
        f"{t:.6f},{y:.6f}" for t, y in zip(data.t, data.y[:, 0])
    ]
    csv.write_text("\n".join(rows) + "\n")
    model = tmp_path / "model.py"
    model.write_text(MODEL_FILE)
    return tmp_path, csv, model


def test_discover_command_on_user_csv(user_files, capsys):
    tmp, csv, model = user_files
    out = tmp / "out"
    code = main(
        [
            "discover",
            str(csv),
            "--model",
            f"{model}:f",
            "--states",
            "position,velocity",
            "--measured",
            "position",
            "--time",
            "time",
            "--noise-variance",
            "0.01",
            "--error-states",
            "velocity",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    assert "velocity' misses" in text and "position^3" in text
    for name in (
        "report.txt",
        "discovery.json",
        "states.png",
        "model_error.png",
        "stepwise_history.png",
    ):
        assert (out / name).stat().st_size > 0


def test_demo_runs_and_writes_figures(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "x2' misses" in text
    assert "x1^2 x2" in text
    for name in ("states.png", "model_error.png", "stepwise_history.png"):
        assert (out / name).stat().st_size > 10_000


@pytest.mark.parametrize(
    "change, phrase",
    [
        (
            lambda a, tmp: a.__setitem__(3, str(tmp / "missing.py") + ":f"),
            "does not exist",
        ),
        (
            lambda a, tmp: a.__setitem__(3, a[3].replace(":f", ":g")),
            "defines no function 'g'",
        ),
        (
            lambda a, tmp: a.__setitem__(3, a[3].replace(":f", ":NOT_A_FUNCTION")),
            "not callable",
        ),
        (lambda a, tmp: a.__setitem__(3, a[3].replace(":f", "")), "FILE.py:FUNCTION"),
        (lambda a, tmp: a.__setitem__(7, "speed"), "'speed' is not one of"),
        (lambda a, tmp: a.__setitem__(9, "clock"), "column 'clock' is not in the CSV"),
        (lambda a, tmp: a.__setitem__(11, "-1"), "noise_variance"),
        (lambda a, tmp: a.__setitem__(1, str(tmp / "nope.csv")), "does not exist"),
    ],
)
def test_bad_command_line_input_exits_2_and_writes_nothing(
    user_files, capsys, change, phrase
):
    tmp, csv, model = user_files
    out = tmp / "never"
    args = [
        "discover",
        str(csv),
        "--model",
        f"{model}:f",
        "--states",
        "position,velocity",
        "--measured",
        "position",
        "--time",
        "time",
        "--noise-variance",
        "0.01",
        "--out",
        str(out),
    ]
    change(args, tmp)
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "pysindy-mme: error:" in err and phrase in err
    assert not out.exists()


def test_non_numeric_and_short_csv(user_files, capsys):
    tmp, csv, model = user_files
    bad = tmp / "bad.csv"
    bad.write_text("time,position\n0,1.0\n0.1,abc\n")
    base = [
        "discover",
        "",
        "--model",
        f"{model}:f",
        "--states",
        "position,velocity",
        "--measured",
        "position",
        "--time",
        "time",
        "--out",
        str(tmp / "o"),
    ]
    base[1] = str(bad)
    assert main(base) == 2
    assert "'abc' is not a number" in capsys.readouterr().err
    short = tmp / "short.csv"
    short.write_text(
        "time,position\n" + "\n".join(f"{0.1 * k},{np.cos(0.1 * k)}" for k in range(6))
    )
    base[1] = str(short)
    base += ["--noise-variance", "0.01"]
    assert main(base) == 2
    assert "samples are needed" in capsys.readouterr().err
    assert not (tmp / "o").exists()
