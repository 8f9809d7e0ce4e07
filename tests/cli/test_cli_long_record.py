"""Issue 9.5: a 10^5-sample record on the command line, with and without --verbose.

The paper's Van der Pol case at 40 Hz over 2,500 s (100,001 samples) as a
CSV. With ``--verbose`` every stage of the study reaches standard error with
the elapsed time; without it the command prints the report and nothing else.
"""

import numpy as np
import pytest
from cli_support import run

from pysindy_mme.core.integrate import simulate
from pysindy_mme.systems import van_der_pol

MODEL = '''
import numpy as np

def f(x, t):
    """The paper's ignorance model: x1' = x2, x2' = 0."""
    return np.column_stack([x[:, 1], np.zeros(len(x))])
'''


@pytest.fixture(scope="module")
def long_record(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("long")
    system = van_der_pol()
    t = np.arange(100_001) / 40.0

    def rhs(x, s, u):
        return system.true_model(x, np.full(len(x), s))

    x = simulate(rhs, np.array([1.0, 0.0]), t, substeps=4).x[0]
    y = x[:, 0] + 0.1 * np.random.default_rng(0).standard_normal(t.size)
    csv = tmp / "long.csv"
    np.savetxt(
        csv,
        np.column_stack([t, y]),
        delimiter=",",
        header="t,x1",
        comments="",
        fmt="%.6f",
    )
    model = tmp / "model.py"
    model.write_text(MODEL)
    return tmp, csv, model


def _argv(tmp, csv, model, *extra):
    return [
        "discover",
        csv,
        "--model",
        f"{model}:f",
        "--states",
        "x1,x2",
        "--measured",
        "x1",
        "--time",
        "t",
        "--noise-variance",
        "0.01",
        "--error-states",
        "x2",
        "--out",
        tmp / "out",
        *extra,
    ]


@pytest.mark.slow
def test_verbose_shows_each_stage_of_a_long_study(long_record):
    tmp, csv, model = long_record
    result = run(_argv(tmp, csv, model, "--verbose"))
    assert result.code == 0, result.err
    stages = [
        "checked: 100001 samples",
        "1. assumed model",
        "2. MME",
        "3. regression of d(t)",
        "4. confirmed",
        "5. gain measured",
    ]
    positions = [result.err.index(stage) for stage in stages]
    assert positions == sorted(positions)
    assert all(line.startswith("[") for line in result.err.splitlines() if "s]" in line)
    assert "x2' misses" in result.out


@pytest.mark.slow
def test_without_verbose_only_the_report(long_record):
    tmp, csv, model = long_record
    result = run(_argv(tmp, csv, model))
    assert result.code == 0, result.err
    assert "checked:" not in result.err and "2. MME" not in result.err
    assert result.out.startswith("pysindy-mme discovery report")
