"""From the ``discover`` command's options to the arguments of :func:`discover`.

Every option is checked here, before any computation, and a problem ends in
a :class:`~.loading.UsageError` naming the option and what to do.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.integrate import HOLDS
from ..differentiation.error_models import error_model_names
from ..discovery.options import grouped_keywords
from ..discovery.parameters import parameter_spec
from ..protocols import KStepAhead
from .loading import (
    UsageError,
    load_csv,
    load_library,
    load_model,
    parse_names,
    parse_rows,
    positional_count,
)

__all__ = ["Request", "build_request", "parse_hidden_states"]


@dataclass
class Request:
    """A checked ``discover`` command: the call to make and what it came from."""

    kwargs: dict
    y: np.ndarray
    t: np.ndarray
    u: np.ndarray | None
    states: list
    measured: list
    inputs: list
    model: object
    model_path: Path
    noise_text: str
    parameters: dict = field(default_factory=dict)
    #: several data files: ``(y, t, u)`` of each (``y``, ``t``, ``u`` above
    #: are the first); None for one
    records: list | None = None


def _number(text, option, example, minimum=None, integer=False):
    try:
        value = int(text) if integer else float(text)
    except (TypeError, ValueError):
        kind = "an integer" if integer else "a number"
        raise UsageError(
            f"{option} must be {kind}, got {text!r} (e.g. {example})"
        ) from None
    if not np.isfinite(value) or (minimum is not None and value < minimum):
        raise UsageError(
            f"{option} must be >= {minimum}, got {text!r} (e.g. {example})"
        )
    return value


def _column(header, data, name, option):
    if name not in header:
        raise UsageError(
            f"{option}: column {name!r} is not in the CSV (has {header}); use a "
            "column name from the CSV's header"
        )
    return data[:, header.index(name)]


def _k_step(args, kwargs) -> None:
    """--k-step K: the validation records (or a held-out stretch) scored by
    K-step-ahead predictions (:class:`~pysindy_mme.protocols.KStepAhead`)."""
    if getattr(args, "k_step", None) is None:
        return
    k = _number(args.k_step, "--k-step", "--k-step 10", 1, integer=True)
    window = kwargs.pop("validation_window", None)
    if window is None and args.validation_window is not None:
        window = _number(
            args.validation_window,
            "--validation-window",
            "--validation-window 20",
            2,
            integer=True,
        )
    kwargs["validation"] = KStepAhead(
        k, kwargs.get("validation"), window=20 if window is None else int(window)
    )


def _times(args, header, data) -> np.ndarray:
    """Sample times of every data row, from --time or --rate."""
    if args.rate is not None:
        if args.time is not None:
            raise UsageError(
                "--rate and --time both given: use --time COLUMN for a time "
                "column, or --rate HZ for evenly spaced rows, not both"
            )
        rate = _number(args.rate, "--rate", "--rate 610.35", minimum=0)
        if rate <= 0:
            raise UsageError(
                f"--rate must be > 0 Hz, got {args.rate!r} (e.g. --rate 610.35)"
            )
        return np.arange(data.shape[0]) / rate
    name = args.time or "t"
    if name not in header:
        raise UsageError(
            f"--time: column {name!r} is not in the CSV (has {header}); name the "
            "time column with --time COLUMN, or give the sampling rate with "
            "--rate HZ"
        )
    t = data[:, header.index(name)]
    if np.any(~np.isfinite(t)):
        raise UsageError(
            f"--time: column {name!r} has missing values (row "
            f"{int(np.flatnonzero(~np.isfinite(t))[0])}); every row needs a time"
        )
    return t


def _noise(text: str):
    if text.strip().lower() == "auto":
        return "auto"
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise UsageError(
            f"--noise-variance must be a number or 'auto' (or one number per "
            f"measured column, comma separated), got {text!r}"
        ) from None
    return values[0] if len(values) == 1 else np.array(values)


_NAME = re.compile(r"^[A-Za-z_]\w*$")


def parse_parameters(text: str) -> dict:
    """``"k=1.0,c=0.1:0:"`` -> ``{"k": 1.0, "c": (0.1, 0.0, None)}``, checked.

    Each item is ``NAME=GUESS`` (unbounded) or ``NAME=GUESS:LOWER:UPPER``
    with either bound left empty for none: the command line's form of
    ``parameters={name: (guess, lower, upper)}``, which the study's advice
    for a parameter that ran away or changed sign writes.
    """
    out = {}
    for item in parse_names(text):
        name, eq, value = item.partition("=")
        name = name.strip()
        if not eq or not value.strip():
            raise UsageError(
                f"--parameters: {name!r} has no value; write NAME=VALUE pairs with "
                "initial guesses, e.g. --parameters k=1.0,c=0.1"
            )
        if not _NAME.match(name):
            raise UsageError(
                f"--parameters: {name!r} is not a valid name (letters, digits, _); "
                "e.g. --parameters k=1.0,c=0.1"
            )
        if name in out:
            raise UsageError(
                f"--parameters: {name!r} is given twice; give each parameter once"
            )
        out[name] = _parameter_value(name, value.strip())
    if not out:
        raise UsageError("--parameters: give NAME=VALUE pairs, e.g. k=1.0,c=0.1")
    return out


def _parameter_value(name: str, text: str):
    """``GUESS`` -> float; ``GUESS:LOWER:UPPER`` -> ``(guess, lower, upper)``."""
    parts = [p.strip() for p in text.split(":")]
    if len(parts) not in (1, 3) or not parts[0]:
        raise UsageError(
            f"--parameters: {name}={text} must be GUESS or GUESS:LOWER:UPPER (a "
            f"bound may be left empty), e.g. {name}=1.0 or {name}=1.0:0:"
        )
    values = []
    for part in parts:
        try:
            values.append(None if part == "" else float(part))
        except ValueError:
            raise UsageError(
                f"--parameters: the value of {name!r}, {text!r}, is not a number; "
                f"e.g. --parameters k=1.0,c=0.1 (bounds: {name}=1.0:0:10)"
            ) from None
    if not np.isfinite(values[0]):
        raise UsageError(
            f"--parameters: the value of {name!r} must be a finite number, e.g. "
            f"{name}=1.0"
        )
    if len(values) == 1:
        return values[0]
    try:  # the study's own check: bounds in order, the guess inside them
        parameter_spec(name, tuple(values))
    except (TypeError, ValueError) as err:
        raise UsageError(f"--{err}") from None
    return tuple(values)


def parameter_guesses(parameters: dict) -> dict:
    """``{name: guess}`` of parsed ``--parameters`` (bounds dropped)."""
    return {k: (v[0] if isinstance(v, tuple) else v) for k, v in parameters.items()}


def parse_hidden_states(values, states, inputs) -> dict:
    """``["z:v", ...]`` (repeated ``--hidden-state``) -> ``{"z": "v", ...}``,
    checked against the state and input names."""
    out = {}
    for text in values or ():
        name, colon, equation = (part.strip() for part in str(text).partition(":"))
        if not colon or not name or not equation:
            raise UsageError(
                f"--hidden-state {text!r} must be NAME:EQUATION, the new state and "
                "the state whose equation it enters, e.g. --hidden-state "
                f"z:{states[-1]}"
            )
        if not _NAME.match(name):
            raise UsageError(
                f"--hidden-state {text}: {name!r} is not a valid name (letters, "
                f"digits, _; not starting with a digit), e.g. --hidden-state "
                f"z:{equation}"
            )
        if name in states or name in inputs:
            kind = "a state of --states" if name in states else "an input"
            raise UsageError(
                f"--hidden-state {text}: {name!r} is already {kind}; give the "
                "hidden state a new name, e.g. --hidden-state "
                f"{_free_name(states + inputs + list(out))}:{equation}"
            )
        if name in out:
            raise UsageError(
                f"--hidden-state: {name!r} is given twice; give each hidden state "
                "once (a state enters one equation)"
            )
        if equation not in states:
            raise UsageError(
                f"--hidden-state {text}: {equation!r} is not one of --states "
                f"{states}; the hidden state enters the equation of one of the "
                f"model's states, e.g. --hidden-state {name}:{states[-1]}"
            )
        out[name] = equation
    return out


def _free_name(taken) -> str:
    for name in ("z", "w", "h1", "h2", "h3"):
        if name not in taken:
            return name
    return "hidden"


def library_from_option(kind: str, degree_text: str):
    """``--library`` and ``--degree`` -> a pysindy feature library."""
    import pysindy as ps

    if kind == "poly":
        degree = _number(degree_text, "--degree", "--degree 3", 1, integer=True)
        return ps.PolynomialLibrary(degree=degree)
    if kind == "power":
        from ..feature_library import PowerLibrary

        return PowerLibrary()
    if ":" in kind:
        return load_library(kind)
    raise UsageError(
        f"--library: invalid choice: {kind!r}; use poly, power, or FILE.py:NAME "
        "naming a pysindy feature library defined in your file"
    )


def _states(args) -> tuple[list, list, list | None, dict]:
    """``(states, measured, error states, hidden states)``; with hidden
    states, the error states are the visible ones named (None when none is:
    the hidden states only) - the hidden states get a model error anyway."""
    states = parse_names(args.states)
    if not states:
        raise UsageError("--states: give the state names, e.g. --states x1,x2")
    if len(set(states)) != len(states):
        raise UsageError(f"--states repeats a name: {states}; list each state once")
    hidden = parse_hidden_states(
        getattr(args, "hidden_state", None), states, parse_names(args.inputs)
    )
    measured = parse_names(args.measured) or list(states)
    for name in measured:
        if name not in states:
            raise UsageError(
                f"--measured: {name!r} is not one of --states {states}; measured "
                "columns are named after the states they measure"
            )
    named = parse_names(args.error_states)
    for name in named:
        if name not in states and name not in hidden:
            also = f" or --hidden-state {list(hidden)}" if hidden else ""
            raise UsageError(
                f"--error-states: {name!r} is not one of --states {states}{also}; "
                "name the states whose equation may be wrong"
            )
    if hidden:
        errors = [name for name in named if name in states] or None
    else:
        errors = named or list(states)
    return states, measured, errors, hidden


def _validation_rows(args, n_rows, train: slice):
    if args.validation_rows is None:
        if (
            args.validation_window is not None
            and not getattr(args, "validation", None)
            and getattr(args, "k_step", None) is None
        ):
            raise UsageError(
                "--validation-window needs --validation-rows (the record it is "
                "taken from), e.g. --validation-rows 16000:20000"
            )
        return None
    if getattr(args, "validation", None):
        raise UsageError(
            "--validation-rows and --validation both given: validate on rows of "
            "the data file or on other files, not both"
        )
    rows = parse_rows(args.validation_rows, n_rows, "--validation-rows")
    if rows.start < train.stop and train.start < rows.stop:
        suggestion = f"0:{rows.start}" if rows.start > 0 else f"{rows.stop}:"
        raise UsageError(
            f"--validation-rows {args.validation_rows} overlaps the training rows "
            f"{train.start}:{train.stop}; validation must be kept out of the fit: "
            f"give --train-rows too, e.g. --train-rows {suggestion}"
        )
    return rows


def _check_signature(model, args, has_inputs: bool) -> None:
    """The model's arguments match --inputs and --parameters."""
    count = positional_count(model)
    if count is None:
        return
    name = args.model.rpartition(":")[2]
    if args.parameters is not None and count < 4:
        raise UsageError(
            f"--parameters: the model {name} must take (x, t, u, p), p a dict of the "
            f"parameters (u is None without --inputs); it takes {count} arguments"
        )
    if args.parameters is None and count >= 4:
        raise UsageError(
            f"--model: {name} takes {count} arguments (x, t, u, p?): give its "
            "parameters with --parameters NAME=VALUE,..., e.g. --parameters k=1.0"
        )
    if args.parameters is None and count == 3 and not has_inputs:
        raise UsageError(
            f"--model: {name} takes an input u, f(x, t, u), but no --inputs were "
            "given; name the input columns with --inputs, e.g. --inputs force"
        )


def _inputs(args, header, data):
    """``(names, values of every row)`` of the --inputs columns (None if none)."""
    inputs = parse_names(args.inputs)
    if not inputs:
        return inputs, None
    u_all = np.column_stack([_column(header, data, c, "--inputs") for c in inputs])
    bad = ~np.all(np.isfinite(u_all), axis=1)
    if np.any(bad):
        raise UsageError(
            f"--inputs: input columns must not have missing values (row "
            f"{int(np.flatnonzero(bad)[0])}); fill them or drop those rows"
        )
    return inputs, u_all


def _grey_box(args, kwargs) -> dict:
    """--clipped, --offsets and --parameters into ``kwargs``; returns the
    parameters."""
    clipped = getattr(args, "clipped", "auto")
    if clipped not in ("auto", "keep"):
        raise UsageError(
            f"--clipped must be auto or keep, got {clipped!r} (auto leaves readings "
            "on a sensor's limits out of the fit; keep fits them as readings)"
        )
    if clipped != "auto":
        kwargs["clipped"] = clipped
    if args.offsets:
        kwargs["offsets"] = True
    if args.parameters is None:
        return {}
    parameters = parse_parameters(args.parameters)
    kwargs["parameters"] = parameters
    return parameter_guesses(parameters)


def _hidden(args, hidden, kwargs) -> None:
    """--hidden-state and --substeps into ``kwargs``."""
    if hidden:
        kwargs["hidden_states"] = hidden
        if kwargs["error_states"] is None:
            del kwargs["error_states"]  # discover's default: the hidden states
    substeps = getattr(args, "substeps", None)
    if substeps is not None:
        value = _number(substeps, "--substeps", "--substeps 4", 1, integer=True)
        kwargs["n_substeps"] = value


def _record(args, path, measured):
    """``(y, t, u)`` of every row of one CSV file (the options' columns)."""
    header, data = load_csv(path)
    t = _times(args, header, data)
    y = np.column_stack([_column(header, data, c, "--measured") for c in measured])
    _, u = _inputs(args, header, data)
    return y, t, u


def _files(args) -> list:
    """The data files (one or more), checked against the row options."""
    files = args.data if isinstance(args.data, list) else [args.data]
    if len(files) > 1:
        for option, value in (
            ("--train-rows", args.train_rows),
            ("--validation-rows", args.validation_rows),
        ):
            if value:
                raise UsageError(
                    f"{option} selects rows of one data file; with several data "
                    f"files ({len(files)} given) give each record as its own file "
                    "and the validation records with --validation FILE"
                )
    return files


def build_request(args) -> Request:
    """Check every option of ``discover``; nothing is computed yet."""
    files = _files(args)
    header, data = load_csv(files[0])
    states, measured, errors, hidden = _states(args)
    t_all = _times(args, header, data)
    y_all = np.column_stack([_column(header, data, c, "--measured") for c in measured])
    inputs, u_all = _inputs(args, header, data)
    records = None
    if len(files) > 1:
        records = [(y_all, t_all, u_all)]
        records += [_record(args, path, measured) for path in files[1:]]
    n_rows = data.shape[0]
    train = (
        parse_rows(args.train_rows, n_rows, "--train-rows")
        if args.train_rows
        else slice(0, n_rows)
    )
    val_rows = _validation_rows(args, n_rows, train)
    if args.input_hold not in HOLDS:
        raise UsageError(
            f"--input-hold must be one of {', '.join(HOLDS)}, got {args.input_hold!r}"
        )
    if args.error_model not in error_model_names():
        raise UsageError(
            f"--error-model must be one of {', '.join(error_model_names())}, got "
            f"{args.error_model!r}"
        )
    model, path = load_model(args.model)
    _check_signature(model, args, bool(inputs))
    kwargs = dict(
        assumed_model=model,
        n_states=len(states),
        measured=[states.index(n) for n in measured],
        noise_variance=_noise(args.noise_variance),
        error_states=None if errors is None else [states.index(n) for n in errors],
        feature_library=library_from_option(args.library, args.degree),
        feature_names=states + inputs,
        alpha=_number(args.alpha, "--alpha", "--alpha 0.05"),
        error_model=args.error_model,
        input_hold=args.input_hold,
        verbose=bool(args.verbose),
    )
    if u_all is not None:
        kwargs["u"] = u_all[train]
    if getattr(args, "validation", None):
        kwargs["validation"] = [
            tuple(r if inputs else r[:2])
            for r in (_record(args, path, measured) for path in args.validation)
        ]
    if getattr(args, "validation", None) and args.validation_window is not None:
        kwargs["validation_window"] = _number(
            args.validation_window,
            "--validation-window",
            "--validation-window 50",
            2,
            integer=True,
        )
    if val_rows is not None:
        record = (y_all[val_rows], t_all[val_rows])
        kwargs["validation"] = record + ((u_all[val_rows],) if inputs else ())
        if args.validation_window is not None:
            kwargs["validation_window"] = _number(
                args.validation_window,
                "--validation-window",
                "--validation-window 50",
                2,
                integer=True,
            )
    _k_step(args, kwargs)
    _hidden(args, hidden, kwargs)
    parameters = _grey_box(args, kwargs)
    return Request(
        kwargs=grouped_keywords(kwargs),
        y=y_all[train],
        t=t_all[train],
        u=None if u_all is None else u_all[train],
        states=states,
        measured=measured,
        inputs=inputs,
        model=model,
        model_path=path,
        noise_text=args.noise_variance,
        parameters=parameters,
        records=records,
    )
