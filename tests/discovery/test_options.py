"""discover's grouped signature (issue 22): options, estimator settings and
protocols as objects; the keywords of earlier versions say where they went."""

from __future__ import annotations

import inspect

import numpy as np
import pytest
from paper_case import DATA, VDP, T, Y
from paper_case import paper_discover as _discover

import pysindy_mme
from pysindy_mme import MME, StudyOptions, discover
from pysindy_mme.discovery.options import MOVED, grouped_keywords
from pysindy_mme.protocols import HeldOut, LeadingWindow


def _public_functions():
    import pysindy_mme.protocols as protocols

    for module in (pysindy_mme, protocols):
        for name in module.__all__:
            obj = getattr(module, name)
            if inspect.isfunction(obj):
                yield name, obj
            elif inspect.isclass(obj):
                yield name, obj.__init__
                for meth, fn in vars(obj).items():
                    if inspect.isfunction(fn) and not meth.startswith("_"):
                        yield f"{name}.{meth}", fn


#: public callables allowed more than 12 parameters, and why (issue 22)
OVER_TWELVE = {
    # y, t, the six names of the design's contract (model and measurements),
    # library, optimizer, u, validation, mme, options; and the catch that
    # names where an earlier version's keyword went
    "discover": 14,
    # scikit-learn estimators keep every setting a flat __init__ parameter
    # (get_params / set_params / clone need them so)
    "MME": 17,
    "FloatingFStepwise": 19,
    # results records (dataclasses) the study builds, not users
    "Discovery": 20,
    "NoiseDiagnostics": 14,
}


def test_no_public_function_takes_more_than_twelve_parameters():
    too_many = {}
    for name, fn in _public_functions():
        n = len(inspect.signature(fn).parameters) - (
            1 if "self" in inspect.signature(fn).parameters else 0
        )
        if n > 12 and n > OVER_TWELVE.get(name, 12):
            too_many[name] = n
    assert not too_many, too_many


def test_discover_takes_the_contract_and_four_objects():
    names = list(inspect.signature(discover).parameters)
    assert names == [
        "y",
        "t",
        "assumed_model",
        "n_states",
        "measured",
        "noise_variance",
        "error_states",
        "feature_library",
        "optimizer",
        "u",
        "validation",
        "mme",
        "options",
        "removed",
    ]


@pytest.mark.parametrize(
    "keyword, value, where",
    [
        ("alpha", 0.01, r"alpha -> options=StudyOptions\(alpha=\.\.\.\)"),
        ("feature_names", ["a", "b"], r"options=StudyOptions\(feature_names"),
        ("W", 5.0, r"W -> mme=MME\(W=\.\.\.\)"),
        ("input_hold", "zoh", r"mme=MME\(input_hold"),
        ("validation_window", 30, r"validation=LeadingWindow\(record, window"),
    ],
)
def test_a_moved_keyword_says_where_it_went(keyword, value, where):
    with pytest.raises(TypeError, match=where):
        discover(Y, T, assumed_model=VDP, n_states=2, **{keyword: value})


def test_an_unknown_keyword_is_called_unexpected():
    with pytest.raises(TypeError, match=r"unexpected keyword argument\(s\) \['alfa'\]"):
        discover(Y, T, assumed_model=VDP, n_states=2, alfa=0.01)


def test_every_moved_keyword_has_a_home():
    options = {f for f in StudyOptions.__dataclass_fields__}
    mme = set(inspect.signature(MME).parameters)
    for name, where in MOVED.items():
        if where.startswith("options="):
            assert name in options
        elif where.startswith("mme="):
            assert name in mme
        else:
            assert name == "validation_window"


def test_estimator_settings_fill_in_from_discover():
    """mme=MME(W=...) carries the settings; the model and measurements come
    from discover's keywords (no need to repeat them)."""
    res = _discover(mme=MME(W=20.0))
    assert float(res.mme.W_) == 20.0
    assert res.mme.assumed_model is not None and res.mme.n_states == 2
    np.testing.assert_allclose(res.mme.noise_variance, np.eye(1) * 0.01)


def test_a_setting_given_twice_is_refused():
    with pytest.raises(ValueError, match="give n_states either to MME"):
        discover(
            Y,
            T,
            assumed_model=VDP,
            n_states=2,
            noise_variance=0.01,
            mme=MME(n_states=3),
        )


def test_options_as_a_dict_and_bad_options():
    res = _discover(options={"alpha": 0.01, "feature_names": ["p", "q"]})
    assert res.study.alpha == 0.01 and res.state_names == ["p", "q"]
    with pytest.raises(TypeError, match=r"options: unknown option\(s\) \['alfa'\]"):
        _discover(options={"alfa": 0.01})
    with pytest.raises(TypeError, match="options must be a StudyOptions"):
        _discover(options=0.01)
    with pytest.raises(TypeError, match="StudyOptions has no option"):
        StudyOptions().replace(alfa=1)


def test_grouped_keywords_puts_flat_settings_where_they_go():
    kw = grouped_keywords(
        {
            "n_states": 2,
            "alpha": 0.01,
            "W": 3.0,
            "input_hold": "zoh",
            "validation": (DATA.y, DATA.t),
            "validation_window": 30,
        }
    )
    assert kw["n_states"] == 2
    assert kw["options"] == StudyOptions(alpha=0.01)
    assert (kw["mme"].W, kw["mme"].input_hold) == (3.0, "zoh")
    assert isinstance(kw["validation"], LeadingWindow) and kw["validation"].window == 30
    assert isinstance(
        grouped_keywords({"validation_window": 20})["validation"], HeldOut
    )
    # an explicit object's settings win over flat defaults; flat ones fill in
    merged = grouped_keywords(
        {
            "feature_names": ["a", "b"],
            "alpha": 0.05,
            "options": StudyOptions(alpha=0.01),
            "W": 2.0,
            "mme": MME(error_model="ou", W=7.0),
        }
    )
    assert merged["options"] == StudyOptions(feature_names=["a", "b"], alpha=0.01)
    assert (merged["mme"].W, merged["mme"].error_model) == (7.0, "ou")
    with pytest.raises(ValueError, match="give the window to the protocol"):
        grouped_keywords({"validation": HeldOut(), "validation_window": 20})
