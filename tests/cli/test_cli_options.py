"""Each option of ``discover`` reaches :func:`discover` as documented.

Most tests stop the command at its call of ``discover`` (a stand-in records
the arguments), so they check the wiring in milliseconds; the grey-box test
runs the whole study.
"""

import json

import numpy as np
import pytest
from cli_support import base_args, discover_arguments, run, write_user_files

import pysindy_mme
from pysindy_mme.cli import build_parser


@pytest.fixture
def call(monkeypatch):
    """``call(argv) -> (args, kwargs)`` that discover would have received."""
    return lambda argv: discover_arguments(monkeypatch, argv)


def test_rate_instead_of_a_time_column(tmp_path, call):
    csv, model, data = write_user_files(tmp_path, time_column=False)
    argv = base_args(csv, model, tmp_path / "o", time=None, rate="40")
    (y, t), _ = call(argv)
    np.testing.assert_allclose(t, np.arange(data.t.size) / 40.0)
    np.testing.assert_allclose(y[:, 0], np.round(data.y[:, 0], 6))


def test_default_time_column_is_t(tmp_path, call):
    csv, model, data = write_user_files(tmp_path)
    csv.write_text(csv.read_text().replace("time,", "t,", 1))
    (_, t), _ = call(base_args(csv, model, tmp_path / "o", time=None))
    np.testing.assert_allclose(t, data.t, atol=1e-6)


def test_row_ranges_and_validation_record(tmp_path, call):
    csv, model, data = write_user_files(tmp_path, time_column=False)
    argv = base_args(
        csv,
        model,
        tmp_path / "o",
        time=None,
        rate="40",
        train_rows="100:500",
        validation_rows="500:",
        validation_window="25",
    )
    (y, t), kw = call(argv)
    np.testing.assert_allclose(t, np.arange(100, 500) / 40.0)  # times keep their rows
    np.testing.assert_allclose(y[:, 0], np.round(data.y[100:500, 0], 6))
    y_v, t_v = kw["validation"].records
    np.testing.assert_allclose(t_v, np.arange(500, data.t.size) / 40.0)
    assert y_v.shape == (data.t.size - 500, 1)
    assert kw["validation"].window == 25


def test_inputs_hold_and_names(tmp_path, call):
    csv, model, _ = write_user_files(tmp_path, force=True)
    argv = base_args(
        csv,
        model,
        tmp_path / "o",
        model=f"{model}:with_input",
        inputs="force",
        input_hold="zoh",
        train_rows=":600",
        validation_rows="600:",
    )
    (y, _), kw = call(argv)
    assert kw["u"].shape == (600, 1) and kw["mme"].input_hold == "zoh"
    assert kw["options"].feature_names == ["position", "velocity", "force"]
    assert len(kw["validation"]) == 3 and kw["validation"][2].shape == (201, 1)


def test_defaults_reach_discover(tmp_path, call):
    csv, model, _ = write_user_files(tmp_path)
    argv = base_args(
        csv,
        model,
        tmp_path / "o",
        noise_variance=None,
        measured=None,
        error_states=None,
        states="position",
        model=f"{model}:f",
    )
    # One state 'position' measured: f returns two columns, so discover would
    # complain; the stand-in only looks at what the defaults became.
    _, kw = call(argv)
    assert kw["noise_variance"] == "auto"
    assert kw["measured"] == [0] and kw["error_states"] == [0]
    # The command line's defaults are the library's own, not a second copy.
    options, estimator = kw["options"], kw["mme"]
    assert options.alpha == pysindy_mme.StudyOptions().alpha
    assert estimator.error_model == pysindy_mme.MME().error_model == "white"
    assert estimator.input_hold == pysindy_mme.MME().input_hold
    assert options.verbose is False
    assert "validation" not in kw and options.parameters is None
    assert type(kw["feature_library"]).__name__ == "PolynomialLibrary"
    assert kw["feature_library"].degree == 3


def test_noise_variance_per_channel_and_other_options(tmp_path, call):
    csv, model, data = write_user_files(tmp_path)
    rows = ["time,position,velocity"] + [
        f"{t:.6f},{a:.6f},{b:.6f}" for t, (a, b) in zip(data.t, data.x)
    ]
    csv.write_text("\n".join(rows) + "\n")
    argv = base_args(
        csv,
        model,
        tmp_path / "o",
        measured="position,velocity",
        noise_variance="0.01,0.04",
        alpha="0.05",
        error_model="random_walk",
        library="power",
        offsets=True,
        verbose=True,
    )
    _, kw = call(argv)
    np.testing.assert_allclose(kw["noise_variance"], [0.01, 0.04])
    assert kw["options"].alpha == 0.05 and kw["mme"].error_model == "random_walk"
    assert type(kw["feature_library"]).__name__ == "PowerLibrary"
    assert kw["options"].offsets is True and kw["options"].verbose is True


def test_library_from_a_user_file(tmp_path, call):
    csv, model, _ = write_user_files(tmp_path)
    lib = tmp_path / "lib.py"
    lib.write_text(
        "import numpy as np\nimport pysindy as ps\n\n"
        "library = ps.CustomLibrary(library_functions=[np.sign, np.sin])\n\n"
        "def make():\n    return ps.FourierLibrary(n_frequencies=2)\n"
    )
    _, kw = call(base_args(csv, model, tmp_path / "o", library=f"{lib}:library"))
    assert type(kw["feature_library"]).__name__ == "CustomLibrary"
    _, kw = call(base_args(csv, model, tmp_path / "o", library=f"{lib}:make"))
    assert type(kw["feature_library"]).__name__ == "FourierLibrary"


def test_every_option_has_a_default_and_an_example_in_help():
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    for name, sub in commands.items():
        for action in sub._actions:
            if action.dest == "help":
                continue
            text = action.help or ""
            assert "Example:" in text or "e.g." in text, (name, action.dest, text)
            if action.option_strings and not action.required:
                assert "Default:" in text, (name, action.dest, text)
            elif action.option_strings:
                assert "Required." in text, (name, action.dest, text)


def test_help_shows_examples_and_exits_0():
    result = run(["discover", "--help"])
    assert result.code == 0
    assert "examples:" in result.out
    assert "pysindy-mme discover data.csv --model my_model.py:f" in result.out
    assert "Default: auto" in result.out  # --noise-variance
    assert "Default: every state" in result.out  # --error-states
    top = run(["--help"])
    assert top.code == 0 and "pysindy-mme demo" in top.out


def test_grey_box_parameters_end_to_end(tmp_path):
    """Duffing record, linear model with stiffness and damping 30 % off."""
    csv, model, _ = write_user_files(tmp_path)
    out = tmp_path / "out"
    argv = base_args(csv, model, out, model=f"{model}:g", parameters="k=1.3,c=0.07")
    result = run(argv)
    assert result.code == 0, result.err
    summary = json.loads((out / "discovery.json").read_text())
    k, c = summary["parameters"]["k"], summary["parameters"]["c"]
    assert k["initial"] == 1.3 and c["initial"] == 0.07
    # The truth: k = 1, c = 0.1, and the cubic spring -x^3 as the missing effect.
    assert abs(k["value"] - 1.0) < 0.05 and abs(c["value"] - 0.1) < 0.01
    assert list(summary["terms"]["velocity"]) == ["position^3"]


def test_grey_box_parameter_bounds_from_the_command_line(tmp_path):
    """``--parameters c=0.07:0:0.08`` holds c below its true 0.1: on its bound."""
    csv, model, _ = write_user_files(tmp_path)
    out = tmp_path / "out"
    argv = base_args(
        csv, model, out, model=f"{model}:g", parameters="k=1.3:0:,c=0.07:0:0.08"
    )
    result = run(argv)
    assert result.code == 0, result.err
    summary = json.loads((out / "discovery.json").read_text())
    c = summary["parameters"]["c"]
    assert c["initial"] == 0.07 and c["value"] == pytest.approx(0.08)
    assert "c = 0.08 sits on its bound" in (out / "report.txt").read_text()


def test_only_warnings_for_the_user_are_printed():
    import warnings

    from pysindy_mme.cli.commands import captured_warnings
    from pysindy_mme.exceptions import DiscoveryWarning

    with captured_warnings() as messages:
        warnings.warn("line one\n  line two", DiscoveryWarning, stacklevel=1)
        warnings.warn(
            "line one\n  line two", DiscoveryWarning, stacklevel=1
        )  # once only
        warnings.warn("a library's internals changed", DeprecationWarning, stacklevel=1)
        warnings.warn("a library's future", FutureWarning, stacklevel=1)
        warnings.warn("overflow encountered", RuntimeWarning, stacklevel=1)
        warnings.warn("plain", UserWarning, stacklevel=1)
    assert messages == ["line one line two", "plain"]


def test_k_step_scores_the_validation_rows_by_predictions(tmp_path, call):
    from pysindy_mme.protocols import KStepAhead

    csv, model, data = write_user_files(tmp_path, time_column=False)
    argv = base_args(
        csv,
        model,
        tmp_path / "o",
        time=None,
        rate="40",
        train_rows="100:500",
        validation_rows="500:",
        validation_window="25",
        k_step="8",
    )
    _, kw = call(argv)
    protocol = kw["validation"]
    assert isinstance(protocol, KStepAhead)
    assert (protocol.k, protocol.window) == (8, 25)
    y_v, t_v = protocol.records
    np.testing.assert_allclose(t_v, np.arange(500, data.t.size) / 40.0)
    assert "validation_window" not in kw


def test_k_step_without_a_record_holds_a_stretch_out(tmp_path, call):
    from pysindy_mme.protocols import KStepAhead

    csv, model, _ = write_user_files(tmp_path)
    _, kw = call(base_args(csv, model, tmp_path / "o", k_step="5"))
    protocol = kw["validation"]
    assert isinstance(protocol, KStepAhead) and protocol.records is None
    assert (protocol.k, protocol.window) == (5, 20)


@pytest.mark.parametrize("value", ["0", "2.5", "ten"])
def test_a_bad_k_step_is_named(tmp_path, value):
    csv, model, _ = write_user_files(tmp_path)
    result = run(base_args(csv, model, tmp_path / "o", k_step=value))
    assert result.code == 2
    assert "--k-step must be" in result.err and "--k-step 10" in result.err
