"""Quantities the measurements cannot pin down: exact trade-offs, named.

A fitted model can carry a combination of quantities the data do not
determine at all: the scale of a state nobody measured (two tanks in series
with only the lower level measured: the upper level times the pump gain and
the outflow rate into the lower tank over the upper level enter only as a
product), a parameter that a correction term re-does, a parameter the
measurements do not depend on. Gauss-Newton then drifts along the valley and
stops anywhere (a rate of -60,241 next to one of -1.1e-9), and covariances
taken at such a point can look tight. A study must not call that an
explanation.

How: the measured output of the model's free run is differentiated with
respect to every fitted quantity (initial state, parameters, correction
coefficients, offsets) along the run itself: each interval's RK4 map
differentiated stage by stage, chained over the intervals by one banded
solve for all quantities at once (independent of the fit's own linear
algebra: no KKT system; tested against central differences of whole free
runs), whitened by the noise, and its columns scaled to unit length. A
singular value below ``NULL_TOLERANCE`` of the largest is an exact
trade-off (the columns are linearly dependent to within the model
Jacobian's differencing error, ~1e-9 here); its singular vector says which
quantities move together and in which proportion, so the report can say
what *is* determined (``b * a2``, ``c / M``). The state trajectories along
that direction tell which states' scale is undetermined (a hidden state).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..core.integrate import (
    perturbation_growth,
    rk4_flow,
    simulate_guided,
    solve_recursion,
)
from ..core.model import ParametricModel, RatesAt
from ..protocols.runs import measurement_function

__all__ = ["TradeOff", "exact_trade_offs", "gauge_choice"]

#: smallest singular value of the column-scaled output Jacobian, relative to
#: the largest, below which a direction is undetermined: the sensitivities
#: are accurate to ~1e-9 (the model's Jacobian by central differences),
#: genuinely weak directions (look-alike terms) sit at 1e-2..1e-4 and are
#: judged by their standard errors instead
NULL_TOLERANCE = 1e-6
#: free runs of at most this many samples (a prefix of longer records)
MAX_SAMPLES = 100_000
#: relative step of the central differences of a callable measurement
STEP = 1e-5
#: a quantity takes part in a direction when its share is at least this
INVOLVED = 0.1
#: the free run is read up to where the model has amplified a change of its
#: initial state this many times (the geometric middle of 1 and
#: 1 / NULL_TOLERANCE): further on, along a chaotic or unstable run, every
#: quantity's effect turns into the growing mode's, and the sensitivities'
#: columns align to within the tolerance whatever the data determine (Lorenz
#: over 40 s, all three states measured, had "x1(0), x2(0) and x3(0) trade
#: off exactly"); an exact trade-off holds on any stretch
GROWTH_LIMIT = NULL_TOLERANCE**-0.5


@dataclass(frozen=True)
class TradeOff:
    """One combination of fitted quantities the data do not determine.

    Attributes
    ----------
    names : list of str
        The quantities that move together.
    exponents : list of float
        Relative change of each per unit move along the direction (scaled
        so the largest magnitude is 1): ``+1, -1`` means their product is
        determined, ``+1, +1`` their ratio. NaN for a quantity at zero.
    hidden_states : list of str
        Unmeasured states whose scale changes along the direction.
    determined : list of str
        Combinations that are determined (``"b*a2"``), where the exponents
        say so.
    gauge : str
        The grey-box parameter the study held at its guess to fix this
        direction (:func:`gauge_choice`), or ``""``: then the direction is
        left in the fit (and the conclusion names it as undetermined).
    """

    names: list
    exponents: list
    hidden_states: list
    determined: list
    gauge: str = ""

    def __str__(self) -> str:
        if len(self.names) == 1:
            return f"{self.names[0]} has no effect on the measurements"
        text = f"{_join(self.names)} trade off exactly"
        if self.hidden_states:
            plural = "s" if len(self.hidden_states) > 1 else ""
            text += (
                f" (the scale of the unmeasured state{plural} "
                f"{_join(self.hidden_states)} is not determined)"
            )
        if self.determined:
            text += f": only {_join(self.determined)} is determined, not each"
        if self.gauge:
            text += (
                f"; {self.gauge} is held at its guess (a gauge: fixed, as the data "
                "do not determine it; the others are estimated relative to it)"
            )
        return text


def exact_trade_offs(engine, fit, names, state_names, measured_states=None) -> list:
    """The exact trade-offs of ``fit``'s quantities (empty when none).

    Parameters
    ----------
    engine : OutputErrorModel
        The record and model the fit belongs to.
    fit : OutputErrorFit
    names : list of str
        One per entry of ``fit.theta`` (parameters, terms, offsets).
    state_names : list of str
    measured_states : sequence of int, optional
        States seen directly (the others are reported as hidden).
    """
    null = _null_space(engine, fit, names, state_names, measured_states)
    if null is None:
        return []
    out = [TradeOff([null.labels[j]], [1.0], [], []) for j in null.dead]
    for v in null.vectors:
        out.append(_describe(v, null))
    return out


def gauge_choice(engine, fit, names, state_names, measured_states=None) -> list:
    """Parameters to hold at their values so that no exact trade-off is left.

    A scale the data cannot fix (an unmeasured state's unit: ``z = s h``
    leaves the measurements as they are when an input gain and an output
    rate change as ``b -> s b``, ``a -> a / s``) makes the fits walk along
    the valley to wherever Gauss-Newton stops (``b = 1e-14``, ``a = 1e10``),
    far from anything the user meant and often where the model is stiff.
    Holding one quantity of each such direction at its value (a *gauge*,
    as a unit is chosen) removes the direction without changing what the
    model can fit: every other quantity is then determined relative to it.

    The quantities held are the grey-box parameters of ``fit`` (the first
    ``engine.n_physical`` entries of ``theta``), one per null direction of
    the output's sensitivities (:func:`exact_trade_offs`): the parameter
    with the largest share of the direction (column-scaled, so unit-free),
    the first in the user's order among those within a factor two of it;
    the direction is then eliminated from the others (Gaussian elimination
    on the null vectors), so that ``k`` directions hold ``k`` distinct
    parameters. Only directions at least two quantities take part in are
    gauged (a parameter with no effect at all is reported, not held), and
    only parameters away from zero (a scale acts on a nonzero value).

    Returns a list of ``(index, TradeOff)``: ``index`` into the grey-box
    parameters, and the direction it fixes.
    """
    null = _null_space(engine, fit, names, state_names, measured_states)
    if null is None or not len(null.vectors):
        return []
    n, n_phys = engine.n_states, int(engine.n_physical)
    positions = [i for i, j in enumerate(null.keep) if n <= j < n + n_phys]
    if not positions:
        return []
    # the null vectors in the column-scaled basis: components are unit-free
    V = np.array([v * null.norms[null.keep] for v in null.vectors], dtype=float)
    originals = list(null.vectors)
    chosen = []
    remaining = list(range(V.shape[0]))
    while remaining:
        best = None
        for r in remaining:
            comp = np.abs(V[r])
            size = comp.max()
            if size == 0 or np.count_nonzero(comp >= INVOLVED * size) < 2:
                continue
            usable = [
                i
                for i in positions
                if null.q0[null.keep[i]] != 0
                and comp[i] >= 0.5 * comp[positions].max()
                and comp[i] >= INVOLVED * size
            ]
            if usable and (best is None or comp[usable[0]] > best[2]):
                best = (r, usable[0], comp[usable[0]])
        if best is None:
            break
        r, i, _ = best
        remaining.remove(r)
        for o in remaining:  # the other directions leave this parameter alone
            V[o] -= V[o, i] / V[r, i] * V[r]
        j = int(null.keep[i]) - n
        chosen.append((j, replace(_describe(originals[r], null), gauge=names[j])))
    return sorted(chosen)


@dataclass
class _NullSpace:
    labels: list
    q0: np.ndarray
    keep: np.ndarray
    norms: np.ndarray
    dead: list
    vectors: list
    state_columns: list
    scale_x: np.ndarray
    hidden: list
    state_names: list


def _null_space(engine, fit, names, state_names, measured_states=None):
    """The output sensitivities' null directions at ``fit`` (None: none to say)."""
    n = engine.n_states
    K = min(engine.t.size, MAX_SAMPLES)
    starts = getattr(engine, "starts", ())
    if len(starts):
        # several records: the first one's free run (its own initial state)
        K = min(K, int(starts[0]))
    # with no fitted constants only the initial states could trade off, and a
    # state nothing measured depends on is refused before the study starts
    if fit.theta.size == 0 or K < 3 or not np.all(np.isfinite(fit.x[:K])):
        return None
    theta = np.asarray(fit.theta, dtype=float)
    n_dyn = theta.size - engine.n_offsets
    model = ParametricModel(
        engine.base,
        n,
        engine.n_physical,
        engine.features,
        fit.slots,
        n_extra=engine.n_offsets,
    )
    t = engine.t[:K]
    inputs = engine.inputs.subset(0, K)
    guess = fit.x[:K]
    q0 = np.concatenate([fit.x[0], theta])
    labels = [f"{name}(0)" for name in state_names] + list(names)

    # The free run, from the fit's trajectory (a converged fit's is the run
    # already), and its exact sensitivities to every quantity at once.
    rhs = RatesAt(model, theta)
    with np.errstate(all="ignore"):
        base = simulate_guided(rhs, q0[:n], t, inputs, engine.n_substeps, guess).x[0]
        S, growth = _run_sensitivities(
            model, theta, n_dyn, base, t, inputs, engine.n_substeps
        )
    over = growth > GROWTH_LIMIT
    if over.any():
        # at least the first few samples (a model that amplifies this fast
        # within them is judged on them)
        K = max(int(np.argmax(over)), min(K, 3))
        base, S = base[:K], S[:K]
    scale_x = np.sqrt(np.mean(fit.x[:K] ** 2, axis=0)) + 1e-300
    if not (np.all(np.isfinite(base)) and np.all(np.isfinite(S))):
        return None  # the free run left the finite range: nothing to say here
    whiten = _whitener(engine.R)
    derivative = _measurement_derivative(engine.measurement, base)
    columns, state_columns = [], []
    for j in range(q0.size):
        if j >= n + n_dyn:
            # an offset: the output moves by one unit per unit offset
            k = j - n - n_dyn
            col = np.zeros((K, engine.R.shape[0]))
            col[:, k] = 1.0
            columns.append((col @ whiten.T).ravel())
            state_columns.append(np.zeros((K, n)))
            continue
        state_columns.append(S[:, :, j])
        columns.append((derivative(S[:, :, j]) @ whiten.T).ravel())
    J = np.column_stack(columns)
    J[:, ~np.isfinite(J).all(axis=0)] = 0.0
    norms = np.linalg.norm(J, axis=0)
    # an initial state of nothing measured is caught elsewhere
    dead = [int(j) for j in np.flatnonzero(norms == 0.0) if j >= n]
    keep = np.flatnonzero(norms > 0)
    hidden = [
        i
        for i in range(n)
        if measured_states is not None and i not in set(measured_states)
    ]
    vectors = []
    if keep.size >= 2:
        Jn = J[:, keep] / norms[keep]
        _, s, vt = np.linalg.svd(Jn, full_matrices=False)
        # a perturbation of the quantities, per null direction
        vectors = [
            vt[k] / norms[keep] for k in np.flatnonzero(s / s[0] < NULL_TOLERANCE)
        ]
    return _NullSpace(
        labels,
        q0,
        keep,
        norms,
        dead,
        vectors,
        state_columns,
        scale_x,
        hidden,
        list(state_names),
    )


def _run_sensitivities(model, theta, n_dyn, x, t, inputs, substeps):
    """``(S, growth)``: ``S = d x_k / d (x_0, theta[:n_dyn])`` along the
    free run ``x``, ``(K, n, n + n_dyn)``, and ``growth (K,)`` the largest
    amplification of a change of ``x_0`` up to each sample
    (:func:`~pysindy_mme.core.integrate.perturbation_growth`). Each
    interval's derivatives are the RK4 map's own (its stages
    differentiated, :func:`~pysindy_mme.core.integrate.rk4_flow`); the
    chain ``S_{k+1} = A_k S_k + B_k`` from ``S_0 = [I 0]`` is one banded
    lower-triangular solve for every column at once."""
    K, n = x.shape
    m = n + n_dyn
    flow = rk4_flow(
        lambda z, s, u: model(z, s, u, theta),
        x[:-1],
        t[:-1],
        np.diff(t),
        inputs.on_intervals,
        substeps,
        jac_x=lambda z, s, u: model.jacobian(z, s, u, theta),
        jac_p=lambda z, s, u: model.param_jacobian(z, s, u, theta)[:, :, :n_dyn],
        n_params=n_dyn,
        split=model.split_at(theta, n),
    )
    D = flow.D
    start = np.zeros((n, m))
    start[:, :n] = np.eye(n)
    forcing = np.zeros((K - 1, n, m))
    forcing[0] = D[0]  # A_0 [I 0] + [0 B_0]
    forcing[1:, :, n:] = D[1:, :, n:]
    out = np.empty((K, n, m))
    out[0] = start
    chained, info = solve_recursion(D[:, :, :n], forcing)
    out[1:] = chained if info == 0 else np.nan
    return out, perturbation_growth(D[:, :, :n])


def _measurement_derivative(measurement, x):
    """``dS -> d(measurement)/dx . dS`` along the trajectory ``x``: the
    matrix itself, or central differences of a callable measurement along
    each direction (steps relative to the state's and the direction's size)."""
    if not callable(measurement):
        C = np.asarray(measurement, dtype=float)
        return lambda dS: dS @ C.T
    measure = measurement_function(measurement)
    size_x = float(np.sqrt(np.mean(x**2))) or 1.0

    def derivative(dS):
        size = float(np.sqrt(np.mean(dS**2)))
        if size == 0.0:
            return np.zeros_like(measure(x))
        e = STEP * size_x / size
        return (measure(x + e * dS) - measure(x - e * dS)) / (2 * e)

    return derivative


def _describe(v, null):
    """A :class:`TradeOff` from a null perturbation ``v`` of ``q0[keep]``."""
    keep, q0, labels = null.keep, null.q0, null.labels
    state_columns, scale_x, hidden = null.state_columns, null.scale_x, null.hidden
    state_names = null.state_names
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(q0[keep] != 0, v / q0[keep], np.nan)
    size = np.where(np.isfinite(rel), np.abs(rel), 0.0)
    # weight by the effect on the output: a quantity at zero still takes part
    share = np.abs(v) * np.array([np.linalg.norm(state_columns[j]) for j in keep])
    share = share / share.max() if share.max() > 0 else share
    involved = [i for i in range(keep.size) if share[i] >= INVOLVED]
    top = max(size[involved]) if involved and max(size[involved]) > 0 else 1.0
    exponents = [
        float(rel[i] / top) if np.isfinite(rel[i]) else np.nan for i in involved
    ]
    chosen = [labels[keep[i]] for i in involved]
    dx = sum(v[i] * state_columns[keep[i]] for i in range(keep.size))
    moved = [
        state
        for state in hidden
        if np.sqrt(np.mean(dx[:, state] ** 2)) > 1e-3 * np.abs(v).max() * scale_x[state]
    ]
    determined = _products(chosen, exponents)
    return TradeOff(chosen, exponents, [state_names[i] for i in moved], determined)


def _products(names, exponents) -> list:
    """``a*b`` (exponents of opposite sign) or ``a/b`` (same sign), paired
    with the quantity that moves most, where the exponents are +-1."""
    pairs = [(nm, e) for nm, e in zip(names, exponents) if np.isfinite(e)]
    if len(pairs) < 2:
        return []
    pairs.sort(key=lambda p: -abs(p[1]))
    lead, e0 = pairs[0]
    out = []
    for name, e in pairs[1:]:
        if abs(abs(e) - abs(e0)) > 0.05:
            continue
        out.append(f"{lead}*{name}" if e * e0 < 0 else f"{lead}/{name}")
    return out


def _whitener(R):
    """``L^-1`` with ``R = L L^T``: whitened outputs have unit noise."""
    return np.linalg.inv(np.linalg.cholesky(np.asarray(R, dtype=float)))


def _join(items) -> str:
    items = list(items)
    if len(items) == 1:
        return items[0]
    return ", ".join(items[:-1]) + " and " + items[-1]
