"""Error models as objects: the registry, and MME working through it.

The registry (``pysindy_mme.differentiation.error_models.ERROR_MODELS``) is
the one list of error models: every name and alias resolves to its class,
and the checks of MME, discover and the command line, and the command
line's help, read it. An object is accepted as well as a name, is copied
(the caller's stays unfitted), and an unregistered subclass works through
MME unchanged: the extension point is the class, the registry only names it.
Each model's own accuracy is tested against an independent reference in
``test_transcription.py`` (white, random walk) and in the model's own test
module.
"""

import numpy as np
import pytest

from pysindy_mme import MME
from pysindy_mme.cli.parser import build_parser
from pysindy_mme.differentiation.error_models import (
    ERROR_MODELS,
    AugmentedErrorModel,
    ErrorModel,
    RandomWalk,
    WhiteNoise,
    error_model_names,
    resolve_error_model,
)
from pysindy_mme.systems import van_der_pol


def _fit(error_model, W=3.0):
    system = van_der_pol()
    m = system.measure(2)
    mme = MME(
        system.assumed_model,
        2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
        error_model=error_model,
        W=W,
    )
    return mme.fit(m.y, m.t)


def test_every_registered_name_resolves_to_its_class():
    names = error_model_names()
    for cls in ERROR_MODELS:
        assert issubclass(cls, ErrorModel)
        assert cls.name and cls.summary.startswith(cls.name)
        for key in (cls.name, *cls.aliases):
            assert names[key] is cls
            resolved = resolve_error_model(key)
            assert type(resolved) is cls
            assert repr(resolved).startswith(cls.__name__ + "(")
    assert names["white"] is WhiteNoise and names["random_walk"] is RandomWalk


def test_unknown_name_lists_every_registered_name():
    with pytest.raises(ValueError) as info:
        resolve_error_model("smooth")
    for cls in ERROR_MODELS:
        for key in (cls.name, *cls.aliases):
            assert repr(key) in str(info.value)


def test_command_line_lists_every_registered_model():
    parser = build_parser()
    sub = parser._subparsers._group_actions[0].choices["discover"]
    action = next(a for a in sub._actions if a.dest == "error_model")
    for cls in ERROR_MODELS:
        assert cls.name in action.metavar.split("|")
        assert cls.summary in action.help
        for alias in cls.aliases:
            assert alias in action.help


def test_an_object_equals_its_name_and_is_copied():
    given = RandomWalk()
    by_object = _fit(given)
    by_name = _fit("random_walk")
    np.testing.assert_array_equal(by_object.smoothed_x_, by_name.smoothed_x_)
    np.testing.assert_array_equal(by_object.d_, by_name.d_)
    assert by_object.error_model is given  # the parameter stays as given
    assert by_object.error_model_ is not given
    assert isinstance(by_name.error_model_, RandomWalk)
    assert isinstance(_fit("white").error_model_, WhiteNoise)


class _Damped(AugmentedErrorModel):
    """An unregistered model: ``d' = -d / tau + w``, tau fixed."""

    def __init__(self, tau=1.0):
        self.tau = tau

    def rate(self, q):
        return -np.eye(q) / self.tau


def test_an_unregistered_subclass_works_through_mme():
    """No registration needed to use an object; tau -> inf is the random walk."""
    damped = _fit(_Damped(tau=0.5))
    assert damped.converged_ and damped.d_.shape == (damped.t_.size, 2)
    assert np.all(damped.d_[:, 0] == 0.0)
    walk = _fit("random_walk")
    assert np.max(np.abs(damped.d_ - walk.d_)) > 1e-3  # the rate matters
    nearly_walk = _fit(_Damped(tau=1e9))
    np.testing.assert_allclose(nearly_walk.d_, walk.d_, atol=1e-6)


class _DampedWithPrior(_Damped):
    """``_Damped`` with a prior ``N(0, P)`` on each record's initial ``d``."""

    def __init__(self, tau=1.0, P=1.0):
        self.tau, self.P = tau, P

    def initial_covariance(self, W):
        return self.P * np.eye(np.shape(W)[0])


def test_a_prior_on_the_initial_model_error():
    """A vague prior is the flat one; a tight one pins d_0 to 0.

    With ``P`` far above the flat posterior variance of ``d_0`` the estimate
    is the flat prior's and ``-2 log p`` gains ``log(2 pi P)`` (the exact
    reference, a Kalman filter with the stationary prior, is in
    ``test_gauss_markov.py``).
    """
    flat = _fit(_Damped(tau=0.5))
    vague = _fit(_DampedWithPrior(tau=0.5, P=1e10))
    np.testing.assert_allclose(vague.smoothed_x_, flat.smoothed_x_, atol=1e-6)
    np.testing.assert_allclose(vague.d_, flat.d_, atol=1e-6)
    assert -2 * (vague.log_likelihood_ - flat.log_likelihood_) == pytest.approx(
        np.log(2 * np.pi * 1e10), abs=1e-3
    )
    tight = _fit(_DampedWithPrior(tau=0.5, P=1e-12))
    assert abs(tight.d_[0, 1]) < 1e-4 < abs(flat.d_[0, 1])
