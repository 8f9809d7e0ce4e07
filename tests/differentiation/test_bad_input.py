"""MME: one table of bad inputs (issue 3: time, noise, indices, model output,
observability), each with its exception type and a phrase of its message.

Every case runs with the solver replaced by a tripwire (checks come before
any long computation) on read-only measurements (an input modified in place
fails the case), and the shared record must be unchanged afterwards.
"""

from __future__ import annotations

import numpy as np
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
from paper_case import paper_mme as _mme
from paper_case import paper_mme_fit as _mme_fit
from paper_case import three_states as _three_states

ENTRY_POINT = "MME"


def _transposed(x, t):
    # A classic slip: np.array([...]) stacks the equations as rows.
    return np.array([x[:, 1], -x[:, 0]])


def _first_only(y):
    """``y`` observed at its first sample only (NaN elsewhere)."""
    return readonly(np.where((np.arange(len(y)) == 0)[:, None], y, np.nan))


BAD_INPUTS = [
    # ---- time
    Bad(
        "MME: t not increasing",
        lambda tmp: _mme_fit(t=T[::-1]),
        ValueError,
        r"t must be strictly increasing",
    ),
    Bad(
        "MME: t repeats a time",
        lambda tmp: _mme_fit(t=with_value(T, 5, T[4])),
        ValueError,
        r"t must be strictly increasing; t\[4\]",
    ),
    Bad(
        "MME: t of the wrong length",
        lambda tmp: _mme_fit(t=T[:300]),
        ValueError,
        r"t has 300 entries but the data have 401 samples",
    ),
    Bad(
        "MME: t contains NaN",
        lambda tmp: _mme_fit(t=with_value(T, 3, np.nan)),
        ValueError,
        r"t contains NaN",
    ),
    Bad(
        "MME: negative time step",
        lambda tmp: _mme_fit(t=-0.025),
        ValueError,
        r"t must be finite and > 0",
    ),
    Bad(
        "MME: called by pysindy with decreasing t",
        lambda tmp: _mme()(Y, T[::-1]),
        ValueError,
        r"t must be strictly increasing",
    ),
    # ---- noise
    Bad(
        "MME: noise variance zero",
        lambda tmp: _mme_fit(noise_variance=0.0),
        ValueError,
        r"noise_variance must be finite and > 0",
    ),
    Bad(
        "MME: noise variance negative",
        lambda tmp: _mme_fit(noise_variance=-1.0),
        ValueError,
        r"noise_variance must be finite and > 0",
    ),
    Bad(
        "MME: noise variance vector not positive",
        lambda tmp: _mme_fit(noise_variance=[-0.01]),
        ValueError,
        r"noise_variance must be positive",
    ),
    Bad(
        "MME: noise covariance not positive definite",
        lambda tmp: _mme_fit(
            y=readonly(np.column_stack([Y, Y])),
            measured=[0, 1],
            noise_variance=[[1.0, 2.0], [2.0, 1.0]],
        ),
        ValueError,
        r"noise_variance \(covariance R\) must be positive definite",
    ),
    Bad(
        "MME: noise variance unknown word",
        lambda tmp: _mme_fit(noise_variance="large"),
        ValueError,
        r"noise_variance must be 'auto', a number",
    ),
    # ---- state indices and the measurement model
    Bad(
        "MME: measured index out of range",
        lambda tmp: _mme_fit(measured=[2]),
        ValueError,
        r"measured = \[2\] is out of range",
    ),
    Bad(
        "MME: measured index negative",
        lambda tmp: _mme_fit(measured=[-1]),
        ValueError,
        r"measured = \[-1\] is out of range",
    ),
    Bad(
        "MME: measured not integers",
        lambda tmp: _mme_fit(measured=[0.5]),
        TypeError,
        r"measured must hold integer indices",
    ),
    Bad(
        "MME: measured empty",
        lambda tmp: _mme_fit(measured=[]),
        ValueError,
        r"measured must name at least one",
    ),
    Bad(
        "MME: measured and measurement_matrix both given",
        lambda tmp: _mme_fit(measurement_matrix=[[1.0, 0.0]]),
        ValueError,
        r"give only one of measured, measurement_matrix",
    ),
    Bad(
        "MME: error_states out of range",
        lambda tmp: _mme_fit(error_states=[5]),
        ValueError,
        r"error_states = \[5\] is out of range",
    ),
    Bad(
        "MME: error_states repeats",
        lambda tmp: _mme_fit(error_states=[1, 1]),
        ValueError,
        r"error_states = \[1, 1\] repeats an index",
    ),
    Bad(
        "MME: n_states zero",
        lambda tmp: _mme_fit(n_states=0),
        ValueError,
        r"n_states must be an integer >= 1",
    ),
    # a non-integer type is a TypeError, as in discover
    Bad(
        "MME: n_states a float",
        lambda tmp: _mme_fit(n_states=2.0),
        TypeError,
        r"n_states must be an integer >= 1",
    ),
    Bad(
        "MME: n_states a bool",
        lambda tmp: _mme_fit(n_states=True),
        TypeError,
        r"n_states must be an integer >= 1",
    ),
    # ---- measurements
    Bad(
        "MME: y has inf",
        lambda tmp: _mme_fit(y=with_value(Y, (7, 0), np.inf)),
        ValueError,
        r"y \(the measurements\) contains inf",
    ),
    Bad(
        "MME: y has 3 dimensions",
        lambda tmp: _mme_fit(y=Y[:, :, None]),
        ValueError,
        r"y \(the measurements\) must have 1 or 2 dimension",
    ),
    Bad(
        "MME: y too short",
        lambda tmp: _mme_fit(y=Y[:2], t=T[:2]),
        ValueError,
        r"needs at least 3 samples, got 2",
    ),
    Bad(
        "MME: y columns do not match measured",
        lambda tmp: _mme_fit(measured=[0, 1]),
        ValueError,
        r"has 1 column\(s\) but the measurement model gives 2",
    ),
    Bad(
        "MME: all measurements missing",
        lambda tmp: _mme_fit(y=readonly(np.full(Y.shape, np.nan))),
        ValueError,
        r"y \(the measurements\) has no observed value \(all NaN\)",
    ),
    Bad(
        "MME: a channel with one observed value",
        lambda tmp: _mme_fit(
            y=readonly(np.column_stack([Y, _first_only(Y)])), measured=[0, 1]
        ),
        ValueError,
        r"y \(the measurements\) column 1 has 1 observed value",
    ),
    # ---- the assumed model
    Bad(
        "MME: model returns the wrong shape",
        lambda tmp: _mme_fit(assumed_model=lambda x, t: x[:, :1]),
        ValueError,
        r"assumed_model returned an array of shape \(401, 1\)",
    ),
    Bad(
        "MME: model returns its equations as rows (transposed)",
        lambda tmp: _mme_fit(assumed_model=_transposed),
        ValueError,
        r"assumed_model returned an array of shape \(2, 401\)",
    ),
    Bad(
        "MME: model returns NaN",
        lambda tmp: _mme_fit(assumed_model=lambda x, t: np.full_like(x, np.nan)),
        ValueError,
        r"assumed_model returned non-finite values",
    ),
    Bad(
        "MME: model raises",
        lambda tmp: _mme_fit(assumed_model=lambda x, t: x / 0 + {}),
        ValueError,
        r"assumed_model failed on its first evaluation",
    ),
    Bad(
        "MME: model not callable",
        lambda tmp: _mme_fit(assumed_model="vdp"),
        TypeError,
        r"assumed_model must be a callable",
    ),
    # ---- observability (structural: before the solver)
    Bad(
        "MME: error state that no measurement sees",
        lambda tmp: _mme_fit(assumed_model=_three_states, n_states=3, error_states=[2]),
        ValueError,
        r"error_states \[2\] cannot be seen in the measurements",
    ),
    Bad(
        "MME: state that no measurement sees",
        lambda tmp: _mme_fit(assumed_model=_three_states, n_states=3, error_states=[1]),
        ValueError,
        r"states \[2\] cannot be seen",
    ),
    # ---- W
    Bad(
        "MME: W zero",
        lambda tmp: _mme_fit(W=0.0),
        ValueError,
        r"W must be finite and > 0",
    ),
    Bad(
        "MME: W negative",
        lambda tmp: _mme_fit(W=-3.0),
        ValueError,
        r"W must be finite and > 0",
    ),
    Bad(
        "MME: W unknown word",
        lambda tmp: _mme_fit(W="best"),
        ValueError,
        r"W must be 'auto', 'ml'",
    ),
    Bad(
        "MME: W matrix of the wrong size",
        lambda tmp: _mme_fit(W=[[1.0, 0.0], [0.0, 1.0]]),
        ValueError,
        r"W must be \(1, 1\)",
    ),
    # ---- inputs
    Bad(
        "MME: u of the wrong length",
        lambda tmp: _mme_fit(u=np.zeros((7, 1))),
        ValueError,
        r"u has 7 rows but y has 401 samples",
    ),
    Bad(
        "MME: u for a model without input",
        lambda tmp: _mme_fit(u=np.zeros((401, 1))),
        ValueError,
        r"u was given but assumed_model takes no input",
    ),
    # ---- the starting trajectory
    Bad(
        "MME: x_guess of the wrong shape",
        lambda tmp: _mme().fit(Y, T, x_guess=np.zeros((401, 1))),
        ValueError,
        r"x_guess must have shape \(n_samples, n_states\) = \(401, 2\), got "
        r"\(401, 1\)",
    ),
    Bad(
        "MME: x_guess not finite",
        lambda tmp: _mme().fit(Y, T, x_guess=with_value(np.zeros((401, 2)), 7, np.nan)),
        ValueError,
        r"x_guess contains NaN \(first at index \[7, 0\]\)",
    ),
    # ---- other options
    Bad(
        "MME: target unknown",
        lambda tmp: _mme_fit(target="x"),
        ValueError,
        r"target must be",
    ),
    Bad(
        "MME: max_iter zero",
        lambda tmp: _mme_fit(max_iter=0),
        ValueError,
        r"max_iter must be an integer >= 1",
    ),
    Bad(
        "MME: tol zero",
        lambda tmp: _mme_fit(tol=0.0),
        ValueError,
        r"tol must be a finite number > 0",
    ),
    Bad(
        "MME: unknown error model",
        lambda tmp: _mme_fit(error_model="smooth"),
        ValueError,
        r"error_model must be an ErrorModel object or a registered name "
        r"\('white'.*'random_walk'.*\); got 'smooth'",
    ),
]


@pytest.mark.parametrize("case", params(BAD_INPUTS))
def test_bad_input(case, tmp_path, no_long_computation):
    assert_raises_as_documented(case, tmp_path)
    np.testing.assert_array_equal(Y, _DATA.y)  # the record is untouched
    np.testing.assert_array_equal(T, _DATA.t)
