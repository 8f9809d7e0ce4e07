"""What both selection states compute the same way from one small factor.

:class:`~.incremental_qr.IncrementalQR` (from the rows) and
:class:`~.gram.GramState` (from the library's moments) keep the same
quantities of the current model: the triangular factor ``T`` of the
weighted constant and the model's columns, the target's coordinates ``z``
in that basis, the residual sum of squares, and for every candidate its
squared residual norm ``nr2`` against the model and ``g = r_j^T e``. The
coefficients and the classic partial F-ratios (the paper's eqs. 10, 19, 20)
follow from those by the same formulas, written once here.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from scipy.linalg.lapack import dtrtri

from ._numeric import safe_ratio

__all__ = ["EXACT_FIT_RTOL", "LeastSquaresState", "RefactoredState"]

# A target reproduced to this relative accuracy is fitted to rounding level:
# partial F-ratios computed from a rounding-noise residual are meaningless, so
# no further function may enter.
EXACT_FIT_RTOL = 1e-12


class LeastSquaresState:
    """Coefficients and classic partial F-ratios of a selection state.

    A subclass sets ``support``, ``in_model``, ``eligible``, ``T``, ``z``,
    ``nr2``, ``g``, ``cn2``, ``tol2``, ``n_eff``, ``sst``, ``floor2``,
    ``scale``, ``y_unit``, ``carrier``, ``carrier_value`` and defines
    :meth:`sse`.
    """

    def _start(self, screen, n_eff, tolerance, y_unit) -> None:
        """The attributes every state takes from the library's screen, and
        the empty model."""
        self.scale = screen.scale
        self.y_unit = y_unit
        self.carrier = screen.carrier
        self.carrier_value = screen.carrier_value
        self.eligible = screen.eligible
        self.cn2 = screen.cn2
        self.n_eff = n_eff
        self.tol2 = tolerance**2
        self.support = []  # library columns, in the order they entered
        self.in_model = np.zeros(screen.eligible.size, dtype=bool)

    @property
    def k(self) -> int:
        return len(self.support)

    def sse(self) -> float:  # pragma: no cover - defined by every subclass
        raise NotImplementedError

    def exact_fit(self) -> bool:
        return self.sse() <= self.floor2

    def coefficients(self) -> np.ndarray:
        """Least-squares coefficients of ``[constant, support...]`` (data units).

        A coefficient beyond the double range (a target in units of ``2**600``
        on a column in units of ``2**-600``) is ``inf`` here, as in ``coef_``:
        the selection works on scaled data and is unaffected.
        """
        beta = scipy.linalg.solve_triangular(self.T, self.z)
        with np.errstate(over="ignore"):
            beta *= self.y_unit
            beta[1:] *= self.scale[self.support]
        return beta

    def coefficient_row(self) -> np.ndarray:
        """Coefficients on every library column; the constant on its carrier column.

        (Without a carrier column the constant is left out: ``coef_``'s meaning.)
        """
        beta = self.coefficients()
        row = np.zeros(self.in_model.size)
        row[self.support] = beta[1:]
        if self.carrier is not None:
            row[self.carrier] = beta[0] / self.carrier_value
        return row

    def overall_f(self) -> float:
        """Model F-ratio MSR / MSE (eq. 10); 0 for the constant-only model."""
        k = self.k
        if k == 0:
            return 0.0
        sse = self.sse()
        return float(safe_ratio((self.sst - sse) / k, sse / (self.n_eff - k - 1)))

    def _tinv(self, T=None):
        T = self.T if T is None else T
        tinv, info = dtrtri(T, lower=0)
        if info != 0:  # pragma: no cover - T is nonsingular by construction
            tinv = np.linalg.pinv(T)
        return tinv

    def in_model_f(self) -> np.ndarray:
        """Partial F-ratios (eq. 20) of ``[constant, support...]``: ``t**2``."""
        tinv = self._tinv()
        beta = tinv @ self.z
        diag = np.einsum("ij,ij->i", tinv, tinv)
        s2 = self.sse() / (self.n_eff - self.k - 1)
        return safe_ratio(beta**2, s2 * diag)

    def candidate_f(self) -> np.ndarray:
        """Partial F-ratios of entry (eq. 19); ``-inf`` where not eligible."""
        sse = self.sse()
        dof_new = self.n_eff - self.k - 2
        elig = self.eligible & ~self.in_model & (self.nr2 > self.tol2 * self.cn2)
        if dof_new < 1:
            elig[:] = False
        with np.errstate(divide="ignore", invalid="ignore"):
            red = np.where(elig, self.g**2 / np.where(elig, self.nr2, 1.0), 0.0)
        red = np.minimum(red, sse)
        f = safe_ratio(red * dof_new, np.maximum(sse - red, 0.0))
        return np.where(elig, f, -np.inf)


class RefactoredState(LeastSquaresState):
    """A state that refactors its model after each step (``_update``), for
    the states read from moments (:class:`~.gram.GramState`,
    :class:`~.corrected_state.CorrectedState`): ``O(m^3)`` per step, no rows."""

    def _update(self) -> None:  # pragma: no cover - defined by every subclass
        raise NotImplementedError

    def add(self, j: int) -> None:
        self.support.append(int(j))
        self.in_model[j] = True
        self._update()

    def remove(self, j: int) -> None:
        self.support.remove(int(j))
        self.in_model[j] = False
        self._update()
