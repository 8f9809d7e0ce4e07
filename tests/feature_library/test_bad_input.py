"""PowerLibrary: one table of bad inputs, each with its exception type and a
phrase of its message.

``__init__`` only stores (scikit-learn convention): bad parameters are
reported by ``fit``; bad data by ``fit``, ``transform`` and
``get_feature_names``. Inputs are read-only, so a library that modified them
would fail here too.
"""

from __future__ import annotations

import numpy as np
import pytest
from bad_input_support import Bad, assert_raises_as_documented, params, readonly
from scipy import sparse

from pysindy_mme import PowerLibrary

ENTRY_POINT = "PowerLibrary"

ONES = readonly(np.ones((3, 2)))


def _fit(**params):
    return PowerLibrary(**params).fit(ONES)  # __init__ only stores


def _data(n_samples, n_vars, seed=0):
    """Values of both signs, bounded away from 0 (read-only)."""
    rng = np.random.default_rng(seed)
    magnitude = rng.uniform(0.3, 2.0, size=(n_samples, n_vars))
    return readonly(magnitude * rng.choice([-1.0, 1.0], size=(n_samples, n_vars)))


def _nan_record():
    """A record with one NaN: ``fit`` accepts it, ``transform`` decides."""
    x = np.array(_data(10, 2))
    x[1, 1] = np.nan
    return readonly(x)


BAD_INPUTS = [
    # ---- powers
    Bad(
        "PowerLibrary: no powers",
        lambda tmp: _fit(powers=()),
        ValueError,
        r"powers must not be empty",
    ),
    Bad(
        "PowerLibrary: power 0",
        lambda tmp: _fit(powers=(0, 1)),
        ValueError,
        r"powers must not contain 0",
    ),
    Bad(
        "PowerLibrary: fractional power",
        lambda tmp: _fit(powers=(1.5,)),
        ValueError,
        r"powers must contain integers, got 1.5",
    ),
    Bad(
        "PowerLibrary: fractional power after a valid one",
        lambda tmp: _fit(powers=(1, 1.5)),
        ValueError,
        r"powers must contain integers",
    ),
    Bad(
        "PowerLibrary: infinite power",
        lambda tmp: _fit(powers=(1, np.inf)),
        ValueError,
        r"powers must contain integers",
    ),
    Bad(
        "PowerLibrary: repeated power",
        lambda tmp: _fit(powers=(1, 2, 1)),
        ValueError,
        r"powers contains duplicates",
    ),
    Bad(
        "PowerLibrary: powers a string",
        lambda tmp: _fit(powers="123"),
        TypeError,
        r"powers must be a sequence",
    ),
    Bad(
        "PowerLibrary: powers a number",
        lambda tmp: _fit(powers=2),
        TypeError,
        r"powers must be a sequence",
    ),
    Bad(
        "PowerLibrary: power a bool",
        lambda tmp: _fit(powers=(1, True)),
        TypeError,
        r"powers must contain integers",
    ),
    # ---- absolute powers
    Bad(
        "PowerLibrary: even absolute power",
        lambda tmp: _fit(abs_powers=(2,)),
        ValueError,
        r"abs_powers must contain odd integers only",
    ),
    Bad(
        "PowerLibrary: even absolute power after a valid one",
        lambda tmp: _fit(abs_powers=(1, 2)),
        ValueError,
        r"abs_powers must contain odd",
    ),
    Bad(
        "PowerLibrary: absolute power 0",
        lambda tmp: _fit(abs_powers=(0,)),
        ValueError,
        r"abs_powers must not contain 0",
    ),
    Bad(
        "PowerLibrary: fractional absolute power",
        lambda tmp: _fit(abs_powers=(0.5,)),
        ValueError,
        r"abs_powers must contain integers",
    ),
    Bad(
        "PowerLibrary: absolute power a string",
        lambda tmp: _fit(abs_powers=(1, "3")),
        TypeError,
        r"abs_powers must contain integers",
    ),
    # ---- flags and modes
    Bad(
        "PowerLibrary: flag an integer",
        lambda tmp: _fit(cross_products=1),
        TypeError,
        r"cross_products must be True or False",
    ),
    Bad(
        "PowerLibrary: flag a string",
        lambda tmp: _fit(cross_products="yes"),
        TypeError,
        r"cross_products",
    ),
    Bad(
        "PowerLibrary: signed_abs_products None",
        lambda tmp: _fit(signed_abs_products=None),
        TypeError,
        r"signed_abs_products",
    ),
    Bad(
        "PowerLibrary: power_products an integer",
        lambda tmp: _fit(power_products=1),
        TypeError,
        r"power_products",
    ),
    Bad(
        "PowerLibrary: include_constant a string",
        lambda tmp: _fit(include_constant="no"),
        TypeError,
        r"include_constant",
    ),
    Bad(
        "PowerLibrary: unknown nonfinite mode",
        lambda tmp: _fit(nonfinite="drop"),
        ValueError,
        r"nonfinite must be one of",
    ),
    # ---- data
    Bad(
        "PowerLibrary: trajectories of different widths",
        lambda tmp: PowerLibrary().fit([_data(11, 2), _data(11, 1)]),
        ValueError,
        r"same number of features",
    ),
    Bad(
        "PowerLibrary: transform with fewer columns",
        lambda tmp: _fit().transform(readonly(np.ones((3, 1)))),
        ValueError,
        r"x must have 2 feature columns \(as in fit\)",
    ),
    Bad(
        "PowerLibrary: transform with more columns",
        lambda tmp: (
            PowerLibrary(nonfinite="zero")
            .fit(_data(9, 2))
            .transform(readonly(np.ones((4, 3))))
        ),
        ValueError,
        r"2 feature columns",
    ),
    Bad(
        "PowerLibrary: sparse transform input",
        lambda tmp: (
            PowerLibrary(nonfinite="zero")
            .fit(_data(9, 2))
            .transform(sparse.csr_matrix(_data(9, 2)))
        ),
        TypeError,
        r"dense",
    ),
    Bad(
        "PowerLibrary: non-numeric transform input",
        lambda tmp: _fit().transform([["a", "b"]]),
        TypeError,
        r"x must be a numeric array",
    ),
    Bad(
        "PowerLibrary: NaN input with nonfinite='zero'",
        lambda tmp: (
            PowerLibrary(nonfinite="zero").fit(_nan_record()).transform(_nan_record())
        ),
        ValueError,
        r"nonfinite='zero' only replaces values the library",
    ),
    Bad(
        "PowerLibrary: feature names of the wrong count",
        lambda tmp: _fit().get_feature_names(["only_one"]),
        ValueError,
        r"input_features",
    ),
]


@pytest.mark.parametrize("case", params(BAD_INPUTS))
def test_bad_input(case, tmp_path, no_long_computation):
    assert_raises_as_documented(case, tmp_path)
