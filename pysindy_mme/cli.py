"""Command line: ``pysindy-mme demo`` and ``pysindy-mme discover``.

Bad input ends with a one-line message on stderr and exit code 2, before
anything is written.
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import json
import sys
from pathlib import Path

import numpy as np

__all__ = ["main"]


class UsageError(Exception):
    """A problem with the command line's input (exit code 2)."""


# --------------------------------------------------------------------------- #
# input loading


def load_model(spec: str):
    """``"path/to/file.py:f"`` -> the callable ``f`` defined in that file."""
    if ":" not in spec:
        raise UsageError(f"--model must look like FILE.py:FUNCTION, got {spec!r}")
    path_text, _, name = spec.rpartition(":")
    path = Path(path_text)
    if not path.is_file():
        raise UsageError(f"--model: file {path} does not exist")
    module_spec = importlib.util.spec_from_file_location(
        f"_user_model_{path.stem}", path
    )
    if module_spec is None or module_spec.loader is None:
        raise UsageError(f"--model: cannot load {path} as Python")
    module = importlib.util.module_from_spec(module_spec)
    try:
        module_spec.loader.exec_module(module)
    except Exception as exc:  # the user's file: report whatever it raised
        raise UsageError(f"--model: running {path} failed: {exc!r}") from None
    func = getattr(module, name, None)
    if func is None:
        raise UsageError(f"--model: {path} defines no function {name!r}")
    if not callable(func):
        raise UsageError(f"--model: {name!r} in {path} is not callable")
    return func


def load_csv(path: str) -> tuple[list, np.ndarray]:
    """Header and float data of a CSV file; empty cells are NaN (missing)."""
    p = Path(path)
    if not p.is_file():
        raise UsageError(f"data file {p} does not exist")
    with p.open(newline="") as fh:
        rows = [r for r in csv.reader(fh) if r and any(c.strip() for c in r)]
    if len(rows) < 2:
        raise UsageError(f"{p}: needs a header row and at least one data row")
    header = [h.strip() for h in rows[0]]
    data = np.full((len(rows) - 1, len(header)), np.nan)
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise UsageError(
                f"{p}: line {i} has {len(row)} fields but the header has {len(header)}"
            )
        for j, cell in enumerate(row):
            cell = cell.strip()
            if cell == "" or cell.lower() == "nan":
                continue
            try:
                data[i - 2, j] = float(cell)
            except ValueError:
                raise UsageError(
                    f"{p}: line {i}, column {header[j]!r}: {cell!r} is not a number"
                ) from None
    return header, data


def _split(text: str | None) -> list:
    return [] if not text else [s.strip() for s in text.split(",") if s.strip()]


def _column(header, data, name, what):
    if name not in header:
        raise UsageError(f"{what}: column {name!r} is not in the CSV (has {header})")
    return data[:, header.index(name)]


def _library(kind: str, degree: int):
    import pysindy as ps

    if kind == "poly":
        return ps.PolynomialLibrary(degree=degree)
    if kind == "power":
        from .libraries import PowerLibrary

        return PowerLibrary()
    raise UsageError(f"--library must be 'poly' or 'power', got {kind!r}")


# --------------------------------------------------------------------------- #
# commands


def _write_outputs(result, out: Path, x_true=None, d_true=None) -> list:
    """Report, JSON summary and figures into ``out``; returns written paths."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    (out / "report.txt").write_text(str(result))
    written.append(out / "report.txt")
    (out / "discovery.json").write_text(json.dumps(result.to_dict(), indent=2))
    written.append(out / "discovery.json")
    try:
        from . import plotting

        plt = plotting._pyplot()
    except ImportError:
        print(
            "matplotlib not installed: no figures (pip install 'pysindy-mme[plot]')",
            file=sys.stderr,
        )
        return written
    n, q = len(result.state_names), len(result.error_states)
    fig, axes = plt.subplots(n, 1, figsize=(9, 2.6 * n), squeeze=False)
    plotting.plot_states(result, axes[:, 0], x_true=x_true)
    fig.suptitle("States: measurements, MME estimate, assumed and extended models")
    fig.tight_layout()
    fig.savefig(out / "states.png", dpi=110)
    written.append(out / "states.png")
    fig, axes = plt.subplots(q, 1, figsize=(9, 2.8 * q), squeeze=False)
    plotting.plot_model_error(result, axes[:, 0], d_true=d_true)
    fig.suptitle("Model error d(t) and the identified correction")
    fig.tight_layout()
    fig.savefig(out / "model_error.png", dpi=110)
    written.append(out / "model_error.png")
    fig, ax = plt.subplots(figsize=(9, 4))
    plotting.plot_stepwise_history(result, ax)
    fig.tight_layout()
    fig.savefig(out / "stepwise_history.png", dpi=110)
    written.append(out / "stepwise_history.png")
    plt.close("all")
    return written


def run_demo(args) -> int:
    """The paper's Van der Pol study, end to end."""
    from .discovery import discover
    from .systems import van_der_pol

    system = van_der_pol()
    data = system.measure(args.seed)
    validation_x0 = (2.0, -1.0)
    val_data = system.measure(args.seed + 1000, x0=validation_x0)
    print(
        "Van der Pol oscillator x'' + (x^2 - 1) x' + x = 0, x0 = [1, 0]; only x1 is "
        "measured\n(noise variance 0.01, 40 Hz, 10 s). The assumed model is the "
        "paper's ignorance model:\nx1' = x2, x2' = 0. Validation: a second record "
        f"from x0 = {list(validation_x0)}.\n"
    )
    result = discover(
        data.y,
        data.t,
        assumed_model=system.assumed_model,
        n_states=2,
        measured=[0],
        noise_variance=system.noise_variance,
        error_states=[1],
        feature_library=_library(args.library, 3),
        feature_names=["x1", "x2"],
        validation=(val_data.y, val_data.t),
        assumed_equations=["x2", "0"],
    )
    print(result)
    x_ext = result.extended_simulation
    rmse_truth = np.sqrt(np.mean((x_ext - data.x) ** 2, axis=0))
    print(
        "Against the noise-free truth (known here because the data are simulated):\n"
        f"  extended-model simulation RMSE: x1 {rmse_truth[0]:.4f}, x2 "
        f"{rmse_truth[1]:.4f}\n  true correction: -x1 + x2 - x1^2 x2"
    )
    written = _write_outputs(result, Path(args.out), x_true=data.x, d_true=data.d)
    print("\nWritten: " + ", ".join(str(p) for p in written))
    return 0


def run_discover(args) -> int:
    """A user's CSV and model file."""
    from .discovery import discover

    header, data = load_csv(args.data)
    f = load_model(args.model)
    states = _split(args.states)
    if not states:
        raise UsageError("--states: give the state names, e.g. --states x1,x2")
    measured = _split(args.measured) or states
    for name in measured:
        if name not in states:
            raise UsageError(f"--measured: {name!r} is not one of --states {states}")
    t = _column(header, data, args.time, "--time")
    y = np.column_stack([_column(header, data, c, "--measured") for c in measured])
    inputs = _split(args.inputs)
    u = (
        np.column_stack([_column(header, data, c, "--inputs") for c in inputs])
        if inputs
        else None
    )
    if u is not None and np.any(~np.isfinite(u)):
        raise UsageError("--inputs: input columns must not have missing values")
    if np.any(~np.isfinite(t)):
        raise UsageError(f"--time: column {args.time!r} has missing values")
    error_states = _split(args.error_states) or states
    for name in error_states:
        if name not in states:
            raise UsageError(f"--error-states: {name!r} is not one of {states}")
    noise = args.noise_variance
    if noise != "auto":
        try:
            noise = float(noise)
        except ValueError:
            raise UsageError(
                f"--noise-variance must be a number or 'auto', got {noise!r}"
            ) from None
    try:
        result = discover(
            y,
            t,
            assumed_model=f,
            n_states=len(states),
            measured=[states.index(n) for n in measured],
            noise_variance=noise,
            error_states=[states.index(n) for n in error_states],
            feature_library=_library(args.library, args.degree),
            feature_names=states + inputs,
            u=u,
        )
    except (ValueError, TypeError) as exc:
        raise UsageError(str(exc)) from None
    except FloatingPointError as exc:  # the model diverged (DivergenceError)
        raise UsageError(f"the assumed model diverged: {exc}") from None
    print(result)
    written = _write_outputs(result, Path(args.out))
    print("Written: " + ", ".join(str(p) for p in written))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pysindy-mme",
        description="Find what a simulation model gets wrong, why, and how much a "
        "fix helps (minimum model error estimation + floating-F stepwise regression).",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="the paper's Van der Pol study")
    demo.add_argument("--out", default="mme_demo_output", help="folder for figures")
    demo.add_argument("--seed", type=int, default=0, help="noise seed")
    demo.add_argument(
        "--library",
        default="poly",
        choices=["poly", "power"],
        help="poly: degree-3 polynomials; power: the paper's Table I",
    )
    disc = sub.add_parser("discover", help="your CSV and your model")
    disc.add_argument("data", help="CSV with a header, a time column, measured columns")
    disc.add_argument(
        "--model",
        required=True,
        help="FILE.py:FUNCTION, a vectorised f(x, t) or f(x, t, u)",
    )
    disc.add_argument("--states", required=True, help="state names, comma separated")
    disc.add_argument("--measured", help="measured states (CSV columns); default all")
    disc.add_argument("--time", default="t", help="time column (default 't')")
    disc.add_argument("--inputs", help="input columns, comma separated")
    disc.add_argument(
        "--noise-variance", default="auto", help="measurement noise variance or 'auto'"
    )
    disc.add_argument("--error-states", help="states whose equation may be wrong")
    disc.add_argument("--library", default="poly", choices=["poly", "power"])
    disc.add_argument("--degree", type=int, default=3, help="polynomial degree")
    disc.add_argument("--out", default="mme_output", help="output folder")
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if args.command == "demo":
            return run_demo(args)
        return run_discover(args)
    except UsageError as exc:
        print(f"pysindy-mme: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
