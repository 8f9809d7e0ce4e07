"""The one integrator of the package: classical RK4 on the sample grid.

Everything that integrates a model goes through here, so that the estimator,
the output-error fit, the gain and the simulations all see the same discrete
dynamics:

* :class:`InputSignal` - known inputs between samples: zero-order hold
  (``hold="zoh"``: ``u`` constant on ``[t_k, t_{k+1})``, the way a digital
  controller or a signal generator applies it) or linear interpolation
  (``hold="linear"``, the default), or a callable ``u(t)``.
* :func:`rk4_flow` - the flow ``Phi_k`` over every sample interval at once
  (vectorised over intervals, a Python loop over the RK4 sub-steps only), and
  optionally its exact derivatives ``dPhi_k/dx`` and ``dPhi_k/dp`` from the
  variational equations of the discrete map (the same stages), as direct
  transcription and Gauss-Newton need them.
* :func:`simulate` - free runs: a batch of trajectories integrated forward in
  time (vectorised over the batch). This is the one place with a Python loop
  per sample; it is used only where a simulation must be sequential
  (validation from a leading window, :meth:`ExtendedModel.simulate`-like
  checks), never inside a fit.
* :func:`simulate_guided` - the same free run solved by Newton's method over
  the whole record (or over blocks, each from the exact end of the one
  before) from a guessed trajectory: a few vectorised passes; the loop of
  :func:`simulate` only where blocks of ``GUIDED_MIN_BLOCK`` intervals fail.
* :func:`solve_recursion` - ``z_{k+1} = A_k z_k + f_k`` by one banded solve:
  Newton's step of a free run, and a run's sensitivities.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .jacobian import column_scale, rowwise_jacobian
from .relaxation import split_form

__all__ = [
    "GUIDED_TOL",
    "RK4_H_RHO",
    "InputSignal",
    "FlowResult",
    "perturbation_growth",
    "rk4_flow",
    "run_jacobians",
    "simulate",
    "simulate_guided",
    "solve_recursion",
    "SimulationResult",
]

HOLDS = ("linear", "zoh", "cubic")


def _catmull_rom(u, k, frac):
    """Cubic (Catmull-Rom) interpolation of samples ``u`` at ``t_k + frac h_k``
    on intervals ``k`` (``frac`` one value or one per interval); the end
    intervals reuse their end samples."""
    last = u.shape[0] - 1
    p0, p1 = u[np.maximum(k - 1, 0)], u[k]
    p2, p3 = u[k + 1], u[np.minimum(k + 2, last)]
    s = np.reshape(frac, (-1, 1))
    return 0.5 * (
        2 * p1
        + (p2 - p0) * s
        + (2 * p0 - 5 * p1 + 4 * p2 - p3) * s**2
        + (3 * p1 - p0 - 3 * p2 + p3) * s**3
    )


#: ``h * spectral radius`` at which a classical RK4 step is accurate to about
#: 1e-5 relative (the study's rule for RK4 steps per interval)
RK4_H_RHO = 0.5


class InputSignal:
    """Known inputs ``u(t)``: samples on the time grid, or a callable.

    Parameters
    ----------
    u : None, array-like (N,) or (N, m), or callable ``u(s) -> (len(s), m)``
    t : ndarray (N,)
        Sample times of the array ``u``.
    hold : {"linear", "zoh", "cubic"}
        Between samples: linear interpolation, zero-order hold (``u_k`` on
        ``[t_k, t_{k+1})``), or cubic (Catmull-Rom) interpolation through the
        neighbouring samples, for inputs that were smooth signals sampled.
        Ignored for a callable.
    """

    def __init__(self, u, t, hold: str = "linear"):
        if hold not in HOLDS:
            raise ValueError(
                f"input_hold must be 'linear', 'zoh' or 'cubic', got {hold!r}"
            )
        self.t = np.asarray(t, dtype=float)
        self.hold = hold
        self._cache = {}
        if u is None or callable(u):
            self.u = u
        else:
            arr = np.asarray(u, dtype=float)
            self.u = arr[:, None] if arr.ndim == 1 else arr

    @property
    def is_none(self) -> bool:
        return self.u is None

    def grid(self):
        """Inputs at the sample times, ``(N, m)``, or None."""
        if self.u is None:
            return None
        if callable(self.u):
            return np.asarray(self.u(self.t), dtype=float).reshape(self.t.size, -1)
        return self.u

    def on_intervals(self, frac: float, sl=slice(None)):
        """Inputs at ``t_k + frac * h_k`` for the intervals ``sl`` (cached).

        With ``hold="zoh"`` every point of interval k, its right end
        included, takes ``u_k``: the interval is integrated with the value
        that was held on it.
        """
        if self.u is None:
            return None
        key = round(float(frac), 12)
        if key not in self._cache:
            if callable(self.u):
                s = self.t[:-1] + frac * np.diff(self.t)
                val = np.asarray(self.u(s), dtype=float).reshape(s.size, -1)
            elif self.hold == "zoh":
                val = self.u[:-1]
            elif self.hold == "cubic":
                val = _catmull_rom(self.u, np.arange(self.t.size - 1), frac)
            else:
                val = (1.0 - frac) * self.u[:-1] + frac * self.u[1:]
            self._cache[key] = val
        return self._cache[key][sl]

    def at(self, s):
        """Inputs at arbitrary times ``s`` (1-D), ``(len(s), m)``, or None."""
        if self.u is None:
            return None
        s = np.atleast_1d(np.asarray(s, dtype=float))
        if callable(self.u):
            return np.asarray(self.u(s), dtype=float).reshape(s.size, -1)
        if self.hold == "zoh":
            k = np.searchsorted(self.t, s, side="right") - 1
            return self.u[np.clip(k, 0, self.t.size - 1)]
        if self.hold == "cubic" and self.t.size > 1:
            # The same cubic on each interval as on_intervals (a model integrated
            # at other times must see the input the fit saw); constant outside.
            s = np.clip(s, self.t[0], self.t[-1])
            k = np.clip(
                np.searchsorted(self.t, s, side="right") - 1, 0, self.t.size - 2
            )
            frac = (s - self.t[k]) / (self.t[k + 1] - self.t[k])
            return _catmull_rom(self.u, k, frac)
        return np.column_stack(
            [np.interp(s, self.t, self.u[:, j]) for j in range(self.u.shape[1])]
        )

    def subset(self, start: int, stop: int) -> InputSignal:
        """The same signal on samples ``start:stop``."""
        u = self.u if (self.u is None or callable(self.u)) else self.u[start:stop]
        return InputSignal(u, self.t[start:stop], self.hold)


@dataclass
class FlowResult:
    """``Phi_k`` for every interval and, if asked, its derivatives.

    ``D[k] = dPhi_k / d[x_k, p]``, shape ``(K, n, n + p)``.
    """

    phi: np.ndarray
    D: np.ndarray | None = None

    def A(self, n: int):
        return None if self.D is None else self.D[:, :, :n]

    def B(self, n: int):
        return None if self.D is None else self.D[:, :, n:]


def rk4_flow(
    rhs,
    x,
    t0,
    h,
    inputs,
    substeps: int = 1,
    jac_x=None,
    jac_p=None,
    n_params: int = 0,
    split=None,
    state_columns: bool = True,
):
    """Classical RK4 over ``K`` independent intervals at once.

    Parameters
    ----------
    rhs : callable ``(X (K, n), s (K,), u (K, m) or None) -> (K, n)``
    x : ndarray (K, n)
        State at the start of each interval.
    t0, h : ndarray (K,)
        Start and length of each interval.
    inputs : callable ``frac -> (K, m) or None``
        Inputs at ``t0 + frac * h`` (see :meth:`InputSignal.on_intervals`).
    substeps : int
        RK4 steps per interval.
    jac_x : callable ``(X, s, u) -> (K, n, n)``, optional
        ``df/dx``; with it the derivatives ``D`` are returned.
    jac_p : callable ``(X, s, u) -> (K, n, p)`` or ``(n, p)``, optional
        ``df/dp`` for ``n_params`` parameters held constant over the interval.
    split : callable ``(X, D, h) -> (X, D)``, optional
        A part of the dynamics solved exactly, not by RK4 (the overflow
        terms, :class:`~pysindy_mme.core.relaxation.Overflows`): it advances
        ``X`` (and ``D``, None without ``jac_x``) by ``h`` ``(K, 1)``. Each
        step is Strang-split: half a step of it, the RK4 step of ``rhs``,
        half a step of it.
    state_columns : bool
        False: ``D`` holds the parameters' columns only (``(K, n, p)``, no
        ``dPhi/dx``). Each column of ``D`` is propagated on its own through
        the stages' Jacobians, so the parameters' columns are the same
        numbers either way; a pass that needs only them (the score tests'
        candidate terms) then carries ``n`` columns fewer. Not with
        ``split`` (its columns are placed after the states').

    Returns
    -------
    FlowResult
        The derivatives are those of the discrete map itself (the RK4
        stages differentiated), so Gauss-Newton sees the exact Jacobian of
        what it solves.
    """
    X = np.array(x, dtype=float)
    K, n = X.shape
    p = int(n_params)
    hs = (np.asarray(h, dtype=float) / substeps)[:, None]
    D = None
    first = n if state_columns else 0  # the parameters' first column of D
    if not state_columns and split is not None:
        raise ValueError("state_columns=False cannot be used with split")
    # The derivatives are carried as (n, columns, K): each entry a run of the
    # K intervals, contiguous. The product with the stages' Jacobians is then
    # a few operations over whole rows of entries; in the (K, n, columns)
    # layout the returned D has, each entry was a strided run and the
    # product (n * columns operations) a tenth of a long record's study.
    # The sums are the same numbers in the same order.
    hsT = hs[:, 0][None, None, :]
    if jac_x is not None:
        D = np.zeros((n, first + p, K))
        for i in range(first):
            D[i, i] = 1.0

    def derivative(Xs, s, us, Dpre):
        dk = _rowwise_matmul(jac_x(Xs, s, us), Dpre)
        if p:
            jp = jac_p(Xs, s, us)
            if jp.ndim == 2:  # (n, p): the same for every interval
                dk[:, first:] += jp[:, :, None]
            else:
                dk[:, first:] += np.moveaxis(jp, 0, 2)
        return dk

    def splitting(X, D, hh):
        # the split works on (K, n, columns) (a view of the same entries)
        X, DK = split(X, None if D is None else np.moveaxis(D, 2, 0), hh)
        return X, None if DK is None else np.ascontiguousarray(np.moveaxis(DK, 0, 2))

    t0 = np.asarray(t0, dtype=float)
    for j in range(substeps):
        c0 = j / substeps
        tj = t0 + c0 * np.asarray(h)
        half = tj + 0.5 * hs[:, 0]
        end = tj + hs[:, 0]
        u0 = inputs(c0)
        uh = inputs((j + 0.5) / substeps)
        u1 = inputs((j + 1.0) / substeps)
        # Each stage's derivative right after its value, at the same point
        # object: a model that keeps what it computed at its last point (the
        # library columns of a ParametricModel, the state in user units)
        # reuses it for the Jacobians instead of evaluating it again. The
        # same numbers in the same operations as value-stages-first.
        jac = D is not None
        if split is not None:
            X, D = splitting(X, D, 0.5 * hs)
        k1 = rhs(X, tj, u0)
        if jac:
            # The derivatives are summed as the stages come (acc) and the
            # next stage's point (arg) is written over the last one: four
            # arrays of D's size alive instead of about eight (with the score
            # tests' candidate columns, 200 bytes a sample each at 10^6
            # samples of two states).
            dk = derivative(X, tj, u0, D)
            acc = np.multiply(dk, hsT / 6.0)
            acc += D
            arg = np.multiply(dk, 0.5 * hsT)
            arg += D
        X2 = X + 0.5 * hs * k1
        k2 = rhs(X2, half, uh)
        if jac:
            dk = derivative(X2, half, uh, arg)
            np.multiply(dk, 0.5 * hsT, out=arg)
            arg += D
            dk *= hsT / 3.0
            acc += dk
        X3 = X + 0.5 * hs * k2
        k3 = rhs(X3, half, uh)
        if jac:
            dk = derivative(X3, half, uh, arg)
            np.multiply(dk, hsT, out=arg)
            arg += D
            dk *= hsT / 3.0
            acc += dk
        X4 = X + hs * k3
        k4 = rhs(X4, end, u1)
        if jac:
            dk = derivative(X4, end, u1, arg)
            dk *= hsT / 6.0
            acc += dk
            D, acc, arg, dk = acc, None, None, None
        X = X + hs / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        if split is not None:
            X, D = splitting(X, D, 0.5 * hs)
    if D is not None:
        D = np.ascontiguousarray(np.moveaxis(D, 2, 0))
    return FlowResult(X, D)


#: states up to which :func:`_rowwise_matmul` multiplies entry by entry over
#: the rows (beyond: numpy's batched product)
_ROWWISE_MAX_STATES = 6


def _rowwise_matmul(J, D):
    """``J @ D`` for ``J (K, n, n)`` and ``D`` in the layout ``(n, m, K)``
    (each entry a contiguous run of the ``K`` rows; :func:`rk4_flow`'s),
    returned in that layout.

    ``n^2`` operations over whole rows of entries. Beyond
    :data:`_ROWWISE_MAX_STATES` they cost more than numpy's batched product
    (measured at 32,768 rows: 6 states 11 against 12 ms, 8 states 36
    against 15 ms), which is used there.
    """
    n = J.shape[1]
    if n > _ROWWISE_MAX_STATES:
        return np.ascontiguousarray(np.moveaxis(J @ np.moveaxis(D, 2, 0), 0, 2))
    out = np.empty_like(D)
    for i in range(n):
        np.multiply(J[:, i, 0], D[0], out=out[i])
        for j in range(1, n):
            out[i] += J[:, i, j] * D[j]
    return out


#: the most multiply-adds ``n * r * m`` per row :func:`_small_matmul` does
#: element by element before numpy's batched matmul is faster (measured at
#: 32,768 rows: n = 2, m = 5: 1.1 ms against 1.8; n = 3, m = 6: 3.2 against
#: 1.9)
_ELEMENTWISE_MAX = 36


def _small_matmul(J, D):
    """``J @ D`` for stacks of small matrices, ``(K, n, r) @ (K, r, m)``.

    numpy's batched matmul pays a per-matrix overhead (about 50 ns, 1.7 ms
    for 32,768 rows whatever the size) that dominates for a few states and
    columns. There each entry is summed over ``j`` with operations that run
    over the ``K`` rows: numpy's loops over views whose last axis has 2-5
    elements (``J[:, :, j, None] * D[:, None, j, :]``) are 3-6x slower.
    """
    K, r, m = D.shape
    n = J.shape[1]
    if n * r * m > _ELEMENTWISE_MAX:
        return J @ D
    out = np.empty((K, n, m))
    for i in range(n):
        for c in range(m):
            o = out[:, i, c]
            np.multiply(J[:, i, 0], D[:, 0, c], out=o)
            for j in range(1, r):
                o += J[:, i, j] * D[:, j, c]
    return out


@dataclass
class SimulationResult:
    """Trajectories of :func:`simulate`.

    Attributes
    ----------
    x : ndarray (B, N, n)
        States at the sample times; NaN from the first sample at which a
        trajectory left the finite range or the bound.
    diverged_at : ndarray of int (B,)
        Index of that first sample (-1 for a trajectory that stayed bounded).
    """

    x: np.ndarray
    diverged_at: np.ndarray

    @property
    def ok(self) -> np.ndarray:
        return self.diverged_at < 0


def simulate(
    rhs,
    x0,
    t,
    inputs: InputSignal | None = None,
    substeps: int = 1,
    bound: float | None = None,
    split=None,
) -> SimulationResult:
    """Integrate ``B`` trajectories forward in time with RK4 (free runs).

    Parameters
    ----------
    rhs : callable ``(X (B, n), s float, u (m,) or None) -> (B, n)``
    x0 : ndarray (B, n) or (n,)
    t : ndarray (N,)
        Output times; each interval takes ``substeps`` RK4 steps.
    inputs : InputSignal, optional
    bound : float, optional
        A trajectory whose largest state magnitude exceeds this is stopped
        (NaN from there, recorded in ``diverged_at``). Default: ``1e8`` times
        the largest initial magnitude (at least 1).
    split : callable ``(X, D, h) -> (X, D)``, optional
        A part solved exactly around each RK4 step (as in :func:`rk4_flow`);
        default the model's own (:func:`~pysindy_mme.core.relaxation.split_form`).

    Returns
    -------
    SimulationResult
    """
    if split is None:
        rhs, split = split_form(rhs)
    x = np.array(np.atleast_2d(x0), dtype=float)
    t = np.asarray(t, dtype=float)
    n_traj = x.shape[0]
    out = np.full((n_traj, t.size, x.shape[1]), np.nan)
    out[:, 0] = x
    if bound is None:
        bound = 1e8 * max(1.0, float(np.nanmax(np.abs(x)))) if x.size else 1e8
    diverged = np.where(np.all(np.isfinite(x), axis=1), -1, 0)
    has_u = inputs is not None and not inputs.is_none
    with np.errstate(all="ignore"):
        for k in range(t.size - 1):
            h = (t[k + 1] - t[k]) / substeps
            for s in range(substeps):
                s0 = t[k] + s * h
                if has_u:
                    ua, um, ub = (
                        inputs.on_intervals(f / substeps, k)
                        for f in (s, s + 0.5, s + 1)
                    )
                else:
                    ua = um = ub = None
                if split is not None:
                    x = split(x, None, 0.5 * h)[0]
                k1 = rhs(x, s0, ua)
                k2 = rhs(x + 0.5 * h * k1, s0 + 0.5 * h, um)
                k3 = rhs(x + 0.5 * h * k2, s0 + 0.5 * h, um)
                k4 = rhs(x + h * k3, s0 + h, ub)
                x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
                if split is not None:
                    x = split(x, None, 0.5 * h)[0]
            bad = ~np.all(np.isfinite(x) & (np.abs(x) < bound), axis=1)
            new = bad & (diverged < 0)
            if np.any(new):
                diverged[new] = k + 1
                x[bad] = np.nan
            out[:, k + 1] = x
    return SimulationResult(out, diverged)


def solve_recursion(A, forcing):
    """``(z, info)``: ``z_1 .. z_K`` of ``z_{k+1} = A_k z_k + f_k`` from
    ``z_0 = 0``, for ``A (K, n, n)`` and ``forcing (K, n)`` or ``(K, n, m)``
    (``z`` has its shape; ``z[k]`` is ``z_{k+1}``). One banded
    lower-triangular solve (LAPACK's ``dtbtrs``), linear in ``K``: the
    linearised free run (Newton's step) and its sensitivities.
    """
    from scipy.linalg import lapack

    K, n = A.shape[:2]
    kd = 2 * n - 1
    ab = np.zeros((kd + 1, K * n))
    ab[0] = 1.0
    for i in range(n):
        for j in range(n):
            ab[n + i - j, j : (K - 1) * n : n] = -A[1:, i, j]
    z, info = lapack.dtbtrs(ab, forcing.reshape(K * n, -1), uplo="L")
    return z.reshape(forcing.shape), info


def perturbation_growth(A) -> np.ndarray:
    """How far a change of the initial state travels along a trajectory.

    For the interval maps' Jacobians ``A (K, n, n)`` (``A_k = dPhi_k/dx``),
    ``g (K + 1,)`` with ``g[k]`` the largest entry, in absolute value, of
    ``A_{k-1} ... A_0`` (``g[0] = 1``): a unit change of one state at the
    start moves no state at sample ``k`` by more than ``n g[k]``. Where the
    product overflows, and from there on, ``inf``.

    The record is cut into about ``sqrt(K)`` blocks of as many intervals,
    and every block is stepped at once: one pass forms each block's product,
    a short loop chains them, a second pass reads every sample's product.
    About ``2 sqrt(K)`` vectorised steps over ``sqrt(K)`` small matrices,
    each held entry by entry as a vector over the blocks (numpy's batched
    ``matmul`` of 2 x 2 matrices costs several times the same sums written
    out). A banded solve of the same chain (LAPACK's ``dtbtrs``, with a
    call per row) took 0.8 s at 10^6 samples; this about a tenth.
    """
    A = np.asarray(A, dtype=float)
    K, n = A.shape[:2]
    out = np.ones(K + 1)
    if K == 0:
        return out
    m = int(np.ceil(np.sqrt(K)))
    nb = -(-K // m)
    # maps[j, i, l, b]: entry (i, l) of block b's j-th map (the identity
    # past the record's end)
    maps = np.zeros((m, n, n, nb))
    maps[:, np.arange(n), np.arange(n), :] = 1.0
    full = K // m
    maps[:, :, :, :full] = A[: full * m].reshape(full, m, n, n).transpose(1, 2, 3, 0)
    if full < nb:
        maps[: K - full * m, :, :, full] = A[full * m :]

    def times(a, b):
        """``a @ b`` for every block: ``(n, n, nb)`` each."""
        c = np.zeros_like(b)
        for i in range(n):
            for j in range(n):
                for l in range(n):
                    c[i, l] += a[i, j] * b[j, l]
        return c

    eye = np.zeros((n, n, nb))
    eye[np.arange(n), np.arange(n)] = 1.0
    with np.errstate(all="ignore"):
        product = eye
        for j in range(m):
            product = times(maps[j], product)
        # before[:, :, b]: the product of every block before block b
        before = eye.copy()
        for b in range(1, nb):
            before[:, :, b] = product[:, :, b - 1] @ before[:, :, b - 1]
        size = np.empty((m, nb))
        product = before
        for j in range(m):
            product = times(maps[j], product)
            size[j] = np.max(np.abs(product).reshape(n * n, nb), axis=0)
    g = size.T.reshape(-1)[:K]
    bad = ~np.isfinite(g)
    if bad.any():
        g[int(np.argmax(bad)) :] = np.inf
    out[1:] = g
    return out


#: a guided free run's Newton iteration stops when every interval's defect is
#: at most this fraction of the trajectory's scale: its trajectory is the
#: model's run to this precision, not to rounding
GUIDED_TOL = 1e-12

#: a guided free run solves its Newton iteration over blocks of intervals,
#: each from the exact end state of the block before: over a long record the
#: linearised recursion can amplify the guess's small defects (a limit cycle's
#: neutral phase direction adds them up over thousands of periods) where a
#: shorter block converges. A block that does not converge is cut to a
#: ``GUIDED_SHRINK``-th; one of ``GUIDED_MIN_BLOCK`` intervals that does not
#: is run by the sequential loop, over stretches that double while Newton
#: keeps failing (so a guess that is no use costs O(log N) Newton attempts)
GUIDED_MIN_BLOCK = 64
GUIDED_SHRINK = 8
#: a Newton iteration whose largest defect grows by more than this factor has
#: left the region where the linearisation holds: the block is cut at once
GUIDED_BLOW_UP = 1e3


class _FromInterval:
    """``inputs`` read from interval ``offset`` on: a sequential stretch of a
    guided run sees the record's own inputs (a subset would move a cubic
    hold's end conditions)."""

    def __init__(self, inputs: InputSignal, offset: int):
        self.inputs, self.offset = inputs, int(offset)

    @property
    def is_none(self) -> bool:
        return self.inputs.is_none

    def on_intervals(self, frac: float, k: int):
        return self.inputs.on_intervals(frac, self.offset + k)


def simulate_guided(
    rhs,
    x0,
    t,
    inputs: InputSignal | None,
    substeps: int,
    guess,
    jac_x=None,
    max_iter: int = 30,
    bound: float | None = None,
) -> SimulationResult:
    """A free run, solved for the whole record at once from a guessed trajectory.

    The same discrete RK4 trajectory as :func:`simulate` (``x_{k+1} =
    Phi_k(x_k)`` from ``x0``), found by Newton's method on all the
    ``x_k`` together: every iteration integrates all intervals as one
    vectorised batch (:func:`rk4_flow`, with ``dPhi/dx``) and solves the
    linearised recursion ``dx_{k+1} = A_k dx_k + defect_k`` (``dx_0 = 0``)
    with LAPACK's banded triangular solver. From a guess near the answer
    (a state estimate of the same record) it converges in a few iterations,
    so a free run of 10^5 samples costs a few vectorised passes instead of a
    Python loop per sample. Where Newton does not converge over the whole
    record, it runs over shorter blocks, each from the exact end of the one
    before (``GUIDED_MIN_BLOCK``); where it does not converge even there (a
    model that departs from the data, a model that blows up), the sequential
    :func:`simulate` decides, and reports a divergence as it does.

    Parameters
    ----------
    rhs : callable ``(X (K, n), s (K,), u (K, m) or None) -> (K, n)``
    jac_x : callable, same arguments, ``-> (K, n, n)``; if None, the
        model's own ``jacobian(X, s, u, scale=...)`` when it has one (an
        :class:`~pysindy_mme.ExtendedModel`'s bare form), else central
        differences of ``rhs``, with steps scaled by each state's RMS
        along ``guess``.
    guess : ndarray (N, n)
    max_iter : int
        Newton iterations per block.
    Other parameters as :func:`simulate` (``rhs`` there is row-batched with
    a scalar time; here it is vectorised over intervals).
    """
    t = np.asarray(t, dtype=float)
    guess = np.asarray(guess, dtype=float)
    x = np.array(guess, dtype=float)
    x[0] = np.asarray(x0, dtype=float).ravel()
    N, n = x.shape
    inputs = inputs if inputs is not None else InputSignal(None, t)
    scale = max(1.0, float(np.max(np.abs(x))))
    bound = 1e8 * scale if bound is None else bound
    rhs, split, jac_x = _run_form(rhs, guess, jac_x)

    def rhs_rows(X, s, u):
        uu = None if u is None else np.broadcast_to(u, (X.shape[0], u.shape[-1]))
        return rhs(X, np.full(X.shape[0], s), uu)

    if not np.all(np.isfinite(x[0])) or N < 2:
        return simulate(rhs_rows, x0, t, inputs, substeps, bound=bound, split=split)
    block = _NewtonBlock(rhs, x, t, inputs, substeps, jac_x, split)
    if block.is_the_run(GUIDED_TOL * scale, bound):
        return SimulationResult(x[None], np.array([-1]))
    start, size, stretch = 0, N - 1, GUIDED_MIN_BLOCK
    while start < N - 1:
        stop = min(start + size, N - 1)
        if block.solve(start, stop, GUIDED_TOL * scale, bound, max_iter):
            start, size, stretch = stop, 2 * size, GUIDED_MIN_BLOCK
            continue
        x[start + 1 : stop + 1] = guess[start + 1 : stop + 1]
        if size > GUIDED_MIN_BLOCK:
            size = max(GUIDED_MIN_BLOCK, size // GUIDED_SHRINK)
            continue
        stop = min(start + stretch, N - 1)
        run = simulate(
            rhs_rows,
            x[start],
            t[start : stop + 1],
            _FromInterval(inputs, start),
            substeps,
            bound=bound,
            split=split,
        )
        at = int(run.diverged_at[0])
        if at >= 0:
            x[start + at :] = np.nan
            x[start + 1 : start + at] = run.x[0, 1:at]
            return SimulationResult(x[None], np.array([start + at]))
        x[start + 1 : stop + 1] = run.x[0, 1:]
        start, stretch = stop, 2 * stretch
        size = GUIDED_MIN_BLOCK * GUIDED_SHRINK
    return SimulationResult(x[None], np.array([-1]))


def _run_form(rhs, guess, jac_x=None):
    """``(rhs, split, jac_x)``: a model as the guided run integrates it.

    An extended model (it offers a split form) without its checks, the same
    values: a run calls it at every RK4 stage of every pass. (Not any
    model's ``unchecked``: a user's bare function may give a one-state
    answer as a row, which only the checked call reshapes.) Its overflow
    terms are split off (solved exactly around each RK4 step), and ``jac_x``
    (when not given) is the model's own Jacobian or central differences
    scaled by ``guess`` (:func:`_difference_jacobian`).
    """
    own_jacobian = None
    if callable(getattr(rhs, "split_form", None)) and callable(
        getattr(rhs, "unchecked", None)
    ):
        rhs = rhs.unchecked()
        own_jacobian = getattr(rhs, "jacobian", None)
    rhs, split = split_form(rhs)
    if jac_x is None:
        jac_x = _difference_jacobian(rhs, guess, own_jacobian)
    return rhs, split, jac_x


def run_jacobians(rhs, x, t, inputs: InputSignal | None, substeps: int, block: int):
    """``(lo, A)`` for the run's intervals in blocks of ``block``: ``A (K, n,
    n)`` the RK4 interval maps' ``dPhi_k/dx`` on intervals ``lo .. lo + K``.

    ``x (N, n)``: the run (a :func:`simulate_guided` result, finite); the
    model as :func:`simulate_guided` integrates it (prepared once, its
    Jacobian's steps scaled by the whole run), each block in one vectorised
    pass: the memory is a block's.
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    inputs = inputs if inputs is not None else InputSignal(None, t)
    rhs, split, jac_x = _run_form(rhs, x)
    h = np.diff(t)
    for lo in range(0, h.size, block):
        rows = slice(lo, min(lo + block, h.size))
        with np.errstate(all="ignore"):
            out = rk4_flow(
                rhs,
                x[rows],
                t[rows],
                h[rows],
                lambda frac, rows=rows: inputs.on_intervals(frac, rows),
                substeps,
                jac_x=jac_x,
                split=split,
            )
        yield lo, out.D


def _difference_jacobian(rhs, guess, own=None):
    """``jac_x(X, s, u)`` for a guided run of ``rhs``: ``own(X, s, u,
    scale=...)`` if given (an extended model's: the correction exact) or
    central differences, with steps scaled by each state's RMS along
    ``guess``.

    The RMS of the whole guess, once: :func:`rowwise_jacobian`'s default
    takes it from the rows of each call (a pass with a NaN-aware mean over
    every block at every RK4 stage, a fifth of a held-out run's time at
    10^6 samples), and a state's typical size is the record's, not a
    block's.
    """
    scale = column_scale(guess)
    if own is not None:
        return lambda X, s, u: own(X, s, u, scale=scale)
    return lambda X, s, u: rowwise_jacobian(lambda z: rhs(z, s, u), X, scale=scale)


#: intervals of a guess checked first for being the run already
JOINED_SAMPLE = 100


class _NewtonBlock:
    """A guided free run's trajectory ``x`` (changed in place): whether it is
    the run already, and Newton's method on its intervals ``start:stop``
    from the exact state ``x[start]``."""

    def __init__(self, rhs, x, t, inputs, substeps, jac_x, split):
        self.rhs, self.x, self.t = rhs, x, t
        self.h = np.diff(t)
        self.inputs, self.substeps = inputs, substeps
        self.jac_x, self.split = jac_x, split

    def _flow(self, rows, jacobian: bool):
        """The RK4 map over the intervals ``rows`` (a slice or indices) from
        the current ``x``, with ``dPhi/dx`` if ``jacobian``."""
        with np.errstate(all="ignore"):
            return rk4_flow(
                self.rhs,
                self.x[:-1][rows],
                self.t[:-1][rows],
                self.h[rows],
                lambda frac: self.inputs.on_intervals(frac, rows),
                self.substeps,
                jac_x=self.jac_x if jacobian else None,
                split=self.split,
            )

    def is_the_run(self, tol, bound) -> bool:
        """Whether ``x`` is the free run already (a converged fit's
        trajectory): every defect at most ``tol`` and no state beyond
        ``bound``. Checked on ``JOINED_SAMPLE`` intervals spread over the
        record first (a guess that is not the run fails there, at a
        hundredth of a pass), then on all of them without derivatives: a
        fifth of the Newton iteration that would find the same."""
        x = self.x
        N = x.shape[0]
        if not np.max(np.abs(x)) < bound:
            return False
        stride = max(1, (N - 1) // JOINED_SAMPLE)
        checks = [slice(0, N - 1)]
        if stride > 1:
            checks.insert(0, np.arange(0, N - 1, stride))
        for rows in checks:
            defect = np.abs(self._flow(rows, jacobian=False).phi - x[1:][rows])
            if not (np.all(np.isfinite(defect)) and np.max(defect) <= tol):
                return False
        return True

    def solve(self, start, stop, tol, bound, max_iter) -> bool:
        """Whether the block converged (every defect at most ``tol``) and
        stayed within ``bound``."""
        x = self.x
        rows = slice(start, stop)
        last = np.inf
        for _ in range(max_iter):
            flow = self._flow(rows, jacobian=True)
            defect = flow.phi - x[start + 1 : stop + 1]
            A = flow.D
            if not (np.all(np.isfinite(defect)) and np.all(np.isfinite(A))):
                return False
            worst = float(np.max(np.abs(defect)))
            if worst <= tol:
                return float(np.max(np.abs(x[start : stop + 1]))) < bound
            if worst > GUIDED_BLOW_UP * last:
                return False
            last = worst
            step, info = solve_recursion(A, defect)
            if info != 0 or not np.all(np.isfinite(step)):
                return False
            x[start + 1 : stop + 1] += step
            inside = x[start + 1 : stop + 1]
            if not np.all(np.isfinite(inside)) or float(np.max(np.abs(inside))) > bound:
                return False
        return False
