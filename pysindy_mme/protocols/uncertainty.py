"""Whether a free run's miss of held-out data is the uncertainty of its fit.

A correct model's run on data it was not fitted to misses them by more than
the noise: its coefficients are estimates (from the rest of the record, or
from the fitting record when a validation record is given) and its start
comes from a short window. So "the held-out run is 2x the noise" says
nothing on its own: it is at the noise for a model known to many digits, and
far from it for one whose cubic coefficient is known to 10 % on a record a
third of the validation record's amplitude. README, "Known limits", until
session 30: "explained" only asked the held-out run to beat the assumed
model's by 1.1x.

:func:`run_uncertainty` measures how far the uncertainty alone moves the run.
Each quantity's share is a column of changes of the measured channels along
the run, in noise standard deviations:

* the coefficients (and grey-box parameters): one run per eigenvector of
  their covariance from the noise alone, moved one standard deviation along
  it, its start fitted to the same window again (so that a change the
  window's data would notice is taken out, as it is for the real run);
* the start: the window estimate's covariance carried along the run
  linearly (:func:`.spread.spread_columns`).

With ``G`` the mean over the scored samples of the columns' products, a
correct model's squared miss, noise-weighted and averaged over channels, is
``c + z^T G z`` with ``z`` standard normal and ``c`` the noise's own mean
square, ``chi2_h / h``: its expectation is ``1 + trace(G)``. The test asks
how often that is at least the miss observed (Monte Carlo over ``z`` with a
fixed seed, the noise's share in closed form, so the answer is the same on
every run). Below :data:`MISS_LEVEL` the miss is the model's, not its
estimates'.

The propagation is linear in each direction's one-standard-deviation run;
a run the draw makes diverge has no spread to read (``expected`` inf): the
study's conclusion is then "inconclusive", the data cannot tell whose the
miss is.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

from .spread import noise_share

__all__ = [
    "AT_THE_NOISE",
    "MISS_LEVEL",
    "MissColumns",
    "coefficient_draws",
    "RunUncertainty",
    "miss_p_value",
    "run_uncertainty",
]

#: a held-out miss this improbable for a correct model with the fit's
#: standard errors is the model's (the approximations: linear propagation,
#: white noise, a model chosen on the same data, argue for a small level)
MISS_LEVEL = 1e-3

#: a run within this factor of the noise (combined over channels) needs no
#: explaining, and its draws are not run: the factor within which an
#: explanation fits its own record (``discovery.conclusion.FIT_FACTOR``, a
#: test keeps them equal)
AT_THE_NOISE = 1.5

#: Monte Carlo draws of the standard normal ``z`` (fixed seed)
DRAWS = 200_000


@dataclass(frozen=True)
class RunUncertainty:
    """How far a run's miss of held-out data can be its estimates' doing.

    Attributes
    ----------
    observed : float
        The run's RMSE over the noise, combined over channels (the root of
        the mean of each channel's squared ratio).
    expected : float
        What a correct model with these standard errors is expected to miss
        by, in the same units (inf: a draw's run diverged).
    upper : float
        The ``1 - MISS_LEVEL`` quantile of that miss.
    p_value : float
        How often a correct model misses by at least ``observed``.
    directions : int
        Coefficient directions run (eigenvectors of their covariance), the
        start's not counted.
    """

    observed: float
    expected: float
    upper: float
    p_value: float
    directions: int
    #: what it was computed from (not saved: several records' runs are
    #: pooled from them, :meth:`MissColumns.stacked`)
    columns: MissColumns | None = field(default=None, repr=False, compare=False)

    @property
    def beyond(self) -> bool:
        """The miss is the model's: improbable for a correct one."""
        return bool(np.isfinite(self.expected) and self.p_value < MISS_LEVEL)

    def sentence(self) -> str:
        from ..core.tables import sig

        if not np.isfinite(self.expected):
            return (
                f"it misses the data by {sig(self.observed, 3)}x the noise, and a "
                "run with a coefficient moved by one standard error diverges, so "
                "how far the estimates alone move the run is not measured"
            )
        where = "beyond what" if self.beyond else "within what"
        return (
            f"it misses the data by {sig(self.observed, 3)}x the noise, {where} "
            "the standard errors of its coefficients and start allow (a correct "
            f"model would miss by about {sig(self.expected, 3)}x, by more than "
            f"{sig(self.upper, 3)}x once in {round(1 / MISS_LEVEL)}; p = "
            f"{sig(self.p_value, 2)})"
        )


@dataclass
class MissColumns:
    """What a :class:`RunUncertainty` is computed from, over a run's scored
    samples (``K`` of them, ``m`` channels, ``n`` states).

    Attributes
    ----------
    draws : list of ndarray (K, m)
        Per coefficient direction: the run at that draw minus the run.
    start : ndarray (K, m, n) or None
        The start's covariance root carried along the run.
    observed : ndarray of bool (K, m)
        The readings the run's RMSE is over.
    noise_sd : ndarray (m,)
    """

    draws: list
    start: np.ndarray | None
    observed: np.ndarray
    noise_sd: np.ndarray

    def uncertainty(self, rmse) -> RunUncertainty:
        """The test for a run of RMSE ``rmse`` over these samples."""
        found = run_uncertainty(
            self.draws, self.start, self.observed, rmse, self.noise_sd
        )
        return replace(found, columns=self)

    @classmethod
    def stacked(cls, parts) -> MissColumns | None:
        """Several records' columns as one run's: the coefficients' draws
        are the same on every record (rows one after another), each record's
        start is its own (its columns zero on the other records). None when
        the records' draws differ in number."""
        if len({len(p.draws) for p in parts}) != 1:
            return None
        draws = [
            np.concatenate([p.draws[j] for p in parts], axis=0)
            for j in range(len(parts[0].draws))
        ]
        starts = [p.start for p in parts]
        start = None
        if all(s is not None for s in starts):
            K = sum(s.shape[0] for s in starts)
            m = starts[0].shape[1]
            start = np.zeros((K, m, sum(s.shape[2] for s in starts)))
            row = col = 0
            for s in starts:
                start[row : row + s.shape[0], :, col : col + s.shape[2]] = s
                row, col = row + s.shape[0], col + s.shape[2]
        observed = np.concatenate([p.observed for p in parts], axis=0)
        return cls(draws, start, observed, parts[0].noise_sd)


def miss_p_value(observed_sq, weights, noise_dof, draws: int = DRAWS):
    """``(P(c + Q >= observed_sq), the 1 - MISS_LEVEL quantile of c + Q)``.

    ``Q = sum_j weights_j z_j^2`` (``z`` standard normal), ``c = chi2_h / h``
    with ``h = noise_dof`` (inf: ``c = 1``). Monte Carlo over ``z`` with a
    fixed seed; given ``Q`` the noise's share is exact.
    """
    w = np.clip(np.asarray(weights, dtype=float), 0.0, None)
    w = w[w > 0]
    rng = np.random.default_rng(0)
    q = (rng.standard_normal((draws, w.size)) ** 2) @ w if w.size else np.zeros(draws)
    h = float(noise_dof)
    if np.isfinite(h):
        p = float(np.mean(stats.chi2.sf((observed_sq - q) * h, h)))
        noise = rng.chisquare(h, q.size) / h
    else:
        p = float(np.mean(q >= observed_sq - 1.0))
        noise = 1.0
    upper = float(np.quantile(q + noise, 1.0 - MISS_LEVEL))
    return p, upper


def run_uncertainty(draw_changes, start_changes, observed, rmse, noise_sd):
    """A :class:`RunUncertainty` from the changes each estimate makes.

    ``draw_changes``: list of ``(K, m)`` arrays, the measured channels of the
    run at a coefficient draw minus the run's, over its scored rows;
    ``start_changes``: ``(K, m, n)`` the start's columns on the same rows
    (None: not measured); ``observed (K, m)``: which of those readings the
    RMSE is over; ``rmse (m,)`` the run's; ``noise_sd (m,)``.
    """
    noise_sd = np.asarray(noise_sd, dtype=float)
    rmse = np.asarray(rmse, dtype=float)
    observed = np.asarray(observed, dtype=bool)
    m = noise_sd.size
    observed_sq = float(np.mean((rmse / noise_sd) ** 2))
    directions = len(draw_changes)
    cols = [np.asarray(c, float)[:, :, None] for c in draw_changes]
    if start_changes is not None:
        cols.append(np.asarray(start_changes, float))
    if not cols:
        cols = [np.zeros(observed.shape + (0,))]
    g = np.concatenate(cols, axis=2) / noise_sd[None, :, None]
    if not np.all(np.isfinite(g[observed])):
        return RunUncertainty(
            float(np.sqrt(observed_sq)), np.inf, np.inf, 1.0, directions
        )
    G = np.zeros((g.shape[2], g.shape[2]))
    counts = observed.sum(axis=0)
    for c in range(m):
        if counts[c]:
            rows = g[observed[:, c], c, :]
            G += rows.T @ rows / counts[c]
    G /= m
    weights = np.linalg.eigvalsh(0.5 * (G + G.T)) if G.size else np.zeros(0)
    # the noise's mean square: chi2_h / h with the variance of the channels'
    # average (each channel's mean of K_c squares has variance 2 / K_c)
    noise_dof = m**2 / float(np.sum(1.0 / counts)) if np.all(counts > 0) else np.inf
    p, upper_sq = miss_p_value(observed_sq, weights, noise_dof)
    expected = np.sqrt(1.0 + float(np.trace(G)))
    return RunUncertainty(
        float(np.sqrt(observed_sq)),
        float(expected),
        float(np.sqrt(upper_sq)),
        p,
        directions,
    )


def coefficient_draws(fit, build) -> list | None:
    """``build(fit at theta)`` for ``theta`` the fit's quantities moved one
    standard deviation along each eigenvector of their covariance from the
    noise alone (as :func:`.spread.noise_covariance_of` reads the start's).

    The quantities are the grey-box parameters and the coefficients that
    are free (not held on a bound or a wall); the offsets are left out (a
    run's window fits its own). None when there are none, or their
    covariance is not finite (an unidentified quantity: the report says so
    already).
    """
    a = fit.n_physical + len(fit.slots)
    free = np.flatnonzero(~np.asarray(fit.held, bool)[:a])
    if free.size == 0:
        return None
    # the noise's share only: a model's misfit is its own
    cov = np.asarray(fit.covariance, dtype=float)[np.ix_(free, free)] / noise_share(fit)
    if not np.all(np.isfinite(cov)):
        return None
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    draws = []
    for k in np.flatnonzero(w > 0):
        theta = np.array(fit.theta, dtype=float)
        theta[free] += np.sqrt(w[k]) * V[:, k]
        draws.append(build(replace(fit, theta=theta)))
    return draws
