"""discover: one table of bad inputs (issue 4: short record; issue 5: the
validation layer), each with its exception type and a phrase of its message.

Every case runs with MME's solver, the stepwise regression and the
output-error fit replaced by tripwires (checks come before any long
computation), on read-only measurements.
"""

from __future__ import annotations

import numpy as np
import pysindy as ps
import pytest
from bad_input_support import (
    Bad,
    assert_raises_as_documented,
    params,
    readonly,
    with_value,
)
from paper_case import DATA as _DATA
from paper_case import T, Y
from paper_case import paper_discover as _discover
from paper_case import three_states as _three_states

from pysindy_mme import MME, PowerLibrary, StudyOptions

ENTRY_POINT = "discover"


BAD_INPUTS = [
    # ---- the record
    Bad(
        "discover: record shorter than the library",
        lambda tmp: _discover(
            y=Y[:8], t=T[:8], feature_library=ps.PolynomialLibrary(degree=3)
        ),
        ValueError,
        r"the feature library has 10 terms: at least 12 samples",
    ),
    Bad(
        "discover: record shorter than the power library",
        lambda tmp: _discover(y=Y[:100], t=T[:100], feature_library=PowerLibrary()),
        ValueError,
        r"has 144 terms: at least 146 samples are needed",
    ),
    Bad(
        "discover: t of the wrong length",
        lambda tmp: _discover(t=T[:5]),
        ValueError,
        r"t has 5 entries but the data have 401 samples",
    ),
    Bad(
        "discover: t not increasing",
        lambda tmp: _discover(t=T[::-1]),
        ValueError,
        r"t must be strictly increasing",
    ),
    Bad(
        "discover: y columns do not match measured",
        lambda tmp: _discover(y=readonly(np.column_stack([Y, Y]))),
        ValueError,
        r"y has 2 columns but measured names 1 states",
    ),
    Bad(
        "discover: no finite measurement",
        lambda tmp: _discover(y=readonly(np.full(Y.shape, np.nan))),
        ValueError,
        r"y contains no finite measurement",
    ),
    Bad(
        "discover: y has inf",
        lambda tmp: _discover(y=with_value(Y, (3, 0), -np.inf)),
        ValueError,
        r"y contains inf",
    ),
    # ---- the problem (states, noise, model)
    Bad(
        "discover: measured out of range",
        lambda tmp: _discover(measured=[3]),
        ValueError,
        r"measured = \[3\] is out of range",
    ),
    Bad(
        "discover: noise variance negative",
        lambda tmp: _discover(noise_variance=-1.0),
        ValueError,
        r"noise_variance must be finite and > 0",
    ),
    Bad(
        "discover: noise variance unknown word",
        lambda tmp: _discover(noise_variance="x"),
        ValueError,
        r"noise_variance must be a number, an array or 'auto'",
    ),
    Bad(
        "discover: error_states out of range",
        lambda tmp: _discover(error_states=[2]),
        ValueError,
        r"error_states = \[2\] is out of range",
    ),
    Bad(
        "discover: error state that no measurement sees",
        lambda tmp: _discover(
            assumed_model=_three_states,
            n_states=3,
            error_states=[2],
            options=StudyOptions(feature_names=["a", "b", "c"]),
        ),
        ValueError,
        r"error_states \[2\] cannot be seen",
    ),
    Bad(
        "discover: n_states zero",
        lambda tmp: _discover(n_states=0),
        ValueError,
        r"n_states",
    ),
    Bad(
        "discover: n_states not an integer",
        lambda tmp: _discover(n_states=2.0),
        TypeError,
        r"n_states must be an integer >= 1",
    ),
    Bad(
        "discover: unknown error model",
        lambda tmp: _discover(mme=MME(error_model=None)),
        ValueError,
        r"error_model must be an ErrorModel object or a registered name "
        r"\('white'.*'random_walk'.*\); got None",
    ),
    Bad(
        "discover: model returns the wrong shape",
        lambda tmp: _discover(assumed_model=lambda x, t: x[:, :1]),
        ValueError,
        r"assumed_model returned an array of shape",
    ),
    Bad(
        "discover: model returns NaN",
        lambda tmp: _discover(assumed_model=lambda x, t: x * np.nan),
        ValueError,
        r"assumed_model returned non-finite values",
    ),
    # ---- the study's own options
    Bad(
        "discover: alpha outside (0, 1)",
        lambda tmp: _discover(options=StudyOptions(alpha=1.5)),
        ValueError,
        r"alpha must lie strictly between 0 and 1",
    ),
    Bad(
        "discover: feature_names count",
        lambda tmp: _discover(options=StudyOptions(feature_names=["a"])),
        ValueError,
        r"feature_names has 1 names but there are 2 states",
    ),
    Bad(
        "discover: feature_names repeat",
        lambda tmp: _discover(options=StudyOptions(feature_names=["a", "a"])),
        ValueError,
        r"feature_names repeats a name",
    ),
    Bad(
        "discover: feature_library not a library",
        lambda tmp: _discover(feature_library="poly"),
        TypeError,
        r"feature_library must be a pysindy feature library",
    ),
    Bad(
        "discover: optimizer not an optimizer",
        lambda tmp: _discover(optimizer="stlsq"),
        TypeError,
        r"optimizer must be a pysindy optimizer",
    ),
    Bad(
        "discover: validation not a tuple",
        lambda tmp: _discover(validation=(np.zeros(3),)),
        TypeError,
        r"validation must be a tuple \(y, t\)",
    ),
    Bad(
        "discover: validation columns",
        lambda tmp: _discover(validation=(np.zeros((50, 2)), np.arange(50.0))),
        ValueError,
        r"validation y has 2 columns but 1 channels are measured",
    ),
    Bad(
        "discover: validation t not increasing",
        lambda tmp: _discover(validation=(np.zeros((50, 1)), np.arange(50.0)[::-1])),
        ValueError,
        r"validation t must be strictly increasing",
    ),
    Bad(
        "discover: u of the wrong length",
        lambda tmp: _discover(u=np.zeros((5, 1))),
        ValueError,
        r"u has 5 rows but y has 401 samples",
    ),
    Bad(
        "discover: assumed_equations count",
        lambda tmp: _discover(options=StudyOptions(assumed_equations=["x2"])),
        ValueError,
        r"assumed_equations has 1 entries, expected 2",
    ),
    Bad(
        "discover: refit not a bool",
        lambda tmp: _discover(options=StudyOptions(refit="no")),
        TypeError,
        r"refit must be True or False",
    ),
]


@pytest.mark.parametrize("case", params(BAD_INPUTS))
def test_bad_input(case, tmp_path, no_long_computation):
    assert_raises_as_documented(case, tmp_path)
    np.testing.assert_array_equal(Y, _DATA.y)  # the record is untouched
    np.testing.assert_array_equal(T, _DATA.t)
