"""The command line's options: every one with its default and an example."""

from __future__ import annotations

import argparse

from ..core.integrate import HOLDS
from ..differentiation.error_models import ERROR_MODELS

__all__ = ["build_parser", "DISCOVER_EXAMPLES"]

DISCOVER_EXAMPLES = """\
examples:
  # only the position is measured; the velocity equation may miss terms
  pysindy-mme discover data.csv --model my_model.py:f --states position,velocity \\
      --measured position --time t --noise-variance 0.01 --error-states velocity \\
      --out results/

  # no time column (sampled at 610.35 Hz), an input, fit on rows 0:16000 and
  # validate on 16000:20000, the model's stiffness k and damping c estimated
  pysindy-mme discover record.csv --rate 610.35 --inputs u \\
      --model oscillator.py:f --states y,v --measured y --error-states v \\
      --parameters k=1.0,c=0.1 --train-rows 0:16000 --validation-rows 16000:20000

The model file defines a vectorised function of x (shape (n_samples, n_states)),
t (shape (n_samples,)) and, with --inputs, u (n_samples, n_inputs):

  import numpy as np
  def f(x, t):
      return np.column_stack([x[:, 1], -x[:, 0] - 0.1 * x[:, 1]])

Outputs (in --out): report.txt, discovery.json, discovery.npz (the result,
reloadable in Python: pysindy_mme.Discovery.load), timeseries.csv (time,
measurements, MME's estimated states and d(t), both models' simulations) and
the figures states.png, model_error.png, gain.png, stepwise_history.png.
Every message and what to do about it: docs/errors.md.
"""

HELP = {
    "data": "CSV file: a header row of column names, then one row per sample "
    "(empty cells or 'nan' are missing measurements). Several files are several "
    "records (experiments) of one system, fitted together: each its own initial "
    "state, the parameters and the correction shared; the same columns in each. "
    "Example: data.csv, or run1.csv run2.csv",
    "--model": "your assumed model, FILE.py:FUNCTION: a vectorised f(x, t) "
    "returning dx/dt with one column per state (f(x, t, u) with --inputs, "
    "f(x, t, u, p) with --parameters). Required. Example: --model my_model.py:f",
    "--states": "names of the model's states, in the order of the columns of x. "
    "Required. Example: --states position,velocity",
    "--measured": "the measured states; each is the CSV column of the same name. "
    "Default: every state. Example: --measured position",
    "--time": "CSV column holding the sample times. Default: t (or give --rate). "
    "Example: --time time",
    "--rate": "sampling rate in Hz, for a CSV without a time column: data row k "
    "is at t = k / HZ (not with --time). Default: none. Example: --rate 610.35",
    "--inputs": "CSV columns of known inputs u; the model is then f(x, t, u) and "
    "the library sees the inputs after the states. Default: none. "
    "Example: --inputs force",
    "--input-hold": None,  # built from the holds the integrator offers
    "--noise-variance": "variance (the standard deviation SQUARED) of the "
    "measurement noise, in the data's units squared: one value, or one per "
    "measured column; 'auto' estimates it from the noise floor of the data's "
    "spectrum and says so. Default: auto. Example: --noise-variance 0.01 (noise "
    "sd 0.1)",
    "--error-states": "states whose equation may be wrong (each gets a model "
    "error d(t)). Default: every state (with --hidden-state: the hidden states "
    "only; the hidden states are always included). Name only the equations that can be "
    "wrong: an error in the equation of a measured state (such as position' = "
    "velocity, a definition) cannot be told apart from errors of the states seen "
    "only through it, and a warning says so. Example: --error-states velocity",
    "--library": "candidate functions for the missing terms: poly (polynomials "
    "of the states and inputs up to --degree), power (the paper's Table I: signed "
    "and absolute powers and their products), or FILE.py:NAME, a pysindy feature "
    "library defined in your file (e.g. a CustomLibrary of sign(v) or sin(x)). "
    "Default: poly. Example: --library power",
    "--degree": "degree of the poly library. Default: 3. Example: --degree 2",
    "--hidden-state": "a state nobody measured that the model lacks, "
    "NAME:EQUATION: a new state NAME entering the equation of the state "
    "EQUATION with gain 1 (EQUATION' = f + NAME, in the units of EQUATION'), its "
    "own law unknown (NAME' = 0 assumed, its terms searched in the library, "
    "whose variables are then the states, the hidden states, then the inputs) and "
    "its initial value fitted. The model error then sits on the hidden states "
    "only, unless --error-states names others. Repeat it for several. The report "
    "suggests it when the model error has memory no function of the states "
    "gives. Default: none. Example: --hidden-state z:velocity",
    "--parameters": "grey box: parameters of your model to estimate, with initial "
    "guesses, and bounds as GUESS:LOWER:UPPER (a bound may be left empty); the "
    "model is then f(x, t, u, p), p a dict name -> value (u is None without "
    "--inputs). Default: none (the model is fixed). "
    "Example: --parameters k=1.0,c=0.1:0:",
    "--train-rows": "data rows to fit on, A:B (counted from 0 after the header, "
    "A included, B excluded; an end may be left out). Default: every row. "
    "Example: --train-rows 0:16000",
    "--validation-rows": "data rows kept out of the fit to measure the gain out "
    "of sample: each model's initial state is estimated from the first "
    "--validation-window rows, then it runs free. Must not overlap the training "
    "rows. Default: none. Example: --validation-rows 16000:20000",
    "--validation": "a CSV file (the same columns as the data) kept out of the "
    "fit to measure the gain out of sample, by the protocol of --validation-rows; "
    "repeat it for several records (the RMSEs are pooled over them). Without it "
    "and with several data files, the last data file is held out whole. "
    "Default: none. Example: --validation test1.csv --validation test2.csv",
    "--validation-window": "leading validation rows used to estimate the initial "
    "state (needs --validation-rows or --validation). Default: 50. Example: "
    "--validation-window 100",
    "--k-step": "score out of sample by K-step-ahead predictions instead of a "
    "free run: each from a state fitted to the --validation-window rows before "
    "it (default window 20 here), starts K rows apart; on --validation / "
    "--validation-rows when given, else on a stretch held out of the fit. "
    "Default: none (a free run). Example: --k-step 10",
    "--substeps": "fewest RK4 steps per sample interval in every fit and "
    "simulation (the study raises it to what the model's fastest time scale "
    "needs); raise it when the report says the result changes with the "
    "integration step. Default: 1. Example: --substeps 4",
    "--alpha": "significance level of the tests (consistency, each term, the "
    "extended model against the assumed one). Default: 0.001. Example: --alpha 0.01",
    "--error-model": None,  # built from the registry of error models
    "--offsets": "estimate a constant offset per measured column (y = state + "
    "offset, e.g. a sensor's bias) instead of letting the dynamics absorb it. "
    "Default: off. Example: --offsets",
    "--clipped": "readings on the end of a sensor's range (runs of samples "
    "exactly on a column's largest or smallest value, as a sensor that reads at "
    "most 10 V reports 10 V above it): auto finds them and leaves them out of the "
    "fit and the RMSEs (they say only 'at or beyond'); keep fits them as "
    "readings. The report names them either way. Default: auto. "
    "Example: --clipped keep",
    "--out": "output folder (created; files in it are overwritten). "
    "Default: mme_output. Example: --out results/",
    "--verbose": "report each stage of the study, with the elapsed time, on "
    "standard error. Default: off. Example: --verbose",
}


HOLD_TEXT = {
    "linear": "linear (interpolated)",
    "zoh": "zoh (held until the next sample, as a digital controller applies them)",
    "cubic": "cubic (a smooth Catmull-Rom curve through the samples)",
}


def _hold_help() -> str:
    kinds = ", ".join(HOLD_TEXT.get(h, h) for h in HOLDS)
    return (
        f"how the inputs act between samples: {kinds}. Default: linear. "
        "Example: --input-hold zoh"
    )


def _error_model_help() -> str:
    kinds = "; ".join(
        cls.summary + (f" (alias {', '.join(cls.aliases)})" if cls.aliases else "")
        for cls in ERROR_MODELS
    )
    return (
        f"MME's prior on d(t): {kinds}. Default: white. "
        "Example: --error-model random_walk"
    )


BUILT_HELP = {"--input-hold": _hold_help, "--error-model": _error_model_help}


def _add(parser, flag, **kwargs):
    text = BUILT_HELP[flag]() if flag in BUILT_HELP else HELP[flag]
    parser.add_argument(flag, help=text, **kwargs)


def _discover_parser(sub):
    disc = sub.add_parser(
        "discover",
        help="your CSV and your model: what the model gets wrong, the fix, the gain",
        description="Run the study on your measurements (CSV) and your assumed "
        "model (a Python file).",
        epilog=DISCOVER_EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add(disc, "data", nargs="+")
    _add(disc, "--model", required=True, metavar="FILE.py:FUNCTION")
    _add(disc, "--states", required=True, metavar="NAMES")
    _add(disc, "--measured", metavar="NAMES")
    _add(disc, "--time", metavar="COLUMN")
    _add(disc, "--rate", metavar="HZ")
    _add(disc, "--inputs", metavar="COLUMNS")
    _add(disc, "--input-hold", default="linear", metavar="HOLD")
    _add(disc, "--noise-variance", default="auto", metavar="VARIANCE|auto")
    _add(disc, "--error-states", metavar="NAMES")
    _add(disc, "--library", default="poly", metavar="poly|power|FILE.py:NAME")
    _add(disc, "--degree", default="3", metavar="N")
    _add(disc, "--parameters", metavar="NAME=VALUE,...")
    _add(disc, "--hidden-state", action="append", metavar="NAME:EQUATION")
    _add(disc, "--train-rows", metavar="A:B")
    _add(disc, "--validation-rows", metavar="A:B")
    _add(disc, "--validation", action="append", metavar="FILE")
    _add(disc, "--validation-window", metavar="N")
    _add(disc, "--k-step", metavar="K")
    _add(disc, "--substeps", metavar="N")
    _add(disc, "--alpha", default="0.001", metavar="P")
    _add(
        disc,
        "--error-model",
        default="white",
        metavar="|".join(c.name for c in ERROR_MODELS),
    )
    _add(disc, "--offsets", action="store_true")
    _add(disc, "--clipped", default="auto", metavar="auto|keep")
    _add(disc, "--out", default="mme_output", metavar="FOLDER")
    _add(disc, "--verbose", action="store_true")
    return disc


def build_parser() -> argparse.ArgumentParser:
    """The ``pysindy-mme`` parser with its ``demo`` and ``discover`` commands."""
    parser = argparse.ArgumentParser(
        prog="pysindy-mme",
        description="Find what a simulation model gets wrong, why, and how much a "
        "fix helps (minimum model error estimation + floating-F stepwise "
        "regression).",
        epilog="examples:\n  pysindy-mme demo\n  pysindy-mme discover --help",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    demo = sub.add_parser(
        "demo",
        help="the paper's Van der Pol study, end to end (about 5 s)",
        description="The paper's Van der Pol study: report on the terminal, "
        "figures and CSV in --out.",
        epilog="example:\n  pysindy-mme demo --out mme_demo_output --library power",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    demo.add_argument(
        "--out",
        default="mme_demo_output",
        metavar="FOLDER",
        help="folder for the report, CSV and figures. Default: mme_demo_output. "
        "Example: --out demo/",
    )
    demo.add_argument(
        "--seed",
        type=int,
        default=0,
        help="noise seed of the simulated record. Default: 0. Example: --seed 3",
    )
    demo.add_argument(
        "--library",
        default="poly",
        choices=["poly", "power"],
        help="poly: degree-3 polynomials; power: the paper's Table I (slower). "
        "Default: poly. Example: --library power",
    )
    demo.add_argument("--verbose", action="store_true", help=HELP["--verbose"])
    _discover_parser(sub)
    return parser
