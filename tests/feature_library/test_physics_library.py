"""PhysicsLibrary (named physical effects): values against hand-written numpy
formulas, exact gradients against central differences, names, restriction to
the chosen variable, kinks and switching functions, bad input, pysindy use
(SINDy, ``+``, GeneralizedLibrary, several trajectories), scikit-learn
conventions, and the fast path of ``SelectedFeatures``/``ExtendedModel``.
"""

from __future__ import annotations

import pickle
from dataclasses import replace

import numpy as np
import pysindy as ps
import pytest
from bad_input_support import Bad, assert_raises_as_documented, params, readonly
from sklearn.base import clone

from pysindy_mme import ExtendedModel, FloatingFStepwise, PhysicsLibrary
from pysindy_mme.core.features import SelectedFeatures
from pysindy_mme.feature_library import (
    Coulomb,
    DeadZone,
    Overflow,
    Saturation,
    SmoothCoulomb,
    Stribeck,
    Torricelli,
    ViscousSplit,
)

NAMES = ["q", "v", "u"]


def _data(n=200, seed=0, scale=3.0):
    """Rows of (q, v, u) of both signs, with exact zeros and kink points mixed in."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(-scale, scale, size=(n, 3))
    z[:5] = [
        [0.0, 0.0, 0.0],
        [1.0, -1.0, 2.0],
        [-2.0, 0.5, -0.5],
        [10, 1, 1],
        [0, 0, 1],
    ]
    return readonly(z)


# -------------------------------------------------------------- references
# Each effect: (effect on column 1 "v", hand-written columns, names, kinks).
# The formulas are written out independently of the library's code.
def _sign(x):
    return np.where(x > 0, 1.0, np.where(x < 0, -1.0, 0.0))


CASES = {
    "coulomb": (Coulomb("v"), lambda x: [_sign(x)], ["sign(v)"], [0.0]),
    "smooth_coulomb": (
        SmoothCoulomb("v", 0.25),
        lambda x: [(np.exp(8 * x) - 1) / (np.exp(8 * x) + 1)],
        ["tanh(v/0.25)"],
        [],
    ),
    "stribeck": (
        Stribeck("v", 0.5),
        lambda x: [_sign(x) * np.exp(-4 * x * x)],
        ["sign(v) exp(-(v/0.5)^2)"],
        [0.0],
    ),
    "viscous_split": (
        ViscousSplit("v"),
        lambda x: [np.where(x > 0, x, 0.0), np.where(x < 0, x, 0.0)],
        ["v+", "v-"],
        [0.0],
    ),
    "saturation": (
        Saturation("v", [1, 2.5]),
        lambda x: [
            np.where(x > 1, 1.0, np.where(x < -1, -1.0, x)),
            np.where(x > 2.5, 2.5, np.where(x < -2.5, -2.5, x)),
        ],
        ["sat(v, 1)", "sat(v, 2.5)"],
        [-2.5, -1.0, 1.0, 2.5],
    ),
    "dead_zone": (
        DeadZone("v", 0.5),
        lambda x: [np.where(x > 0.5, x - 0.5, np.where(x < -0.5, x + 0.5, 0.0))],
        ["dz(v, 0.5)"],
        [-0.5, 0.5],
    ),
    "torricelli": (
        Torricelli("v"),
        lambda x: [np.array([xi**0.5 if xi > 0 else 0.0 for xi in x])],
        ["sqrt(v+)"],
        [0.0],
    ),
    "overflow": (
        Overflow("v", [1, -0.5]),
        lambda x: [np.where(x > 1, x - 1, 0.0), np.where(x > -0.5, x + 0.5, 0.0)],
        ["over(v, 1)", "over(v, -0.5)"],
        [-0.5, 1.0],
    ),
}


def _fitted(*effects, include_bias=False, names=NAMES):
    return PhysicsLibrary(list(effects), include_bias=include_bias, names=names).fit(
        _data()
    )


@pytest.mark.parametrize("case", sorted(CASES))
def test_columns_match_hand_written_formulas(case):
    effect, reference, names, _ = CASES[case]
    z = _data()
    lib = _fitted(effect)
    expected = np.column_stack(reference(z[:, 1]))
    np.testing.assert_allclose(np.asarray(lib.transform(z)), expected, atol=1e-14)
    np.testing.assert_allclose(lib.evaluate(z, exact=True), expected, atol=1e-14)
    assert lib.get_feature_names() == names
    assert lib.n_output_features_ == len(names)


@pytest.mark.parametrize("case", sorted(CASES))
def test_gradients_match_central_differences_away_from_kinks(case):
    effect, _, _, kinks = CASES[case]
    lib = _fitted(effect)
    rng = np.random.default_rng(5)
    z = rng.uniform(-3, 3, size=(300, 3))
    away = np.all(np.abs(z[:, [1]] - np.array(kinks)[None, :]) > 1e-2, axis=1)
    z = z[away & (np.abs(z[:, 1]) > 1e-2)]  # Torricelli: steep near 0
    h = 1e-6
    numeric = np.empty((len(z), lib.n_output_features_, 3))
    for v in range(3):
        step = np.zeros(3)
        step[v] = h
        numeric[:, :, v] = (lib.evaluate(z + step) - lib.evaluate(z - step)) / (2 * h)
    exact = lib.gradient(z)
    assert exact.shape == (len(z), lib.n_output_features_, 3)
    np.testing.assert_allclose(exact, numeric, rtol=1e-6, atol=1e-7)


def test_gradient_conventions_at_the_kinks():
    lib = _fitted(
        Coulomb("v"),
        ViscousSplit("v"),
        Torricelli("v"),
        Saturation("v", 1),
        DeadZone("v", 1),
        Overflow("v", 1),
    )
    at = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
    grad = lib.gradient(at, exact=True)[:, :, 1]
    # sign: 0; v+ / v-: one-sided from above (1, 0) at 0; sqrt: 0 at an empty
    # tank (its slope is infinite); at +-1 every kink takes the slope above it
    np.testing.assert_array_equal(grad[0], [0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    np.testing.assert_array_equal(grad[1, 4:], [0.0, 1.0, 1.0])
    np.testing.assert_array_equal(grad[2, 4:], [1.0, 0.0, 0.0])
    assert np.all(np.isfinite(lib.gradient(_data())))


def test_worked_example_names_and_bias_first():
    lib = PhysicsLibrary(
        [Coulomb("v"), ViscousSplit("v"), SmoothCoulomb("v", 0.001)],
        include_bias=True,
        names=NAMES,
    ).fit(_data())
    assert lib.get_feature_names() == ["1", "sign(v)", "v+", "v-", "tanh(v/0.001)"]
    np.testing.assert_array_equal(np.asarray(lib.transform(_data()))[:, 0], 1.0)
    lib = _fitted(
        Stribeck(1, 0.01),
        Torricelli("q"),
        Overflow(0, 10),
        Saturation(2, 3),
        SmoothCoulomb(1, 0.1 + 0.2),
    )
    assert lib.get_feature_names() == [
        "sign(v) exp(-(v/0.01)^2)",
        "sqrt(q+)",
        "over(q, 10)",
        "sat(u, 3)",
        "tanh(v/0.3)",  # %g
    ]
    # pysindy's input_features label the columns
    lib = _fitted(Torricelli("q"), DeadZone(2, [0.1, 2e-5]))
    assert lib.get_feature_names(["h1", "v", "w"]) == [
        "sqrt(h1+)",
        "dz(w, 0.1)",
        "dz(w, 2e-05)",
    ]


def test_names_resolve_against_input_features_without_names():
    lib = PhysicsLibrary([Overflow("h1", 10), Coulomb(1)]).fit(np.zeros((3, 2)))
    assert lib.get_feature_names(["h1", "v"]) == ["over(h1, 10)", "sign(v)"]
    assert lib.get_feature_names(["h2", "h1"]) == ["over(h1, 10)", "sign(h1)"]
    assert lib.get_feature_names() == ["over(h1, 10)", "sign(x1)"]
    with pytest.raises(ValueError, match="input_features has no variable 'h1'"):
        lib.get_feature_names(["a", "b"])
    with pytest.raises(ValueError, match="pass names="):
        lib.transform(np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"Overflow\('h1'\)"):
        lib.evaluate(np.zeros((3, 2)))
    # with_names: a copy, the original untouched
    named = lib.with_names(["v", "h1"])
    assert named is not lib and lib.names is None and named.names == ["v", "h1"]
    z = np.array([[1.0, 12.0], [-1.0, -3.0]])
    np.testing.assert_allclose(named.fit(z).transform(z), [[2.0, 1.0], [0.0, -1.0]])


def test_names_and_input_features_must_agree():
    lib = _fitted(Coulomb("v"))
    assert lib.get_feature_names(["a", "b", "c"]) == ["sign(b)"]
    with pytest.raises(ValueError, match="disagree on 'v'"):
        lib.get_feature_names(["v", "q", "u"])


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("variable", [0, 2])
def test_each_column_depends_on_its_variable_only(case, variable):
    lib = _fitted(replace(CASES[case][0], variable=variable))
    z = np.array(_data())
    base = lib.evaluate(z)
    others = [v for v in range(3) if v != variable]
    z[:, others] = np.random.default_rng(9).normal(size=(len(z), 2))
    np.testing.assert_array_equal(lib.evaluate(z), base)
    grad = lib.gradient(z)
    np.testing.assert_array_equal(grad[:, :, others], 0.0)
    # the chosen variable's name, and no other, appears in the names
    labels = ["alpha", "beta", "gamma"]
    for name in lib.get_feature_names(labels):
        assert labels[variable] in name
        assert not any(labels[o] in name for o in others)


def test_kinks_and_switching_functions():
    lib = _fitted(
        SmoothCoulomb("v", 0.1),
        Coulomb("v"),
        Saturation("u", 2),
        DeadZone("u", 0.5),
        Overflow("q", 10),
        Torricelli("q"),
        include_bias=True,
    )
    assert lib.has_kinks
    assert lib.kinked_columns() == [2, 3, 4, 5, 6]
    assert lib.kinked_columns([0, 1, 4]) == [4]
    assert not PhysicsLibrary([SmoothCoulomb(0, 1.0)], include_bias=True).has_kinks
    z = _data()
    s = lib.switching(z, [0, 1, 2, 3, 4, 5, 6])
    assert s.shape == (len(z), 7) and np.all(np.isfinite(s))
    np.testing.assert_array_equal(s[:, :2], 1.0)  # bias, smooth: never switch
    np.testing.assert_allclose(s[:, 2], z[:, 1])
    np.testing.assert_allclose(s[:, 3], np.abs(z[:, 2]) - 2)
    np.testing.assert_allclose(s[:, 4], np.abs(z[:, 2]) - 0.5)
    np.testing.assert_allclose(s[:, 5], z[:, 0] - 10)
    np.testing.assert_allclose(s[:, 6], z[:, 0])
    assert lib.switching(z, [5]).shape == (len(z), 1)
    for effect in [Coulomb(0), Stribeck(0, 1), ViscousSplit(0), Saturation(0, 1)]:
        assert effect.nonsmooth
    for effect in [DeadZone(0, 1), Torricelli(0), Overflow(0, 1)]:
        assert effect.nonsmooth
    assert not SmoothCoulomb(0, 1).nonsmooth


def test_evaluate_selected_columns_in_order_and_single_rows():
    lib = _fitted(Coulomb("v"), Saturation("u", [1, 2]), include_bias=True)
    z = _data()
    full = np.asarray(lib.transform(z))
    np.testing.assert_array_equal(
        lib.evaluate(z, [3, 0, 1], exact=True), full[:, [3, 0, 1]]
    )
    np.testing.assert_array_equal(lib.evaluate(z[7], [2], exact=True), full[7:8, [2]])
    assert lib.evaluate(z, []).shape == (len(z), 0)
    assert lib.gradient(z[:2], [3, 1]).shape == (2, 2, 3)


def test_several_trajectories_and_axes():
    lib = PhysicsLibrary([Coulomb(0), Overflow(1, 0.5)])
    xs = [np.random.default_rng(i).normal(size=(20 + i, 2)) for i in range(3)]
    lib.fit(xs)
    out = lib.transform(xs)
    assert isinstance(out, list) and [o.shape for o in out] == [
        (20, 2),
        (21, 2),
        (22, 2),
    ]
    for x, o in zip(xs, out, strict=True):
        np.testing.assert_array_equal(o[:, 0], _sign(x[:, 0]))
        assert isinstance(o, ps.utils.AxesArray)


def test_pickle_and_clone():
    lib = _fitted(
        Coulomb("v"), Saturation("u", [1, 2]), DeadZone(2, 0.5), include_bias=True
    )
    again = pickle.loads(pickle.dumps(lib))
    np.testing.assert_array_equal(again.transform(_data()), lib.transform(_data()))
    assert again.get_feature_names() == lib.get_feature_names()
    fresh = clone(lib)
    assert fresh.get_params()["effects"] == lib.effects
    assert not hasattr(fresh, "n_output_features_")
    np.testing.assert_array_equal(
        fresh.fit(_data()).transform(_data()), lib.transform(_data())
    )
    assert Saturation("u", 2) == Saturation("u", [2.0])
    assert hash(Saturation("u", 2)) == hash(Saturation("u", (2,)))


# ----------------------------------------------------------- pysindy use
def _sign_toy():
    """``x' = -2 sign(x) - x``: exact trajectories from both sides of 0."""
    xs, xdots = [], []
    for x0 in (3.0, -3.0, 1.5, -2.0):
        s = np.sign(x0)
        t_zero = np.log((abs(x0) + 2) / 2)  # where x reaches 0
        t = np.linspace(0, 0.9 * t_zero, 60)
        x = (x0 + 2 * s) * np.exp(-t) - 2 * s
        xs.append(x[:, None])
        xdots.append((-2 * s - x)[:, None])
    return xs, xdots


@pytest.mark.parametrize(
    "optimizer", [ps.STLSQ(threshold=0.1), FloatingFStepwise()], ids=["stlsq", "ff"]
)
def test_sindy_recovers_the_coulomb_coefficient(optimizer):
    xs, xdots = _sign_toy()
    bias = isinstance(optimizer, ps.STLSQ)  # FloatingFStepwise fits its own
    lib = PhysicsLibrary([Coulomb("x"), ViscousSplit("x")], include_bias=bias)
    lib = lib.with_names(["x"])
    model = ps.SINDy(feature_library=lib, optimizer=optimizer)
    model.fit(xs, t=0.01, x_dot=xdots, feature_names=["x"])
    names = model.get_feature_names()
    coef = dict(zip(names, np.asarray(model.coefficients())[0], strict=True))
    assert coef["sign(x)"] == pytest.approx(-2.0, abs=1e-6)
    assert coef["x+"] == pytest.approx(-1.0, abs=1e-6)
    assert coef["x-"] == pytest.approx(-1.0, abs=1e-6)
    pred = model.predict(xs[0])
    np.testing.assert_allclose(pred, xdots[0], atol=1e-6)
    t = np.linspace(0, 0.5, 11)  # x(t) = 5 e^-t - 2 stays positive
    sim = model.simulate([3.0], t, integrator_kws={"rtol": 1e-10, "atol": 1e-12})
    np.testing.assert_allclose(sim[:, 0], 5 * np.exp(-t) - 2, atol=1e-6)


def test_concatenated_with_polynomial_library():
    xs, xdots = _sign_toy()
    lib = ps.PolynomialLibrary(degree=2) + PhysicsLibrary([Coulomb(0)])
    model = ps.SINDy(feature_library=lib, optimizer=ps.STLSQ(threshold=0.1))
    model.fit(xs, t=0.01, x_dot=xdots, feature_names=["x"])
    names = model.get_feature_names()
    assert names == ["1", "x", "x^2", "sign(x)"]
    np.testing.assert_allclose(
        np.asarray(model.coefficients())[0], [0, -1, 0, -2], atol=1e-6
    )


def test_inside_generalized_library_with_inputs():
    rng = np.random.default_rng(3)
    x = rng.uniform(-2, 2, size=(300, 2))
    u = rng.uniform(-3, 3, size=(300, 1))
    # x0' = -0.5 sign(x1) + 2 sat(u, 1), x1' = x0 - dz(u, 0.5)
    sat = np.clip(u[:, 0], -1, 1)
    dz = u[:, 0] - np.clip(u[:, 0], -0.5, 0.5)
    xdot = np.column_stack([-0.5 * _sign(x[:, 1]) + 2 * sat, x[:, 0] - dz])
    physics = PhysicsLibrary([Coulomb("v"), Saturation("u", 1), DeadZone("u", 0.5)])
    lib = ps.GeneralizedLibrary(
        [ps.PolynomialLibrary(degree=1), physics], inputs_per_library=[[0, 1], [1, 2]]
    )
    model = ps.SINDy(feature_library=lib, optimizer=ps.STLSQ(threshold=0.05))
    with pytest.raises(ValueError, match="pass names="):
        model.fit(x, t=0.01, x_dot=xdot, u=u, feature_names=["q", "v", "u"])
    physics.set_params(names=["v", "u"])  # the columns this library receives
    model.fit(x, t=0.01, x_dot=xdot, u=u, feature_names=["q", "v", "u"])
    assert model.get_feature_names() == [
        "1",
        "q",
        "v",
        "sign(v)",
        "sat(u, 1)",
        "dz(u, 0.5)",
    ]
    coef = np.asarray(model.coefficients())
    np.testing.assert_allclose(coef[0], [0, 0, 0, -0.5, 2, 0], atol=1e-8)
    np.testing.assert_allclose(coef[1], [0, 1, 0, 0, 0, -1], atol=1e-8)


# ----------------------------------------- SelectedFeatures / ExtendedModel
def _extended(lib):
    names = lib.get_feature_names(["q", "v"])
    coef = np.zeros((2, len(names)))
    coef[1, names.index("sign(v)")] = -2.0
    coef[1, names.index("sat(q, 1)")] = 0.5
    coef[1, names.index("tanh(v/0.5)")] = 0.3
    coef[0, names.index("v+")] = 1.5
    model = ExtendedModel(
        lambda x, t: np.column_stack([x[:, 1], -x[:, 0]]), lib, coef, ["q", "v"]
    )
    return model, coef


def test_extended_model_uses_the_library_evaluator():
    lib = PhysicsLibrary(
        [
            Coulomb("v"),
            Saturation("q", [1, 2]),
            SmoothCoulomb("v", 0.5),
            ViscousSplit(1),
        ],
        include_bias=True,
        names=["q", "v"],
        smoothing=0,  # exact kinks: the correction must equal transform's
    ).fit(np.zeros((2, 2)))
    model, coef = _extended(lib)
    assert model._features.is_fast and model._features._own
    z = np.random.default_rng(4).uniform(-3, 3, size=(100, 2))
    np.testing.assert_allclose(
        model.correction(z), np.asarray(lib.transform(z)) @ coef.T, atol=1e-13
    )
    # gradients: exact against central differences away from the kinks
    z = z[np.all(np.abs(np.abs(z) - 1) > 1e-2, axis=1) & (np.abs(z[:, 1]) > 1e-2)]
    feats = model._features
    grad = feats.gradient(z)
    h = 1e-6
    for v in range(2):
        step = np.zeros(2)
        step[v] = h
        numeric = (feats(z + step) - feats(z - step)) / (2 * h)
        np.testing.assert_allclose(grad[:, :, v], numeric, rtol=1e-6, atol=1e-8)
    # a subset of the selected columns, in the order asked
    np.testing.assert_array_equal(feats(z, [2, 0]), feats(z)[:, [2, 0]])
    np.testing.assert_array_equal(feats.gradient(z, [1]), grad[:, [1]])


class _LyingLibrary(PhysicsLibrary):
    """``evaluate`` disagrees with ``transform``: must not be trusted."""

    def evaluate(self, z, indices=None):
        return super().evaluate(z, indices) + 1.0


def test_selected_features_fall_back_when_evaluate_disagrees():
    lib = _LyingLibrary([Coulomb(1), Saturation(0, 1)], names=["q", "v"])
    lib.fit(np.zeros((2, 2)))
    z = np.random.default_rng(6).uniform(-2, 2, size=(30, 2))
    sel = SelectedFeatures(lib, ["q", "v"], [0, 1], z)
    assert not sel.is_fast
    np.testing.assert_allclose(sel(z), np.asarray(lib.transform(z)))
    # gradient by central differences of transform, away from the kinks
    ok = (np.abs(z[:, 1]) > 1e-2) & (np.abs(np.abs(z[:, 0]) - 1) > 1e-2)
    grad = sel.gradient(z[ok])
    np.testing.assert_allclose(grad[:, 0], 0.0, atol=1e-6)
    np.testing.assert_allclose(grad[:, 1, 0], (np.abs(z[ok, 0]) < 1).astype(float))


def test_selected_features_with_unresolved_names_use_transform_path():
    lib = PhysicsLibrary([Coulomb("v")]).fit(np.zeros((2, 2)))
    sel = SelectedFeatures(lib, ["q", "v"], [0], np.zeros((4, 2)))
    assert not sel.is_fast  # evaluate refused (no names): no fast path claimed


def test_selected_features_keep_the_parsed_path_for_other_libraries():
    z = np.random.default_rng(7).normal(size=(20, 2))
    lib = ps.PolynomialLibrary(degree=2).fit(z)
    sel = SelectedFeatures(lib, ["a", "b"], [1, 4], z)
    assert sel.is_fast and not sel._own


# ------------------------------------------------------------- bad input
def _lib(*effects, **kw):
    return PhysicsLibrary(list(effects), **kw)


ONES = readonly(np.ones((3, 3)))

BAD_INPUTS = [
    Bad("width 0", lambda tmp: SmoothCoulomb("v", 0), ValueError, r"width must be"),
    Bad("width neg", lambda tmp: SmoothCoulomb("v", -1e-3), ValueError, "positive"),
    Bad("width str", lambda tmp: SmoothCoulomb("v", "1"), TypeError, r"width must"),
    Bad("velocity 0", lambda tmp: Stribeck("v", 0.0), ValueError, r"velocity must"),
    Bad("velocity inf", lambda tmp: Stribeck(1, np.inf), ValueError, r"finite"),
    Bad("sat level 0", lambda tmp: Saturation("u", [1, 0]), ValueError, r"levels must"),
    Bad("sat empty", lambda tmp: Saturation("u", []), ValueError, r"levels must not"),
    Bad("sat dup", lambda tmp: Saturation("u", [1, 1.0]), ValueError, r"duplicates"),
    Bad("dz width neg", lambda tmp: DeadZone("u", -1), ValueError, r"widths must"),
    Bad("over nan", lambda tmp: Overflow("h", np.nan), ValueError, r"levels must be"),
    Bad("over str", lambda tmp: Overflow("h", "10"), TypeError, r"levels must be"),
    Bad("variable float", lambda tmp: Coulomb(1.0), TypeError, r"variable must"),
    Bad("variable neg", lambda tmp: Coulomb(-1), ValueError, r"variable must"),
    Bad("variable bool", lambda tmp: Coulomb(True), TypeError, r"variable must"),
    Bad("variable empty", lambda tmp: Torricelli(""), ValueError, r"variable must"),
    Bad("no columns", lambda tmp: _lib(), ValueError, r"effects is empty"),
    Bad(
        "not a list",
        lambda tmp: _lib(Coulomb(0)).set_params(effects=Coulomb(0)).fit(ONES),
        TypeError,
        r"effects must be a list",
    ),
    Bad(
        "not an effect",
        lambda tmp: _lib(Coulomb(0), np.sign),
        TypeError,
        r"effects\[1\] must be an effect",
    ),
    Bad(
        "unknown name",
        lambda tmp: _lib(Coulomb("w"), names=NAMES),
        ValueError,
        r"names has no variable 'w'",
    ),
    Bad(
        "index vs names",
        lambda tmp: _lib(Coulomb(3), names=NAMES),
        ValueError,
        r"variable 3 of effect Coulomb\(3\) is out of range",
    ),
    Bad(
        "index vs data",
        lambda tmp: _lib(Coulomb(3)).fit(ONES),
        ValueError,
        r"out of range",
    ),
    Bad(
        "names vs data",
        lambda tmp: _lib(Coulomb(0), names=["a", "b"]).fit(ONES),
        ValueError,
        r"names has 2 names",
    ),
    Bad(
        "names dup",
        lambda tmp: _lib(Coulomb(0), names=["a", "a", "b"]),
        ValueError,
        r"names contains duplicates",
    ),
    Bad(
        "names str",
        lambda tmp: _lib(Coulomb(0), names="qvu"),
        TypeError,
        r"names must be a list",
    ),
    Bad(
        "bias not bool",
        lambda tmp: _lib(Coulomb(0), include_bias=1),
        TypeError,
        r"include_bias must be",
    ),
    Bad(
        "same column twice",
        lambda tmp: _lib(Coulomb("v"), Coulomb(1), names=NAMES).fit(ONES),
        ValueError,
        r"repeats a column",
    ),
    Bad(
        "unresolved transform",
        lambda tmp: _lib(Coulomb("v")).fit(ONES).transform(ONES),
        ValueError,
        r"pass names=",
    ),
    Bad(
        "transform width",
        lambda tmp: _lib(Coulomb(0)).fit(ONES).transform(np.ones((3, 2))),
        ValueError,
        r"x must have 3 feature columns",
    ),
    Bad(
        "evaluate width",
        lambda tmp: _lib(Coulomb(0)).fit(ONES).evaluate(np.ones((3, 2))),
        ValueError,
        r"z must have shape",
    ),
    Bad(
        "evaluate index",
        lambda tmp: _lib(Coulomb(0)).fit(ONES).evaluate(ONES, [1]),
        IndexError,
        r"indices must be column numbers below 1",
    ),
    Bad(
        "kinked index",
        lambda tmp: _lib(Coulomb(0)).kinked_columns([2]),
        IndexError,
        r"indices must be column numbers below 1",
    ),
    Bad(
        "input_features count",
        lambda tmp: _lib(Coulomb(0)).fit(ONES).get_feature_names(["a"]),
        ValueError,
        r"input_features must have 3",
    ),
    Bad(
        "sparse",
        lambda tmp: _lib(Coulomb(0)).fit(
            __import__("scipy").sparse.csr_matrix(np.ones((3, 3)))
        ),
        TypeError,
        r"dense",
    ),
]


@pytest.mark.parametrize("case", params(BAD_INPUTS))
def test_bad_input(case, tmp_path, no_long_computation):
    assert_raises_as_documented(case, tmp_path)


def test_docstring_example_runs():
    import doctest

    from pysindy_mme.feature_library import physics

    result = doctest.testmod(physics)
    assert result.attempted >= 4 and result.failed == 0


SMOOTHED = [
    Coulomb("v"),
    Stribeck("v", 0.5),
    ViscousSplit("v"),
    Saturation("v", 1),
    DeadZone("v", 1),
    Torricelli("v"),
    Overflow("v", 1),
]


def test_smoothing_widths_follow_the_variable_spread():
    z = _data()
    lib = PhysicsLibrary(SMOOTHED, include_bias=True, names=NAMES, smoothing=0.01)
    lib.fit(z)
    spread = np.std(z[:, 1])
    # bias first, then every kinked column at 1 % of v's sd
    np.testing.assert_allclose(lib.widths_, [0.0] + [0.01 * spread] * 8)
    exact = PhysicsLibrary(SMOOTHED, names=NAMES, smoothing=0).fit(z)
    np.testing.assert_array_equal(exact.widths_, 0.0)
    np.testing.assert_array_equal(exact.evaluate(z), np.asarray(exact.transform(z)))
    # transform is exact whatever the smoothing
    np.testing.assert_array_equal(
        np.asarray(lib.transform(z)), lib.evaluate(z, exact=True)
    )


def test_smoothed_columns_match_exact_ones_beyond_a_few_widths():
    z = _data()
    lib = PhysicsLibrary(SMOOTHED, names=NAMES, smoothing=0.01).fit(z)
    w = lib.widths_[0]
    exact = lib.evaluate(z, exact=True)
    smooth = lib.evaluate(z)
    # distance of each row to the nearest kink of each column
    v = z[:, 1]
    kinks = [[0.0], [0.0], [0.0], [0.0], [-1.0, 1.0], [-1.0, 1.0], [0.0], [1.0]]
    for j, at in enumerate(kinks):
        far = np.min(np.abs(v[:, None] - np.array(at)[None, :]), axis=1) > 40 * w
        # tanh and softplus approach their limits like e^(-40), about 1e-18
        # of w; Torricelli's square root of it like its square root
        atol = 1e-9 if j == 6 else 1e-12
        np.testing.assert_allclose(smooth[far, j], exact[far, j], atol=atol)
    # everywhere: a ramp is off by at most w log 2, a step by at most 1
    ramps = [2, 3, 4, 5, 7]
    assert np.max(np.abs(smooth[:, ramps] - exact[:, ramps])) <= 2 * w * np.log(2)


def test_smoothed_gradients_match_central_differences_through_the_kinks():
    lib = PhysicsLibrary(SMOOTHED, names=NAMES, smoothing=0.05).fit(_data())
    w = lib.widths_[0]
    v = np.linspace(-1.2, 1.2, 97)
    v = v[np.abs(v) > 0.1 * w]  # Torricelli's sqrt of a softplus is smooth at 0
    z = np.column_stack([np.zeros_like(v), v, np.zeros_like(v)])
    h = 1e-7
    step = np.array([0.0, h, 0.0])
    numeric = (lib.evaluate(z + step) - lib.evaluate(z - step)) / (2 * h)
    np.testing.assert_allclose(lib.gradient(z)[:, :, 1], numeric, rtol=1e-5, atol=1e-6)
    # the exact sign has no derivative at its jump; the smoothed one is 1/w
    at0 = np.array([[0.0, 0.0, 0.0]])
    assert lib.gradient(at0)[0, 0, 1] == pytest.approx(1.0 / w)


@pytest.mark.parametrize("bad", [-1e-3, float("nan"), "1e-3", True])
def test_smoothing_must_be_a_non_negative_number(bad):
    with pytest.raises(ValueError, match="smoothing"):
        PhysicsLibrary([Coulomb("v")], names=NAMES, smoothing=bad)
