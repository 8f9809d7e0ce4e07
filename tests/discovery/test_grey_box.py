"""Issue 10.2: assumed models with unknown parameters (grey box).

A Duffing oscillator modelled as linear, with its mass-normalised stiffness
and damping 30 % off: the study must fit them (within 2 %), name the cubic
spring (within 5 %) as the missing effect, and never report a library term
that merely re-does a parameter (``x1`` in ``x2'``) as a discovery.
"""

import warnings

import numpy as np
import pysindy as ps
import pytest

from pysindy_mme import StudyOptions, discover
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.systems import duffing

NOISE = 1e-3  # sd 0.03 on an amplitude of 1.5


def linear_oscillator(x, t, u, p):
    """The modeller's linear model, its parameters unknown: x2' = -k x1 - c x2."""
    return np.column_stack([x[:, 1], -p["k"] * x[:, 0] - p["c"] * x[:, 1]])


def _study(data, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return discover(
            data.y,
            data.t,
            assumed_model=linear_oscillator,
            n_states=2,
            measured=[0],
            noise_variance=NOISE,
            error_states=[1],
            feature_library=ps.PolynomialLibrary(degree=3),
            **grouped_keywords(
                {
                    "parameters": {"k": 0.7, "c": 0.13},
                    "feature_names": ["x1", "x2"],
                    **kwargs,
                }
            ),
        )


def test_parameters_and_the_missing_effect_come_apart():
    data = duffing().measure(0, noise_variance=NOISE)
    res = _study(data)
    k, c = res.parameters["k"], res.parameters["c"]
    assert k.value == pytest.approx(1.0, rel=0.02)
    assert c.value == pytest.approx(0.1, rel=0.02)
    assert k.ci_low < 1.0 < k.ci_high
    # step 1 alone (no correction) bends k to mimic the cubic spring
    assert k.assumed_fit > 1.5
    assert set(res.terms["x2"]) == {"x1^3"}
    assert res.terms["x2"]["x1^3"] == pytest.approx(-1.0, rel=0.05)
    text = str(res)
    assert "Parameters of the assumed model" in text and "missing effects" in text
    # x1 in x2' would only re-estimate k: set aside with that reason
    assert any(
        "duplicates the assumed model's parameter k" in r for r in res.pruned_terms
    )
    assert set(res.to_dict()["parameters"]) == {"k", "c"}


@pytest.mark.slow
def test_grey_box_duffing_ten_seeds():
    hits = 0
    for seed in range(10):
        res = _study(duffing().measure(seed, noise_variance=NOISE))
        p = res.parameters
        hits += bool(
            abs(p["k"].value - 1.0) <= 0.02
            and abs(p["c"].value - 0.1) <= 0.002
            and set(res.terms["x2"]) == {"x1^3"}
            and abs(res.terms["x2"]["x1^3"] + 1.0) <= 0.05
        )
    print(f"\nGrey-box Duffing: parameters within 2 %, cubic within 5 %: {hits}/10")
    assert hits >= 9


def test_bad_parameters_are_rejected_up_front():
    data = duffing().measure(0, noise_variance=NOISE)
    with pytest.raises(TypeError, match="parameters must be a non-empty dict"):
        discover(
            data.y,
            data.t,
            assumed_model=linear_oscillator,
            n_states=2,
            measured=[0],
            noise_variance=NOISE,
            options=StudyOptions(parameters=[1.0]),
        )
    with pytest.raises(ValueError, match="parameters: k must be finite"):
        discover(
            data.y,
            data.t,
            assumed_model=linear_oscillator,
            n_states=2,
            measured=[0],
            noise_variance=NOISE,
            options=StudyOptions(parameters={"k": np.nan, "c": 0.1}),
        )


def test_grey_box_with_an_explicit_mme_configuration():
    # issue 23: parameters= together with mme=MME(...) (its own n_substeps):
    # the same answer as the keyword route, and the substeps reach the fits
    from pysindy_mme import MME

    data = duffing().measure(0, noise_variance=NOISE)
    mme = MME(
        assumed_model=linear_oscillator,
        n_states=2,
        measured=[0],
        noise_variance=NOISE,
        error_states=[1],
        n_substeps=3,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = discover(
            data.y,
            data.t,
            mme=mme,
            feature_library=ps.PolynomialLibrary(degree=3),
            options=StudyOptions(
                parameters={"k": 0.7, "c": 0.13}, feature_names=["x1", "x2"]
            ),
        )
    keywords = _study(data)
    assert res.substeps >= 3
    assert set(res.terms["x2"]) == {"x1^3"} == set(keywords.terms["x2"])
    for name in ("k", "c"):
        got, ref = res.parameters[name], keywords.parameters[name]
        assert abs(got.value - ref.value) <= 2 * ref.std_error
    # the user's estimator is not modified
    assert mme.assumed_model is linear_oscillator


def test_grey_box_mme_model_must_take_parameters():
    from pysindy_mme import MME

    data = duffing().measure(0, noise_variance=NOISE)
    fitted = ps.SINDy().fit(np.column_stack([data.y[:, 0], data.y[:, 0]]), t=data.t)
    mme = MME(assumed_model=fitted, n_states=2, measured=[0], noise_variance=NOISE)
    with pytest.raises(TypeError, match="f\\(x, t, u, p\\)"):
        discover(data.y, data.t, mme=mme, options=StudyOptions(parameters={"k": 0.7}))
