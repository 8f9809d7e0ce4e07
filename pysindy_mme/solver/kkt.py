"""The banded KKT system of one Gauss-Newton step of direct transcription.

Unknowns per sample ``k``: ``[dx_k (n), lam_k (n)]`` (the last multiplier
block is a dummy identity so that every block has size ``2 n``); rows::

    x_k:    Q_k dx_k + A_k^T lam_k - lam_{k-1}            = b_x[k]
    lam_k:  A_k dx_k - S_k lam_k   - dx_{k+1}             = b_lam[k]

``Q_k = H_k^T R_k^-1 H_k``, ``A_k = dPhi_k/dx``, ``S_k = G_k (h_k W)^-1 G_k^T``
(zero when the dynamics are hard constraints: output error). The matrix is
symmetric indefinite with bandwidth ``2 n - 1``; LAPACK's banded LU with
partial pivoting (``dgbtrf``/``dgbtrs``) solves it in ``O(N n^3)`` time and
``O(N n^2)`` memory.

A break between records (interval ``k`` with no dynamics link: the next
record starts at ``k + 1``) turns ``lam_k``'s block into the dummy identity
of the last block and drops its couplings, so ``x_{k+1}`` is a free initial
state; the bandwidth is unchanged.

Global parameters ``theta`` (``p`` of them: correction coefficients,
physical parameters, measurement offsets) border the band::

    [ K    E ] [ z      ]   [ b ]
    [ E^T  D ] [ dtheta ] = [ c ]

``E`` holds ``H_k^T R_k^-1 M_k`` in the ``x_k`` rows and ``B_k = dPhi_k /
dtheta`` in the ``lam_k`` rows; ``D = sum_k M_k^T R_k^-1 M_k``. It is solved
by the Schur complement ``Sc = D - E^T K^-1 E`` (``p + 1`` banded solves),
which is also the reduced Hessian of the cost in ``theta`` once the states
are optimised out: ``s^2 Sc^-1`` is the covariance of ``theta``. ``Sc`` is
equilibrated (unit diagonal) before it is factorised, so parameters of any
scale (coefficients from 1e-4 to 1e6 in one model) are handled alike.
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import blas, lapack

__all__ = [
    "BandedKKT",
    "Border",
    "KKTFactor",
    "ReducedBorder",
    "as_border",
    "drop_kept_border",
    "drop_kept_factor",
    "equilibrated_inverse",
    "keep_factor",
    "kept_factor",
    "solve_reduced",
    "subtract_product",
    "undetermined",
]

# Intervals assembled per block: bounded temporaries stay in cache.
CHUNK = 1 << 15

# Band buffers of factors no longer alive (flat; at most _IDLE_MAX kept, the
# largest), for the next factorisation that fits in one. Any buffer at least
# as large serves, whatever the shape it was made for: the refits of a
# held-out stretch (a band of 0.8 N samples) reuse the whole record's band
# instead of allocating a second one next to it (576 instead of 320 bytes
# per sample of two states at that stage of a study, its peak). One idle
# buffer only: after a stage where two factors lived at once (MME), a second
# idle band would sit beside the one in use for the rest of the study.
_IDLE: list = []
_IDLE_MAX = 1
# factors may die in any thread (studies run in threads by a scheduler)
_IDLE_LOCK = threading.Lock()


# One factor kept after its solve for the statistics that follow at the same
# linearisation (a fit's last Gauss-Newton step, then its covariance and its
# score tests factorise the same matrix). It holds the band only until any
# factorisation wants one (_take_band drops it first), so it never puts a
# second band beside the one in use.
_KEPT: list = []
_KEPT_LOCK = threading.Lock()


def keep_factor(key, fac) -> None:
    """Keep ``fac`` for :func:`kept_factor` with the same ``key``.

    ``key`` is a tuple of the objects the matrix was built from (held by
    weak reference: a key whose objects died matches nothing) and
    hashable values (compared by ``==``).
    """
    refs = tuple(weakref.ref(k) if _weakrefable(k) else ("value", k) for k in key)
    with _KEPT_LOCK:
        _KEPT[:] = [(refs, fac)]


def kept_factor(key):
    """The factor kept under ``key`` (see :func:`keep_factor`), or None."""
    with _KEPT_LOCK:
        if not _KEPT:
            return None
        refs, fac = _KEPT[0]
    if len(refs) != len(key):
        return None
    for ref, k in zip(refs, key):
        if isinstance(ref, tuple):
            # a value: k must be a value too, and equal
            if _weakrefable(k) or ref[1] != k:
                return None
        elif ref() is not k:
            return None
    return fac


def drop_kept_factor() -> None:
    """Forget the kept factor (its band goes back to the pool)."""
    with _KEPT_LOCK:
        dropped = list(_KEPT)
        _KEPT.clear()
    del dropped  # the factor dies here, outside the lock (_give_back locks)


def drop_kept_border() -> None:
    """Forget the border eliminated with the kept factor (see
    :meth:`KKTFactor.keep_border`); the factor itself stays kept."""
    with _KEPT_LOCK:
        kept = _KEPT[0][1] if _KEPT else None
    if kept is not None:
        kept.border = None


def _weakrefable(obj) -> bool:
    try:
        weakref.ref(obj)
    except TypeError:
        return False
    return True


def _take_band(shape) -> np.ndarray:
    """A band buffer of ``shape`` to factorise in: a view of the smallest idle
    buffer that holds it, or a new one.

    The buffer belongs to the factor made in it until that factor is garbage
    (:func:`_give_back`), so two live factors never share memory. When no
    idle buffer is large enough, the idle ones are dropped before the new
    one is allocated: they would only sit next to it.
    """
    size = int(np.prod(shape))
    drop_kept_factor()  # its band serves the new factor
    with _IDLE_LOCK:
        fits = [k for k, b in enumerate(_IDLE) if b.size >= size]
        if fits:
            flat = _IDLE.pop(min(fits, key=lambda k: _IDLE[k].size))
        else:
            _IDLE.clear()
            flat = None
    if flat is None:
        flat = np.empty(size)
    return flat[:size].reshape(shape)


def _give_back(band) -> None:
    """Keep the (whole) buffer of a dead factor for the next factorisation."""
    flat = band if band.base is None else band.base
    with _IDLE_LOCK:
        _IDLE.append(flat)
        while len(_IDLE) > _IDLE_MAX:  # the largest stay: they serve any size
            del _IDLE[min(range(len(_IDLE)), key=lambda k: _IDLE[k].size)]


@dataclass
class KKTFactor:
    """A factorised KKT matrix (see :meth:`BandedKKT.factor`)."""

    lu: np.ndarray
    piv: np.ndarray
    n: int
    N: int
    logdet: float
    pivot_ratio: float
    #: ``(weak reference to B, KEt, EtKE)``: a border ``E`` (its block
    #: ``B``, compared by identity) eliminated with this factor, ``K^-1 E``
    #: as ``(p, N 2n)`` rows and ``E^T K^-1 E`` (see :meth:`eliminated`)
    border: tuple | None = field(default=None, repr=False, compare=False)

    def keep_border(self, E, KEt, EtKE) -> None:
        """Keep ``K^-1 E`` (``KEt``, ``(p, N 2n)``) and ``E^T K^-1 E`` for
        later solves with the same border (:meth:`eliminated`).

        A fit's statistics (covariance, score tests, the integrator check)
        solve the bordered system of its last Gauss-Newton step again, with
        the same factor and border: kept, the ``p`` columns of the border
        are not solved again (on a long record each statistic solved them
        anew, a banded solve of ``p`` columns and a copy of the border).
        Only a :class:`Border` without offsets' rows is kept: its block
        ``B`` is the linearisation's own array, so identity says it is the
        same border (the offsets' rows are a product made anew at each
        call). It is forgotten when ``B`` dies: a fit that releases its
        linearisation (``keep_statistics``) releases it too, instead of it
        sitting, with the kept band, beside the next linearisation (at 10^6
        samples that was the study's peak).
        """
        if type(E) is not Border or E.Ex is not None:
            return
        me = weakref.ref(self)

        def forget(_, me=me):
            fac = me()
            if fac is not None:
                fac.border = None

        self.border = (weakref.ref(E.B, forget), KEt, EtKE)

    def eliminated(self, E):
        """``(K^-1 E as (p, N 2n), E^T K^-1 E)`` for ``E`` kept by
        :meth:`keep_border` or a column subset of it, else None."""
        border = self.border
        if border is None or not isinstance(E, Border) or E.Ex is not None:
            return None
        ref, KEt, EtKE = border
        B = ref()
        if B is None:
            return None
        if E.B is B:
            return KEt, EtKE
        parent, keep = E.parent
        if parent is not None and parent.B is B and parent.Ex is None:
            keep = np.arange(EtKE.shape[0])[keep]
            return KEt[keep], EtKE[np.ix_(keep, keep)]
        return None

    def solve(self, rhs: np.ndarray, rows=None) -> np.ndarray:
        """Solve ``K z = rhs`` for ``rhs`` of shape ``(N, 2n)`` or ``(N, 2n, k)``.

        ``rows`` (a contiguous slice of the samples) returns only those
        samples of ``z`` (the covariance of the initial state needs sample 0
        of ``n`` solutions: not a copy of ``n`` columns of the record).
        """
        shape = rhs.shape
        # a Fortran-ordered copy (the caller's array stays as it was)
        cols = np.array(np.reshape(rhs, (self.N * 2 * self.n, -1)), order="F")
        sol = self.solve_in_place(cols)
        if rows is not None:
            sl = range(self.N)[rows]
            if sl.step != 1:  # pragma: no cover - a bug, not a user error
                raise ValueError("rows must be a contiguous slice")
            per = 2 * self.n
            sol = sol[sl.start * per : sl.stop * per]
            shape = (len(sl),) + shape[1:]
        return np.ascontiguousarray(sol).reshape(shape)

    def solve_in_place(self, cols: np.ndarray) -> np.ndarray:
        """Overwrite ``cols`` (Fortran-ordered, ``(N 2n, k)``) with ``K^-1 cols``.

        LAPACK works on Fortran columns: a right-hand side in that order is
        solved where it is, where a C-ordered one is copied in and the
        answer copied out again (on a long record, with the parameters'
        columns, each copy is as large as the band).
        """
        if not cols.flags.f_contiguous:  # pragma: no cover - a bug
            raise ValueError("solve_in_place needs a Fortran-ordered array")
        kl = ku = 2 * self.n - 1
        sol, info = lapack.dgbtrs(self.lu, kl, ku, cols, self.piv, overwrite_b=1)
        if info != 0:  # pragma: no cover - a bug, not a user error
            raise RuntimeError(f"dgbtrs: illegal argument {-info}")
        return sol


class BandedKKT:
    """Assembles and factorises the KKT matrix for ``N`` samples of ``n`` states.

    Band buffers are reused, not allocated per factorisation: a fresh
    ``O(N)`` allocation per iteration costs more in page faults than the
    factorisation itself. A factor owns its buffer while it is alive; when
    it is garbage the buffer goes to a small pool (:data:`_IDLE`) from which
    the next factorisation of the same size, by any instance, takes it. So a
    solver does not hold a band between its factorisations: on a long record
    every fitted model (MME's smoother, each output-error fit kept for its
    statistics) held one of its own, 320 bytes per sample for two states,
    most of the memory of a study.
    """

    def __init__(self, N: int, n: int, breaks=None):
        self.N, self.n = N, n
        #: intervals ``k`` with no dynamics link between samples ``k`` and
        #: ``k + 1`` (a new record starts at ``k + 1``): their multiplier rows
        #: become ``lam_k = 0`` and ``x_{k+1}`` a free initial state
        self.breaks = (
            np.zeros(0, dtype=int) if breaks is None else np.asarray(breaks, int)
        )

    def factor(self, Q, A, S) -> KKTFactor:
        """Assemble from ``Q (N, n, n)``, ``A (N-1, n, n)``, ``S (N-1, n, n)``
        (or None: hard constraints) and factorise.

        Matrix entry (i, j) lives in ``ab[kl + ku + i - j, j]`` (LAPACK band
        storage); ``abT`` is its transpose in C order, so ``abT.T`` is the
        Fortran-ordered array dgbtrf factorises in place without a copy.
        Raises ``LinAlgError`` if a pivot is exactly zero or not finite.
        """
        n, N = self.n, self.N
        kl = ku = 2 * n - 1
        ldab = 2 * kl + ku + 1
        diag = kl + ku
        shape = (N, 2 * n, ldab)
        abT = _take_band(shape)
        try:
            lu, piv, info = self._factor_in(abT, Q, A, S)
        except BaseException:
            _give_back(abT)
            raise
        udiag = np.abs(lu[diag])
        umax = float(np.max(udiag))
        if info > 0 or not (np.isfinite(umax) and umax > 0):
            _give_back(abT)
            raise np.linalg.LinAlgError("singular KKT system")
        logdet = float(np.sum(np.log(udiag)))
        fac = KKTFactor(lu, piv, n, N, logdet, float(np.min(udiag)) / umax)
        weakref.finalize(fac, _give_back, abT)
        return fac

    def _factor_in(self, abT, Q, A, S):
        """Assemble into the buffer ``abT`` and run ``dgbtrf`` in place."""
        n, N = self.n, self.N
        kl = ku = 2 * n - 1
        diag = kl + ku
        ldab = abT.shape[2]
        K = N - 1
        for lo in range(0, N, CHUNK):
            hi = min(lo + CHUNK, N)
            blk = abT[lo:hi]
            blk.fill(0.0)
            m = min(hi, K) - lo  # rows of this block that have an interval
            for b in range(n):
                # Column b of block k: rows x_k (Q_k[:, b]) and lam_k
                # (A_k[:, b]); column n + b (lam_k's): rows x_k (A_k^T),
                # lam_k (-S_k), and x_{k+1}'s -1 below.
                blk[:, b, diag - b : diag - b + n] = Q[lo:hi, :, b]
                blk[:m, b, diag + n - b : diag + 2 * n - b] = A[lo : lo + m, :, b]
                blk[:m, n + b, diag - n - b : diag - b] = A[lo : lo + m, b, :]
                if S is not None:
                    blk[:m, n + b, diag - b : diag - b + n] = -S[lo : lo + m, :, b]
                blk[:m, n + b, diag + n] = -1.0
                blk[1 if lo == 0 else 0 :, b, diag - n] = -1.0
        abT[-1, n:, :] = 0.0
        abT[-1, np.arange(n, 2 * n), diag] = 1.0  # dummy multiplier, last block
        kb = self.breaks
        if kb.size:
            # a break only removes couplings: the band stays the band
            for b in range(n):
                abT[kb, b, diag + n - b : diag + 2 * n - b] = 0.0  # A_k (lam rows)
                abT[kb, n + b, :] = 0.0  # A_k^T, -S_k and the -1 to x_{k+1}
                abT[kb, n + b, diag] = 1.0  # lam_k = 0: a dummy multiplier
                abT[kb + 1, b, diag - n] = 0.0  # -x_{k+1} in lam_k's row
        ab = abT.reshape(N * 2 * n, ldab).T
        lu, piv, info = lapack.dgbtrf(ab, kl, ku, overwrite_ab=1)
        if info < 0:  # pragma: no cover - a bug, not a user error
            raise RuntimeError(f"dgbtrf: illegal argument {-info}")
        return lu, piv, info


@dataclass
class ReducedSolution:
    """Solution of the bordered system.

    Attributes
    ----------
    z : ndarray (N, 2n[, k])
    dtheta : ndarray (p[, k])
    Sc : ndarray (p, p)
        Reduced Hessian ``D - E^T K^-1 E``.
    rank_deficient : bool
        ``Sc`` is singular to working precision (a parameter the data do not
        determine); the step then uses the pseudo-inverse.
    """

    z: np.ndarray
    dtheta: np.ndarray
    Sc: np.ndarray
    rank_deficient: bool


def undetermined(Sc: np.ndarray, rcond: float = 1e-10) -> np.ndarray:
    """Which parameters take part in a direction ``Sc`` does not determine.

    Boolean mask: parameters with a component above 1e-3 in an eigenvector
    of the equilibrated ``Sc`` whose eigenvalue is below ``rcond`` times the
    largest (or a zero or non-finite diagonal).
    """
    p = Sc.shape[0]
    if p == 0:
        return np.zeros(0, bool)
    diag = np.abs(np.diag(Sc))
    good = np.isfinite(diag) & (diag > 0)
    scale = np.where(good, 1.0 / np.sqrt(np.where(good, diag, 1.0)), 0.0)
    scaled = 0.5 * (Sc + Sc.T) * scale[:, None] * scale[None, :]
    if not np.all(np.isfinite(scaled)):
        return np.ones(p, bool)
    w, V = np.linalg.eigh(scaled)
    weak = w <= rcond * max(float(np.max(w)), 0.0)
    mask = ~good
    if np.any(weak):
        mask |= np.any(np.abs(V[:, weak]) > 1e-3, axis=1)
    return mask


def equilibrated_inverse(Sc: np.ndarray, rcond: float = 1e-10):
    """``Sc^-1`` via unit-diagonal scaling and a symmetric eigendecomposition.

    Returns ``(inverse, rank_deficient)``. Directions with eigenvalues below
    ``rcond`` times the largest (after scaling) are dropped (pseudo-inverse).
    """
    p = Sc.shape[0]
    if p == 0:
        return np.zeros((0, 0)), False
    Sc = 0.5 * (Sc + Sc.T)
    diag = np.abs(np.diag(Sc))
    good = np.isfinite(diag) & (diag > 0)
    scale = np.where(good, 1.0 / np.sqrt(np.where(good, diag, 1.0)), 0.0)
    scaled = Sc * scale[:, None] * scale[None, :]
    if not np.all(np.isfinite(scaled)):
        return np.full((p, p), np.nan), True
    w, V = np.linalg.eigh(scaled)
    top = max(float(np.max(w)), 0.0)
    keep = w > rcond * top if top > 0 else np.zeros(p, bool)
    inv_w = np.where(keep, 1.0 / np.where(keep, w, 1.0), 0.0)
    inverse = (V * inv_w) @ V.T
    deficient = bool(np.sum(keep) < p) or not np.all(good)
    return inverse * scale[:, None] * scale[None, :], deficient


class Border:
    """The parameters' columns ``E`` of the bordered KKT matrix, by blocks.

    ``E`` is ``(N, 2n, p)``: ``H_k^T R_k^-1 M`` in the ``x_k`` rows (``Ex``,
    None where it is zero: no measurement offsets) and ``B_k = dPhi_k /
    dtheta`` in the ``lam_k`` rows (the last sample's are zero). Kept as
    these blocks, ``E`` costs nothing beside the linearisation that holds
    ``B`` (written out it was 96 bytes per sample of two states with three
    parameters, half of them zeros, at every KKT step and statistic of a
    long record's fit).
    """

    #: ``(border, keep)`` when this one is ``border.columns(keep)``
    parent: tuple = (None, None)

    def __init__(self, Ex, B, N: int, n: int, p: int):
        self.Ex, self.B = Ex, B
        self.N, self.n, self.p = N, n, p

    @property
    def shape(self):
        return (self.N, 2 * self.n, self.p)

    def write_transposed(self, out) -> None:
        """``out[j] = E[:, :, j]`` for ``out (p, N, 2n)``."""
        n = self.n
        if self.Ex is None:
            out[:, :, :n] = 0.0
        else:
            out[:, :, :n] = np.moveaxis(self.Ex, 2, 0)
        out[:, :-1, n:] = np.moveaxis(self.B, 2, 0)
        out[:, -1, n:] = 0.0

    def dense(self) -> np.ndarray:
        out = np.empty((self.p, self.N, 2 * self.n))
        self.write_transposed(out)
        return np.ascontiguousarray(np.moveaxis(out, 0, 2))

    def t_dot(self, cols) -> np.ndarray:
        """``E^T X`` (``(p, k)``) for ``X``'s columns ``cols (k, N, 2n)``."""
        n = self.n
        # sums over the blocks where they lie: no copy of the columns. One
        # einsum per column: with several columns at once ("kip,jki->pj")
        # numpy's einsum runs 5x slower at 10^6 samples and p = k = 5
        # (550 ms against 100 ms), for the same sums in the same order
        out = np.empty((self.p, cols.shape[0]))
        for j, col in enumerate(cols):
            out[:, j] = np.einsum("kip,ki->p", self.B, col[:-1, n:])
            if self.Ex is not None:
                out[:, j] += np.einsum("kip,ki->p", self.Ex, col[:, :n])
        return out

    def dot(self, v) -> np.ndarray:
        """``E v`` (``(N, 2n)``) for ``v (p,)``."""
        n = self.n
        out = np.zeros((self.N, 2 * n))
        out[:-1, n:] = self.B @ v
        if self.Ex is not None:
            out[:, :n] = self.Ex @ v
        return out

    def columns(self, keep) -> Border:
        """The border of the parameters ``keep`` (a mask or indices)."""
        Ex = None if self.Ex is None else self.Ex[:, :, keep]
        B = self.B[:, :, keep]
        out = Border(Ex, B, self.N, self.n, B.shape[2])
        # a factor that eliminated this border serves the subset too
        out.parent = (self, keep)
        return out


class _DenseBorder(Border):
    """Any ``E (N, 2n, p)`` behind :class:`Border`'s methods."""

    def __init__(self, E):
        N, m, p = E.shape
        self.E, self.N, self.n, self.p = E, N, m // 2, p

    def write_transposed(self, out) -> None:
        out[:] = np.moveaxis(self.E, 2, 0)

    def dense(self) -> np.ndarray:
        return self.E

    def t_dot(self, cols) -> np.ndarray:
        k = cols.shape[0]
        return self.E.reshape(-1, self.p).T @ cols.reshape(k, -1).T

    def dot(self, v) -> np.ndarray:
        return self.E @ v

    def columns(self, keep) -> Border:
        return _DenseBorder(self.E[:, :, keep])


def as_border(E) -> Border:
    """``E`` as a :class:`Border` (a dense ``(N, 2n, p)`` array is wrapped)."""
    return E if isinstance(E, Border) else _DenseBorder(np.asarray(E, float))


def subtract_product(out: np.ndarray, a: np.ndarray, b: np.ndarray) -> None:
    """``out -= a.T @ b`` in place, for ``out (k, m)`` and ``b (p, m)`` in C
    order and a small ``a (p, k)``.

    ``out -= a.T @ b`` in numpy first makes the product: a temporary the size
    of ``out`` (k columns of the record: 64 MB for two candidates over 10^6
    samples of two states, at the peak of a study's score tests). BLAS adds
    the product into ``out`` where it lies (the transposes are Fortran views).
    """
    if out.size == 0 or a.size == 0:
        return
    if not (
        out.flags.c_contiguous
        and b.flags.c_contiguous
        and out.dtype == b.dtype == np.float64
    ):
        out -= a.T @ b
        return
    res = blas.dgemm(-1.0, b.T, np.asarray(a, float), beta=1.0, c=out.T, overwrite_c=1)
    if not np.shares_memory(res, out):  # pragma: no cover - BLAS copied
        out[...] = res.T


class ReducedBorder:
    """The border of one factor eliminated once, for many right-hand sides.

    :func:`solve_reduced` solves ``[b, E]`` together: right for one
    right-hand side. Tests of many candidates against one fit (score tests,
    in groups) would re-solve the ``p`` columns of ``E`` for every group;
    here ``K^-1 E`` and ``Sc`` are computed once and each group costs only
    its own columns (and holds only them beside ``K^-1 E``).
    """

    def __init__(self, fac: KKTFactor, E, D):
        self.fac, self.p = fac, D.shape[0]
        self._E = as_border(E)
        N, m = fac.N, 2 * fac.n
        kept = fac.eliminated(self._E) if self.p else None
        if kept is not None:
            KEt, EtKE = kept
            self._KEt = KEt.reshape(self.p, N, m)
        else:
            # K^-1 E as (p, N, 2n) C-ordered: the Fortran columns LAPACK solves
            self._KEt = np.empty((self.p, N, m))
            self._E.write_transposed(self._KEt)
            if self.p:
                fac.solve_in_place(self._KEt.reshape(self.p, -1).T)
            EtKE = self._E.t_dot(self._KEt)
        Sc = D - EtKE
        self.Sc = 0.5 * (Sc + Sc.T)
        self._inverse, self.rank_deficient = (
            equilibrated_inverse(self.Sc) if self.p else (self.Sc, False)
        )

    def new_columns(self, k: int) -> np.ndarray:
        """A zeroed ``(k, N, 2n)`` array to write ``k`` right-hand sides in
        (column ``j`` is ``out[j]``), for :meth:`solve_columns`."""
        return np.zeros((k, self.fac.N, 2 * self.fac.n))

    def solve_columns(self, cols: np.ndarray, c) -> np.ndarray:
        """Overwrite ``cols`` (from :meth:`new_columns`) with the states'
        part ``z`` of the bordered solution; returns ``dtheta (p, k)``."""
        k = cols.shape[0]
        flat = cols.reshape(k, -1)
        self.fac.solve_in_place(flat.T)
        if not self.p:
            return np.zeros((0, k))
        dtheta = self._inverse @ (np.asarray(c, float) - self._E.t_dot(cols))
        subtract_product(flat, dtheta, self._KEt.reshape(self.p, -1))
        return dtheta


def solve_reduced(
    fac: KKTFactor, E, D, b, c, rows=None, keep_border: bool = False
) -> ReducedSolution:
    """Solve the bordered system for ``b (N, 2n[, k])`` and ``c (p[, k])``.

    ``E`` has shape ``(N, 2n, p)``, ``D`` ``(p, p)``. ``rows`` (a slice of
    the samples) returns only those samples of ``z``: the covariance of the
    initial state needs sample 0 of ``n`` solutions, not ``n`` copies of the
    record. ``keep_border``: keep ``K^-1 E`` with ``fac`` for later solves
    with the same border (:meth:`KKTFactor.keep_border`); a border kept
    already is used instead of being solved again.
    """
    p = D.shape[0]
    if p == 0:
        z = fac.solve(b, rows)
        return ReducedSolution(z, np.zeros((0,) + b.shape[2:]), D, False)
    E = as_border(E)
    multi = b.ndim == 3
    bb = b if multi else b[:, :, None]
    cc = c if multi else c[:, None]
    k = bb.shape[2]
    rows_all = bb.shape[0] * bb.shape[1]
    # [b, E] as the Fortran columns LAPACK solves in place (its transpose
    # in C order): one array, not a concatenation, its copy and the copy of
    # the answer. The answer is read where it is: the transposes below are
    # views, and BLAS multiplies them as they lie (no C-ordered copies of
    # k + p columns of the record beside it: at the peak of a study that
    # was 192 bytes per sample of two states).
    kept = fac.eliminated(E)
    # A fresh array per call, not pooled as the band is: at 10^6 samples its
    # fresh pages cost 0.7-1.1 s of a study's system time, but kept idle
    # between solves it raised the study's peak over 1.5 kB per sample, and
    # pooled within a solve or on 4 kB pages it saved nothing measurable
    # (sessions 22 and 26, README)
    work = np.empty((k + (p if kept is None else 0), rows_all))
    work[:k] = bb.reshape(rows_all, k).T
    if kept is None:
        E.write_transposed(work[k:].reshape(p, fac.N, 2 * fac.n))
    fac.solve_in_place(work.T)
    if kept is None:
        Kbt, KEt = work[:k], work[k:]  # (k, rows), (p, rows): K^-1 b, K^-1 E
        EtKE = E.t_dot(KEt.reshape(p, fac.N, 2 * fac.n))
        if keep_border:
            # its rows stay in ``work``: with one right-hand side (a Gauss-
            # Newton step) that is k rows more than K^-1 E alone, where a
            # copy of K^-1 E would be a second array its size for a moment
            fac.keep_border(E, KEt, EtKE)
    else:
        Kbt, (KEt, EtKE) = work, kept
    Sc = D - EtKE
    Sc = 0.5 * (Sc + Sc.T)
    inverse, deficient = equilibrated_inverse(Sc)
    dtheta = inverse @ (cc - E.t_dot(Kbt.reshape(k, fac.N, 2 * fac.n)))
    # z = K^-1 b - K^-1 E dtheta, in place in the answer's first k rows
    if rows is None:
        subtract_product(Kbt, dtheta, KEt)
        # a copy, even where the transpose is contiguous already (k = 1):
        # a view would keep the whole answer alive
        z = np.array(Kbt.T, order="C").reshape(bb.shape)
    else:
        per = bb.shape[1]
        sl = range(bb.shape[0])[rows]
        cols = slice(sl.start * per, sl.stop * per) if sl.step == 1 else None
        if cols is None:  # pragma: no cover - a bug, not a user error
            raise ValueError("rows must be a contiguous slice")
        zt = Kbt[:, cols] - dtheta.T @ KEt[:, cols]
        z = np.array(zt.T, order="C").reshape((len(sl),) + bb.shape[1:])
    del work, Kbt, KEt
    if not multi:
        z, dtheta = z[..., 0], dtheta[:, 0]
    return ReducedSolution(z, dtheta, Sc, deficient)
