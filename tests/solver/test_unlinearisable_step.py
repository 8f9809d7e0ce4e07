"""A Gauss-Newton step whose merit goes down but whose new point cannot be
linearised (a square-root outflow with an RK4 stage just above an empty
tank amplifies a perturbation a million-fold there) is shortened, as a step
whose merit did not go down would be, instead of ending the fit."""

import numpy as np
import pytest

from pysindy_mme import MME
from pysindy_mme.exceptions import DivergenceError
from pysindy_mme.solver.transcription import MMESmoother
from pysindy_mme.systems import van_der_pol

SYSTEM = van_der_pol()
DATA = SYSTEM.measure(0, t=SYSTEM.time(10, 40))


def _mme():
    return MME(
        SYSTEM.assumed_model, 2, measured=[0], noise_variance=0.01, error_states=[1]
    )


def _refusing(monkeypatch, refuse):
    """Make ``MMESmoother.linearize`` raise on the calls ``refuse(k)`` picks
    (k counts calls from 1); returns the list of the points asked for."""
    original = MMESmoother.linearize
    calls, points = [0], []

    def linearize(self, x, d, theta=None):
        calls[0] += 1
        points.append(x.copy())
        if refuse(calls[0]):
            raise DivergenceError("assumed_model amplifies perturbations (test)")
        return original(self, x, d, theta)

    monkeypatch.setattr(MMESmoother, "linearize", linearize)
    return points


def test_a_refused_point_shortens_the_step_and_the_fit_ends_where_it_did(
    monkeypatch,
):
    reference = _mme().fit(DATA.y, DATA.t)
    # the first Gauss-Newton step's full-length point is refused
    points = _refusing(monkeypatch, lambda k: k == 2)
    got = _mme().fit(DATA.y, DATA.t)
    assert got.converged_
    # the retried point lies on the same direction, at half the length
    start, refused, retried = points[0], points[1], points[2]
    np.testing.assert_allclose(retried - start, 0.5 * (refused - start), atol=1e-12)
    np.testing.assert_allclose(got.smoothed_x_, reference.smoothed_x_, atol=1e-5)
    np.testing.assert_allclose(got.d_, reference.d_, atol=1e-4)
    assert got.W_ == pytest.approx(reference.W_, rel=1e-4)


def test_a_model_that_cannot_be_linearised_anywhere_still_raises(monkeypatch):
    # every point after the start is refused: the step shrinks to nothing
    # and the model's own error is raised, not a hang or a silent stop
    _refusing(monkeypatch, lambda k: k > 1)
    with pytest.raises(DivergenceError, match="amplifies perturbations"):
        _mme().fit(DATA.y, DATA.t)
