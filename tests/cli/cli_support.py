"""Shared helpers of the command-line tests: a user's CSV and model file, a runner."""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass

from pysindy_mme.cli import main
from pysindy_mme.systems import duffing

MODEL_FILE = '''import numpy as np


def f(x, t):
    """Linear damped oscillator: the user's model of a Duffing oscillator."""
    return np.column_stack([x[:, 1], -x[:, 0] - 0.1 * x[:, 1]])


def g(x, t, u, p):
    """The same with its stiffness and damping as parameters (grey box)."""
    return np.column_stack([x[:, 1], -p["k"] * x[:, 0] - p["c"] * x[:, 1]])


def divides(x, t):
    """Raises inside the model, on its first evaluation."""
    return np.column_stack([x[:, 1], x[:, 0] * (1 / 0)])


def with_input(x, t, u):
    return np.column_stack([x[:, 1], -x[:, 0] - 0.1 * x[:, 1] + u[:, 0]])


CALLS = [0]


def fails_later(x, t):
    """Raises after some calls: during the study, not on its first evaluation
    (the solver's choice of units probes the model a few times first; the
    study proper starts its long computation after about 25 calls)."""
    CALLS[0] += 1
    if CALLS[0] > 15:
        raise RuntimeError("lookup table out of range")
    return f(x, t)


NOT_A_FUNCTION = 3
'''


@dataclass
class Run:
    code: int
    out: str
    err: str


def run(argv) -> Run:
    """``pysindy-mme argv``: exit code, stdout, stderr (argparse exits included)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code
    return Run(code, out.getvalue(), err.getvalue())


def write_user_files(tmp, seed=0, time_column=True, force=False):
    """``data.csv`` (time, position[, force]) of the Duffing record and ``model.py``."""
    data = duffing().measure(seed)
    header = (
        (["time"] if time_column else []) + ["position"] + (["force"] if force else [])
    )
    rows = [",".join(header)]
    for k, (t, y) in enumerate(zip(data.t, data.y[:, 0])):
        cells = ([f"{t:.6f}"] if time_column else []) + [f"{y:.6f}"]
        if force:
            cells.append(f"{0.0:.1f}" if k % 2 else "0")
        rows.append(",".join(cells))
    csv = tmp / "data.csv"
    csv.write_text("\n".join(rows) + "\n")
    model = tmp / "model.py"
    model.write_text(MODEL_FILE)
    return csv, model, data


def base_args(csv_path, model_path, out_dir, /, **changes):
    """A valid ``discover`` command line, with options changed or dropped (None)."""
    options = {
        "--model": f"{model_path}:f",
        "--states": "position,velocity",
        "--measured": "position",
        "--time": "time",
        "--noise-variance": "0.01",
        "--error-states": "velocity",
        "--out": str(out_dir),
    }
    for key, value in changes.items():
        flag = "--" + key.replace("_", "-")
        if value is None:
            options.pop(flag, None)
        else:
            options[flag] = value
    argv = ["discover", str(csv_path)]
    for flag, value in options.items():
        argv += [flag] if value is True else [flag, value]
    return argv


class _DiscoverReached(BaseException):
    """Stops the command at its call of ``discover`` (not an Exception, so
    that no ``except Exception`` in the command swallows it)."""


def discover_arguments(monkeypatch, argv):
    """``(args, kwargs)`` the command line ``argv`` hands to ``discover``.

    A stand-in records them and stops the command there, so the wiring of
    an option is checked in milliseconds, without a study.
    """
    import pysindy_mme.discovery as discovery

    seen = {}

    def stand_in(*args, **kwargs):
        seen["args"], seen["kwargs"] = args, kwargs
        raise _DiscoverReached

    monkeypatch.setattr(discovery, "discover", stand_in)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            main([str(a) for a in argv])
        except _DiscoverReached:
            return seen["args"], seen["kwargs"]
    raise AssertionError(f"discover was not called: {err.getvalue()}")
