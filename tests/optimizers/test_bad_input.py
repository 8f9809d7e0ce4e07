"""FloatingFStepwise.fit: the bad-input table of the stepwise regression.

Bad parameters (values and types), bad data (library, target, weights) and
names that do not fit the library: each must raise its documented exception
with a message that names the culprit.

Every case runs with the tripwires of ``bad_input_support.py`` in place
(checks come before any screening of the library) on read-only arrays.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse
from bad_input_support import (
    Bad,
    assert_raises_as_documented,
    params,
    readonly,
    with_value,
)

from pysindy_mme import FloatingFStepwise

ENTRY_POINT = "FloatingFStepwise"

_RNG = np.random.default_rng(5)
X_LIB = readonly(_RNG.standard_normal((20, 3)))
Y_LIB = readonly(X_LIB @ [1.0, -2.0, 0.0] + 0.1 * _RNG.standard_normal(20))


def _stepwise(x=X_LIB, y=Y_LIB, sample_weight=None, feature_names=None, **params):
    try:
        opt = FloatingFStepwise(**params)
    except Exception as exc:  # fit() checks the parameters; __init__ only stores
        raise AssertionError("FloatingFStepwise() raised") from exc
    return opt.fit(x, y, sample_weight=sample_weight, feature_names=feature_names)


BAD_INPUTS = [
    # parameters: values (fit checks them; __init__ only stores)
    Bad(
        "stepwise: f_enter zero",
        lambda tmp: _stepwise(f_enter=0),
        ValueError,
        r"f_enter must be None or a finite number > 0",
    ),
    Bad(
        "stepwise: f_enter negative",
        lambda tmp: _stepwise(f_enter=-4),
        ValueError,
        r"f_enter must be None or a finite number > 0",
    ),
    Bad(
        "stepwise: f_enter NaN",
        lambda tmp: _stepwise(f_enter=np.nan),
        ValueError,
        r"f_enter must be None or a finite number",
    ),
    Bad(
        "stepwise: f_enter inf",
        lambda tmp: _stepwise(f_enter=np.inf),
        ValueError,
        r"f_enter must be None or a finite number",
    ),
    Bad(
        "stepwise: f_remove zero",
        lambda tmp: _stepwise(f_remove=0),
        ValueError,
        r"f_remove must be None or a finite number > 0",
    ),
    Bad(
        "stepwise: f_remove above f_enter",
        lambda tmp: _stepwise(f_enter=4, f_remove=5),
        ValueError,
        r"f_remove \(5.0\) must not exceed f_enter",
    ),
    Bad(
        "stepwise: float_ratio below 1",
        lambda tmp: _stepwise(float_ratio=0.5),
        ValueError,
        r"float_ratio must be a finite number >= 1",
    ),
    Bad(
        "stepwise: alpha_enter zero",
        lambda tmp: _stepwise(alpha_enter=0.0),
        ValueError,
        r"alpha_enter must be None or a finite number strictly between 0 and 1",
    ),
    Bad(
        "stepwise: alpha_enter one",
        lambda tmp: _stepwise(alpha_enter=1.0),
        ValueError,
        r"alpha_enter must be None or a finite number strictly between 0 and 1",
    ),
    Bad(
        "stepwise: alpha_remove below alpha_enter",
        lambda tmp: _stepwise(alpha_enter=0.1, alpha_remove=0.05),
        ValueError,
        r"alpha_remove .* must be >= alpha_enter",
    ),
    Bad(
        "stepwise: alpha_remove without alpha_enter",
        lambda tmp: _stepwise(alpha_remove=0.1),
        ValueError,
        r"alpha_remove requires alpha_enter",
    ),
    Bad(
        "stepwise: alpha_remove above 1",
        lambda tmp: _stepwise(alpha_enter=0.05, alpha_remove=1.5),
        ValueError,
        r"alpha_remove must be None or a finite number strictly",
    ),
    Bad(
        "stepwise: max_iter zero",
        lambda tmp: _stepwise(max_iter=0),
        ValueError,
        r"max_iter must be an integer >= 1",
    ),
    Bad(
        "stepwise: max_report negative",
        lambda tmp: _stepwise(max_report=-1),
        ValueError,
        r"max_report must be an integer >= 0",
    ),
    Bad(
        "stepwise: tolerance zero",
        lambda tmp: _stepwise(tolerance=0.0),
        ValueError,
        r"tolerance must be a finite number strictly between 0 and 1",
    ),
    Bad(
        "stepwise: tolerance above 1",
        lambda tmp: _stepwise(tolerance=2.0),
        ValueError,
        r"tolerance must be a finite number strictly between 0 and 1",
    ),
    # parameters: types (a ValueError, pysindy's convention, that is also a
    # TypeError)
    Bad(
        "stepwise: max_iter not an integer",
        lambda tmp: _stepwise(max_iter=2.5),
        ValueError,
        r"max_iter must be an integer",
    ),
    Bad(
        "stepwise: max_iter not an integer (as TypeError)",
        lambda tmp: _stepwise(max_iter=2.5),
        TypeError,
        r"max_iter must be an integer",
    ),
    Bad(
        "stepwise: floating not a bool",
        lambda tmp: _stepwise(floating="yes"),
        ValueError,
        r"floating must be True or False",
    ),
    Bad(
        "stepwise: floating the string 'None'",
        lambda tmp: _stepwise(floating="None"),
        ValueError,
        r"floating must be True or False",
    ),
    Bad(
        "stepwise: f_enter a string",
        lambda tmp: _stepwise(f_enter="10"),
        ValueError,
        r"f_enter must be None or a finite number",
    ),
    Bad(
        "stepwise: drop_insignificant_constant not a bool",
        lambda tmp: _stepwise(drop_insignificant_constant="no"),
        ValueError,
        r"drop_insignificant_constant must be True or False",
    ),
    Bad(
        "stepwise: fit_intercept not a bool",
        lambda tmp: _stepwise(fit_intercept=None),
        ValueError,
        r"fit_intercept must be True or False",
    ),
    Bad(
        "stepwise: time_ordered not a bool",
        lambda tmp: _stepwise(time_ordered="sometimes"),
        ValueError,
        r"time_ordered must be True or False or 'auto'",
    ),
    Bad(
        "stepwise: autocorrelation unknown",
        lambda tmp: _stepwise(autocorrelation="bogus"),
        ValueError,
        r"autocorrelation must be 'newey-west' or None",
    ),
    # data: the library
    Bad(
        "stepwise: empty library",
        lambda tmp: _stepwise(x=X_LIB[:, :0]),
        ValueError,
        r"x has no columns",
    ),
    Bad(
        "stepwise: x not numeric",
        lambda tmp: _stepwise(x=[["a"]] * 20),
        ValueError,
        r"x must be a numeric array",
    ),
    Bad(
        "stepwise: x complex",
        lambda tmp: _stepwise(x=X_LIB + 1j),
        ValueError,
        r"Complex data not supported: x has complex values",
    ),
    Bad(
        "stepwise: x sparse",
        lambda tmp: _stepwise(x=scipy.sparse.csr_matrix(X_LIB)),
        ValueError,
        r"x is a sparse matrix: sparse input is not supported",
    ),
    Bad(
        "stepwise: x one-dimensional",
        lambda tmp: _stepwise(x=X_LIB[:, 0]),
        ValueError,
        r"x must be 2-D",
    ),
    Bad(
        "stepwise: one observation",
        lambda tmp: _stepwise(x=X_LIB[:1], y=Y_LIB[:1]),
        ValueError,
        r"need at least 2 observations",
    ),
    # data: the target
    Bad(
        "stepwise: NaN in one of two targets",
        lambda tmp: _stepwise(y=np.column_stack([Y_LIB, with_value(Y_LIB, 3, np.nan)])),
        ValueError,
        r"y \(the target\) contains NaN \(first at row 3, column 1",
    ),
    Bad(
        "stepwise: y complex",
        lambda tmp: _stepwise(y=Y_LIB * (1 + 1j)),
        ValueError,
        r"Complex data not supported: y has complex values",
    ),
    Bad(
        "stepwise: y None",
        lambda tmp: _stepwise(y=None),
        ValueError,
        r"requires y to be passed, but the target y is None",
    ),
    Bad(
        "stepwise: inf in the target",
        lambda tmp: _stepwise(y=with_value(Y_LIB, 0, np.inf)),
        ValueError,
        r"y \(the target\) contains inf",
    ),
    Bad(
        "stepwise: target one row short",
        lambda tmp: _stepwise(y=Y_LIB[:-1]),
        ValueError,
        r"y has 19 rows but x has 20",
    ),
    # data: the weights
    Bad(
        "stepwise: sample_weight one entry short",
        lambda tmp: _stepwise(sample_weight=readonly(np.ones(19))),
        ValueError,
        r"sample_weight must have one entry per sample",
    ),
    Bad(
        "stepwise: sample_weight negative",
        lambda tmp: _stepwise(sample_weight=with_value(np.ones(20), 4, -1.0)),
        ValueError,
        r"sample_weight must be non-negative",
    ),
    Bad(
        "stepwise: NaN in sample_weight",
        lambda tmp: _stepwise(sample_weight=with_value(np.ones(20), 4, np.nan)),
        ValueError,
        r"sample_weight contains NaN",
    ),
    Bad(
        "stepwise: sample_weight all zero",
        lambda tmp: _stepwise(sample_weight=readonly(np.zeros(20))),
        ValueError,
        r"sample_weight is zero for every sample",
    ),
    Bad(
        "stepwise: one observation's weight",
        lambda tmp: _stepwise(sample_weight=with_value(np.zeros(20), 4, 1.0)),
        ValueError,
        r"need at least 2 observations",
    ),
    # names
    Bad(
        "stepwise: feature_names length",
        lambda tmp: _stepwise(feature_names=["a", "b"]),
        ValueError,
        r"feature_names has 2 names but x has 3",
    ),
]


@pytest.mark.parametrize("case", params(BAD_INPUTS))
def test_bad_input(case, tmp_path, no_long_computation):
    assert_raises_as_documented(case, tmp_path)
