"""A held-out miss judged against the uncertainty of the model's estimates.

"Explained" used to ask only that the extended model's run on data it was
not fitted to beat the assumed model's by 1.1x. A look-alike of the effect
passed that while missing the held-out data by more than a correct model
with its standard errors could; a correct model whose coefficients are
known to a few percent misses a long validation record by several times the
noise and is still right. ``protocols/uncertainty.py`` tells them apart.

The development cases (looked at while building it) come first; the
held-out set (marked slow, fixed seeds, run once after the design was
fixed) is reported apart at the end, with the counts it gave.
"""

import warnings

import numpy as np
import pysindy as ps
import pytest
from oscillator_case import oscillator, record, study
from paper_case import VDP, paper_discover

from pysindy_mme import Discovery
from pysindy_mme.core.model import simulate_model
from pysindy_mme.protocols.uncertainty import MISS_LEVEL
from pysindy_mme.systems import van_der_pol


def _van_der_pol(mu=1.0):
    def f(x, t):
        return np.column_stack([x[:, 1], -x[:, 0] + mu * (1 - x[:, 0] ** 2) * x[:, 1]])

    return f


def _validation(f, x0, t_end, seed, noise_sd=0.1, rate=40.0):
    t = np.arange(0, t_end + 1e-9, 1 / rate)
    x = simulate_model(f, np.asarray(x0, float), t, rtol=1e-10, atol=1e-12)
    rng = np.random.default_rng(seed)
    return x[:, :1] + noise_sd * rng.standard_normal((t.size, 1)), t


def _paper_with_long_validation(seed, t_end=300.0, **kwargs):
    """The paper's record (another seed), the true library, and a validation
    record 30 times as long from another state: the run drifts in phase as
    far as its coefficients' errors take it."""
    y_v, t_v = _validation(_van_der_pol(), (0.5, -1.0), t_end, 1000 + seed)
    return _paper_study(seed, (y_v, t_v), **kwargs)


def _paper_study(seed, validation, **kwargs):
    """``discover`` on the paper's record of ``seed`` with the true library."""
    data = VDP.measure(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return paper_discover(
            data.y,
            data.t,
            feature_library=ps.PolynomialLibrary(degree=3),
            validation=validation,
            **kwargs,
        )


def _friction(seed, sharpness=3.0, amplitude=1.5, validation_amplitude=1.7):
    """A spring with a smooth Coulomb friction ``-0.3 tanh(c v)`` that the
    polynomial library can only imitate; the validation record swings a
    little wider than the fitting record."""
    f = oscillator(lambda v: -0.3 * np.tanh(sharpness * v))
    y, t, _ = record(f, (amplitude, 0.0), seed=seed)
    y_v, t_v, _ = record(f, (validation_amplitude, 0.0), seed=100 + seed)
    return study(y, t, validation=(y_v, t_v))


def _uncertainty(res):
    return res.gain.validation_runs["extended"].uncertainty


# -- development cases -----------------------------------------------------------
@pytest.fixture(scope="module")
def right_model():
    return _paper_with_long_validation(0)


def test_a_right_model_that_misses_a_long_record_is_still_explained(right_model):
    res = right_model
    assert sorted(res.terms["x2"]) == ["x1", "x1^2 x2", "x2"]
    out = _uncertainty(res)
    # the run misses by several times the noise (phase drift) ...
    assert out.observed > 3.0
    # ... as far as a correct model with these standard errors is expected to
    assert 0.5 * out.expected < out.observed < out.upper
    assert not out.beyond and out.p_value > 0.05
    assert res.conclusion == "explained"
    assert any("within what the standard errors" in r for r in res.reasons)


def test_the_uncertainty_is_saved_with_the_result(right_model, tmp_path):
    path = tmp_path / "long.npz"
    right_model.save(path)
    loaded = Discovery.load(path)
    out, back = _uncertainty(right_model), _uncertainty(loaded)
    assert back == out  # every field (a result keeps no columns)
    assert back.columns is None and out.columns is None
    assert loaded.conclusion == right_model.conclusion


@pytest.mark.parametrize("seed", [1, 2])
def test_a_look_alike_that_misses_beyond_its_uncertainty_is_partly_explained(seed):
    res = _friction(seed)
    # the polynomial look-alike fits its record and beats the assumed model
    # on the validation record, which the old rule called "explained"
    assert np.all(res.gain.rmse_extended <= 1.5 * res.gain.noise_floor)
    gain = res.gain.validation_rmse_assumed / res.gain.validation_rmse_extended
    assert np.all(gain > 1.1)
    out = _uncertainty(res)
    assert out.beyond and out.p_value < MISS_LEVEL**3
    assert out.observed > 1.5 * out.expected
    assert res.conclusion == "partly explained"
    assert "not for data they were not fitted to" in res.verdict
    assert any("beyond what the standard errors" in r for r in res.reasons)
    assert any("validation record that exercises" in a for a in res.advice)


def test_a_run_its_one_standard_error_draw_makes_diverge_concludes_nothing():
    res = _friction(0, sharpness=2.0, validation_amplitude=1.8)
    out = _uncertainty(res)
    assert not np.isfinite(out.expected) and not out.beyond
    assert res.conclusion == "inconclusive"
    assert any("moved by one standard error diverges" in r for r in res.reasons)


def _paper_with_two_validation_records(t_end, first_seed):
    """The paper's seed-0 record, the true library, and two validation
    records of ``t_end`` seconds from other states."""
    starts = [(0.5, -1.0), (-2.0, 0.0)]
    records = [
        _validation(_van_der_pol(), x0, t_end, first_seed + k)
        for k, x0 in enumerate(starts)
    ]
    return _paper_study(0, records)


def test_several_validation_records_share_the_coefficients_draws():
    res = _paper_with_two_validation_records(300.0, 1000)
    run = res.gain.validation_runs["extended"]
    # every record's draws are run, whatever its own run misses by: the
    # pooled run's miss is what is judged
    per_record = [r.uncertainty for r in run.records]
    assert all(u is not None for u in per_record)
    pooled = run.uncertainty
    assert pooled.observed > 1.5 and pooled.directions == per_record[0].directions
    # the draws are shared, each record's start is its own: the expected
    # squared miss is the records' average, weighted by their scored samples
    scored = [r.x.shape[0] - r.window for r in run.records]
    mean_sq = np.average([u.expected**2 for u in per_record], weights=scored)
    assert pooled.expected**2 == pytest.approx(mean_sq, rel=1e-9)
    assert pooled.expected > 1.0 and not pooled.beyond
    assert pooled.columns is None  # a result keeps the numbers only
    assert res.conclusion == "explained"


def test_records_pooled_at_the_noise_run_no_draws(monkeypatch):
    import pysindy_mme.protocols.runs as runs_module

    calls = []
    original = runs_module.miss_columns

    def counted(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(runs_module, "miss_columns", counted)
    res = _paper_with_two_validation_records(10.0, 500)
    run = res.gain.validation_runs["extended"]
    assert np.sqrt(np.mean((run.rmse / res.gain.noise_floor) ** 2)) <= 1.5
    assert run.uncertainty is None and not calls
    assert all(r.uncertainty is None for r in run.records)


def test_validate_on_a_new_record_judges_the_miss_too(right_model):
    y_v, t_v = _validation(_van_der_pol(), (-1.0, 2.0), 300.0, 77)
    runs = right_model.validate(y_v, t_v)
    out = runs["extended"].uncertainty
    assert out is not None and out.observed > 1.5
    assert not out.beyond and out.directions == 3


# -- the held-out set ------------------------------------------------------------
# Fixed before it was first run; run once, the counts below are what it gave.
# Each case: (a study of one seed, whether its truth is in the library).
SEEDS = range(8)


def _right_van_der_pol(seed):
    system = van_der_pol(0.5)
    data = system.measure(seed)
    y_v, t_v = _validation(_van_der_pol(0.5), (0.5, -1.0), 200.0, 2000 + seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return paper_discover(
            data.y,
            data.t,
            assumed_model=system.assumed_model,
            feature_library=ps.PolynomialLibrary(degree=3),
            validation=(y_v, t_v),
        )


def _oscillator_study(law, amplitude, validation_amplitude, seed, t_v=60.0):
    f = oscillator(law)
    y, t, _ = record(f, (amplitude, 0.0), noise=0.01, seed=seed)
    y_v, t_v, _ = record(
        f, (validation_amplitude, 0.0), t_end=t_v, noise=0.01, seed=300 + seed
    )
    return study(y, t, noise=0.01, validation=(y_v, t_v))


def _right_duffing(seed):
    # a stiffening spring and a light damping, both in the library
    def law_with_spring(x, t):
        return np.column_stack(
            [x[:, 1], -x[:, 0] - 0.5 * x[:, 0] ** 3 - 0.05 * x[:, 1]]
        )

    y, t, _ = record(law_with_spring, (2.0, 0.0), noise=0.01, seed=seed)
    y_v, t_v, _ = record(
        law_with_spring, (1.5, 0.0), t_end=60.0, noise=0.01, seed=400 + seed
    )
    return study(y, t, noise=0.01, validation=(y_v, t_v))


def _right_cubic_damping(seed):
    return _oscillator_study(lambda v: -0.3 * v**3, 1.5, 2.0, seed)


def _quadratic_drag(seed):
    # |v| v: the polynomial library has only look-alikes of it
    return _oscillator_study(lambda v: -0.4 * np.abs(v) * v, 1.5, 1.8, seed)


def _sharp_friction(seed):
    return _oscillator_study(lambda v: -0.3 * np.tanh(4.0 * v), 1.2, 1.4, seed)


# added after the first run (the look-alikes above stayed at the noise on
# their validation records), before their own first run
def _wider_quadratic_drag(seed):
    return _oscillator_study(lambda v: -0.4 * np.abs(v) * v, 1.5, 2.0, seed)


def _softer_friction(seed):
    return _oscillator_study(lambda v: -0.3 * np.tanh(2.0 * v), 1.2, 1.5, seed)


HELD_OUT_SET = {
    "Van der Pol, alpha 0.5, 200 s validation": (_right_van_der_pol, True),
    "Duffing spring, validation at 3/4 amplitude": (_right_duffing, True),
    "cubic damping, validation at 4/3 amplitude": (_right_cubic_damping, True),
    "quadratic drag |v| v, validation at 6/5 amplitude": (_quadratic_drag, False),
    "friction tanh(4 v), validation at 7/6 amplitude": (_sharp_friction, False),
    "quadratic drag |v| v, validation at 4/3 amplitude": (_wider_quadratic_drag, False),
    "friction tanh(2 v), validation at 5/4 amplitude": (_softer_friction, False),
}


def _tally(case):
    run, _ = HELD_OUT_SET[case]
    rows = []
    for seed in SEEDS:
        res = run(seed)
        out = (res.gain.validation_runs or {}).get("extended")
        out = None if out is None else out.uncertainty
        rows.append((seed, res.conclusion, out))
    return rows


@pytest.mark.slow
@pytest.mark.parametrize("case", list(HELD_OUT_SET))
def test_held_out_set(case):
    rows = _tally(case)
    for seed, label, out in rows:
        text = (
            "at the noise"
            if out is None
            else (
                f"{out.observed:.2f}x, expected {out.expected:.2f}x, "
                f"p = {out.p_value:.2g}"
            )
        )
        print(f"{case} | seed {seed} | {label} | {text}")
    for _, label, out in rows:
        # "explained" now stands on a held-out run at the noise or within
        # what its estimates' uncertainty allows
        if label == "explained" and out is not None:
            assert np.isfinite(out.expected) and not out.beyond
    beyond = sum(out is not None and out.beyond for _, _, out in rows)
    if HELD_OUT_SET[case][1]:
        # a right model is called "partly explained" by this test at most
        # once in eight (its level is 1e-3)
        assert beyond <= 1
    labels = {}
    for _, label, _ in rows:
        labels[label] = labels.get(label, 0) + 1
    assert labels == HELD_OUT_LABELS[case]


#: the conclusions the held-out set gave on its one run (session 30). The
#: right models: no run beyond its uncertainty (6 of 24 runs measured, p =
#: 0.017-0.69). The look-alikes: their runs on validation records 6/5 to
#: 4/3 of the fitting amplitude were at the noise in 29 of 32 studies (the
#: data do not show the look-alike there); the other 3 missed by 1.5-1.8x
#: the noise with a one-standard-error draw that diverges: "inconclusive"
HELD_OUT_LABELS = {
    "Van der Pol, alpha 0.5, 200 s validation": {"explained": 8},
    "Duffing spring, validation at 3/4 amplitude": {"explained": 8},
    "cubic damping, validation at 4/3 amplitude": {"explained": 8},
    "quadratic drag |v| v, validation at 6/5 amplitude": {"explained": 8},
    "friction tanh(4 v), validation at 7/6 amplitude": {
        "explained": 4,
        "inconclusive": 2,
        "not explained": 2,
    },
    "quadratic drag |v| v, validation at 4/3 amplitude": {"explained": 8},
    "friction tanh(2 v), validation at 5/4 amplitude": {
        "explained": 7,
        "inconclusive": 1,
    },
}
