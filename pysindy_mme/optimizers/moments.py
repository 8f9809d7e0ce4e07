"""Sufficient statistics of a tall, narrow library: the selection in two passes.

With ``n`` rows and few columns (a million samples of a degree-2 polynomial
library), every statistic the selection reads is a function of a few small
matrices that two passes over the data compute once for every target:

* ``R``, the triangular factor of ``Z = sqrt(w) [1, X, Y]`` (the weighted
  constant, the eligible library columns, every target; each column in its
  power-of-two units). The least-squares fit of any target on any subset of
  columns, hence every classic partial F-ratio, follows from ``R`` alone
  (``R^T R = Z^T Z``, and a QR factor is as accurate as a QR of the data).
* With ``U`` the library's columns orthonormalised and, for each target,
  its part orthogonal to the library normalised, every vector the selection
  forms (a model's residual, a candidate's part orthogonal to the model,
  the rows of a model's pseudo-inverse) is ``U a`` for a small coefficient
  vector ``a``. A Newey-West score is a product of two such vectors,
  ``(U a) * (U b) = P v`` with ``P`` the products of pairs of columns of
  ``U`` and ``v`` built from ``a`` and ``b``; so its long-run variance is
  ``v^T S v`` with ``S`` the Bartlett long-run covariance of ``P``
  (:attr:`LibraryMoments.bartlett`). Scores are of fourth order in the data,
  so lagged Gram matrices of the library itself would not do.
* The lag-0 and lag-1 Gram matrices of ``U`` give a residual's lag-1
  autocorrelation (``floating="auto"``), and the Bartlett long-run
  covariance of ``U`` itself a residual's long-run variance (the table's
  effective number of observations).

Cost: ``O(n m^2)`` for ``R`` and ``O(n m^4 / 4)`` for ``S`` with ``m``
columns in ``Z``, against ``O(n (k + 20) lags)`` per step of the direct
computation: worth it for tall, narrow libraries only (:func:`use_moments`).
Where ``Z`` is ill-conditioned (``U`` would not be orthonormal to working
accuracy, e.g. a noise-free target in the span of the library), there are
no moments and the selection works on the data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ._numeric import BLOCK_ELEMENTS, one_blas_thread, pow2_scale
from .robust import WINDOW_ROWS, BartlettWindows

__all__ = [
    "LibraryMoments",
    "library_moments",
    "pair_vectors",
    "tall_moments",
    "use_moments",
]

# The moments pay off from this many rows ...
MIN_ROWS = 20_000
# ... for at most this many columns in Z (constant, eligible columns,
# targets): S is (m (m + 1) / 2)^2 and costs n m^4 / 8 multiply-adds.
MAX_COLUMNS = 16
# U = Z R^-1 is orthonormal to about eps * cond(R); beyond this the robust
# statistics would lose more than a few digits.
MAX_CONDITION = 1e7


def use_moments(n_rows: int, n_columns: int) -> bool:
    """Whether a library of ``n_rows`` rows and ``n_columns`` columns of ``Z``
    is tall and narrow enough for :func:`library_moments`."""
    return n_rows >= MIN_ROWS and n_columns <= MAX_COLUMNS


@dataclass(frozen=True)
class LibraryMoments:
    """What the selection of every target reads, computed once.

    Attributes
    ----------
    R : ndarray (m, m)
        Upper triangular factor of ``Z = sqrt(w) [1, X[:, columns], Y]``.
    target_norms : ndarray (n_targets,)
        Norm of each target's part orthogonal to the library.
    usable : ndarray of bool (n_targets,)
        Whether that part is large enough for the target to be selected from
        the moments (not where the target is in the library's span to within
        ``1 / MAX_CONDITION``, e.g. noise-free: its columns of ``U`` are 0).
    columns : ndarray of int (m_x,)
        Library column of each of ``Z``'s columns ``1 .. m_x``.
    position : ndarray of int (n_features,)
        Column of ``Z`` holding each library column (-1: not eligible).
    n_rows : int
        Number of rows (the Newey-West small-sample factor counts rows).
    lags : int or None
        Bartlett bandwidth of :attr:`bartlett` (None: not computed).
    lag0, lag1 : ndarray (m, m)
        ``U^T U`` and ``sum_t U[t]^T U[t + 1]``.
    bartlett : ndarray (m (m + 1) / 2, m (m + 1) / 2) or None
        Long-run covariance of the pair products ``U[:, i] * U[:, j]``,
        ``i <= j`` in :func:`numpy.triu_indices` order.
    bartlett_linear : ndarray (m, m) or None
        Long-run covariance of ``U``.
    """

    R: np.ndarray
    target_norms: np.ndarray
    usable: np.ndarray
    columns: np.ndarray
    position: np.ndarray
    n_rows: int
    lags: int | None
    lag0: np.ndarray
    lag1: np.ndarray
    bartlett: np.ndarray | None
    bartlett_linear: np.ndarray | None

    def target_column(self, target: int) -> int:
        """Column of ``Z`` (and ``U``) that holds ``target``."""
        return 1 + self.columns.size + int(target)

    def target_factor(self, target: int) -> np.ndarray:
        """Triangular factor of ``[1, X, y_target]`` in the columns of ``U``.

        ``[1, X, y] = [U_x, u_target] R_t``: the library's factor, the
        target's coordinates on the library's columns and its own norm.
        """
        mx = 1 + self.columns.size
        rt = np.zeros((mx + 1, mx + 1))
        rt[:mx, :mx] = self.R[:mx, :mx]
        rt[:mx, mx] = self.R[:mx, self.target_column(target)]
        rt[mx, mx] = self.target_norms[target]
        return rt


def pair_vectors(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Coefficients on the pair products of the scores ``(U a) * (U b)``.

    ``a``, ``b``: (m, c) (or (m,), broadcast). ``(U a)_t (U b)_t =
    sum_{i <= j} v_ij U_ti U_tj`` with ``v_ij = a_i b_j + a_j b_i`` (``i <
    j``) and ``v_ii = a_i b_i``. Returns (m (m + 1) / 2, c).
    """
    a = np.atleast_2d(np.asarray(a, dtype=float).T).T
    b = np.atleast_2d(np.asarray(b, dtype=float).T).T
    i, j = np.triu_indices(a.shape[0])
    v = a[i] * b[j] + a[j] * b[i]
    v[i == j] *= 0.5
    return v


def _design_blocks(x, sw, y_scaled, columns, scale, rows: int):
    """Row blocks of ``Z = sqrt(w) [1, X[:, columns] * scale, Y]``."""
    n = x.shape[0]
    for start in range(0, n, rows):
        stop = min(start + rows, n)
        s = sw[start:stop, None]
        yield np.hstack(
            [s, x[start:stop, columns] * scale[columns] * s, y_scaled[start:stop] * s]
        )


def library_moments(x, sw, y_scaled, screen, lags=None):
    """The :class:`LibraryMoments` of a library, or None if ``Z`` is ill-conditioned.

    Parameters
    ----------
    x : ndarray (n, n_features)
        The library (columns that are not ``screen.eligible`` are not read).
    sw : ndarray (n,)
        Square roots of the (positive) frequency weights.
    y_scaled : ndarray (n, n_targets)
        The targets, each in its power-of-two units.
    screen : Screen
        The library screen (eligible columns and their scales).
    lags : int, optional
        Newey-West bandwidth; None skips the Bartlett moments (classic rules).
    """
    # The passes make hundreds of small BLAS calls (one per block of rows):
    # with several BLAS threads on a busy machine each call waits for its
    # threads (measured: 50 s instead of 4.5 s at a million rows, load 12 on
    # 2 cores); one thread loses little where the machine is idle.
    with one_blas_thread():
        return _library_moments(x, sw, y_scaled, screen, lags)


def _library_moments(x, sw, y_scaled, screen, lags):
    y_scaled = np.asarray(y_scaled, dtype=float).reshape(x.shape[0], -1)
    columns = np.flatnonzero(screen.eligible)
    m = 1 + columns.size + y_scaled.shape[1]
    rows = max(WINDOW_ROWS, BLOCK_ELEMENTS // m)
    # Pass 1: R by a QR of each block, then of the stacked factors (TSQR).
    factors = [
        np.linalg.qr(z, mode="r")
        for z in _design_blocks(x, sw, y_scaled, columns, screen.scale, rows)
    ]
    R = np.linalg.qr(np.vstack(factors), mode="r")
    if R.shape[0] < m:
        return None
    R = R * np.where(np.diag(R) < 0, -1.0, 1.0)[:, None]
    mx = 1 + columns.size
    if not np.linalg.cond(R[:mx, :mx]) < MAX_CONDITION:
        return None
    # U: the library orthonormalised, then each target's part orthogonal to
    # the library, normalised (targets need not be independent of each other:
    # a target's vectors only use the library's columns and its own).
    rho = np.linalg.norm(R[mx:, mx:], axis=0)
    usable = rho > np.linalg.norm(R[:, mx:], axis=0) / MAX_CONDITION
    rinv = np.eye(m)
    rinv[:mx, :mx] = scipy.linalg.solve_triangular(R[:mx, :mx], np.eye(mx))
    for t in np.flatnonzero(usable):
        rinv[:mx, mx + t] = -(rinv[:mx, :mx] @ R[:mx, mx + t]) / rho[t]
        rinv[mx + t, mx + t] = 1.0 / rho[t]
    rinv[:, mx:][:, ~usable] = 0.0
    # Pass 2: U = Z rinv block by block, its lag-0/1 Gram matrices and the
    # Bartlett moments of its pair products.
    lag0 = np.zeros((m, m))
    lag1 = np.zeros((m, m))
    i, j = np.triu_indices(m)
    windows = linear = bartlett = bartlett_linear = None
    if lags is not None:
        windows = BartlettWindows(lags, i.size)
        linear = BartlettWindows(lags, m)
        bartlett = np.zeros((i.size, i.size))
        bartlett_linear = np.zeros((m, m))
    last = None
    for z in _design_blocks(x, sw, y_scaled, columns, screen.scale, WINDOW_ROWS):
        u = z @ rinv
        lag0 += u.T @ u
        lag1 += u[:-1].T @ u[1:]
        if last is not None:
            lag1 += np.outer(last, u[0])
        last = u[-1]
        if windows is not None:
            b = windows.feed(u[:, i] * u[:, j])
            bartlett += b.T @ b
            b = linear.feed(u)
            bartlett_linear += b.T @ b
    if windows is not None:
        b = windows.tail()
        bartlett += b.T @ b
        bartlett /= windows.lags + 1.0
        b = linear.tail()
        bartlett_linear += b.T @ b
        bartlett_linear /= linear.lags + 1.0
    position = np.full(x.shape[1], -1)
    position[columns] = 1 + np.arange(columns.size)
    return LibraryMoments(
        R=R,
        target_norms=rho,
        usable=usable,
        columns=columns,
        position=position,
        n_rows=int(x.shape[0]),
        lags=None if lags is None else int(lags),
        lag0=lag0,
        lag1=lag1,
        bartlett=bartlett,
        bartlett_linear=bartlett_linear,
    )


def tall_moments(x, w, y, screen, lags=None):
    """The moments of a tall, narrow library (:func:`use_moments`), else None.

    ``w``: positive frequency weights; ``y`` (n, n_targets), each target put
    in its power-of-two units here as the selection does.
    """
    if not use_moments(x.shape[0], int(screen.eligible.sum()) + 1 + y.shape[1]):
        return None
    y_scale = pow2_scale(np.max(np.abs(y), axis=0, initial=0.0))
    return library_moments(x, np.sqrt(w), y * y_scale, screen, lags)
