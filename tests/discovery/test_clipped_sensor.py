"""Issue 19, "sensors as they come": a study on a record whose sensor clips.

The clipped oscillator (``pysindy_mme.machines.clipped_oscillator``): a Van
der Pol oscillator of amplitude 2 seen by a position sensor that reads at
most 1.6, so that every positive swing sits on the ceiling for a while
(about 18 % of the readings), and an assumed model that lacks the Van der
Pol damping. ``discover`` must name the clipped readings with their count,
leave them out of the fit and of the RMSEs (``clipped="auto"``), fit them
as readings on request (``clipped="keep"``, a different study), say when a
model's free run crosses the ceiling, and say nothing of the kind on a
record that does not clip. Every study here is also audited
(``tests/report_audit.py``: the report's claims and the RMSEs against an
independent free run).
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pysindy as ps
import pytest
import report_audit

from pysindy_mme import MME, StudyOptions, discover
from pysindy_mme.cli.arguments import build_request
from pysindy_mme.cli.parser import build_parser
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.machines import cascaded_tanks, clipped_oscillator
from pysindy_mme.protocols.runs import observed_window

MACHINE = clipped_oscillator()
REC = MACHINE.record(0)
CHECK = MACHINE.record(1, x0=(1.0, 0.5))
CEILING_LINE = (
    "sit on the sensor's ceiling 1.6: treated as censored (left out of the fit)"
)


def study(rec=REC, **kwargs):
    options = dict(
        assumed_model=MACHINE.assumed_model,
        parameters=MACHINE.parameters,
        n_states=2,
        measured=[0],
        noise_variance=0.05**2,
        error_states=[1],
        feature_library=ps.PolynomialLibrary(degree=3),
        feature_names=["x1", "x2"],
    )
    options.update(kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return discover(rec.y, rec.t, **grouped_keywords(options))


def audited(res):
    # module-scoped studies run before the autouse audit is in place
    report_audit.audit(res)
    return res


@pytest.fixture(scope="module")
def censored():
    return audited(study(validation=(CHECK.y, CHECK.t)))


@pytest.fixture(scope="module")
def kept():
    return audited(study(clipped="keep"))


def test_the_record_clips():
    assert 50 < REC.n_clipped < 0.3 * REC.t.size
    assert CHECK.n_clipped > 50


def test_the_clipped_readings_are_named_with_their_count(censored):
    (c,) = censored.clipped
    assert (c.channel, c.side, c.level) == (0, "ceiling", 1.6)
    assert c.count == REC.n_clipped
    share = f"{100 * REC.n_clipped / REC.t.size:.2g} %"
    text = str(censored)
    assert f"Clipped: x1: {REC.n_clipped} samples ({share}) {CEILING_LINE}" in text
    (v,) = censored.validation_clipped
    assert v.count == CHECK.n_clipped
    assert f"Clipped: validation record, x1: {CHECK.n_clipped} samples" in text
    assert "Clipped readings are left out of every RMSE" in text
    record = censored.to_dict()["clipped"]
    assert record["option"] == "auto" and record["censored"] is True
    assert record["fitting_record"][0]["count"] == REC.n_clipped
    assert record["validation_record"][0]["count"] == CHECK.n_clipped
    json.dumps(record)


def test_the_clipped_readings_are_left_out_of_the_fit(censored):
    mask = censored.clipped.mask
    assert np.isnan(censored.y[mask]).all()
    np.testing.assert_array_equal(censored.y[~mask], REC.y[~mask])
    np.testing.assert_array_equal(censored.readings, REC.y)
    n_left = REC.t.size - REC.n_clipped
    assert censored.assumed.fit.n_residuals == n_left
    assert censored.extended_fit.n_residuals == n_left
    assert censored.consistency_dof == n_left - 2
    assert f"({n_left} residuals less 2 initial states)" in str(censored)
    # MME saw the same gaps: its residuals are NaN there
    assert np.isnan(np.asarray(censored.mme.residuals_)[mask[:, 0]]).all()


def test_the_rmses_leave_the_clipped_readings_out(censored):
    run = censored.gain.in_sample_runs["extended"]
    keep = ~censored.clipped.mask[:, 0]
    expected = np.sqrt(np.mean((REC.y[keep, 0] - run.x[keep, 0]) ** 2))
    assert censored.gain.rmse_extended[0] == pytest.approx(expected, rel=1e-9)
    y_v = censored.study.validation[0]
    assert np.isnan(y_v[censored.validation_clipped.mask]).all()


def test_censored_the_missing_damping_is_found(censored):
    # the Van der Pol damping mu (1 - x1^2) x2 with mu = 1, and k = 1
    terms = censored.terms["x2"]
    assert set(terms) == {"x2", "x1^2 x2"}
    assert terms["x2"] == pytest.approx(1.0, abs=0.1)
    assert terms["x1^2 x2"] == pytest.approx(-1.0, abs=0.1)
    assert censored.parameters["k"].value == pytest.approx(1.0, abs=0.05)


def test_the_input_is_not_modified():
    y = REC.y.copy()
    y.setflags(write=False)
    v = CHECK.y.copy()
    res = study(REC, validation=(v, CHECK.t))
    np.testing.assert_array_equal(y, REC.y)
    np.testing.assert_array_equal(v, CHECK.y)
    assert res.clipped.count == REC.n_clipped


def test_keep_fits_the_clipped_readings_as_readings(censored, kept):
    assert kept.clipped.count == REC.n_clipped  # found, and named
    assert "fitted as readings (clipped='keep')" in str(kept)
    assert "treated as censored" not in str(kept)
    assert np.isfinite(kept.y).all()
    assert kept.assumed.fit.n_residuals == REC.t.size
    # a different study: fitting the ceiling as readings bends the model to it
    assert kept.terms != censored.terms
    assert kept.assumed.chi2 != pytest.approx(censored.assumed.chi2, rel=0.01)
    assert kept.to_dict()["clipped"]["censored"] is False


def test_a_given_range_censors_at_or_beyond_it():
    res = study(clipped=(None, 1.55))
    (c,) = res.clipped
    assert c.given and c.level == 1.55
    assert c.count == int(np.sum(REC.y >= 1.55)) > REC.n_clipped
    assert "sit at or beyond the sensor's ceiling 1.55 (given)" in str(res)
    assert np.isnan(res.y[REC.y >= 1.55]).all()


def test_a_model_that_crosses_the_ceiling_is_named(censored):
    # the Van der Pol limit cycle reaches x1 = 2, above the 1.6 the sensor shows
    crossing = [r for r in censored.reasons if "reaches" in r]
    assert len(crossing) == 1
    (line,) = crossing
    assert line.startswith("the extended model's x1 reaches 2.0")
    assert "above the highest reading (1.6, a sensor ceiling)" in line
    assert (
        "the plant may saturate there (an overflow or a limit the model lacks)" in line
    )
    assert "PhysicsLibrary effects Overflow/Saturation" in line
    assert any("Overflow or Saturation" in a for a in censored.advice)
    assert f"- {line}" in str(censored)
    # the label is the evidence's, not the crossing's
    assert censored.conclusion == "explained"


def test_no_clipping_no_line():
    machine = clipped_oscillator(ceiling=10.0)
    rec = machine.record(0)
    assert rec.n_clipped == 0
    res = study(rec)
    assert not res.clipped and res.clipped.count == 0
    text = str(res)
    assert "Clipped" not in text and "sensor ceiling" not in text
    assert not any("reaches" in r for r in res.reasons)
    assert not any("Saturation" in a for a in res.advice)
    assert res.to_dict()["clipped"]["fitting_record"] == []


def test_validate_censors_another_record(censored):
    runs = censored.validate(CHECK.y, CHECK.t)
    keep = ~censored.validation_clipped.mask[:, 0]
    x = runs["extended"].x
    w = censored.study.validation_window
    expected = np.sqrt(np.mean((CHECK.y[w:][keep[w:], 0] - x[w:][keep[w:], 0]) ** 2))
    assert runs["extended"].rmse[0] == pytest.approx(expected, rel=1e-9)


def test_a_validation_record_on_the_ceiling_is_cut_and_its_window_lengthened():
    # the validation record starts above the ceiling: its first 21 readings
    # are clipped (cut: nothing before them), and a clipped reading among the
    # next ones lengthens the window so that the initial state sees 5 readings
    val = MACHINE.record(1, x0=(2.0, 0.3))
    readings = np.flatnonzero(val.y[:, 0] < 1.6)
    lead = int(readings[0])
    window = int(readings[4]) + 1 - lead  # the leading samples holding 5 readings
    assert lead > 5 and window > 5
    res = study(validation=(val.y, val.t), validation_window=5)
    assert res.study.validation_clipped_cut == (lead, 0)
    np.testing.assert_array_equal(res.study.validation[1], val.t[lead:])
    # 5 readings: the window the clipped readings lengthen to ...
    assert observed_window(5, res.study.validation[0]) == window
    # ... and further while it leaves an initial state undetermined (5 %)
    used = res.gain.validation_window
    assert used >= window
    runs = res.gain.validation_runs
    assert runs["extended"].window == runs["assumed"].window == used
    assert f"initial state from its first {used} samples" in str(res)
    assert f"the validation record's first {lead} samples are all on" in str(res)
    assert np.isfinite(res.gain.validation_rmse_extended).all()


def test_a_record_that_starts_and_ends_on_the_ceiling_is_cut_there():
    # nothing before (after) a leading (trailing) clipped stretch anchors the
    # states in it: the study runs on the samples between
    rec = MACHINE.record(0, x0=(2.0, 0.3))
    clipped = rec.y[:, 0] == 1.6
    lead = int(np.argmin(clipped))
    stop = rec.t.size - 40
    while not clipped[stop - 1]:
        stop -= 1  # end the record inside a clipped stretch
    trail = stop - 1 - int(np.flatnonzero(~clipped[:stop])[-1])
    part = dataclasses.replace(rec, t=rec.t[:stop], y=rec.y[:stop], x=rec.x[:stop])
    assert lead > 0 and trail > 0
    res = study(part)
    assert res.study.clipped_cut == (lead, trail)
    assert res.t.size == stop - lead - trail
    np.testing.assert_array_equal(res.t, part.t[lead : stop - trail])
    assert res.clipped.count + lead + trail == part.n_clipped
    assert res.clipped.mask.shape == res.y.shape
    assert f"the record's first {lead} and last {trail} samples are all on" in str(res)
    assert res.to_dict()["clipped"]["cut"]["fitting_record"] == [lead, trail]


@pytest.mark.parametrize(
    "clipped, error, phrase",
    [
        ("yes", ValueError, "clipped must be 'auto', 'keep' or a"),
        (None, TypeError, "clipped must be 'auto', 'keep' or a"),
        ((2.0, 1.0), ValueError, "clipped: low must be below high"),
        ([(0, 1), (0, 1)], ValueError, "clipped has 2 ranges but there are 1"),
    ],
)
def test_a_bad_clipped_option_fails_first(no_long_computation, clipped, error, phrase):
    with pytest.raises(error, match=phrase):
        study(clipped=clipped)


def test_every_reading_clipped_is_an_error(no_long_computation):
    with pytest.raises(ValueError, match="every reading of y is on the sensor's"):
        study(clipped=(None, -10.0))


def test_the_command_line_passes_clipped(tmp_path):
    csv = tmp_path / "data.csv"
    rows = ["t,x1"] + [f"{t:.6f},{y:.6f}" for t, y in zip(REC.t, REC.y[:, 0])]
    csv.write_text("\n".join(rows) + "\n")
    model = tmp_path / "model.py"
    model.write_text(
        "import numpy as np\n\n\ndef g(x, t, u, p):\n"
        "    return np.column_stack([x[:, 1], -p['k'] * x[:, 0]])\n"
    )
    base = ["discover", str(csv), "--model", f"{model}:g", "--states", "x1,x2"]
    base += ["--measured", "x1", "--parameters", "k=0.8"]
    parser = build_parser()
    request = build_request(parser.parse_args(base + ["--clipped", "keep"]))
    assert request.kwargs["options"].clipped == "keep"
    request = build_request(parser.parse_args(base))
    assert request.kwargs["options"].clipped == "auto"  # the library's default
    from pysindy_mme.cli.loading import UsageError

    with pytest.raises(UsageError, match="--clipped must be auto or keep"):
        build_request(parser.parse_args(base + ["--clipped", "drop"]))


@pytest.mark.slow
def test_the_two_tanks_ceiling_and_floor():
    """The tanks' 12-bit sensor clips at 10 V (and reads 0 V in an empty
    tank): every clipped reading found, the model's h2 named above 10 V."""
    machine = cascaded_tanks(assumed="sqrt")
    rec = machine.record(0, duration=2048.0)
    val = machine.record(1, duration=2048.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = discover(
            rec.y,
            rec.t,
            u=rec.u,
            assumed_model=machine.assumed_model,
            n_states=2,
            measured=[1],
            noise_variance=0.02**2,
            error_states=[0, 1],
            feature_library=ps.PolynomialLibrary(degree=2),
            validation=(val.y, val.t, val.u),
            options=StudyOptions(
                parameters=machine.parameters, feature_names=["h1", "h2", "u"]
            ),
            mme=MME(input_hold="zoh"),
        )
    # the record ends on the ceiling: those last samples are cut, not fitted
    lead, trail = res.study.clipped_cut
    assert lead == 0 and trail > 0
    assert res.clipped.count + trail == rec.n_clipped
    assert res.t.size == rec.t.size - trail
    assert res.validation_clipped.count == val.n_clipped
    assert res.clipped.on(0, "ceiling").level == 10.0
    text = str(res)
    assert "sit on the sensor's ceiling 10: treated as censored" in text
    assert f"the record's last {trail} samples are all on the sensor's limits" in text
    assert any("h2 reaches" in r and "(10, a sensor ceiling)" in r for r in res.reasons)
