"""How far the uncertainty of a free run's initial state spreads the run.

An out-of-sample run starts from a state fitted to a short window of the
record (:func:`~.runs.determined_window`), known only to its standard
error. Along the run the model carries a change of that state with it,
damped on an attracting cycle, amplified where the model is unstable or
chaotic. Where the spread it causes in a measured channel grows past the
channel's noise, the run there is set by the window's estimate as much as
by the model: even a perfect model is expected to miss the data by more
than the noise, and an RMSE over those samples can measure the estimate,
not the model (one run's own error is one draw: it can be smaller). README,
"Known limits": the window was checked against the state's standard error,
not against the run's sensitivity to it.

:func:`run_spread` propagates the initial state's covariance along the run
with the RK4 interval maps' Jacobians (one vectorised pass and one banded
solve, linear in the run's length); :func:`determined_until` reads where
the spread first passes :data:`SPREAD_LIMIT` noise standard deviations.
The propagation is linear: past that point a real run's spread may
saturate (a chaotic attractor is bounded), but the run is no longer
determined by its start either way.
"""

from __future__ import annotations

import numpy as np

from ..core.integrate import run_jacobians, solve_recursion
from ..core.jacobian import column_scale, rowwise_jacobian

__all__ = [
    "SPREAD_LIMIT",
    "run_spread",
    "spread_columns",
    "start_covariance_of",
    "determined_until",
    "noise_covariance_of",
    "noise_share",
]

#: a run counts as determined by its initial state while the spread that
#: state's standard error causes in every measured channel is at most this
#: many of the channel's noise standard deviations (at one, a perfect
#: model's run misses the data by as much from its start as from the noise)
SPREAD_LIMIT = 1.0

#: intervals of a run propagated at once (:func:`run_spread`)
BLOCK = 1 << 16


def noise_covariance_of(fit) -> np.ndarray:
    """``fit``'s initial-state covariance from the measurement noise alone
    (a model's misfit beyond the noise is its own, not its start's): the
    fit's covariance over its residual variance times inflation, as
    :func:`~.runs._x0_relative_se` reads it. NaN where undetermined."""
    return np.asarray(fit.x0_covariance, dtype=float) / noise_share(fit)


def noise_share(fit) -> float:
    """What ``fit``'s covariances are divided by to be the noise's alone: its
    residual variance times inflation (1 where that is not a positive
    number)."""
    s2 = float(fit.residual_variance * fit.inflation)
    return s2 if np.isfinite(s2) and s2 > 0 else 1.0


def start_covariance_of(fit, n_offsets: int) -> np.ndarray:
    """``(n + n_offsets)``: the joint covariance from the noise alone of a
    window fit's initial state and its measurement offsets (the fit's last
    ``n_offsets`` quantities; none: :func:`noise_covariance_of`). A short
    window can hardly tell an offset from a shift of the state: each alone
    is uncertain, their sum much less, and a run's spread needs both."""
    x0 = noise_covariance_of(fit)
    if n_offsets == 0:
        return x0
    scale = noise_share(fit)
    off = slice(fit.theta.size - n_offsets, fit.theta.size)
    cov_off = np.asarray(fit.covariance, dtype=float)[off, off] / scale
    cross = np.asarray(fit.theta_x0_covariance, dtype=float)[off] / scale
    return np.block([[x0, cross.T], [cross, cov_off]])


def _square_root(cov) -> np.ndarray | None:
    """``L`` with ``L L^T = cov`` (None: a covariance that is not finite)."""
    cov = np.asarray(cov, dtype=float)
    if not np.all(np.isfinite(cov)):
        return None
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    return V * np.sqrt(np.clip(w, 0.0, None))


def run_spread(model, x, t, inputs, substeps, measure, x0_cov) -> np.ndarray:
    """``(N, m)``: each measured channel's standard deviation along the run
    ``x (N, n)`` from an initial state of covariance ``x0_cov`` (linear
    propagation; inf throughout when the covariance is not finite).

    ``model``, ``inputs``, ``substeps``: as the run was simulated
    (:func:`~pysindy_mme.core.integrate.simulate_guided`); ``measure``:
    ``x -> y`` for all rows (its Jacobian is taken along the run). The run
    is taken in blocks of :data:`BLOCK` intervals, each from the end of the
    one before: the memory is a block's, the cost linear in the run.
    """
    x = np.asarray(x, dtype=float)
    spread = None
    for rows, HZ in spread_columns(model, x, t, inputs, substeps, measure, x0_cov):
        if spread is None:
            spread = np.empty((x.shape[0], HZ.shape[1]))
        with np.errstate(all="ignore"):
            spread[rows] = np.sqrt(np.einsum("kcl,kcl->kc", HZ, HZ))
    return np.where(np.isfinite(spread), spread, np.inf)


def spread_columns(model, x, t, inputs, substeps, measure, x0_cov):
    """``(rows, HZ)`` along the run ``x`` in blocks: ``HZ (K, m, r)`` the
    measured channels' changes at the samples ``rows`` per column of a square
    root ``L`` of ``x0_cov`` (``H_k A_{k-1} ... A_0 L``; inf throughout when
    the covariance is not finite). Arguments as :func:`run_spread`, which
    sums their squares; :mod:`.uncertainty` needs the columns themselves.
    ``x0_cov`` may go on past the ``n`` states with one row per channel, the
    channels' offsets (:func:`start_covariance_of`): their rows of ``L`` add
    to every sample's change."""
    x = np.asarray(x, dtype=float)
    N, n = x.shape
    scale = column_scale(x)
    H = rowwise_jacobian(measure, x[:1], scale=scale)
    root = _square_root(x0_cov)
    if root is None:
        size = np.shape(x0_cov)[0]
        yield slice(0, N), np.full((N, H.shape[1], size), np.inf)
        return
    root, shift = root[:n], root[n:]  # the states' rows, the offsets'
    with np.errstate(all="ignore"):
        yield slice(0, 1), _shifted(np.einsum("kcj,jl->kcl", H, root), shift)
    Z = root  # Z_k = A_{k-1} ... A_0 L, at the sample a block starts from
    for lo, A in run_jacobians(model, x, t, inputs, substeps, BLOCK):
        K = A.shape[0]
        # Z_{k+1} = A_k Z_k over the block: one banded solve with the
        # block's first state as the forcing of its first row
        forcing = np.zeros((K, n, Z.shape[1]))
        forcing[0] = A[0] @ Z
        with np.errstate(all="ignore"):
            z, info = solve_recursion(A, forcing)
        if info != 0:
            z = np.full((K, n, Z.shape[1]), np.inf)
        rows = slice(lo + 1, lo + K + 1)
        H = rowwise_jacobian(measure, x[rows], scale=scale)
        with np.errstate(all="ignore"):
            yield rows, _shifted(np.einsum("kcj,kjl->kcl", H, z), shift)
        Z = z[-1]


def _shifted(HZ, shift):
    """``HZ`` with the offsets' rows of the root added to every sample."""
    if shift.shape[0]:
        HZ += shift[None]
    return HZ


def determined_until(spread, noise_sd, t, first: int = 0) -> float | None:
    """The first time at or after sample ``first`` at which some channel's
    ``spread`` exceeds :data:`SPREAD_LIMIT` times its ``noise_sd`` (None:
    nowhere)."""
    spread = np.asarray(spread, dtype=float)
    over = np.any(spread[first:] > SPREAD_LIMIT * np.asarray(noise_sd)[None], axis=1)
    if not over.any():
        return None
    return float(t[first + int(np.argmax(over))])
