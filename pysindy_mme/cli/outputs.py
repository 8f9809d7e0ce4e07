"""What the command line leaves in its output folder.

``report.txt`` (the printed report), ``discovery.json`` (its numbers),
``discovery.npz`` (the whole result, reloadable with
``pysindy_mme.Discovery.load``: :mod:`pysindy_mme.discovery.storage`),
``timeseries.csv`` (one row per sample: time, inputs, measurements, MME's
state estimate and model error, both models' simulations) and the four
figures of :func:`pysindy_mme.plotting.save_figures`.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

__all__ = ["timeseries_columns", "write_outputs"]


def timeseries_columns(result) -> dict:
    """``{column name: values}`` of ``timeseries.csv``, in order.

    ``t``; ``input <name>``; ``measured <channel>`` (as the sensor reported
    it) and, when a channel clips, ``clipped <channel>`` (1 on a reading at
    the sensor's limit, left out of the fit); ``estimate <state>``
    (MME); ``d <state>`` (MME's model error, error states only);
    ``assumed <state>`` and ``extended <state>`` (each model's simulation,
    from its own fitted initial state).
    """
    cols = {"t": np.asarray(result.t, dtype=float)}
    if result.u is not None:
        for k, name in enumerate(result.input_names):
            cols[f"input {name}"] = np.asarray(result.u)[:, k]
    readings = np.asarray(getattr(result, "readings", result.y))
    clipped = getattr(result, "clipped", None)
    for j, name in enumerate(result.channel_names):
        cols[f"measured {name}"] = readings[:, j]
        if clipped:  # 1 where the reading is on a sensor's limit
            cols[f"clipped {name}"] = clipped.mask[:, j].astype(float)
    x_hat = np.asarray(result.mme.smoothed_x_)
    d_hat = np.asarray(result.mme.d_)
    for i, name in enumerate(result.state_names):
        cols[f"estimate {name}"] = x_hat[:, i]
    for i in result.error_states:
        cols[f"d {result.state_names[i]}"] = d_hat[:, i]
    for which, x in (
        ("assumed", result.assumed_simulation),
        ("extended", result.extended_simulation),
    ):
        x = np.asarray(x)
        for i, name in enumerate(result.state_names):
            cols[f"{which} {name}"] = x[:, i]
    return cols


def _write_csv(path: Path, columns: dict) -> None:
    names = list(columns)
    data = np.column_stack([columns[n] for n in names])
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(names)
        for row in data:
            writer.writerow(["" if not np.isfinite(v) else f"{v:.10g}" for v in row])


def write_outputs(result, out, notes=(), x_true=None, d_true=None) -> list:
    """Report, JSON, saved result, time series and figures into ``out``;
    returns the paths.

    ``notes``: the command line's own warnings, kept in the JSON.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    (out / "report.txt").write_text(str(result))
    written.append(out / "report.txt")
    summary = result.to_dict()
    summary["command_line_warnings"] = list(notes)
    (out / "discovery.json").write_text(json.dumps(summary, indent=2))
    written.append(out / "discovery.json")
    result.save(out / "discovery.npz")
    written.append(out / "discovery.npz")
    _write_csv(out / "timeseries.csv", timeseries_columns(result))
    written.append(out / "timeseries.csv")
    try:
        from ..plotting import save_figures

        written += save_figures(result, out, x_true=x_true, d_true=d_true)
    except ImportError:
        print(
            "pysindy-mme: matplotlib is not installed, so no figures were drawn "
            "(pip install 'pysindy-mme[plot]')",
            file=sys.stderr,
        )
    return written
