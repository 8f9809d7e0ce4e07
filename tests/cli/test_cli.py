"""The command line end to end: the demo, a user's CSV and model, its outputs."""

import csv as csv_module
import json

import numpy as np
import pytest
from cli_support import base_args, run, write_user_files


def _table(path):
    with path.open(newline="") as fh:
        rows = list(csv_module.reader(fh))
    header = rows[0]
    data = np.array(
        [[float(c) if c else np.nan for c in row] for row in rows[1:]], dtype=float
    )
    return {name: data[:, j] for j, name in enumerate(header)}


def test_discover_command_on_user_csv(tmp_path):
    csv, model, data = write_user_files(tmp_path)
    out = tmp_path / "out"
    result = run(base_args(csv, model, out))
    assert result.code == 0, result.err
    assert "velocity' misses" in result.out and "position^3" in result.out
    assert "standard deviation" not in result.err  # the noise variance is right
    for name in (
        "report.txt",
        "discovery.json",
        "timeseries.csv",
        "states.png",
        "model_error.png",
        "gain.png",
        "stepwise_history.png",
    ):
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "discovery.json").read_text())
    assert "position^3" in summary["terms"]["velocity"]
    series = _table(out / "timeseries.csv")
    assert list(series) == [
        "t",
        "measured position",
        "estimate position",
        "estimate velocity",
        "d velocity",
        "assumed position",
        "assumed velocity",
        "extended position",
        "extended velocity",
    ]
    np.testing.assert_allclose(series["t"], data.t, atol=1e-6)
    np.testing.assert_allclose(series["measured position"], data.y[:, 0], atol=1e-6)
    # The columns are what they say: the extended simulation follows the truth
    # (noise sd 0.1) far better than the assumed one, and so does MME's estimate
    # of the unmeasured velocity.
    err_ext = np.sqrt(np.mean((series["extended position"] - data.x[:, 0]) ** 2))
    err_ass = np.sqrt(np.mean((series["assumed position"] - data.x[:, 0]) ** 2))
    err_vel = np.sqrt(np.mean((series["estimate velocity"] - data.x[:, 1]) ** 2))
    assert err_ext < 0.03 < 0.3 < err_ass
    assert err_vel < 0.15 * np.std(data.x[:, 1])
    np.testing.assert_allclose(
        np.sqrt(np.mean(series["d velocity"] ** 2)),
        summary["model_error"]["velocity"]["rms_d"],
        rtol=1e-6,
    )


@pytest.fixture(scope="module")
def auto_verbose_run(tmp_path_factory):
    """One study with 'auto' noise, --verbose and a validation block."""
    tmp = tmp_path_factory.mktemp("auto")
    csv, model, _ = write_user_files(tmp)
    out = tmp / "out"
    argv = base_args(
        csv,
        model,
        out,
        noise_variance="auto",
        verbose=True,
        train_rows="0:600",
        validation_rows="600:",
        validation_window="40",
    )
    return run(argv), out


def test_verbose_prints_each_stage_on_stderr(auto_verbose_run):
    result, _ = auto_verbose_run
    assert result.code == 0, result.err
    stages = [line for line in result.err.splitlines() if line.startswith("[")]
    for stage in ("checked: 600 samples", "1. assumed model", "2. MME", "5. gain"):
        assert any(stage in line for line in stages), (stage, result.err)
    assert not any(line.startswith("[") for line in result.out.splitlines())


def test_warnings_are_one_plain_line_each(auto_verbose_run):
    result, _ = auto_verbose_run
    lines = [ln for ln in result.err.splitlines() if not ln.startswith("[")]
    warns = [ln for ln in lines if ln.startswith("pysindy-mme: warning: ")]
    assert any("noise_variance='auto'" in ln for ln in warns), result.err
    # Python's warning format would add "path.py:123: UserWarning:" and the
    # offending source line; none of that reaches the user.
    assert not any(".py:" in ln or "Warning:" in ln for ln in warns), warns
    assert all(ln.startswith("pysindy-mme: warning: ") for ln in lines if ln.strip())


def test_validation_rows_measure_the_gain_out_of_sample(auto_verbose_run):
    result, out = auto_verbose_run
    summary = json.loads((out / "discovery.json").read_text())
    gain = summary["gain"]
    assert summary["n_samples"] == 600
    assert gain["validation_window"] == 40
    assert gain["validation_ratio"][0] > 2.0
    assert "valid. gain" in result.out


def test_demo_runs_and_writes_figures(tmp_path):
    out = tmp_path / "demo"
    result = run(["demo", "--out", out])
    assert result.code == 0, result.err
    assert "x2' misses" in result.out
    assert "x1^2 x2" in result.out
    for name in ("states.png", "model_error.png", "gain.png", "stepwise_history.png"):
        assert (out / name).stat().st_size > 10_000, name
    series = _table(out / "timeseries.csv")
    assert {"d x2", "extended x2", "assumed x1"} <= set(series)
    for line in result.err.splitlines():  # warnings, if any, are plain lines
        assert line.startswith("pysindy-mme: warning: ") and ".py:" not in line
