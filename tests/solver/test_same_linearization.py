"""The test that a full step left the linearisation unchanged (a linear
problem solved exactly) against the plain whole-array comparison it speeds up.
"""

import numpy as np
import pytest

from pysindy_mme.solver.gauss_newton import GaussNewton
from pysindy_mme.solver.records import Linearization


class _Solver(GaussNewton):
    def scale(self, x):
        return float(np.max(np.abs(x)))


def _reference(old, new, tol=1e-8):
    def same(a, b, floor):
        scale = max(floor, float(np.max(np.abs(a), initial=0.0)))
        return np.max(np.abs(b - a), initial=0.0) <= tol * scale

    return bool(
        same(old.A, new.A, 1.0)
        and same(old.G, new.G, 1e-300)
        and same(old.B, new.B, 1e-300)
        and np.max(np.abs(new.defects), initial=0.0)
        <= tol * float(np.max(np.abs(new.x)))
    )


def _lin(N, q, p, seed):
    rng = np.random.default_rng(seed)
    n = 2
    return Linearization(
        x=rng.standard_normal((N, n)),
        d=np.zeros((N - 1, q)),
        theta=np.zeros(p),
        A=rng.standard_normal((N - 1, n, n)),
        G=rng.standard_normal((N - 1, n, q)),
        B=rng.standard_normal((N - 1, n, p)),
        defects=np.zeros((N - 1, n)),
        r=np.zeros((N, 1)),
        H=np.eye(2)[:1],
    )


def _changed(lin, name, row, by):
    out = Linearization(**{k: getattr(lin, k).copy() for k in lin.__dataclass_fields__})
    arr = getattr(out, name)
    arr[row].flat[0] += by
    return out


@pytest.mark.parametrize("q, p", [(0, 3), (1, 0), (0, 0)])
@pytest.mark.parametrize("N", [50, 10_001])
def test_same_linearization_agrees_with_the_whole_array_test(N, q, p):
    old = _lin(N, q, p, 0)
    cases = [old, _changed(old, "A", 0, 1e-12)]
    # a change on one interval the probe skips, and on one it sees
    for name in ["A", "G", "B"]:
        if getattr(old, name).size:
            for row in [1, N // 2 + 1, N - 2]:
                cases += [
                    _changed(old, name, row, 1e-3),
                    _changed(old, name, row, 1e-9),
                ]
    cases.append(_changed(old, "defects", N // 3, 1.0))
    solver = _Solver()
    answers = []
    for new in cases:
        got = solver._same_quadratic_model(old, new)
        assert got == _reference(old, new)
        answers.append(got)
    assert True in answers and False in answers
    # a stack of measurement Jacobians (nonlinear measurement): never linear
    stacked = Linearization(**{**old.__dict__, "H": np.ones((N, 1, 2))})
    assert not solver._same_quadratic_model(old, stacked)


def test_a_feasible_stationary_point_ends_the_fit_one_iteration_earlier(monkeypatch):
    # On 10^5 samples the merit's slope (the cost's plus mu times the sum of
    # the defects) stays above the tolerance while every defect is at
    # rounding level; the fit that stops there takes the step that closes
    # them and ends where one more iteration would: the same cost and
    # coefficients to far below their standard errors.
    from pysindy_mme.solver import gauss_newton as gn
    from pysindy_mme.solver.output_error import OutputErrorModel
    from pysindy_mme.systems import van_der_pol

    from .test_lean_confirmation import _features, _ignorance

    system = van_der_pol()
    data = system.measure(3, t=system.time(10, 10_000))
    engine = OutputErrorModel(
        _ignorance, 2, _features, data.y, data.t, None, np.eye(1) * 0.01, np.eye(2)[:1]
    )
    slots = [(1, 1), (1, 2), (1, 7)]
    start = data.x + 0.05 * np.random.default_rng(0).standard_normal(data.x.shape)
    theta0 = np.array([-0.9, 0.9, -0.9])
    fits = {}
    default = gn.FEASIBLE
    for feasible in [default, -1.0]:  # -1: the merit's slope alone
        monkeypatch.setattr(gn, "FEASIBLE", feasible)
        fits[feasible] = engine.fit(slots, theta0, start, max_iter=50, tol=1e-9)
    new, old = fits[default], fits[-1.0]
    assert new.converged and old.converged
    assert new.n_iter == old.n_iter - 1
    assert new.cost == pytest.approx(old.cost, rel=1e-12)
    np.testing.assert_allclose(
        new.theta, old.theta, rtol=0, atol=1e-3 * new.std_errors.min()
    )
    assert new.joined
