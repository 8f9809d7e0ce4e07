"""Issues 10.1 and 19: the Silverbox study on the official training block.

Real measurements (Wigren and Schoukens, ECC 2013; read from
``../shared/data/silverbox``, never copied into the repository): the linear
mass-spring-damper with unknown parameters, extended by what the data say it
misses, must name the cubic spring as the dominant missing effect, return
mass, damping and stiffness as parameters (not as discoveries), and simulate
each official test split to within 0.9 mV (RMSE after the 50 settling
samples).

Issue 19, choices made on training data only: the example's input hold is
the one with the smallest held-out error in the training-only table it
prints (the study then runs with it), the choice sees training samples only,
and the printed comparison lists the best published results on the arrow
(PNLSS 0.26 mV, nonlinear ARX 0.30 mV) next to ours.
"""

import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data" / "silverbox"


def _load(name, path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _example():
    return _load("silverbox_example", ROOT / "examples" / "silverbox.py")


def _hold_table(text):
    """``({hold: RMSE in mV}, marked hold)`` from the printed training table."""
    block = text.split("| hold | training held-out RMSE (mV) |", 1)[1]
    rows, marked = {}, None
    for line in block.splitlines()[2:]:
        m = re.fullmatch(r"\| (\w+)( \(chosen\))? \| (\S+) \|", line)
        if not m:
            break
        rows[m[1]] = float(m[3])
        if m[2]:
            marked = m[1]
    return rows, marked


@pytest.mark.slow
def test_silverbox_study_names_the_cubic_spring_and_beats_the_baselines(
    capsys, tmp_path
):
    if not DATA.is_dir():
        pytest.skip(
            f"needs the Silverbox measurements in {DATA} (not in this checkout)"
        )
    from pysindy_mme.core.integrate import HOLDS
    from pysindy_mme.datasets import fetch_silverbox

    example = _example()
    sb = fetch_silverbox(DATA, download_if_missing=False)
    res, scores, choice = example.main(
        ["--data", str(DATA), "--out", str(tmp_path), "--no-figure"]
    )
    text = capsys.readouterr().out

    # --- issue 19: the hold, chosen by the training-only criterion ----------
    rows, marked = _hold_table(text)
    assert set(rows) == set(HOLDS), rows
    printed_choice = re.search(r"^Chosen input hold: (\w+)$", text, re.M)[1]
    assert printed_choice == marked == min(rows, key=rows.get) == choice.hold
    assert res.study.inputs.hold == choice.hold  # the study ran with it
    for hold, rmse in rows.items():
        assert rmse == pytest.approx(1e3 * choice.rmse[hold][0], rel=5e-3)
    # the choice saw the start of the training block and nothing else
    train = sb.split("train")
    assert choice.n_fit + choice.n_held_out <= train.y.size
    for hold, st in choice.studies.items():
        assert st.study.inputs.hold == hold
        np.testing.assert_array_equal(st.y[:, 0], train.y[: choice.n_fit])
    # the published best rows on the arrow, next to ours
    assert re.search(
        r"^\| polynomial nonlinear state space, PNLSS .* \| 0\.26 \|", text, re.M
    )
    assert re.search(r"^\| nonlinear ARX .* \| 0\.30 \|", text, re.M)
    assert "Automatica 46(4)" in text
    assert re.search(r"^\| extended model \(this study\) \| \d", text, re.M)

    # --- issue 10.1: the study itself ----------------------------------------
    # the cubic spring: the largest share of the correction
    shares = {te.feature: te.share_of_correction for te in res.term_estimates}
    assert max(shares, key=shares.get) == "y^3", shares
    assert res.terms["v"]["y^3"] < 0  # a hardening spring
    # the linear model's parameters come back as parameters ...
    assert set(res.parameters) == {"k", "c", "b"}
    for pe in res.parameters.values():
        assert pe.ci_low < pe.value < pe.ci_high
    # ... and the terms that only re-do them are not discoveries
    assert "y" not in res.terms["v"] and "u" not in res.terms["v"]
    assert any(
        "duplicates the assumed model's parameter" in r for r in res.pruned_terms
    )
    for name, rmse in scores.items():
        assert rmse["extended"] <= 0.9, (name, rmse)
        assert rmse["extended"] < rmse["assumed"] / 5, (name, rmse)
    # twice better than the recurrent networks on the arrow (the published
    # PNLSS and nonlinear ARX results, 0.26 and 0.30 mV, are not beaten there)
    recurrent_arrow_full = sb.baselines_mv["recurrent networks (GRU, LSTM)"][
        "test_arrow_full"
    ][0]
    assert scores["test_arrow_full"]["extended"] <= recurrent_arrow_full / 2
