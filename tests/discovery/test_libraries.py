"""discover with every pysindy feature library that applies to ODEs.

Each library gets a record whose hidden effect it can express, with only the
position measured, and must name that effect. The libraries that do not
describe an ODE's right-hand side (PDE, weak-form, implicit SINDy-PI,
parameterised) are refused with a message naming ``feature_library``.
"""

from __future__ import annotations

import numpy as np
import pysindy as ps
import pytest
from oscillator_case import record, study

from pysindy_mme import PowerLibrary


def _record(hidden, seed=0):
    """Position of ``x1'' = -x1 + hidden(x1, x2)`` from (2, 0) over 20 s."""

    def truth(x, t):
        return np.column_stack([x[:, 1], -x[:, 0] + hidden(x[:, 0], x[:, 1])])

    y, t, _ = record(truth, (2.0, 0.0), t_end=20.0, seed=seed)
    return y, t


def _study(y, t, library):
    return study(y, t, feature_library=library)


def _abs_power(x):
    return x * np.abs(x)


def _sin(x):  # pysindy's CustomLibrary counts arguments: no numpy ufuncs
    return np.sin(x)


def _custom():
    return ps.CustomLibrary(
        library_functions=[_abs_power, _sin],
        function_names=[lambda s: f"{s}|{s}|", lambda s: f"sin({s})"],
    )


# library, hidden effect, the term it must name, its coefficient
LIBRARIES = {
    "PolynomialLibrary": (
        lambda: ps.PolynomialLibrary(degree=3),
        lambda x1, x2: -0.3 * x2**3,
        "x2^3",
        -0.3,
    ),
    "FourierLibrary": (
        lambda: ps.FourierLibrary(n_frequencies=1),
        lambda x1, x2: -0.4 * np.sin(x2),
        "sin(1 x2)",
        -0.4,
    ),
    "IdentityLibrary": (
        ps.IdentityLibrary,
        lambda x1, x2: -0.2 * x2,
        "x2",
        -0.2,
    ),
    "CustomLibrary": (_custom, lambda x1, x2: -0.2 * _abs_power(x2), "x2|x2|", -0.2),
    "ConcatLibrary": (
        lambda: ps.PolynomialLibrary(degree=1) + _custom(),
        lambda x1, x2: -0.2 * _abs_power(x2),
        "x2|x2|",
        -0.2,
    ),
    "TensoredLibrary": (
        lambda: (
            ps.PolynomialLibrary(degree=1, include_bias=False)
            * ps.FourierLibrary(n_frequencies=1)
        ),
        lambda x1, x2: -0.3 * x2 * np.cos(x1),
        "x2 cos(1 x1)",
        -0.3,
    ),
    "GeneralizedLibrary": (
        lambda: ps.GeneralizedLibrary([ps.PolynomialLibrary(degree=2), _custom()]),
        lambda x1, x2: -0.2 * _abs_power(x2),
        "x2|x2|",
        -0.2,
    ),
    "PowerLibrary (ours)": (
        lambda: PowerLibrary(),
        lambda x1, x2: -0.2 * _abs_power(x2),
        "x2 |x2|",
        -0.2,
    ),
}


@pytest.mark.parametrize("name", sorted(LIBRARIES))
def test_each_library_names_the_effect_it_can_express(name):
    make, hidden, term, value = LIBRARIES[name]
    y, t = _record(hidden)
    res = _study(y, t, make())
    assert term in res.terms["x2"], (name, res.terms)
    assert res.terms["x2"][term] == pytest.approx(value, rel=0.1)
    assert res.gain.ratio[0] > 2.0


@pytest.mark.slow
def test_custom_library_names_quadratic_drag_in_most_seeds():
    """Issue 13: an effect only a user's own functions express (quadratic
    drag ``x2|x2|``), the position alone measured: named within 10 % in at
    least 4 of 5 seeds (measured: 5 of 5)."""
    hits = 0
    for seed in range(5):
        y, t = _record(lambda x1, x2: -0.2 * _abs_power(x2), seed=seed)
        terms = _study(y, t, _custom()).terms["x2"]
        hits += set(terms) == {"x2|x2|"} and abs(terms["x2|x2|"] + 0.2) <= 0.02
    assert hits >= 4


_GRID = np.linspace(0, 1, 50)[:, None]


@pytest.mark.parametrize(
    "library",
    [
        pytest.param(lambda: ps.PDELibrary(), id="PDELibrary"),
        pytest.param(
            lambda: ps.SINDyPILibrary(library_functions=[_sin]), id="SINDyPILibrary"
        ),
        pytest.param(
            lambda: ps.WeakPDELibrary(
                function_library=ps.PolynomialLibrary(), spatiotemporal_grid=_GRID
            ),
            id="WeakPDELibrary",
        ),
    ],
)
def test_libraries_for_other_problems_are_refused_by_name(library):
    y, t = _record(lambda x1, x2: -0.3 * x2**3)
    with pytest.raises((TypeError, ValueError), match="feature_library"):
        _study(y, t, library())
