"""Several records in one study (issue 19): each record its own initial state,
the parameters and the correction shared, no dynamics link across a break."""

from __future__ import annotations

import json
import time
import warnings

import numpy as np
import pysindy as ps
import pytest

from pysindy_mme import MME, Record, discover
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.systems import van_der_pol


def assumed(x, t):
    """The paper's assumed model of Van der Pol: x1' = x2, x2' = 0."""
    return np.column_stack([x[:, 1], np.zeros(len(x))])


OPTIONS = dict(
    assumed_model=assumed,
    n_states=2,
    measured=[0],
    noise_variance=0.01,
    error_states=[1],
    feature_library=ps.PolynomialLibrary(degree=3),
    feature_names=["x1", "x2"],
)
TRUE_TERMS = {"x1", "x2", "x1^2 x2"}


def study(y, t=None, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return discover(y, t, **grouped_keywords({**OPTIONS, **kwargs}))


def estimates(result) -> dict:
    return {e.feature: (e.coefficient, e.std_error) for e in result.term_estimates}


def test_mme_decouples_exactly_at_a_break():
    """With W fixed, MME on two concatenated records is MME on each alone."""
    a = van_der_pol().measure(0)
    b = van_der_pol().measure(1, x0=(2.0, -1.0))
    kw = dict(OPTIONS, W=3.0)
    for key in ("feature_library", "feature_names"):
        kw.pop(key)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        alone = [MME(**kw).fit(r.y, r.t) for r in (a, b)]
        both = MME(**kw).fit(
            np.vstack([a.y, b.y]), np.concatenate([a.t, b.t]), starts=[a.t.size]
        )
    x = np.vstack([m.smoothed_x_ for m in alone])
    d = np.vstack([m.d_ for m in alone])
    assert np.max(np.abs(both.smoothed_x_ - x)) < 1e-9
    assert np.max(np.abs(both.d_ - d)) < 1e-9
    assert both.cost_ == pytest.approx(sum(m.cost_ for m in alone), rel=1e-12)


def test_one_record_split_in_two_agrees_with_the_whole():
    """(a) The same data as one record and as two: same terms, coefficients
    within 2 standard errors; the report counts the records."""
    data = van_der_pol().measure(0)
    k = 200
    whole = study(data.y, data.t)
    split = study([data.y[:k], data.y[k:]], [data.t[:k], data.t[k:]])
    assert set(whole.terms["x2"]) == set(split.terms["x2"]) == TRUE_TERMS
    one, two = estimates(whole), estimates(split)
    for name, (value, se) in one.items():
        other, se2 = two[name]
        assert abs(value - other) <= 2 * max(se, se2), (name, value, other, se, se2)
    text = str(split)
    assert "Data: 2 records, 200 + 201 samples" in text
    assert "pooled over the records" in text
    assert "400 residuals less 4 initial states" in text.replace("401", "400") or (
        "less 4 initial states" in text
    )
    # no validation: the last record is held out whole
    assert "the last record held out whole" in split.gain.validation_source
    runs = split.gain.in_sample_runs["extended"]
    assert len(runs.records) == 2 and len(runs.x0s) == 2
    assert runs.x.shape == (data.t.size, 2)


def test_records_as_Record_and_as_lists_are_the_same_study():
    data = van_der_pol().measure(0)
    k = 200
    a = study([data.y[:k], data.y[k:]], [data.t[:k], data.t[k:]])
    b = study([Record(data.y[:k], data.t[:k]), Record(data.y[k:], data.t[k:])])
    assert a.terms == b.terms


def test_two_short_records_from_different_states_beat_either_alone():
    """(b) Two short records (different initial states, amplitudes and noise
    seeds, times each from 0): together they pin the hidden terms down better
    than either alone."""
    system = van_der_pol()
    t = np.arange(0, 5.0 + 1e-9, 0.025)
    a = system.measure(3, t=t)
    b = system.measure(4, t=t, x0=(2.5, -1.0))
    alone = [study(r.y, r.t) for r in (a, b)]
    both = study([a.y, b.y], [a.t, b.t])
    assert set(both.terms["x2"]) == TRUE_TERMS
    together = estimates(both)
    truth = {"x1": -1.0, "x2": 1.0, "x1^2 x2": -1.0}
    for name, value in truth.items():
        c, se = together[name]
        assert abs(c - value) < 4 * se + 0.02, (name, c, se)
        for single in alone:
            if name in estimates(single):
                assert se < estimates(single)[name][1], (name, se)
    assert "Data: 2 records, 201 + 201 samples" in str(both)


def test_validation_as_a_list_pools_the_rmse():
    """(c) Validation records as a list: each gets the window protocol, the
    RMSE is pooled over them and kept per record."""
    data = van_der_pol().measure(0)
    v1 = van_der_pol().measure(1000, x0=(2.0, -1.0))
    v2 = van_der_pol().measure(1001, x0=(0.5, 0.5))
    res = study(data.y, data.t, validation=[(v1.y, v1.t), Record(v2.y, v2.t)])
    g = res.gain
    assert "2 validation records" in g.validation_source
    for name, pooled in (
        ("assumed", g.validation_rmse_assumed),
        ("extended", g.validation_rmse_extended),
    ):
        per = [r.rmse[0] for r in g.validation_runs[name].records]
        assert len(per) == 2
        assert min(per) - 1e-12 <= pooled[0] <= max(per) + 1e-12
    assert g.validation_rmse_extended[0] < 0.15  # near the noise floor 0.1
    # a list of one record is the single-record protocol
    one = study(data.y, data.t, validation=[(v1.y, v1.t)])
    single = study(data.y, data.t, validation=(v1.y, v1.t))
    assert one.gain.validation_rmse_extended == pytest.approx(
        single.gain.validation_rmse_extended
    )


@pytest.fixture
def no_long_computation(monkeypatch):
    """Bad input must be refused before step 1 starts."""
    import pysindy_mme.discovery.study as module

    def tripwire(*args, **kwargs):
        raise AssertionError("a long computation started before the check")

    monkeypatch.setattr(module, "fit_assumed_model", tripwire)


BAD = [
    (
        "mismatched lengths",
        lambda y, t: dict(y=[y, y], t=[t]),
        ValueError,
        "t has 1 time arrays but y has 2 records",
    ),
    (
        "inputs per record",
        lambda y, t: dict(y=[y, y], t=[t, t], u=[np.zeros(t.size)]),
        ValueError,
        "u must be a list of 2 input arrays",
    ),
    (
        "a record too short",
        lambda y, t: dict(y=[y, y[:5]], t=[t, t[:5]]),
        ValueError,
        "y[1] has 5 samples",
    ),
    (
        "different channels",
        lambda y, t: dict(y=[y, np.hstack([y, y])], t=[t, t]),
        ValueError,
        "y[1] has 2 columns but y[0] has 1",
    ),
    (
        "time not increasing within a record",
        lambda y, t: dict(y=[y, y], t=[t, t[::-1]]),
        ValueError,
        "t[1] must be strictly increasing",
    ),
    (
        "a short validation record",
        lambda y, t: dict(y=y, t=t, validation=[(y, t), (y[:30], t[:30])]),
        ValueError,
        "validation[1] has 30 samples",
    ),
    (
        "a validation record with other channels",
        lambda y, t: dict(y=y, t=t, validation=[(y, t), (np.hstack([y, y]), t)]),
        ValueError,
        "validation[1] y has 2 columns",
    ),
    (
        "Records and t",
        lambda y, t: dict(y=[Record(y, t), Record(y, t)], t=t),
        TypeError,
        "give t and u inside each Record",
    ),
]


@pytest.mark.parametrize("case", BAD, ids=[c[0] for c in BAD])
def test_bad_records_are_refused_up_front(case, no_long_computation):
    """(d) Clear errors naming the argument, before any long computation."""
    _, build, kind, message = case
    data = van_der_pol().measure(0)
    args = build(data.y, data.t)
    y, t = args.pop("y"), args.pop("t")
    start = time.perf_counter()
    with pytest.raises(kind) as info:
        discover(y, t, **grouped_keywords({**OPTIONS, **args}))
    assert message in str(info.value)
    assert time.perf_counter() - start < 5.0


def test_cli_two_data_files_and_validation(tmp_path):
    """(e) Two data files and --validation FILE on the command line."""
    from tests.cli.cli_support import base_args, run, write_user_files

    dirs = [tmp_path / name for name in ("a", "b", "v")]
    for d in dirs:
        d.mkdir()
    (csv_a, model, _), (csv_b, _, _), (csv_v, _, _) = (
        write_user_files(d, seed=s) for d, s in zip(dirs, (0, 1, 2))
    )
    out = tmp_path / "out"
    argv = base_args(csv_a, model, out)
    argv.insert(2, str(csv_b))
    argv += ["--validation", str(csv_v)]
    result = run(argv)
    assert result.code == 0, result.err
    report = (out / "report.txt").read_text()
    assert "Data: 2 records" in report
    gain = json.loads((out / "discovery.json").read_text())["gain"]
    assert gain["validation_source"] == "the validation record"
    # row options select rows of one file: refused with several
    argv = base_args(csv_a, model, out, train_rows="0:100")
    argv.insert(2, str(csv_b))
    bad = run(argv)
    assert bad.code != 0 and "--train-rows selects rows of one data file" in bad.err


def test_grey_box_parameter_split_agrees_with_the_whole():
    """(a) A grey-box parameter shared by the records: the same estimate,
    within 2 standard errors, from one record and from it split in two."""

    def grey(x, t, u, p):
        return np.column_stack([x[:, 1], -p["k"] * x[:, 0]])

    data = van_der_pol().measure(0)
    kw = dict(assumed_model=grey, parameters={"k": 0.5})
    whole = study(data.y, data.t, **kw)
    for k in (120, 200):
        split = study([data.y[:k], data.y[k:]], [data.t[:k], data.t[k:]], **kw)
        assert set(split.terms["x2"]) == set(whole.terms["x2"])
        a, b = whole.extended_fit, split.extended_fit
        se = max(a.std_errors[0], b.std_errors[0])
        assert abs(a.physical[0] - b.physical[0]) <= 2 * se
        assert abs(b.physical[0] - 1.0) < 0.05
