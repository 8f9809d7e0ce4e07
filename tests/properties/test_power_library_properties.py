"""Property-based tests (hypothesis) of ``PowerLibrary.transform``: any float
input (zeros of both signs, tiny and huge values, NaN, inf), against a
direct evaluation of every column from its signs and exponents; the library
never warns and never modifies its input.

The hypothesis profile ("ci": derandomised, fixed example counts) is set in
``tests/conftest.py``, which also prints how many cases each entry point
received.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from reliability_support import readonly

from pysindy_mme import PowerLibrary

_SPECIAL = [0.0, -0.0, 1.0, -1.0, 1e-200, -1e-200, 1e200, np.nan, np.inf, -np.inf]


def _reference_columns(lib, x):
    """Every column straight from ``signs_`` and ``exponents_``."""
    out = np.ones((x.shape[0], lib.n_output_features_))
    with np.errstate(all="ignore"):
        for c, (s_row, k_row) in enumerate(zip(lib.signs_, lib.exponents_)):
            col = None
            for v in range(x.shape[1]):
                s, k = int(s_row[v]), int(k_row[v])
                if s == 0 and k == 0:
                    continue
                factor = np.power(np.abs(x[:, v]), float(k))
                if s:
                    factor = np.copysign(factor, x[:, v])
                col = factor if col is None else col * factor
            if col is not None:
                out[:, c] = col
    return out


@settings(max_examples=250)
@given(
    n_features=st.integers(1, 3),
    powers=st.lists(
        st.sampled_from([-3, -2, -1, 1, 2, 3]), min_size=1, max_size=4, unique=True
    ),
    abs_powers=st.lists(st.sampled_from([-3, -1, 1, 3]), max_size=3, unique=True),
    flags=st.tuples(st.booleans(), st.booleans(), st.booleans(), st.booleans()),
    nonfinite=st.sampled_from(["keep", "nan", "zero"]),
    data=st.data(),
)
def test_power_library_transform(
    n_features, powers, abs_powers, flags, nonfinite, data, case_counter
):
    case_counter["PowerLibrary.transform"] += 1
    cross, signed_abs, power_products, constant = flags
    x = data.draw(
        hnp.arrays(
            float,
            st.tuples(st.integers(0, 6), st.just(n_features)),
            elements=st.one_of(
                st.floats(-1e3, 1e3), st.sampled_from(_SPECIAL), st.floats()
            ),
        ),
        label="x",
    )
    lib = PowerLibrary(
        powers=powers,
        abs_powers=abs_powers,
        cross_products=cross,
        signed_abs_products=signed_abs,
        power_products=power_products,
        include_constant=constant,
        nonfinite=nonfinite,
    ).fit(np.ones((1, n_features)))
    names = lib.get_feature_names()
    assert len(names) == len(set(names)) == lib.n_output_features_
    x_ro = readonly(x)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the library never warns
        if nonfinite == "zero" and not np.all(np.isfinite(x)):
            with pytest.raises(ValueError, match="nonfinite='zero'"):
                lib.transform(x_ro)
            return
        out = np.asarray(lib.transform(x_ro))
    np.testing.assert_array_equal(x_ro, x)
    assert out.shape == (x.shape[0], lib.n_output_features_)
    ref = _reference_columns(lib, x)
    if nonfinite == "nan":
        ref = np.where(np.isfinite(ref), ref, np.nan)
    elif nonfinite == "zero":
        ref = np.where(np.isfinite(ref), ref, 0.0)
        assert np.all(np.isfinite(out))
    # Same non-finite values at the same places; finite values to a few ulp
    # (numpy's vectorised power may round differently from the scalar loop).
    finite = np.isfinite(ref)
    np.testing.assert_array_equal(np.isfinite(out), finite)
    np.testing.assert_array_equal(out[~finite], ref[~finite])
    np.testing.assert_allclose(out[finite], ref[finite], rtol=1e-14, atol=1e-300)
