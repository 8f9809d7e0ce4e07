"""The MME solver against independent references.

1. For a linear assumed model and a fixed W, MME is the maximum a posteriori
   estimate of a linear Gaussian state-space model (process noise
   ``d_k ~ N(0, (h_k W)^-1)`` held over each interval, flat prior on
   ``x_0``), so it must equal a Kalman filter + Rauch-Tung-Striebel smoother
   written from scratch with the exact discretisation (matrix exponentials)
   and a diffuse prior (``tests/kalman_reference.py``).
2. Its marginal likelihood must equal the Kalman filter's prediction-error
   decomposition (with the diffuse prior's normalisation removed).
3. For the integrated random walk (``x1' = x2, x2' = d``) it must approach
   the continuous-time smoother of the ``derivative`` package as the sampling
   gets finer, at the rate the zero-order hold predicts.
4. A change of units ``x -> c x`` maps the problem onto itself (the model,
   the measurement and ``R``, ``W`` transformed accordingly), so the estimate
   must transform exactly, and the marginal likelihood as a density does.

The W search is tested in ``test_weight.py``, the failure diagnosis
(observability) in ``test_observability.py``.
"""

import numpy as np
import pytest
from derivative import Kalman
from kalman_reference import kalman_rts

from pysindy_mme import MME
from pysindy_mme.solver import MMESmoother, internal_unit
from pysindy_mme.systems import duffing, van_der_pol


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


@pytest.mark.parametrize("measurement", ["matrix", "function"])
def test_random_walk_error_model_equals_augmented_kalman_smoother(measurement):
    """``error_model="random_walk"``: d is a state with d' = w, W weighs w.

    The reference is the same Kalman + RTS smoother on the augmented linear
    system ``[x, d]' = [[A, B], [0, 0]] [x, d] + [0, I] w``; irregular steps,
    missing samples, a nonlinear-looking measurement callable with its
    Jacobian, and the likelihood included.
    """
    system = duffing()
    rng = np.random.default_rng(11)
    t = _irregular_times(rng, 250, 0.05)
    A = np.array([[0.0, 1.0], [-1.0, -0.1]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.0]])
    R = np.array([[0.01]])
    W = np.array([[0.7]])
    y = system.simulate(t)[:, :1] + 0.1 * rng.standard_normal((t.size, 1))
    y[rng.choice(t.size, 20, replace=False)] = np.nan
    if measurement == "matrix":
        kwargs = dict(measured=[0])
    else:
        kwargs = dict(
            measurement_function=lambda x: x[:, :1].copy(),
            measurement_jacobian=lambda x: np.tile(C, (len(x), 1, 1)),
        )
    mme = MME(
        system.assumed_model,
        2,
        noise_variance=0.01,
        error_states=[1],
        error_model="random_walk",
        W=0.7,
        n_substeps=4,
        **kwargs,
    ).fit(y, t)
    A_aug = np.block([[A, B], [np.zeros((1, 3))]])
    B_aug = np.array([[0.0], [0.0], [1.0]])
    C_aug = np.hstack([C, np.zeros((1, 1))])
    zs, ws, n2ll = kalman_rts(A_aug, B_aug, C_aug, R, W, y, t)

    assert mme.converged_
    np.testing.assert_allclose(mme.smoothed_x_, zs[:, :2], rtol=0, atol=1e-6)
    np.testing.assert_allclose(mme.d_[:, 1], zs[:, 2], rtol=0, atol=1e-6)
    assert np.all(mme.d_[:, 0] == 0.0)
    np.testing.assert_allclose(
        mme.d_intervals_[:, 0], 0.5 * (zs[1:, 2] + zs[:-1, 2]), atol=1e-6
    )
    assert mme.log_likelihood_ == pytest.approx(-0.5 * n2ll, abs=1e-4)
    # derivative_ is the base model plus d at the estimate
    np.testing.assert_allclose(
        mme.derivative_, zs[:, :2] @ A.T + zs[:, 2:] @ B.T, atol=1e-5
    )


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


# ------------------------------------------------------------------- units


def _duffing_in_units(c):
    """Duffing (cubic) model and a nonlinear measurement in units of ``1/c``:
    ``x_c = c x``, so ``f_c(x_c) = c f(x_c / c)``, ``g_c(x_c) = c g(x_c / c)``."""
    system = duffing()

    def model(x, t):
        return c * system.assumed_model(x / c, t)

    def measurement(x):
        x = x / c
        return c * np.column_stack([x[:, 0], x[:, 0] + 0.3 * x[:, 0] * x[:, 1]])

    return model, measurement


@pytest.mark.parametrize("unit", [1e-9, 3.7, 1e10])
@pytest.mark.parametrize("W", [5.0, "ml"])
def test_estimate_transforms_exactly_under_a_change_of_units(unit, W):
    """The same problem in units of 1e-9 .. 1e10: x, d, W, the ratio and the
    cost transform exactly; ``log p(y)`` as a density of ``N_obs`` values
    given ``n`` free initial states: ``- (N_obs - n) log(unit)``.

    Before the solver worked in internal units, the KKT pivots (R^-1 against
    h W^-1) spread over ~unit^4 and these problems were rejected as singular.
    """
    m = duffing().measure(2, t=np.arange(0, 10, 0.05))
    y = np.column_stack([m.y[:, 0], m.x[:, 0] + 0.3 * m.x[:, 0] * m.x[:, 1]])
    y[:, 1] += 0.05 * np.random.default_rng(0).standard_normal(len(y))
    y[::9, 1] = np.nan  # missing values count out of N_obs
    R = np.array([0.01, 0.0025])
    fits = []
    for c in (1.0, unit):
        model, g = _duffing_in_units(c)
        w = W if isinstance(W, str) else W / c**2
        mme = MME(
            model,
            2,
            measurement_function=g,
            noise_variance=R * c**2,
            error_states=[1],
            W=w,
        )
        fits.append(mme.fit(y * c, m.t))
    base, scaled = fits
    assert base.converged_ and scaled.converged_
    rtol = 1e-6
    np.testing.assert_allclose(scaled.smoothed_x_ / unit, base.smoothed_x_, rtol=rtol)
    np.testing.assert_allclose(
        scaled.d_ / unit, base.d_, rtol=rtol, atol=rtol * np.abs(base.d_).max()
    )
    assert scaled.W_ * unit**2 == pytest.approx(base.W_, rel=rtol)
    np.testing.assert_allclose(scaled.covariance_ratio_, base.covariance_ratio_, rtol)
    assert scaled.cost_ == pytest.approx(base.cost_, rel=rtol)
    n_obs = int(np.sum(~np.isnan(y)))
    shift = (n_obs - 2) * np.log(unit)
    assert scaled.log_likelihood_ + shift == pytest.approx(
        base.log_likelihood_, abs=1e-5
    )


def test_internal_unit_is_a_power_of_two_near_the_noise_sd():
    for var in (1e-20, 0.01, 1.0, 7.0, 1e30):
        s = internal_unit(np.array([[var]]))
        assert np.log2(s) == int(np.log2(s))  # exact change of units
        assert 2**-0.5 <= s / np.sqrt(var) <= 2**0.5
