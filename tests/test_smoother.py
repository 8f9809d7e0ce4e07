"""The MME solver against independent references.

1. For a linear assumed model and a fixed W, MME is the maximum a posteriori
   estimate of a linear Gaussian state-space model (process noise
   ``d_k ~ N(0, (h_k W)^-1)`` held over each interval, flat prior on
   ``x_0``), so it must equal a Kalman filter + Rauch-Tung-Striebel smoother
   written here from scratch with the exact discretisation (matrix
   exponentials) and a diffuse prior.
2. Its marginal likelihood must equal the Kalman filter's prediction-error
   decomposition (with the diffuse prior's normalisation removed).
3. For the integrated random walk (``x1' = x2, x2' = d``) it must approach
   the continuous-time smoother of the ``derivative`` package as the sampling
   gets finer, at the rate the zero-order hold predicts.
"""

import numpy as np
import pytest
from derivative import Kalman
from scipy.linalg import expm

from pysindy_mme import MME
from pysindy_mme.smoother import MMESmoother
from pysindy_mme.systems import duffing, van_der_pol

# ---------------------------------------------------------------- reference


def _discretise(A, B, h):
    """Exact ZOH discretisation: Phi = e^{Ah}, Gamma = int_0^h e^{As} ds B."""
    n, q = B.shape
    M = np.zeros((n + q, n + q))
    M[:n, :n] = A
    M[:n, n:] = B
    E = expm(M * h)
    return E[:n, :n], E[:n, n:]


def kalman_rts(A, B, C, R, W, y, t, p0=1e8):
    """Kalman filter + RTS smoother for x' = A x + B d, y = C x + v.

    ``d`` is constant on each interval with covariance ``(h W)^-1``, which is
    the ZOH reading of the MME cost; the prior on ``x_0`` is ``N(0, p0 I)``.
    Missing measurements (NaN) are skipped. (``p0 = 1e10`` would lose about
    six digits to cancellation in the covariance update; ``1e8`` is diffuse
    enough that its pull on the estimate is below 1e-7.) Returns the
    smoothed states, the smoothed model errors on the intervals, and
    ``-2 log p(y)`` (prediction error decomposition).
    """
    N, n = len(t), A.shape[0]
    Winv = np.linalg.inv(W)
    xf = np.zeros((N, n))
    Pf = np.zeros((N, n, n))
    xp = np.zeros((N, n))
    Pp = np.zeros((N, n, n))
    Phis, Gams = [], []
    x, P = np.zeros(n), p0 * np.eye(n)
    n2ll = 0.0
    for k in range(N):
        if k > 0:
            h = t[k] - t[k - 1]
            Phi, Gam = _discretise(A, B, h)
            Phis.append(Phi)
            Gams.append(Gam)
            x = Phi @ x
            P = Phi @ P @ Phi.T + Gam @ (Winv / h) @ Gam.T
        xp[k], Pp[k] = x, P
        ok = ~np.isnan(y[k])
        if ok.any():
            Ck, Rk = C[ok], R[np.ix_(ok, ok)]
            e = y[k, ok] - Ck @ x
            S = Ck @ P @ Ck.T + Rk
            K = P @ Ck.T @ np.linalg.inv(S)
            x = x + K @ e
            P = (np.eye(n) - K @ Ck) @ P
            P = 0.5 * (P + P.T)
            n2ll += np.linalg.slogdet(S)[1] + e @ np.linalg.solve(S, e)
            n2ll += ok.sum() * np.log(2 * np.pi)
        xf[k], Pf[k] = x, P
    xs = xf.copy()
    ds = np.zeros((N - 1, B.shape[1]))
    for k in range(N - 2, -1, -1):
        Gk = Pf[k] @ Phis[k].T @ np.linalg.inv(Pp[k + 1])
        xs[k] = xf[k] + Gk @ (xs[k + 1] - xp[k + 1])
        h = t[k + 1] - t[k]
        # E[d_k | y]: d_k is independent of y_0..y_k, so it is updated only
        # through x_{k+1}: Cov(d_k, x_{k+1}) = (hW)^-1 Gamma^T.
        ds[k] = (
            (Winv / h) @ Gams[k].T @ np.linalg.solve(Pp[k + 1], xs[k + 1] - xp[k + 1])
        )
    # remove the prior's normalisation: a flat prior has density 1, the
    # N(0, p0 I) prior (2 pi p0)^{-n/2}
    n2ll -= n * np.log(2 * np.pi * p0)
    return xs, ds, n2ll


def _irregular_times(rng, n, mean_step):
    return np.concatenate([[0.0], np.cumsum(mean_step * rng.uniform(0.5, 1.5, n - 1))])


# ------------------------------------------------------------------- tests


@pytest.mark.parametrize("case", ["one_channel", "two_channels_full_R"])
def test_linear_model_equals_kalman_rts_smoother(case):
    """Irregular steps and missing samples included."""
    system = duffing()  # its assumed model is the linear damped oscillator
    rng = np.random.default_rng(3)
    t = _irregular_times(rng, 300, 0.05)
    A = np.array([[0.0, 1.0], [-1.0, -0.1]])
    x_true = system.simulate(t)
    if case == "one_channel":
        C = np.array([[1.0, 0.0]])
        R = np.array([[0.01]])
        B_idx = [1]
        W = np.array([[3.0]])
        kwargs = dict(measured=[0], noise_variance=0.01, error_states=[1], W=3.0)
    else:
        C = np.array([[1.0, 0.5], [0.2, -1.0]])
        R = np.array([[0.02, 0.006], [0.006, 0.01]])
        B_idx = [0, 1]
        W = np.array([[40.0, 5.0], [5.0, 2.0]])
        kwargs = dict(measurement_matrix=C, noise_variance=R, error_states=B_idx, W=W)
    y = x_true @ C.T + rng.multivariate_normal(np.zeros(len(R)), R, size=t.size)
    y[rng.choice(t.size, 30, replace=False), 0] = np.nan  # missing samples
    y_before = y.copy()

    # 4 RK4 sub-steps: the discretisation error of the transition matrices
    # (exact matrix exponentials here) then stays below 1e-7
    mme = MME(system.assumed_model, 2, n_substeps=4, **kwargs).fit(y, t)
    B = np.eye(2)[:, B_idx]
    xs, ds, n2ll = kalman_rts(A, B, C, R, W, y, t)

    np.testing.assert_array_equal(y, y_before)  # input untouched
    assert mme.converged_
    np.testing.assert_allclose(mme.smoothed_x_, xs, rtol=0, atol=1e-6)
    np.testing.assert_allclose(mme.d_intervals_, ds, rtol=1e-6, atol=1e-6)
    # the marginal likelihood is the Kalman filter's prediction-error one
    assert mme.log_likelihood_ == pytest.approx(-0.5 * n2ll, abs=1e-4)
    # d on the sample grid: mean of the adjacent intervals, one-sided at ends
    grid, di = mme.d_[:, B_idx], mme.d_intervals_
    np.testing.assert_allclose(grid[1:-1], 0.5 * (di[1:] + di[:-1]), rtol=1e-12)
    np.testing.assert_allclose(grid[[0, -1]], di[[0, -1]], rtol=1e-12)
    if len(B_idx) == 1:
        assert np.all(np.delete(mme.d_, B_idx, axis=1) == 0.0)


def test_maximum_likelihood_W_maximises_the_kalman_likelihood():
    """W='ml' lands on the maximum of the independent Kalman likelihood."""
    system = duffing()
    m = system.measure(5, t=np.arange(0, 15, 0.05))
    A = np.array([[0.0, 1.0], [-1.0, -0.1]])
    mme = MME(
        system.assumed_model,
        2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
        W="ml",
    ).fit(m.y, m.t)
    C, R, B = np.array([[1.0, 0.0]]), np.array([[0.01]]), np.array([[0.0], [1.0]])

    def ll(w):
        return -0.5 * kalman_rts(A, B, C, R, np.array([[w]]), m.y, m.t)[2]

    best = ll(mme.W_)
    assert best >= ll(mme.W_ * 1.05) and best >= ll(mme.W_ / 1.05)
    assert mme.log_likelihood_ == pytest.approx(best, abs=1e-4)


def test_integrated_random_walk_approaches_continuous_kalman():
    """MME with x1' = x2, x2' = d against ``derivative.Kalman``.

    ``derivative.Kalman(alpha)`` minimises ``sum (y - x)^2 + alpha int d^2``
    with ``d`` continuous white noise (its per-step covariance
    ``[[h, h^2/2], [h^2/2, h^3/3]]`` is the exact minimum-energy transfer),
    so it is the continuous-time MME with ``alpha = R W``. Our ``d`` is held
    constant over each step, whose covariance ``(1/(hW)) G G^T`` with
    ``G = [h^2/2, h]`` equals the continuous one except in the position
    entry: ``h^3/(4W)`` instead of ``h^3/(3W)``. The position increment the
    hold cannot represent is ``~ |d'| h^3 / 12`` per step; the smoother
    averages over ``~ tau / h`` steps, where ``tau = (R W)^(1/4)`` is its
    time constant, and its ``d`` has amplitude ``~ sigma / tau^2`` and varies
    on the scale ``tau``, so ``|d'| ~ sigma / tau^3``. The estimates therefore
    differ by ``~ sigma (h / tau)^2 / 12`` in position and ``~ 1/tau`` times
    that in velocity, vanishing as ``h^2``: at coarse sampling (``h`` not
    small against ``tau``) the two estimators genuinely differ. We allow 12
    times the estimate (a constant 1 instead of 1/12) in position and 3 (1/4)
    in velocity, and check the second-order rate on the velocity.
    """
    system = van_der_pol()
    W, R = 5.0, 0.01
    tau, sigma = (R * W) ** 0.25, np.sqrt(R)
    diffs = []
    for rate in (100.0, 200.0):
        t = np.arange(0.0, 5.0 + 1e-9, 1.0 / rate)
        m = system.measure(1, t=t)
        mme = MME(
            system.assumed_model,
            2,
            measured=[0],
            noise_variance=R,
            error_states=[1],
            W=W,
        ).fit(m.y, m.t)
        k = Kalman(alpha=R * W)
        x_hat = np.array(list(k.compute_x_for(t, m.y[:, 0], range(t.size))))
        v_hat = np.array(list(k.compute_for(t, m.y[:, 0], range(t.size))))
        h = 1.0 / rate
        bound = sigma * (h / tau) ** 2
        d_pos = np.max(np.abs(mme.smoothed_x_[:, 0] - x_hat))
        d_vel = np.max(np.abs(mme.smoothed_x_[:, 1] - v_hat))
        assert d_pos <= bound, (rate, d_pos, bound)
        assert d_vel <= 3.0 * bound / tau, (rate, d_vel, 3 * bound / tau)
        diffs.append(d_vel)
    # halving h divides the velocity difference by about 4 (at least 2.5)
    assert diffs[0] / diffs[1] >= 2.5


def test_blockwise_integration_matches_one_block(monkeypatch):
    """Long records are integrated in blocks of intervals; nothing changes."""
    system = van_der_pol()
    m = system.measure(4)
    kw = dict(measured=[0], noise_variance=0.01, error_states=[1], W=5.0)
    whole = MME(system.true_model, 2, **kw).fit(m.y, m.t)
    monkeypatch.setattr(MMESmoother, "_CHUNK", 37)
    blocks = MME(system.true_model, 2, **kw).fit(m.y, m.t)
    np.testing.assert_allclose(blocks.smoothed_x_, whole.smoothed_x_, rtol=1e-12)
    np.testing.assert_allclose(blocks.d_, whole.d_, rtol=1e-10, atol=1e-12)
