"""The command line on a CSV: a forced oscillator whose actuator is stronger.

Run: ``python examples/command_line.py [--quick] [--out FOLDER]``
(default FOLDER ``example_output/command_line``; ``--quick`` fits on fewer rows).

Writes what a user would have - ``record.csv`` (columns ``force`` and
``position``, no time column: sampled at 40 Hz) and ``oscillator.py`` (the
assumed model, input gain 1.0; the truth's is 1.5) - into FOLDER, then runs
the same study as this shell command::

    pysindy-mme discover record.csv --rate 40 --inputs force --input-hold linear \\
        --model oscillator.py:f --states position,velocity --measured position \\
        --error-states velocity --noise-variance 0.01 --degree 2 \\
        --train-rows 0:600 --validation-rows 600:801 --out results

and shows the start of ``results/timeseries.csv``.
"""

import argparse
import shlex
from pathlib import Path

from pysindy_mme.cli import main as pysindy_mme
from pysindy_mme.systems import forced_oscillator

MODEL = '''import numpy as np


def f(x, t, u):
    """Assumed model: x'' = -x - 0.2 x' + force (input gain 1.0)."""
    return np.column_stack([x[:, 1], -x[:, 0] - 0.2 * x[:, 1] + u[:, 0]])
'''


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer training rows")
    parser.add_argument("--out", default="example_output/command_line")
    args = parser.parse_args(argv)
    folder = Path(args.out)
    folder.mkdir(parents=True, exist_ok=True)
    system = forced_oscillator()
    data = system.measure(seed=3)
    lines = ["force,position"] + [
        f"{u:.8g},{y:.8g}" for u, y in zip(data.u[:, 0], data.y[:, 0])
    ]
    (folder / "record.csv").write_text("\n".join(lines) + "\n")
    (folder / "oscillator.py").write_text(MODEL)
    train = "200:600" if args.quick else "0:600"
    command = (
        f"discover {folder / 'record.csv'} --rate 40 --inputs force "
        f"--input-hold linear --model {folder / 'oscillator.py'}:f "
        "--states position,velocity --measured position --error-states velocity "
        f"--noise-variance {system.noise_variance} --degree 2 --train-rows {train} "
        f"--validation-rows 600:{len(data.t)} --out {folder / 'results'}"
    )
    print("$ pysindy-mme " + command + "\n")
    code = pysindy_mme(shlex.split(command))
    if code != 0:
        raise SystemExit(code)
    series = (folder / "results" / "timeseries.csv").read_text().splitlines()
    print("\nresults/timeseries.csv starts with:")
    print("\n".join(series[:3]))
    print("true hidden effect in velocity':", system.hidden_terms["x2"], "(u = force)")
    return code


if __name__ == "__main__":
    main()
