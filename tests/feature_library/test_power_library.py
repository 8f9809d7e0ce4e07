"""PowerLibrary (the paper's Table I function library): counts, names, values
against direct numpy evaluation, non-finite values, pysindy use, scikit-learn
conventions. Bad input: ``test_bad_input.py``; generated inputs:
``tests/properties/test_power_library_properties.py``.
"""

import io
import pickle
import re
import warnings
from itertools import combinations
from math import comb

import numpy as np
import pysindy as ps
import pytest
from reliability_support import (
    assert_same_global_random_state,
    global_random_state,
    readonly,
)
from sklearn.base import clone

from pysindy_mme import PowerLibrary, systems

DEFAULT_POWERS = (-3, -2, -1, 1, 2, 3)
DEFAULT_ABS = (-3, -1, 1, 3)


def _random_data(n_samples, n_vars, seed=0):
    """Values of both signs, bounded away from 0 so every column is finite."""
    rng = np.random.default_rng(seed)
    magnitude = rng.uniform(0.3, 2.0, size=(n_samples, n_vars))
    return magnitude * rng.choice([-1.0, 1.0], size=(n_samples, n_vars))


_FACTOR = re.compile(r"^(\|)?([A-Za-z_]\w*)(\|)?(?:\^(-?\d+))?$")


def _column_from_name(name, X, input_names):
    """Evaluate a feature name with plain numpy: an independent reference.

    ``"x0^-2 |x1|^3"`` -> ``X[:, 0] ** -2.0 * abs(X[:, 1]) ** 3.0``.
    """
    if name == "1":
        return np.ones(len(X))
    value = np.ones(len(X))
    for token in name.split(" "):
        match = _FACTOR.match(token)
        assert match, f"unparseable factor {token!r} in {name!r}"
        bar_open, var, bar_close, power = match.groups()
        assert bool(bar_open) == bool(bar_close), name
        column = X[:, input_names.index(var)]
        base = np.abs(column) if bar_open else column
        value = value * base ** float(power or 1)
    return value


def _default_names(n_vars, names=None):
    return PowerLibrary().fit(np.ones((2, n_vars))).get_feature_names(names)


# ---------------------------------------------------------------- counting
@pytest.mark.parametrize("n_vars", [1, 2, 3, 4])
def test_default_count_formula(n_vars):
    lib = PowerLibrary().fit(np.ones((3, n_vars)))
    assert lib.n_features_in_ == n_vars
    assert lib.n_output_features_ == 22 * n_vars + 100 * comb(n_vars, 2)
    with_constant = PowerLibrary(include_constant=True).fit(np.ones((3, n_vars)))
    assert with_constant.n_output_features_ == lib.n_output_features_ + 1
    X = _random_data(7, n_vars)
    assert lib.transform(X).shape == (7, lib.n_output_features_)
    assert len(lib.get_feature_names()) == lib.n_output_features_


def test_two_variables_give_the_papers_145():
    lib = PowerLibrary(include_constant=True).fit(np.ones((3, 2)))
    assert lib.n_output_features_ == 145
    names = lib.get_feature_names(["x1", "x2"])
    # intercept 0 and functions 1-20 in the order of Table I
    table_one = (
        ["1"]
        + [f"x1^{i}" if i != 1 else "x1" for i in DEFAULT_POWERS]
        + [f"x2^{i}" if i != 1 else "x2" for i in DEFAULT_POWERS]
        + [f"|x1|^{j}" if j != 1 else "|x1|" for j in DEFAULT_ABS]
        + [f"|x2|^{j}" if j != 1 else "|x2|" for j in DEFAULT_ABS]
    )
    assert names[:21] == table_one
    # The paper's truth functions (4) x1 and (10) x2 keep their numbers.
    assert names[4] == "x1" and names[10] == "x2"
    cross = [n for n in names if set(re.findall(r"x[12]", n)) == {"x1", "x2"}]
    assert len(cross) == 100
    same = set(names[21:45])
    assert len(same) == 24 and same.isdisjoint(table_one)
    assert {"x1 |x1|", "x2 |x2|", "x1^4", "|x2|^5"} <= same


def _distinct_new_products(powers, abs_powers, signed_abs, power_prod):
    """Count new same-variable products numerically (no symbolic rule).

    Columns are compared on random data of both signs: a product is new if it
    equals no single function, no earlier product, not 1 and not sign(x).
    """
    x = _random_data(64, 1, seed=3)[:, 0]
    known = [x**i for i in powers] + [np.abs(x) ** j for j in abs_powers]
    known += [np.ones_like(x), np.sign(x)]
    candidates = []
    if signed_abs:
        candidates += [x**i * np.abs(x) ** j for i in powers for j in abs_powers]
    if power_prod:
        candidates += [x**a * x**b for a, b in combinations(powers, 2)]
        candidates += [
            np.abs(x) ** a * np.abs(x) ** b for a, b in combinations(abs_powers, 2)
        ]
    new = 0
    for column in candidates:
        if not any(np.allclose(column, other, rtol=1e-10) for other in known):
            known.append(column)
            new += 1
    return new


@pytest.mark.parametrize(
    "params",
    [
        {},
        {"powers": (1, 2, 3), "abs_powers": (1, 3)},
        {"powers": (-1, 1, 2), "abs_powers": (-1, 1), "include_constant": True},
        {"powers": (1,), "abs_powers": (), "cross_products": False},
        {"signed_abs_products": False},
        {"power_products": False, "cross_products": False},
        {"powers": (3, -4, 5), "abs_powers": (-5, 1)},
    ],
)
@pytest.mark.parametrize("n_vars", [1, 3])
def test_count_formula_matches_numerical_count(params, n_vars):
    full = {
        "powers": DEFAULT_POWERS,
        "abs_powers": DEFAULT_ABS,
        "cross_products": True,
        "signed_abs_products": True,
        "power_products": True,
        "include_constant": False,
    }
    full.update(params)
    m = len(full["powers"]) + len(full["abs_powers"])
    p = _distinct_new_products(
        full["powers"],
        full["abs_powers"],
        full["signed_abs_products"],
        full["power_products"],
    )
    expected = (
        int(full["include_constant"])
        + n_vars * (m + p)
        + (comb(n_vars, 2) * m * m if full["cross_products"] else 0)
    )
    lib = PowerLibrary(**params).fit(np.ones((2, n_vars)))
    assert lib.n_output_features_ == expected
    names = lib.get_feature_names()
    assert len(set(names)) == len(names)


def test_default_per_variable_products_are_the_documented_twelve():
    assert _distinct_new_products(DEFAULT_POWERS, DEFAULT_ABS, True, True) == 12
    names = _default_names(1, ["x"])
    assert names[10:] == [
        "x^-1 |x|^-5",
        "|x|^-5",
        "x^-1 |x|^-3",
        "x^-1 |x|^-1",
        "x |x|",
        "x |x|^3",
        "|x|^5",
        "x |x|^5",
        "x^-5",
        "x^-4",
        "x^4",
        "x^5",
    ]


# ------------------------------------------------------------------ values
@pytest.mark.parametrize(
    "params",
    [
        {"include_constant": True},
        {"powers": (2, -1, 5), "abs_powers": (3, -5), "include_constant": True},
    ],
)
def test_every_column_equals_direct_numpy(params):
    X = _random_data(200, 3, seed=1)
    lib = PowerLibrary(**params).fit(X)
    names = lib.get_feature_names(["a", "b", "c"])
    Theta = np.asarray(lib.transform(X))
    assert Theta.shape == (200, lib.n_output_features_)
    for k, name in enumerate(names):
        expected = _column_from_name(name, X, ["a", "b", "c"])
        np.testing.assert_allclose(Theta[:, k], expected, rtol=1e-12, err_msg=name)


def test_columns_are_distinct_functions():
    X = _random_data(300, 2, seed=2)
    Theta = np.asarray(PowerLibrary(include_constant=True).fit(X).transform(X))
    scaled = Theta / np.linalg.norm(Theta, axis=0)
    gram = np.abs(scaled.T @ scaled)
    np.fill_diagonal(gram, 0.0)
    assert gram.max() < 1 - 1e-6  # no column is a multiple of another


def test_signs_and_exponents_describe_the_columns():
    X = _random_data(50, 2, seed=4)
    lib = PowerLibrary(include_constant=True).fit(X)
    expected = np.ones((50, lib.n_output_features_))
    for v in range(2):
        expected *= np.sign(X[:, [v]]) ** lib.signs_[:, v]
        expected *= np.abs(X[:, [v]]) ** lib.exponents_[:, v].astype(float)
    np.testing.assert_allclose(lib.transform(X), expected, rtol=1e-12)


def test_small_library_names_exactly():
    lib = PowerLibrary(powers=(1, 2), abs_powers=(1,), include_constant=True)
    names = lib.fit(np.ones((2, 2))).get_feature_names(["x", "v"])
    assert names == [
        "1",
        "x",
        "x^2",
        "v",
        "v^2",
        "|x|",
        "|v|",
        "x |x|",
        "|x|^3",
        "x^3",
        "v |v|",
        "|v|^3",
        "v^3",
        "x v",
        "x v^2",
        "x |v|",
        "x^2 v",
        "x^2 v^2",
        "x^2 |v|",
        "|x| v",
        "|x| v^2",
        "|x| |v|",
    ]


def test_default_names_follow_pysindy():
    names = _default_names(2)
    for name in ["x0", "x0^-1", "x1^2", "|x0|", "|x1|^3", "|x0|^-1", "x0^2 x1"]:
        assert name in names
    assert "x0 |x1|" in names and "x1 |x1|" in names
    assert _default_names(2, ["x1", "x2"]).count("x2 |x2|") == 1


def test_hidden_drag_term_of_systems_module_is_a_library_column():
    system = systems.quadratic_drag()
    meas = system.measure(0)
    lib = PowerLibrary().fit(meas.x)
    names = lib.get_feature_names(list(system.state_names))
    Theta = np.asarray(lib.transform(meas.x))
    for state, terms in system.hidden_terms.items():
        i = system.state_names.index(state)
        model = sum(c * Theta[:, names.index(term)] for term, c in terms.items())
        np.testing.assert_allclose(model, meas.d[:, i], rtol=1e-10, atol=1e-12)


# --------------------------------------------------------------- nonfinite
def test_zero_gives_inf_without_warnings():
    X = _random_data(20, 2, seed=5)
    X[3, 0] = 0.0
    X[4, 0] = -0.0
    X[5] = 0.0
    lib = PowerLibrary().fit(X)
    names = lib.get_feature_names()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Theta = np.asarray(lib.transform(X))
    col = {n: Theta[:, k] for k, n in enumerate(names)}
    assert col["x0^-1"][3] == np.inf and col["x0^-1"][4] == -np.inf
    assert col["|x0|^-1"][3] == np.inf and col["|x0|^-1"][4] == np.inf
    assert col["x0^-2"][4] == np.inf
    assert col["x0^-1 |x0|^-1"][4] == -np.inf  # sign(x)|x|^-2 follows x^-1
    assert col["x0"][4] == 0 and col["x0 |x0|"][3] == 0
    assert np.isnan(col["x0 x1^-1"][5])  # 0 * inf
    # exactly the columns with a negative power of x0 are singular at row 3
    singular = ~np.isfinite(Theta[3])
    np.testing.assert_array_equal(singular, lib.exponents_[:, 0] < 0)
    assert np.all(np.isfinite(np.delete(Theta, [3, 4, 5], axis=0)))


def test_overflow_is_not_a_warning():
    X = np.array([[1e80, 1.0], [2.0, 1e-80]])
    lib = PowerLibrary().fit(X)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Theta = np.asarray(lib.transform(X))
    names = lib.get_feature_names()
    assert Theta[0, names.index("x0^5")] == np.inf
    assert Theta[1, names.index("x1^-5")] == np.inf


@pytest.mark.parametrize("mode, fill", [("nan", np.nan), ("zero", 0.0)])
def test_nonfinite_replacement(mode, fill):
    X = _random_data(30, 2, seed=6)
    X[[2, 7], [0, 1]] = 0.0
    kept = np.asarray(PowerLibrary().fit(X).transform(X))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        replaced = np.asarray(PowerLibrary(nonfinite=mode).fit(X).transform(X))
    bad = ~np.isfinite(kept)
    assert bad.sum() > 50
    np.testing.assert_array_equal(replaced[~bad], kept[~bad])
    np.testing.assert_array_equal(replaced[bad], np.full(bad.sum(), fill))


def test_nonfinite_input():
    X = _random_data(10, 2)
    X[1, 1] = np.nan
    theta = np.asarray(PowerLibrary().fit(X).transform(X))
    assert np.all(np.isnan(theta[1, PowerLibrary().fit(X).exponents_[:, 1] != 0]))
    assert np.all(np.isfinite(np.delete(theta, 1, axis=0)))


def test_downstream_pysindy_optimizer_refuses_kept_inf_and_zero_mode_fits():
    t = np.linspace(0.0, 2.0, 81)
    x = np.column_stack([np.sin(3 * t), np.cos(2 * t)])  # x0 = 0 at t = 0
    x_dot = np.column_stack([3 * np.cos(3 * t), -2 * np.sin(2 * t)])
    lib = PowerLibrary(powers=(-1, 1), abs_powers=(), include_constant=True)
    model = ps.SINDy(feature_library=lib, optimizer=ps.STLSQ(threshold=0.1))
    with pytest.raises(ValueError, match="infinity|NaN"):
        model.fit(x, t=t, x_dot=x_dot)
    lib.set_params(nonfinite="zero")
    model.fit(x, t=t, x_dot=x_dot)
    assert np.all(np.isfinite(model.coefficients()))
    # nonfinite is read at transform time: predict at x0 = 0 stays finite
    assert np.all(np.isfinite(model.predict(np.array([[0.0, 1.0]]))))


# ------------------------------------------------------------------- SINDy
def test_sindy_recovers_quadratic_drag_and_simulates():
    # x' = -x|x| from both sides of 0; solution x0 / (1 + |x0| t)
    t = np.linspace(0.0, 4.0, 201)
    xs = [(x0 / (1 + abs(x0) * t))[:, None] for x0 in (2.0, -1.5)]
    x_dots = [-x * np.abs(x) for x in xs]
    lib = PowerLibrary(include_constant=True)
    # clean data: no ridge (the default alpha biases the exact solution)
    optimizer = ps.STLSQ(threshold=0.05, alpha=1e-10)
    model = ps.SINDy(feature_library=lib, optimizer=optimizer)
    model.fit(xs, t=t, x_dot=x_dots, feature_names=["x"])
    names = model.get_feature_names()
    assert len(names) == 23
    coef = model.coefficients()[0]
    support = np.flatnonzero(coef)
    assert [names[k] for k in support] == ["x |x|"]
    assert coef[support[0]] == pytest.approx(-1.0, abs=1e-6)
    printed = io.StringIO()
    model.print(file=printed)
    assert printed.getvalue().strip() == "(x)' = -1.000 x |x|"
    np.testing.assert_allclose(model.predict(xs[1]), x_dots[1], atol=1e-6)
    ts = np.linspace(0.0, 3.0, 61)
    for x0 in (1.0, -1.0):
        sim = model.simulate(np.array([x0]), ts)
        np.testing.assert_allclose(sim[:, 0], x0 / (1 + ts), atol=1e-6)


def test_sindy_on_quadratic_drag_system():
    system = systems.quadratic_drag()
    meas = system.measure(1)
    x_dot = system.true_model(meas.x, meas.t)
    lib = PowerLibrary(powers=(1, 2, 3), abs_powers=(1, 3), include_constant=True)
    model = ps.SINDy(feature_library=lib, optimizer=ps.STLSQ(threshold=0.05))
    model.fit(meas.x, t=meas.t, x_dot=x_dot, feature_names=list(system.state_names))
    names = model.get_feature_names()
    coef = model.coefficients()
    expected = np.zeros_like(coef)
    expected[0, names.index("x2")] = 1.0
    expected[1, names.index("x1")] = -1.0
    expected[1, names.index("x2 |x2|")] = -0.3
    np.testing.assert_allclose(coef, expected, atol=1e-6)


def test_control_inputs_are_further_variables():
    system = systems.forced_oscillator()
    meas = system.measure(2)
    x_dot = system.true_model(meas.x, meas.t, meas.u)
    lib = PowerLibrary(powers=(1, 2), abs_powers=(1,), include_constant=True)
    model = ps.SINDy(feature_library=lib, optimizer=ps.STLSQ(threshold=0.05))
    model.fit(meas.x, t=meas.t, x_dot=x_dot, u=meas.u, feature_names=["x1", "x2", "u"])
    assert lib.n_features_in_ == 3
    names = model.get_feature_names()
    assert {"u", "|u|", "u |u|", "x1 u", "x2^2 |u|"} <= set(names)
    coef = model.coefficients()
    expected = np.zeros_like(coef)
    expected[0, names.index("x2")] = 1.0
    expected[1, names.index("x1")] = -1.0
    expected[1, names.index("x2")] = -0.2
    expected[1, names.index("u")] = 1.5
    np.testing.assert_allclose(coef, expected, atol=1e-6)
    np.testing.assert_allclose(model.predict(meas.x, u=meas.u), x_dot, atol=1e-6)


# --------------------------------------------------------- shapes and API
def test_trajectories_and_leading_axes():
    X1, X2 = _random_data(11, 2, seed=7), _random_data(5, 2, seed=8)
    lib = PowerLibrary().fit([X1, X2])
    out = lib.transform([X1, X2])
    assert isinstance(out, list) and [o.shape[0] for o in out] == [11, 5]
    np.testing.assert_array_equal(out[1], lib.transform(X2))
    X3 = np.stack([X1[:5], X2])  # (2, 5, 2): extra leading axis
    out3 = np.asarray(lib.transform(X3))
    assert out3.shape == (2, 5, lib.n_output_features_)
    np.testing.assert_array_equal(out3[1], lib.transform(X2))


def test_input_not_modified():
    X = _random_data(9, 2)
    X[0, 0] = 0.0
    before = X.copy()
    lib = PowerLibrary(nonfinite="zero").fit(X)
    lib.transform(X)
    np.testing.assert_array_equal(X, before)


def test_clone_params_pickle():
    lib = PowerLibrary(powers=(1, -2), abs_powers=(3,), nonfinite="nan")
    assert clone(lib).get_params() == lib.get_params()
    assert lib.get_params()["powers"] == (1, -2)
    X = _random_data(12, 3)
    lib.fit(X)
    restored = pickle.loads(pickle.dumps(lib))
    np.testing.assert_array_equal(restored.transform(X), lib.transform(X))
    assert restored.get_feature_names() == lib.get_feature_names()
    fresh = clone(lib)
    assert not hasattr(fresh, "n_output_features_")
    fresh.set_params(cross_products=False).fit(X)
    assert fresh.n_output_features_ < lib.n_output_features_


def test_integral_floats_are_accepted_as_powers():
    lib = PowerLibrary(powers=np.array([1.0, 2.0]), abs_powers=[np.int64(1)])
    names = lib.fit(np.ones((2, 1))).get_feature_names()
    assert names[:3] == ["x0", "x0^2", "|x0|"]


def test_power_library_leaves_inputs_and_random_state_alone():
    x = readonly(np.random.default_rng(2).standard_normal((50, 2)))
    before = global_random_state()
    lib = PowerLibrary()
    a = np.asarray(lib.fit(x).transform(x))
    b = np.asarray(PowerLibrary().fit(x).transform(x))
    np.testing.assert_array_equal(a, b)
    assert_same_global_random_state(before)
