"""``error_model="gauss_markov"`` (alias ``"ou"``) against independent references.

1. For a linear assumed model, fixed ``W`` and ``tau``, MME with the
   Ornstein-Uhlenbeck prior ``d' = -d / tau + w`` must equal a Kalman filter
   + RTS smoother (``tests/kalman_reference.py``) on the state augmented by
   ``d``, discretised exactly (matrix exponentials), with a diffuse prior on
   ``x_0`` and the stationary ``N(0, tau W^-1 / 2)`` on ``d_0``, and its
   marginal likelihood the filter's.
2. ``tau="auto"`` must find the maximum of that same Kalman likelihood:
   over ``tau`` at a fixed ``W``, and over ``(W, tau)`` jointly with
   ``W="ml"``, on data simulated from the prior itself.
3. The limits: ``tau -> infinity`` is the random walk; a ``tau`` short
   against the estimate's time scale is the white model with
   ``W_white = W / tau^2``.
4. It is reachable by name from ``MME``, ``discover`` and the command line.
"""

import numpy as np
import pytest
from cli_support import base_args, run, write_user_files
from kalman_reference import kalman_rts
from scipy.linalg import expm
from scipy.optimize import minimize, minimize_scalar

from pysindy_mme import MME, StudyOptions, discover
from pysindy_mme.differentiation.error_models import GaussMarkov
from pysindy_mme.systems import duffing, van_der_pol

A = np.array([[0.0, 1.0], [-1.0, -0.1]])  # duffing()'s assumed model
B = np.array([[0.0], [1.0]])
C = np.array([[1.0, 0.0]])


def _augmented(tau):
    """``[x, d]' = [[A, B], [0, -1/tau]] [x, d] + [0, 1] w``."""
    A_aug = np.block([[A, B], [np.zeros((1, 2)), -np.ones((1, 1)) / tau]])
    return A_aug, np.array([[0.0], [0.0], [1.0]]), np.hstack([C, np.zeros((1, 1))])


def _kalman_n2ll(tau, W, R, y, t, p0=1e8):
    """``-2 log p(y)``: diffuse ``x_0``, stationary ``d_0 ~ N(0, tau / (2 W))``.

    The filter half of ``kalman_rts`` (the same exact ZOH discretisation,
    ``w`` constant on each interval with covariance ``(h W)^-1``), with the
    discretisation cached per step length: fast enough for the optimisers
    below. Tied to ``kalman_rts`` in the first test.
    """
    A_aug, B_aug, C_aug = _augmented(tau)
    x = np.zeros(3)
    P = np.diag([p0, p0, tau / (2.0 * W)])
    n2ll, cache = 0.0, {}
    for k in range(len(t)):
        if k > 0:
            h = round(t[k] - t[k - 1], 12)
            if h not in cache:
                M = np.zeros((4, 4))
                M[:3, :3], M[:3, 3:] = A_aug, B_aug
                E = expm(M * h)
                cache[h] = E[:3, :3], E[:3, 3:]
            Phi, Gam = cache[h]
            x = Phi @ x
            P = Phi @ P @ Phi.T + Gam @ Gam.T / (h * W)
        if not np.isnan(y[k, 0]):
            e = y[k] - C_aug @ x
            S = C_aug @ P @ C_aug.T + R
            K = P @ C_aug.T @ np.linalg.inv(S)
            x = x + K @ e
            P = (np.eye(3) - K @ C_aug) @ P
            P = 0.5 * (P + P.T)
            n2ll += np.linalg.slogdet(S)[1] + e @ np.linalg.solve(S, e)
            n2ll += np.log(2 * np.pi)
    return n2ll - 2 * np.log(2 * np.pi * p0)


def _mme(error_model, W, **kwargs):
    return MME(
        duffing().assumed_model,
        2,
        noise_variance=0.01,
        error_states=[1],
        error_model=error_model,
        W=W,
        **kwargs,
    )


@pytest.mark.parametrize("measurement", ["matrix", "function"])
def test_fixed_tau_equals_augmented_kalman_smoother(measurement):
    """Irregular steps, missing samples, a measurement callable, the likelihood."""
    rng = np.random.default_rng(5)
    t = np.concatenate([[0.0], np.cumsum(0.05 * rng.uniform(0.5, 1.5, 249))])
    y = duffing().simulate(t)[:, :1] + 0.1 * rng.standard_normal((t.size, 1))
    y[rng.choice(t.size, 20, replace=False)] = np.nan
    tau, W, R = 0.8, 0.7, np.array([[0.01]])
    if measurement == "matrix":
        kwargs = dict(measured=[0])
    else:
        kwargs = dict(
            measurement_function=lambda x: x[:, :1].copy(),
            measurement_jacobian=lambda x: np.tile(C, (len(x), 1, 1)),
        )
    mme = _mme(GaussMarkov(tau=tau), W, n_substeps=4, **kwargs).fit(y, t)
    A_aug, B_aug, C_aug = _augmented(tau)
    stationary = ([2], np.array([[tau / (2.0 * W)]]))
    zs, _, n2ll = kalman_rts(
        A_aug, B_aug, C_aug, R, np.array([[W]]), y, t, prior=stationary
    )

    assert mme.converged_
    assert mme.error_model_.tau_ == tau and mme.error_model_.tau_history_ == []
    np.testing.assert_allclose(mme.smoothed_x_, zs[:, :2], rtol=0, atol=1e-6)
    np.testing.assert_allclose(mme.d_[:, 1], zs[:, 2], rtol=0, atol=1e-6)
    assert np.all(mme.d_[:, 0] == 0.0)
    np.testing.assert_allclose(
        mme.d_intervals_[:, 0], 0.5 * (zs[1:, 2] + zs[:-1, 2]), atol=1e-6
    )
    np.testing.assert_allclose(
        mme.derivative_, zs[:, :2] @ A.T + zs[:, 2:] @ B.T, atol=1e-5
    )
    if measurement == "matrix":
        # d starts in its stationary distribution, which the test can tell
        # from a flat prior: d_0 is pulled towards 0
        flat, _, _ = kalman_rts(A_aug, B_aug, C_aug, R, np.array([[W]]), y, t)
        assert abs(zs[0, 2] - flat[0, 2]) > 1e-3
    assert mme.log_likelihood_ == pytest.approx(-0.5 * n2ll, abs=1e-4)
    assert _kalman_n2ll(tau, W, R, y, t) == pytest.approx(n2ll, abs=1e-6)


def _ou_record(seed, tau_true=0.5, W_true=2.0, n=600, h=0.05):
    """The linear oscillator driven by a model error drawn from the OU prior."""
    rng = np.random.default_rng(seed)
    t = h * np.arange(n)
    A_aug, B_aug, C_aug = _augmented(tau_true)
    M = np.zeros((4, 4))
    M[:3, :3], M[:3, 3:] = A_aug, B_aug
    E = expm(M * h)
    z = np.array([1.0, 0.0, rng.normal(0.0, np.sqrt(tau_true / (2 * W_true)))])
    y = np.empty((n, 1))
    for k in range(n):
        y[k] = C_aug @ z + 0.1 * rng.standard_normal()
        w = rng.normal(0.0, 1.0 / np.sqrt(h * W_true))
        z = E[:3, :3] @ z + E[:3, 3] * w
    return y, t


def test_tau_at_a_fixed_W_is_the_kalman_likelihood_maximum():
    y, t = _ou_record(1)
    W, R = 2.0, np.array([[0.01]])
    mme = _mme("ou", W, measured=[0], n_substeps=2).fit(y, t)
    ref = minimize_scalar(
        lambda lt: _kalman_n2ll(np.exp(lt), W, R, y, t),
        bounds=(np.log(0.025), np.log(30.0)),
        method="bounded",
        options={"xatol": 1e-4},
    )
    fitted = mme.error_model_
    assert not fitted.tau_at_bound_
    # the search's tolerance is 2 % in tau; the criterion is flat at its top
    assert np.log(fitted.tau_) == pytest.approx(ref.x, abs=0.03)
    assert -2 * mme.log_likelihood_ == pytest.approx(ref.fun, abs=2e-3)
    assert -2 * mme.log_likelihood_ >= ref.fun - 2e-3  # never beyond the top


def test_W_ml_finds_the_joint_kalman_likelihood_maximum():
    y, t = _ou_record(2)
    R = np.array([[0.01]])
    mme = _mme("gauss_markov", "ml", measured=[0], n_substeps=2).fit(y, t)
    ref = minimize(
        lambda p: _kalman_n2ll(np.exp(p[1]), np.exp(p[0]), R, y, t),
        x0=[np.log(mme.W_) + 0.3, np.log(mme.error_model_.tau_) - 0.3],
        method="Nelder-Mead",
        options={"xatol": 1e-4, "fatol": 1e-7},
    )
    assert np.log(mme.W_) == pytest.approx(ref.x[0], abs=0.05)
    assert np.log(mme.error_model_.tau_) == pytest.approx(ref.x[1], abs=0.05)
    assert -2 * mme.log_likelihood_ == pytest.approx(ref.fun, abs=2e-3)
    # the history holds every trial tau with its W and criterion, sorted
    taus = [row[0] for row in mme.error_model_.tau_history_]
    assert taus == sorted(taus) and mme.error_model_.tau_ in taus


def test_limits_random_walk_and_white():
    """tau -> inf: the random walk; tau short: white with W / tau^2."""
    system = van_der_pol()
    m = system.measure(3)
    common = dict(measured=[0], noise_variance=0.01, error_states=[1])

    def fit(error_model, W, **kwargs):
        est = MME(system.assumed_model, 2, error_model=error_model, W=W, **common)
        return est.set_params(**kwargs).fit(m.y, m.t)

    walk = fit("random_walk", 0.1)
    long = fit(GaussMarkov(tau=1e8), 0.1)
    np.testing.assert_allclose(long.smoothed_x_, walk.smoothed_x_, atol=1e-6)
    np.testing.assert_allclose(long.d_, walk.d_, atol=1e-6)
    # white with W = 5 smooths on a time scale of (R W)^(1/4) = 0.47 s; an OU
    # with tau = 0.03 (RK4 resolving it: 4 sub-steps of 6 ms) is white on it
    white = fit("white", 5.0)
    short = fit(GaussMarkov(tau=0.03), 5.0 * 0.03**2, n_substeps=4)
    gap = np.max(np.abs(short.smoothed_x_ - white.smoothed_x_), axis=0)
    walk_gap = np.max(np.abs(walk.smoothed_x_ - white.smoothed_x_), axis=0)
    assert np.all(gap < 0.1 * walk_gap), (gap, walk_gap)
    assert gap[0] < 0.01  # a tenth of the noise sd


def test_a_w_search_warning_is_given_once_for_the_tau_chosen():
    """The constraint cannot be met at any tau (noise stated 100 times too
    large): one warning, the chosen tau's, not one per trial tau."""
    y, t = _ou_record(0)
    mme = _mme("ou", "auto", measured=[0]).set_params(noise_variance=1.0)
    with pytest.warns(UserWarning, match="covariance constraint cannot be met") as rec:
        mme.fit(y, t)
    assert sum("covariance constraint" in str(r.message) for r in rec) == 1
    assert mme.W_at_bound_


def test_bad_tau_is_named():
    with pytest.raises(ValueError, match="tau must be 'auto' or a positive number"):
        _mme(GaussMarkov(tau=-1.0), "auto", measured=[0]).fit(*_ou_record(0))
    with pytest.raises(ValueError, match="shorter than the integration step"):
        _mme(GaussMarkov(tau=0.01), "auto", measured=[0]).fit(*_ou_record(0))


def test_reachable_by_name_from_mme_discover_and_the_command_line(tmp_path):
    system = duffing()
    data = system.measure(1)
    by_alias = _mme("ou", "auto", measured=[0]).fit(data.y, data.t)
    by_name = _mme("gauss_markov", "auto", measured=[0]).fit(data.y, data.t)
    np.testing.assert_array_equal(by_alias.d_, by_name.d_)
    assert isinstance(by_alias.error_model_, GaussMarkov)
    assert by_alias.error_model == "ou"  # the parameter as given

    res = discover(
        data.y,
        data.t,
        assumed_model=system.assumed_model,
        n_states=2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
        options=StudyOptions(feature_names=list(system.feature_names)),
        mme=MME(error_model="ou"),
    )
    assert isinstance(res.mme.error_model_, GaussMarkov)
    assert set(res.terms["x2"]) == {"x1^3"}
    assert res.terms["x2"]["x1^3"] == pytest.approx(-1.0, rel=0.1)

    csv, model, _ = write_user_files(tmp_path)
    out = tmp_path / "out"
    result = run(base_args(csv, model, out, error_model="ou"))
    assert result.code == 0, result.err
    assert "x1^3" in result.out or "position^3" in result.out
