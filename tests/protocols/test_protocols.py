"""Validation protocols as objects (issue 22): one interface, three protocols.

Checked against references that share no code with the package: the
k-step-ahead RMSE against an independent moving-horizon protocol (scipy's
``least_squares`` over ``solve_ivp`` runs); ``KStepAhead`` with one start
and ``k`` to the end of the record against the free run it then is; a
protocol written here, outside the package, run by ``discover`` with no
edit of the study.
"""

from __future__ import annotations

import warnings

import numpy as np
import pysindy as ps
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

from pysindy_mme import Discovery, discover
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.protocols import (
    HeldOut,
    KStepAhead,
    LeadingWindow,
    ValidationProtocol,
)
from pysindy_mme.protocols.runs import window_runs
from pysindy_mme.systems import van_der_pol

SYSTEM = van_der_pol()
DATA = SYSTEM.measure(1)
VAL = SYSTEM.measure(2, x0=(2.0, -1.0))


def _discover(**options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return discover(
            DATA.y,
            DATA.t,
            assumed_model=SYSTEM.assumed_model,
            n_states=2,
            measured=list(SYSTEM.measured),
            noise_variance=SYSTEM.noise_variance,
            error_states=list(SYSTEM.error_states),
            feature_library=ps.PolynomialLibrary(degree=3),
            **grouped_keywords({"feature_names": SYSTEM.feature_names, **options}),
        )


@pytest.fixture(scope="module")
def study():
    return _discover(validation=(VAL.y, VAL.t))


def _solve(model, x0, t):
    sol = solve_ivp(
        lambda s, x: model(x[None, :], np.array([s]), None)[0],
        (t[0], t[-1]),
        x0,
        t_eval=t,
        rtol=1e-10,
        atol=1e-12,
    )
    out = np.full((t.size, len(x0)), np.nan)
    out[: sol.y.shape[1]] = sol.y.T
    return out


def independent_k_step(model, y, t, k, window, starts, guesses):
    """RMSE of k-step-ahead predictions, each from a state fitted by single
    shooting to the ``window`` samples before its start."""
    errors = []
    for p, guess in zip(starts, guesses):
        a, b = p - window, min(p + k, t.size)

        def residual(x0, a=a, p=p):
            r = _solve(model, x0, t[a:p])[:, 0] - y[a:p, 0]
            return np.where(np.isfinite(r), r, 1e3)

        x0 = least_squares(residual, guess, xtol=1e-12, ftol=1e-12).x
        errors.append(_solve(model, x0, t[a:b])[window:, 0] - y[p:b, 0])
    e = np.concatenate(errors)
    return float(np.sqrt(np.mean(e**2)))


def test_k_step_ahead_equals_an_independent_moving_horizon_protocol(study):
    protocol = KStepAhead(8, window=20, max_starts=12)
    runs = study.validate(VAL.y, VAL.t, protocol=protocol)
    ext = runs["extended"]
    assert len(ext.starts) == 12
    model = study.extended_model

    def rows(x, t, u):
        return model.predict(x, t=t)

    guesses = [ext.x[p] for p in ext.starts]  # near the answer: speeds it up
    mine = independent_k_step(rows, VAL.y, VAL.t, 8, 20, ext.starts, guesses)
    np.testing.assert_allclose(ext.rmse[0], mine, rtol=0.02)


def test_k_step_with_one_start_to_the_end_is_the_free_run(study):
    n = VAL.t.size
    window = 30
    k_step = study.validate(
        VAL.y, VAL.t, protocol=KStepAhead(n, window=window, max_starts=1)
    )
    free = study.validate(VAL.y, VAL.t, protocol=LeadingWindow(window=window))
    for name in ("assumed", "extended"):
        assert k_step[name].starts == [window]
        np.testing.assert_allclose(k_step[name].rmse, free[name].rmse, rtol=1e-9)
        np.testing.assert_allclose(
            k_step[name].x[window:], free[name].x[window:], rtol=1e-9, atol=1e-12
        )


def test_short_predictions_miss_less_than_a_free_run(study):
    """The assumed model's error grows with the horizon (its slow mode is
    wrong): 2 steps ahead miss less than 20, which miss less than a free run."""
    errors = [
        study.validate(VAL.y, VAL.t, protocol=KStepAhead(k, window=20))["assumed"].rmse[
            0
        ]
        for k in (2, 20)
    ]
    free = study.gain.validation_rmse_assumed[0]
    assert errors[0] < errors[1] < free


def test_a_protocol_object_gives_the_numbers_of_the_record_and_window(study):
    again = _discover(validation=LeadingWindow((VAL.y, VAL.t), window=50))
    np.testing.assert_array_equal(
        again.gain.validation_rmse_extended, study.gain.validation_rmse_extended
    )
    assert study.gain.validation_method == again.gain.validation_method
    assert "then a free run" in study.gain.validation_method


def test_k_step_in_the_study_report_plot_and_file(tmp_path):
    res = _discover(validation=KStepAhead(10, (VAL.y, VAL.t)))
    g = res.gain
    assert g.validation_method.startswith("10-step-ahead predictions")
    assert "10-step-ahead predictions" in str(res)
    runs = g.validation_runs["extended"]
    assert runs.starts[0] == 20 and np.diff(runs.starts).min() == 10
    # the same numbers as validating the finished study by the protocol
    again = res.validate(VAL.y, VAL.t, protocol=KStepAhead(10))
    np.testing.assert_allclose(again["extended"].rmse, g.validation_rmse_extended)
    res.save(tmp_path / "k_step")
    loaded = Discovery.load(tmp_path / "k_step")
    assert loaded.gain.validation_method == g.validation_method
    assert str(loaded.summary()) == str(res.summary())
    assert str(loaded) == str(res)
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    fig = res.plot()
    labels = [ax.get_xlabel() for ax in fig.axes]
    assert any("10-step-ahead" in text for text in labels)


def test_without_a_record_the_protocol_runs_on_a_held_out_stretch():
    res = _discover(validation=KStepAhead(5))
    g = res.gain
    assert g.validation_source.startswith("a held-out stretch")
    assert g.validation_method.startswith("5-step-ahead predictions")
    res_default = _discover()
    assert res_default.gain.validation_source == g.validation_source
    assert "then a free run" in res_default.gain.validation_method
    # HeldOut with a larger share holds out more samples
    wider = _discover(validation=HeldOut(fraction=0.3))
    assert "the last 120 samples" in wider.gain.validation_source
    assert "the last 80 samples" in g.validation_source


class LastHalf(ValidationProtocol):
    """A protocol written outside the package: the free run scored on the
    record's second half only."""

    label = "second half"

    def score(self, study, models, features, substeps, record, window):
        y, t, u = record
        half = y.shape[0] // 2
        return window_runs(
            study, models, features, substeps, (y[half:], t[half:], u), window
        )

    def describe_method(self, window):
        return f"a free run over the second half, from its first {window} samples."


def test_a_protocol_written_outside_the_package_runs_in_the_study(study):
    # without records it runs on a held-out stretch, as a HeldOut's method
    res = _discover(validation=LastHalf())
    assert "second half" in res.gain.validation_method
    res = _discover(validation=LastHalf((VAL.y, VAL.t), window=50))
    half = VAL.t.size // 2
    direct = study.validate(VAL.y[half:], VAL.t[half:])
    np.testing.assert_allclose(
        res.gain.validation_rmse_extended, direct["extended"].rmse, rtol=1e-9
    )
    assert res.gain.validation_method.startswith("a free run over the second half")


@pytest.mark.parametrize(
    "validation, message",
    [
        (KStepAhead(0), "k must be an integer >= 1"),
        (KStepAhead(3, max_starts=0), "max_starts must be an integer >= 1"),
        (KStepAhead(3, window=1), "window must be an integer >= 2"),
        (HeldOut(fraction=0.7), r"fraction must be a number in \(0, 0.5\)"),
        (HeldOut(method="free"), "method must be a record protocol"),
        (LeadingWindow(window=2.5), "window must be an integer >= 2"),
    ],
    ids=["k", "max_starts", "window", "fraction", "method", "float window"],
)
def test_bad_protocols_are_named_before_any_fit(validation, message, monkeypatch):
    import pysindy_mme.discovery.study as study_module

    def tripwire(*args, **kwargs):
        raise AssertionError("a fit ran before the protocol was checked")

    monkeypatch.setattr(study_module, "fit_assumed_model", tripwire)
    with pytest.raises((ValueError, TypeError), match=message):
        _discover(validation=validation)


def test_the_old_window_keyword_says_where_it_went():
    with pytest.raises(TypeError, match=r"validation_window -> validation="):
        discover(DATA.y, DATA.t, validation=(VAL.y, VAL.t), validation_window=30)


def test_validate_rejects_what_is_not_a_protocol(study):
    with pytest.raises(TypeError, match="protocol must be a validation protocol"):
        study.validate(VAL.y, VAL.t, protocol="k-step")
