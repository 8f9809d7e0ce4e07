"""README.md runs as written: its Python blocks, its command line, its numbers.

The ``python`` blocks run in order in one namespace (as a reader pasting
them into one session would), in a temporary folder, with matplotlib on
the Agg backend. The command-line block runs on a CSV and the model file
the README shows. Numbers the README quotes from these runs are checked
against the runs, so the text cannot drift from the code.
"""

import ast
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()

#: what CI runs (.ci/run: "README, second command"); edit both together
OPENING = (
    'python3.11 -m venv .venv && . .venv/bin/activate && pip install ".[plot]" '
    "&& pysindy-mme demo\n"
    'python3.11 -m venv .venv && . .venv/bin/activate && pip install ".[test]" '
    "&& python -m pytest\n"
)


def fenced_blocks(text, language):
    """``[(line number, code)]`` of the fenced blocks in ``language``."""
    out = []
    pattern = re.compile(rf"^```{language}\n(.*?)^```", re.S | re.M)
    for match in pattern.finditer(text):
        out.append((text[: match.start()].count("\n") + 2, match.group(1)))
    return out


def section(text, heading):
    start = text.index(heading)
    end = text.find("\n## ", start + len(heading))
    return text[start : end if end > 0 else len(text)]


def test_opening_commands_are_the_ones_ci_runs():
    first = fenced_blocks(README, "bash")[0][1]
    assert first == OPENING
    ci = (ROOT / ".ci" / "run").read_text()
    assert 'pip install --quiet ".[test]"' in ci and "python -m pytest" in ci


@pytest.fixture(scope="module")
def readme_session(tmp_path_factory):
    """Every python block of README.md, run in order in one namespace."""
    import matplotlib

    matplotlib.use("Agg")
    import os

    folder = tmp_path_factory.mktemp("readme")
    namespace = {"__name__": "__readme__"}
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        for line, code in fenced_blocks(README, "python"):
            exec(compile(code, f"README.md:{line}", "exec"), namespace)
    finally:
        os.chdir(cwd)
        import matplotlib.pyplot as plt

        plt.close("all")
    return namespace, folder


def test_python_blocks_run_as_written(readme_session):
    namespace, folder = readme_session
    assert (folder / "study.png").stat().st_size > 10_000
    assert namespace["result"].found_correction
    assert namespace["x"].shape == (401, 2)


def test_quoted_terms_are_what_discover_finds(readme_session):
    namespace, _ = readme_session
    line = next(ln for ln in README.splitlines() if "print(result.terms)" in ln)
    quoted = ast.literal_eval(line.split("#", 1)[1].strip())
    terms = namespace["result"].terms
    assert set(terms) == set(quoted)
    for state, values in quoted.items():
        assert set(terms[state]) == set(values)
        for name, value in values.items():
            assert round(terms[state][name], 3) == value, (name, terms[state][name])
    truth = {"x1": -1.0, "x2": 1.0, "x1^2 x2": -1.0}
    within = float(re.search(r"`discover` gets within\s+([0-9.]+)", README).group(1))
    assert max(abs(terms["x2"][k] - v) for k, v in truth.items()) < within


def test_quoted_hidden_state_law_is_what_discover_finds(readme_session):
    namespace, _ = readme_session
    line = next(ln for ln in README.splitlines() if "print(hidden.terms)" in ln)
    quoted = ast.literal_eval(line.split("#", 1)[1].strip())
    terms = namespace["hidden"].terms
    assert set(terms) == set(quoted) == {"z"}
    assert set(terms["z"]) == set(quoted["z"])
    for name, value in quoted["z"].items():
        assert round(terms["z"][name], 1) == value, (name, terms["z"][name])


def test_quoted_sindy_route_coefficients(readme_session):
    namespace, _ = readme_session
    model = namespace["model"]  # rebound by the optimizer-alone block: refit
    assert model.feature_names == ["prey", "predator"]
    match = re.search(
        r"here\s+(-?[0-9.]+),\s+\+([0-9.]+),\s+(-?[0-9.]+)\s+for\s+true", README
    )
    quoted = [float(g) for g in match.groups()]
    mme = namespace["mme"]
    names = namespace["full"].library_feature_names
    coef = namespace["full"].correction_coef_[1]
    got = [coef[names.index(n)] for n in ("x1", "x2", "x1^2 x2")]
    np.testing.assert_allclose(got, quoted, atol=5e-4)
    comment = re.search(r"the correction: \(x2\)' = (-?[0-9.]+) x1", README)
    assert round(got[0], 3) == float(comment.group(1))
    assert mme.smoothed_x_.shape == (401, 2)


def test_command_line_block_runs_on_the_model_file_it_shows(tmp_path, monkeypatch):
    from pysindy_mme.cli import main
    from pysindy_mme.systems import duffing

    text = section(README, "## Command line")
    model_code = fenced_blocks(text, "python")[0][1]
    command = next(c for _, c in fenced_blocks(text, "bash") if "discover" in c)
    (tmp_path / "my_model.py").write_text(model_code)
    data = duffing().measure(0)
    rows = ["t,position"] + [f"{t:.6f},{y:.6f}" for t, y in zip(data.t, data.y[:, 0])]
    (tmp_path / "data.csv").write_text("\n".join(rows) + "\n")
    monkeypatch.chdir(tmp_path)
    argv = shlex.split(command.replace("\\\n", " "))
    assert argv[0] == "pysindy-mme"
    assert main(argv[1:]) == 0
    after = text[text.index(command) :]
    promised = re.findall(r"`([a-z_]+\.(?:txt|json|csv|png))`", after.split("\n\n")[1])
    assert len(promised) == 7
    for name in promised:
        assert (tmp_path / "results" / name).stat().st_size > 0, name


def test_options_in_the_readme_table_exist():
    from pysindy_mme.cli import build_parser

    parser = build_parser()
    help_text = parser._subparsers._group_actions[0].choices["discover"].format_help()
    options = re.findall(r"(--[a-z][a-z-]+)", section(README, "## Command line"))
    assert len(set(options)) >= 12
    for option in set(options):
        assert option in help_text, option


def test_images_the_readme_shows_exist():
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", README)
    assert "docs/gain.png" in images
    for image in images:
        assert (ROOT / image).stat().st_size > 10_000, image


def test_quoted_gain_is_the_studys(readme_session):
    namespace, _ = readme_session
    gain = namespace["result"].gain
    match = re.search(r"a gain of ([0-9.]+)x in-sample and ([0-9.]+)x out of", README)
    quoted = [float(v) for v in match.groups()]
    got = [float(gain.ratio[0]), float(gain.validation_ratio[0])]
    np.testing.assert_allclose(got, quoted, rtol=0.005)
    np.testing.assert_allclose(gain.rmse_extended, gain.noise_floor, rtol=0.05)
