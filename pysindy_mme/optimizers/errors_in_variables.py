"""Errors in variables: the selection's statistics corrected for noisy states.

Why. SINDy regresses derivative estimates on a library evaluated at the
*measured* states ``y = x + v``. With noise of a few per cent the library is
not the plant's: ``E[y^2] = x^2 + s^2``, ``E[y^3] = x^3 + 3 s^2 x``, so the
Gram matrix ``Theta(y)^T Theta(y)`` is biased, the least-squares
coefficients are attenuated, and a model that absorbs the bias with extra
terms fits the data better than the plant's model does. Measured on the
drop-in benchmark's records at 5 % noise (``python
benchmarks/bench_errors_in_variables.py``): with the same smoothed
derivatives and the library evaluated at the noise-free states, the default
rule finds Rossler's exact model in 20 of 20 seeds (11 on the measured
library) and Rikitake's in 17 (0); with exact derivatives and the measured
library, in 2 and 0. It is the library, not the derivative, that misleads.

What. For a library of monomials of base columns ``y_s = x_s + v_s`` with
independent Gaussian noise of variance ``s_s^2``, white in time, the
probabilists' Hermite polynomials give an unbiased estimate of every power,
``E[s^k He_k(y / s)] = x^k`` (computed by the recurrence ``P_0 = 1``,
``P_1 = y``, ``P_k+1 = y P_k - k s^2 P_k-1``), and of every monomial as the
product over its variables. Each entry of the Gram matrix is a monomial, so
each is replaced by the sum of these estimates: corrected least squares
(Cheng & Schneeweiss 1998, J. R. Statist. Soc. B 60, 189-199; Kukush,
Schneeweiss & Wolf 2005). The cross-products with the target are kept: a
centred derivative estimate (pysindy's ``FiniteDifference``,
``SmoothedFiniteDifference``, ``SpectralDerivative``) gives a sample's own
measurement zero weight, so the derivative's noise at a row is independent
of the library's noise at that row.

Statistics. The classic ones (partial F-ratios, sums of squares, the final
table's coefficients) come from a triangular factor of the corrected Gram
matrix, read exactly as :class:`~.gram.GramState` reads the data's. The
Newey-West ones come from the corrected estimating equations
``psi_t = Theta_t dx_t - G_t beta`` (``G_t`` the row's corrected outer
product): the sandwich ``A^-1 Omega A^-1``, which carries the variance of
the correction itself, so a term fitted through noisy high-order moments
gets the large variance it has. With no noise both reduce to the usual
statistics (``tests/optimizers/test_errors_in_variables.py``).

When (:func:`correction_for`, ``errors_in_variables="auto"``): the eligible
columns are monomials of some of them (found from the values: a column equal
to the product of two others; each base column's square among them), rows
in time order with unit weights, at most :data:`MAX_COLUMNS` columns and
fewer than :data:`MAX_ROWS` rows, each base column's noise variance found by
the spectral floor (:func:`~pysindy_mme.core.noise.estimate_noise_variance`,
reliable), and the base columns' noises uncorrelated (a library of ``x``
and ``sin(x)`` is not independent additive noise). A target whose noise
shares the library's (computed from the measured states) is fitted as given
(:meth:`CorrectedMoments.target_noise_is_separate`). The selection on the
library as given runs beside the corrected one, and the larger model must be
relevantly better (:func:`corrected_or_as_given`). Otherwise the usual
statistics; ``FloatingFStepwise.errors_in_variables_`` keeps the reason.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ..core.noise import estimate_noise_variance
from .corrected_state import CorrectedState
from .moments import MIN_ROWS as MOMENT_ROWS
from .selection import JOINT_MIN_EFFECT, Step, restart_effect

__all__ = [
    "MAX_COLUMNS",
    "MAX_ROWS",
    "MIN_ROWS",
    "Correction",
    "CorrectedMoments",
    "corrected_or_as_given",
    "correction_for",
    "hermite_powers",
    "monomial_structure",
]

#: libraries of at most this many eligible columns (the per-row moments cost
#: ``O(n m^2)`` and the robust statistics ``O(n k^2)`` per candidate)
MAX_COLUMNS = 100
#: rows at least (the noise's spectral floor needs a few segments of 128)
MIN_ROWS = 256
#: rows at most: the corrected robust statistics read every row for every
#: candidate of every step, where the library as given is read from its
#: moments from this size on (:data:`~.moments.MIN_ROWS`); measured on
#: Lorenz at 10^5 rows, 5 % noise: 2.4 s per fit against 0.12 s (degree 2),
#: 13 s against 2.9 s (degree 3). A cost limit, not a statistical one.
MAX_ROWS = MOMENT_ROWS
#: rows compared before a product of two columns is checked on every row
_PROBE_ROWS = 64
#: a column equals a product of two others to this relative accuracy
_PRODUCT_RTOL = 1e-9
#: base columns whose high-frequency parts correlate more than this (and more
#: than chance) do not carry independent noise
_MAX_NOISE_CORRELATION = 0.2


def hermite_powers(y, variance, degree: int) -> np.ndarray:
    """Unbiased estimates of ``x^k``, ``k = 0..degree``, from ``y = x + v``.

    ``v`` Gaussian of the given ``variance``: ``P_k = s^k He_k(y / s)``
    (``He`` the probabilists' Hermite polynomials), by the recurrence
    ``P_k+1 = y P_k - k s^2 P_k-1``; with ``variance`` 0 the powers of ``y``.
    Returns ``(degree + 1, n)``.
    """
    y = np.asarray(y, dtype=float)
    out = np.empty((degree + 1,) + y.shape)
    out[0] = 1.0
    if degree >= 1:
        out[1] = y
    for k in range(1, degree):
        out[k + 1] = y * out[k] - k * variance * out[k - 1]
    return out


def monomial_structure(x, columns):
    """``(base, powers)`` if ``x[:, columns]`` are monomials of some of them.

    A column equal (to ``_PRODUCT_RTOL``) to the product of two others is
    derived; the rest are the base. ``base``: the base columns (library
    indices); ``powers``: ``(len(columns), len(base))`` integer exponents of
    each column in ``columns``. None when there is no column, when a
    derived column's factors do not resolve to the base, or when a base
    column's square is not a column (a library of degree one, or a Fourier
    library, whose columns need not be measured states).
    """
    columns = np.asarray(columns, dtype=int)
    m = columns.size
    if m == 0:
        return None
    n = x.shape[0]
    probe = np.unique(np.linspace(0, n - 1, min(n, _PROBE_ROWS)).astype(int))
    f = np.asarray(x[probe][:, columns], dtype=float)
    size = np.max(np.abs(f), axis=0)
    factors = {}
    ia, ib = np.triu_indices(m)
    products = f[:, ia] * f[:, ib]  # (probe, pairs)
    for j in range(m):
        if not size[j] > 0:
            continue
        close = np.max(np.abs(products - f[:, [j]]), axis=0) <= _PRODUCT_RTOL * size[j]
        close &= (ia != j) & (ib != j)
        for pair in np.flatnonzero(close):
            a, b = int(ia[pair]), int(ib[pair])
            full = np.asarray(x[:, columns[j]], dtype=float)
            prod = np.asarray(x[:, columns[a]], dtype=float) * x[:, columns[b]]
            top = float(np.max(np.abs(full)))
            if np.max(np.abs(prod - full)) <= _PRODUCT_RTOL * top:
                factors[j] = (a, b)
                break
    base = [j for j in range(m) if j not in factors]
    if not base:
        return None
    powers = np.full((m, len(base)), -1, dtype=int)
    for i, j in enumerate(base):
        powers[j] = 0
        powers[j, i] = 1

    def resolve(j, depth=0):
        if powers[j, 0] >= 0:
            return powers[j]
        if depth > m:
            return None
        a, b = factors[j]
        pa, pb = resolve(a, depth + 1), resolve(b, depth + 1)
        if pa is None or pb is None:
            return None
        powers[j] = pa + pb
        return powers[j]

    for j in factors:
        if resolve(j) is None:
            return None
    # Each base column's square must be a column too (as in a polynomial
    # library of degree 2 or more): nothing else in the values says that a
    # column without products is a measured state (sin(x) and cos(x) of a
    # Fourier library multiply to no column of theirs).
    squares = {tuple(p) for p in powers}
    for i in range(len(base)):
        square = np.zeros(len(base), dtype=int)
        square[i] = 2
        if tuple(square) not in squares:
            return None
    return columns[base], powers


@dataclass
class Correction:
    """What the errors-in-variables correction found for one library.

    Attributes
    ----------
    applied : bool
        Whether the selection used the corrected statistics.
    reason : str
        Why not (empty when applied).
    base_columns : tuple of int
        Library columns the others are monomials of (the measured states).
    noise_variance : tuple of float
        Estimated noise variance of each base column.
    """

    applied: bool
    reason: str = ""
    base_columns: tuple = ()
    noise_variance: tuple = ()
    # the corrected moments (not part of the report)
    moments: object = field(default=None, repr=False)

    def as_dict(self) -> dict:
        return dict(
            applied=self.applied,
            reason=self.reason,
            base_columns=self.base_columns,
            noise_variance=self.noise_variance,
        )


def corrected_or_as_given(
    corrected, moments, select_as_given, make_corrected, history_row, name
):
    """``((state, result, history, rule), route)``: the corrected selection,
    or the one on the library as given (``route`` None: no correction here).

    ``corrected``: what ``FloatingFStepwise._select`` returned on
    ``moments`` (the library's: a :class:`CorrectedMoments` or not);
    ``select_as_given()`` runs it on the library as given;
    ``make_corrected()`` makes a fresh corrected state.

    The library's noise also regularises: it keeps a nearly degenerate clean
    library (monomials along a limit cycle) well conditioned. Without it the
    corrected selection can represent the derivative's systematic error with
    a larger model that fits better (the Brusselator at 5 % noise: seven
    terms for three). So the selection also runs on the library as given,
    both models are compared in the corrected metric, and the larger is kept only if it
    is relevantly better: each extra term reduces the corrected residual sum
    of squares by ``JOINT_MIN_EFFECT`` times the larger model's (the joint
    restart's rule, :func:`~.selection.restart_effect`); between models of
    one size, the smaller residual. The coefficients are the corrected ones
    on the support kept.

    Then the model kept must not be beaten by a smaller one: where a model
    of fewer terms has a smaller corrected residual
    (:meth:`~.corrected_state.CorrectedState.dominating_support`), it is
    taken (Rikitake's ``y'`` at 5 % noise: the restart's backward
    elimination from every column, in a metric without the noise's
    regularisation, ends at five terms where the true three fit better).
    The exchange is recorded as steps (``partial_f``: the ratio of the
    residual sums of squares, ``threshold`` 1; ``name(column)`` names them)
    and ``history_row(state)`` adds its row to the history.
    """
    chosen, route = _corrected_or_as_given(
        corrected, moments, select_as_given, make_corrected
    )
    state = chosen[0]
    if not isinstance(state, CorrectedState):
        return chosen, route
    support = state.dominating_support()
    if support is None:
        return chosen, route
    before = state.sse()
    again = make_corrected()
    for j in support:
        again.add(j)
    result = chosen[1]
    ratio = before / again.sse() if again.sse() > 0 else np.inf
    result.steps = list(result.steps) + _exchange_steps(
        state.support, support, len(result.steps) + 1, name, ratio
    )
    chosen[2].append(history_row(again))
    route += ", then a smaller model that fits better"
    return (again,) + tuple(chosen[1:]), route


def _exchange_steps(old, support, iteration: int, name, ratio) -> list:
    """Steps from the model ``old`` to ``support`` (removals, then additions)."""
    old = list(old)
    moves = [("remove", j) for j in old if j not in support]
    moves += [("add", j) for j in support if j not in old]
    steps, k = [], len(old)
    for action, j in moves:
        k += 1 if action == "add" else -1
        steps.append(
            Step(iteration + len(steps), 1, action, int(j), name(j), ratio, 1.0, k)
        )
    return steps


def _corrected_or_as_given(corrected, moments, select_as_given, make_corrected):
    """:func:`corrected_or_as_given` before the smaller-model check."""
    state = corrected[0]
    if not isinstance(moments, CorrectedMoments):
        return corrected, None
    if not isinstance(state, CorrectedState):
        return corrected, "as given (the target shares the library's noise)"
    as_given = select_as_given()
    support = list(as_given[0].support)
    if sorted(support) == sorted(state.support):
        return corrected, "both"
    if not np.isfinite(state.sse_of(support)):
        # The corrected Gram matrix is not positive definite on the model
        # as given: some of its columns are collinear to within the noise
        # the correction removes, so it cannot be fitted (nor compared) in
        # the corrected metric (Hopf normal form at 5 %, a 794-row training
        # fold: it raised LinAlgError)
        return corrected, "corrected, the model as given indefinite"
    again = make_corrected()
    for j in support:
        again.add(j)
    small, large = (again, state) if again.k <= state.k else (state, again)
    effect = restart_effect(small.k, small.sse(), large.k, large.sse())
    larger_kept = effect >= JOINT_MIN_EFFECT
    if (again is large) != larger_kept:
        return corrected, "corrected"
    return (again,) + tuple(as_given[1:]), "as given"


def _noise_is_independent(x_base) -> bool:
    """Whether the base columns' high-frequency parts are uncorrelated.

    Fourth differences of smooth signals are their noise; independent noises
    give correlations within chance (``4 / sqrt(n)``).
    """
    if x_base.shape[1] < 2:
        return True
    d = np.diff(x_base, n=4, axis=0)
    sd = d.std(axis=0)
    if not np.all(sd > 0):
        return False
    c = np.corrcoef(d, rowvar=False)
    off = np.abs(c[~np.eye(c.shape[0], dtype=bool)])
    return bool(np.all(off <= _noise_correlation_limit(d.shape[0])))


def _noise_correlation_limit(n: int) -> float:
    """The largest correlation of two independent noises' ``n`` fourth
    differences taken as chance (and at least :data:`_MAX_NOISE_CORRELATION`)."""
    return max(_MAX_NOISE_CORRELATION, 4.0 / np.sqrt(max(n, 1)))


def correction_for(x, w, screen, rule, time_ordered: bool):
    """The :class:`Correction` of library ``x`` (with its moments when applied).

    ``w``: the rows' weights; ``screen``, ``rule``: the library's screen and
    entry rule; ``time_ordered``: whether the rows are samples in time order.
    """
    if not time_ordered:
        return Correction(False, "rows not in time order")
    if not np.all(w == 1.0):
        return Correction(False, "sample weights")
    columns = np.flatnonzero(screen.eligible)
    if columns.size > MAX_COLUMNS:
        return Correction(False, f"more than {MAX_COLUMNS} columns")
    if x.shape[0] < MIN_ROWS:
        return Correction(False, f"fewer than {MIN_ROWS} rows")
    if x.shape[0] > MAX_ROWS:
        return Correction(False, f"more than {MAX_ROWS:,} rows")
    with np.errstate(all="ignore"):
        found = monomial_structure(x, columns)
    if found is None:
        return Correction(False, "the library is not monomials of its columns")
    base, powers = found
    x_base = np.asarray(x[:, base], dtype=float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            variance, diags = estimate_noise_variance(
                x_base, warn=False, return_diagnostics=True
            )
        except (ValueError, TypeError) as exc:
            return Correction(False, f"noise not estimated ({exc})", tuple(base))
    info = dict(base_columns=tuple(int(b) for b in base))
    info["noise_variance"] = tuple(float(v) for v in variance)
    if not all(d.reliable for d in diags):
        return Correction(False, "noise of a base column not determined", **info)
    if not _noise_is_independent(x_base):
        return Correction(False, "the base columns' noises are correlated", **info)
    moments = CorrectedMoments(x, x_base, variance, columns, powers, screen, rule)
    return Correction(True, "", moments=moments, **info)


class CorrectedMoments:
    """The corrected moments of one library, shared by its targets.

    Holds the rows' library (scaled), the per-row monomial estimates and the
    corrected Gram matrix of ``[1, eligible columns]`` (scaled units); each
    target's selection state comes from :meth:`make_state`.
    """

    def __init__(self, x, x_base, variance, columns, powers, screen, rule):
        self.n_rows = n = x.shape[0]
        self.columns = columns
        self.position = np.full(x.shape[1], -1)
        self.position[columns] = 1 + np.arange(columns.size)
        self.lags = rule.lags if rule.robust else None
        scale = screen.scale[columns]
        # [1, columns] with the constant's zero exponent first
        self.powers = np.vstack([np.zeros((1, powers.shape[1]), int), powers])
        self.unit = np.concatenate([[1.0], scale])
        self.rows = np.empty((n, columns.size + 1))
        self.rows[:, 0] = 1.0
        self.rows[:, 1:] = np.asarray(x[:, columns], dtype=float) * scale
        top = 2 * int(self.powers.max(initial=0))
        self._p = [
            hermite_powers(x_base[:, s], variance[s], top)
            for s in range(x_base.shape[1])
        ]
        self._cache = {}
        self._base_differences = [np.diff(c, n=4) for c in x_base.T]
        self._noise_correlation_limit = _noise_correlation_limit(n - 4)
        m = self.unit.size
        gram = np.empty((m, m))
        for a in range(m):
            for b in range(a, m):
                gram[a, b] = gram[b, a] = self.entry(a, b).sum()
        self.gram = gram

    def make_state(self, yw, screen, n_eff, tolerance, y_unit):
        """The :class:`CorrectedState` of the scaled target ``yw``, or None
        where the target's noise is not independent of the library's
        (:meth:`target_noise_is_separate`)."""
        if not self.target_noise_is_separate(yw):
            return None
        return CorrectedState(self, yw, screen, n_eff, tolerance, y_unit)

    def target_noise_is_separate(self, yw) -> bool:
        """Whether the target's noise at a row is independent of the base
        columns' noise at that row, as the kept cross-products assume.

        A centred derivative estimate's noise is an antisymmetric filter of
        the measurement noise; fourth (centred) differences are symmetric, so
        the fourth differences of the target and of a base column are
        uncorrelated at lag 0. A target that holds the library's own noise
        (computed from the measured states, ``1 - y``) correlates fully.
        """
        d = np.diff(np.asarray(yw, dtype=float), n=4)
        if not d.std() > 0:
            return False
        for db in self._base_differences:
            r = np.corrcoef(db, d)[0, 1]
            if not abs(r) <= self._noise_correlation_limit:
                return False
        return True

    def monomial(self, exponents) -> np.ndarray:
        """Per-row unbiased estimate of the monomial ``exponents`` (raw units)."""
        key = tuple(int(e) for e in exponents)
        out = self._cache.get(key)
        if out is None:
            out = np.ones(self.n_rows)
            for s, e in enumerate(key):
                if e:
                    out = out * self._p[s][e]
            self._cache[key] = out
        return out

    def entry(self, a: int, b: int) -> np.ndarray:
        """Per-row corrected product of columns ``a`` and ``b`` of ``[1, X]``."""
        return self.monomial(self.powers[a] + self.powers[b]) * (
            self.unit[a] * self.unit[b]
        )

    def outer_times(self, cols, beta) -> np.ndarray:
        """Per row, the corrected outer product of columns ``cols`` of ``[1,
        X]`` times ``beta``: (n, c), without forming the (n, c, c) products."""
        out = np.zeros((len(cols), self.n_rows))
        weights = self.unit[cols] * beta
        for i, a in enumerate(cols):
            for j, b in enumerate(cols):
                out[i] += self.monomial(self.powers[a] + self.powers[b]) * weights[j]
            out[i] *= self.unit[a]
        return out.T
