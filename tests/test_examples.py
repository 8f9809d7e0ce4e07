"""Every script in examples/ runs (``--quick``), and finds what it says it finds.

Each example is run as ``python examples/NAME.py --quick`` would run it
(``runpy`` in this process, in a temporary folder, matplotlib on Agg). An
example that needs the real measurements in ``../shared/data`` runs only in
the slow suite and is skipped, with the reason, where the data are absent.
"""

import contextlib
import io
import re
import runpy
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))
SHARED = ROOT.parent / "shared" / "data"

#: what each example's output must contain (regular expressions): the effect
#: it is about, named with a coefficient of the right sign
FINDS = {
    "van_der_pol_paper.py": [
        r"x2' misses: .*x1\^2 x2",
        "note: the correction's coefficients were regressed on MME's estimate",
    ],
    "duffing_hidden_stiffness.py": [r"x2' misses: -0\.9\d* x1\^3\n"],
    "forced_oscillator_input.py": [r"x2' misses: 0\.[45]\d* u\n"],
    "command_line.py": [r"velocity' misses: 0\.[45]\d* force\n", "timeseries.csv"],
    "hysteresis.py": [
        r"hidden state entering v': discover\(\.\.\., hidden_states=\{'z': 'v'\}\)",
        r"\(v\)' = \[assumed\] f_v\(x, t\) \+ z\n",
        r"Conclusion: explained\. ",
        r"alpha +(49[5-9]\d\d|50[0-4]\d\d) +50000 ",
        r"beta gamma +(79[2-9]|80[0-7])(\.\d+)? +800 ",
        r"beta delta +-(10[89]\d|11[01]\d)(\.\d+)? +-1100 ",
        r"extended / noise = (0\.9[5-9]\d|1\.0[0-4]\d)\)",
    ],
}
#: examples on real data: data folder and extra arguments
REAL_DATA = {"silverbox.py": ("silverbox", ["--data"])}


def _run(path, argv, folder, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    monkeypatch.chdir(folder)
    monkeypatch.setattr(sys, "argv", [str(path), *argv])
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        runpy.run_path(str(path), run_name="__main__")
    import matplotlib.pyplot as plt

    plt.close("all")
    return out.getvalue()


def test_every_example_is_covered():
    names = {p.name for p in EXAMPLES}
    assert names == set(FINDS) | (names & set(REAL_DATA))
    assert set(FINDS) <= names


@pytest.mark.parametrize("name", sorted(FINDS))
def test_example_runs_quick(name, tmp_path, monkeypatch):
    text = _run(ROOT / "examples" / name, ["--quick"], tmp_path, monkeypatch)
    for pattern in FINDS[name]:
        assert re.search(pattern, text), (name, pattern)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(REAL_DATA))
def test_real_data_example_runs_quick(name, tmp_path, monkeypatch):
    folder, flag = REAL_DATA[name]
    data = SHARED / folder
    if not (ROOT / "examples" / name).exists():
        pytest.skip(f"examples/{name} is not in this checkout")
    if not data.is_dir():
        pytest.skip(f"needs the real measurements in {data} (not in this checkout)")
    text = _run(
        ROOT / "examples" / name, ["--quick", *flag, str(data)], tmp_path, monkeypatch
    )
    assert "mV" in text
