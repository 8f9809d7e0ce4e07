"""Reading what the user points the command line at: the CSV and Python files.

Every problem ends in a :class:`UsageError` whose message names the option
(or the file and line) and what to do. Errors inside the user's own Python
file are reported as ``file:line: message``, the way compilers do, with no
traceback of this package.
"""

from __future__ import annotations

import csv
import importlib.util
import inspect
import re
import sys
import traceback
from pathlib import Path

import numpy as np

__all__ = [
    "UsageError",
    "load_csv",
    "load_object",
    "load_model",
    "load_library",
    "user_line",
    "parse_rows",
    "parse_names",
    "forget_modules",
    "positional_count",
]


class UsageError(Exception):
    """A problem with the command line's input (exit code 2)."""


# --------------------------------------------------------------------------- CSV


def _number(cell: str, path: Path, line: int, column: str) -> float:
    cell = cell.strip()
    if cell == "" or cell.lower() == "nan":
        return np.nan
    try:
        return float(cell)
    except ValueError:
        raise UsageError(
            f"{path}: line {line}, column {column!r}: {cell!r} is not a number "
            "(cells must be numbers; leave a cell empty or write nan for a missing "
            "measurement)"
        ) from None


def load_csv(path) -> tuple[list, np.ndarray]:
    """Header and float data of a CSV file; empty cells and ``nan`` are NaN."""
    p = Path(path)
    if not p.is_file():
        raise UsageError(
            f"data file {p} does not exist (the first argument of 'discover' is "
            "the CSV file)"
        )
    try:
        with p.open(newline="") as fh:
            rows = [r for r in csv.reader(fh) if r and any(c.strip() for c in r)]
    except (UnicodeDecodeError, csv.Error) as exc:
        raise UsageError(f"{p}: cannot be read as a CSV text file ({exc})") from None
    if len(rows) < 2:
        raise UsageError(
            f"{p}: needs a header row and at least one data row (a first line of "
            "column names, then one line per sample)"
        )
    header = [h.strip() for h in rows[0]]
    repeated = sorted({h for h in header if header.count(h) > 1})
    if repeated:
        raise UsageError(f"{p}: the header repeats the column name(s) {repeated}")
    data = np.full((len(rows) - 1, len(header)), np.nan)
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise UsageError(
                f"{p}: line {i} has {len(row)} fields but the header has {len(header)}"
            )
        for j, cell in enumerate(row):
            data[i - 2, j] = _number(cell, p, i, header[j])
    return header, data


def parse_names(text: str | None) -> list:
    """``"a, b,c"`` -> ``["a", "b", "c"]`` (empty for None)."""
    return [] if not text else [s.strip() for s in text.split(",") if s.strip()]


_ROWS = re.compile(r"^\s*(\d*)\s*:\s*(\d*)\s*$")


def parse_rows(text: str, n_rows: int, option: str) -> slice:
    """``"A:B"`` -> ``slice(A, B)`` over the CSV's data rows, checked."""
    match = _ROWS.match(text)
    if not match:
        raise UsageError(
            f"{option}: {text!r} is not a row range; write A:B (data rows counted "
            f"from 0 after the header, A included, B excluded; either end may be "
            f"left out), e.g. {option} 0:1000"
        )
    a = int(match.group(1)) if match.group(1) else 0
    b = int(match.group(2)) if match.group(2) else n_rows
    if b > n_rows:
        raise UsageError(
            f"{option} {text}: the CSV has only {n_rows} data rows (0:{n_rows})"
        )
    if b - a < 3:
        raise UsageError(
            f"{option} {text}: selects {max(b - a, 0)} rows; give a range A:B with "
            "A < B that holds at least 3 rows"
        )
    return slice(a, b)


# ------------------------------------------------------------------ Python files


def user_line(exc: BaseException, path: Path) -> int | None:
    """Line of ``path`` where ``exc`` (or an exception it chains) was raised."""
    target = str(Path(path).resolve())
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, SyntaxError) and exc.filename:
            if str(Path(exc.filename).resolve()) == target and exc.lineno:
                return int(exc.lineno)
        frames = traceback.extract_tb(exc.__traceback__)
        lines = [f.lineno for f in frames if str(Path(f.filename).resolve()) == target]
        if lines:
            return lines[-1]
        exc = exc.__cause__ or exc.__context__
    return None


_MODULES: dict = {}


def forget_modules() -> None:
    """Forget the user files loaded so far (each command reads them afresh)."""
    for module in _MODULES.values():
        sys.modules.pop(module.__name__, None)
    _MODULES.clear()


def _module(path: Path, option: str):
    """Run the user's file once (per command) and return it as a module."""
    key = str(path.resolve())
    if key in _MODULES:
        return _MODULES[key]
    stem = re.sub(r"\W", "_", path.stem)
    name = f"_pysindy_mme_user_{len(_MODULES)}_{stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise UsageError(f"{option}: cannot load {path} as Python")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses and pickling need the module known
    try:
        spec.loader.exec_module(module)
    except SyntaxError as exc:
        del sys.modules[name]
        line = exc.lineno if exc.lineno else "?"
        raise UsageError(
            f"{path}:{line}: SyntaxError: {exc.msg} (running {path} failed: fix the "
            f"file given to {option})"
        ) from None
    except Exception as exc:  # the user's file: report what it raised, and where
        del sys.modules[name]
        line = user_line(exc, path) or "?"
        raise UsageError(
            f"{path}:{line}: {type(exc).__name__}: {exc} (running {path} failed: "
            f"fix the file given to {option})"
        ) from None
    _MODULES[key] = module
    return module


def load_object(spec: str, option: str, example: str):
    """``"path/file.py:NAME"`` -> the object ``NAME`` defined in that file."""
    if ":" not in spec or spec.endswith(":") or spec.startswith(":"):
        raise UsageError(f"{option} must look like FILE.py:NAME, e.g. {example}")
    path_text, _, name = spec.rpartition(":")
    path = Path(path_text)
    if not path.is_file():
        raise UsageError(f"{option}: file {path} does not exist")
    module = _module(path, option)
    if not hasattr(module, name):
        defined = sorted(
            k for k, v in vars(module).items() if callable(v) and not k.startswith("_")
        )
        raise UsageError(
            f"{option}: {path} defines no function {name!r} (it defines "
            f"{', '.join(defined) or 'no functions'})"
        )
    return getattr(module, name), path


def load_model(spec: str):
    """``"path/file.py:f"`` -> ``(f, path)`` for ``--model``."""
    if ":" not in spec:
        raise UsageError(
            f"--model must look like FILE.py:FUNCTION, got {spec!r} (e.g. --model "
            "my_model.py:f)"
        )
    func, path = load_object(spec, "--model", "--model my_model.py:f")
    if not callable(func):
        name = spec.rpartition(":")[2]
        raise UsageError(
            f"--model: {name!r} in {path} is not callable; name the function "
            "f(x, t) that returns dx/dt"
        )
    return func, path


def _callable_without_arguments(func) -> bool:
    try:
        inspect.signature(func).bind()
    except TypeError:
        return False
    except ValueError:  # no signature (builtins): let the call decide
        return True
    return True


def positional_count(func) -> int | None:
    """Positional parameters ``func`` takes (None: any number, or unknown)."""
    try:
        params = inspect.signature(func).parameters.values()
    except (TypeError, ValueError):
        return None
    if any(p.kind == p.VAR_POSITIONAL for p in params):
        return None
    return sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in params)


def load_library(spec: str):
    """``"path/file.py:NAME"`` -> a pysindy feature library for ``--library``.

    ``NAME`` is a library object or a function of no arguments returning one.
    """
    obj, path = load_object(spec, "--library", "--library my_library.py:library")
    name = spec.rpartition(":")[2]
    takes_nothing = callable(obj) and _callable_without_arguments(obj)
    if not (hasattr(obj, "fit") and hasattr(obj, "transform")) and takes_nothing:
        try:
            obj = obj()
        except Exception as exc:
            line = user_line(exc, path) or "?"
            raise UsageError(
                f"{path}:{line}: {type(exc).__name__}: {exc} (calling {name}() for "
                "--library failed)"
            ) from None
    if not (hasattr(obj, "fit") and hasattr(obj, "transform")):
        raise UsageError(
            f"--library: {name!r} in {path} is not a pysindy feature library (e.g. "
            "ps.CustomLibrary(library_functions=[np.sin, np.sign]))"
        )
    return obj
