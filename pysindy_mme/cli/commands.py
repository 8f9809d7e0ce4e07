"""The two commands: ``demo`` (the paper's study) and ``discover`` (your data).

Warnings from the study are collected and printed as one plain line each on
standard error (``pysindy-mme: warning: ...``), without the file paths and
line numbers of Python's warning format; the ones the report already lists
(its "Warnings" section) are not repeated.
"""

from __future__ import annotations

import contextlib
import sys
import warnings
from pathlib import Path

import numpy as np

from .arguments import build_request
from .checks import error_state_warnings, noise_hints
from .loading import UsageError, user_line
from .outputs import write_outputs

__all__ = ["run_demo", "run_discover", "warn_line", "captured_warnings"]

#: discover's argument names and the options that set them
OPTION_OF = {
    "noise_variance": "--noise-variance",
    "error_states": "--error-states",
    "measured": "--measured",
    "feature_library": "--library",
    "feature_names": "--states / --inputs",
    "validation_window": "--validation-window",
    "validation": "--validation-rows / --validation",
    "parameters": "--parameters",
    "hidden_states": "--hidden-state",
    "n_substeps": "--substeps",
    "alpha": "--alpha",
    "input_hold": "--input-hold",
    "assumed_model": "--model",
    "u ": "--inputs",
    "t ": "--time / --rate",
    "y ": "--measured",
}


def one_line(text) -> str:
    """``text`` on one line (internal newlines and runs of spaces collapsed)."""
    return " ".join(str(text).split())


def warn_line(message) -> None:
    print(f"pysindy-mme: warning: {one_line(message)}", file=sys.stderr)


@contextlib.contextmanager
def captured_warnings():
    """Collect the warnings meant for the user raised inside, in order, once each.

    Those are ``UserWarning`` and its subclasses (the package's own, and
    scikit-learn's ``ConvergenceWarning``). Deprecation and future warnings
    of the libraries underneath, and numerical ``RuntimeWarning``s, say
    nothing a user of the command line can act on and are left out.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        messages = []
        yield messages
    for w in caught:
        text = one_line(w.message)
        if issubclass(w.category, UserWarning) and text not in messages:
            messages.append(text)


def _print_warnings(messages, result) -> None:
    reported = {one_line(w) for w in getattr(result, "warnings", [])}
    for text in messages:
        if text not in reported:
            warn_line(text)


def _with_option(message: str) -> str:
    """A message of :func:`discover` with the option that sets its argument."""
    for name, option in OPTION_OF.items():
        if message.startswith(name):
            return f"{message} (option {option})"
    return message


def _study(request):
    """Run :func:`discover`; the user's mistakes become :class:`UsageError`."""
    from ..discovery import discover

    try:
        if request.records:
            ys, ts, us = zip(*request.records)
            kwargs = dict(request.kwargs)
            if request.inputs:
                kwargs["u"] = list(us)
            return discover(list(ys), list(ts), **kwargs)
        return discover(request.y, request.t, **request.kwargs)
    except (ValueError, TypeError) as exc:
        line = user_line(exc, request.model_path)
        where = f"{request.model_path}:{line}: " if line else ""
        raise UsageError(where + _with_option(one_line(exc))) from None
    except FloatingPointError as exc:  # DivergenceError: the model blew up
        raise UsageError(
            f"the assumed model diverged: {one_line(exc)} (check the model given "
            "to --model and the units of the data)"
        ) from None
    except Exception as exc:  # raised inside the user's model during the study
        line = user_line(exc, request.model_path)
        if line is None:
            raise
        raise UsageError(
            f"{request.model_path}:{line}: {type(exc).__name__}: {one_line(exc)} "
            "(raised by the model given to --model during the study)"
        ) from None


def print_conclusion(result) -> None:
    """The last lines a user sees: the conclusion, why, and what to try."""
    print(f"\nConclusion: {result.conclusion}. {one_line(result.verdict)}.")
    for reason in result.reasons:
        print(f"  because {one_line(reason)}")
    for tip in result.advice:
        print(f"  try: {one_line(tip)}")


def run_discover(args) -> int:
    """A user's CSV and model file."""
    request = build_request(args)
    notes = error_state_warnings(request)
    for note in notes:
        warn_line(note)
    with captured_warnings() as messages:
        result = _study(request)
    print(result)
    _print_warnings(messages, result)
    hints = noise_hints(result, request.noise_text)
    for hint in hints:
        warn_line(hint)
    written = write_outputs(result, Path(args.out), notes=notes + hints)
    print("Written: " + ", ".join(str(p) for p in written))
    print_conclusion(result)
    return 0


def run_demo(args) -> int:
    """The paper's Van der Pol study, end to end."""
    import pysindy as ps

    from ..discovery import StudyOptions, discover
    from ..feature_library import PowerLibrary
    from ..systems import van_der_pol

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
    library = PowerLibrary() if args.library == "power" else ps.PolynomialLibrary(3)
    with captured_warnings() as messages:
        result = discover(
            data.y,
            data.t,
            assumed_model=system.assumed_model,
            n_states=2,
            measured=[0],
            noise_variance=system.noise_variance,
            error_states=[1],
            feature_library=library,
            validation=(val_data.y, val_data.t),
            options=StudyOptions(
                feature_names=["x1", "x2"],
                assumed_equations=["x2", "0"],
                verbose=bool(getattr(args, "verbose", False)),
            ),
        )
    print(result)
    _print_warnings(messages, result)
    x_ext = result.extended_simulation
    rmse_truth = np.sqrt(np.mean((x_ext - data.x) ** 2, axis=0))
    print(
        "Against the noise-free truth (known here because the data are simulated):\n"
        f"  extended-model simulation RMSE: x1 {rmse_truth[0]:.4f}, x2 "
        f"{rmse_truth[1]:.4f}\n  true correction: -x1 + x2 - x1^2 x2"
    )
    written = write_outputs(result, Path(args.out), x_true=data.x, d_true=data.d)
    print("\nWritten: " + ", ".join(str(p) for p in written))
    print_conclusion(result)
    return 0
