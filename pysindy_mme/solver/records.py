"""What the transcription solver works on and returns."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Linearization", "SmootherResult"]


@dataclass
class Linearization:
    """Everything the KKT system needs at one trajectory (independent of W)."""

    x: np.ndarray  # (N, n)
    d: np.ndarray  # (N-1, q)
    theta: np.ndarray  # (p,)
    A: np.ndarray  # (N-1, n, n)
    G: np.ndarray  # (N-1, n, q)
    B: np.ndarray  # (N-1, n, p)
    defects: np.ndarray  # (N-1, n): Phi_k(x_k, d_k) - x_{k+1}
    r: np.ndarray  # (N, m) residuals, 0 where y is missing
    H: np.ndarray  # (N, m, n) or (m, n) for a linear measurement


@dataclass
class SmootherResult:
    """Solution of the transcribed problem for one weight ``W``.

    Attributes
    ----------
    W : ndarray (q, q)
    x : ndarray (N, n)
        State estimate at the sample times.
    d : ndarray (N-1, q)
        Model error, constant on each interval.
    theta : ndarray (p,)
        Global parameters (empty for plain MME).
    lam : ndarray (N-1, n)
        Multipliers of the dynamics constraints (of ``J / 2``).
    residuals : ndarray (N, m)
        ``y - g(x)``; NaN where ``y`` is missing.
    cost : float
        ``J`` at the solution.
    measurement_cost, model_error_cost : float
        Its two parts.
    logdet : float
        ``log|det K|`` of the last KKT matrix (see the module docstring).
    neg2_log_likelihood : float
        ``-2 log p(y | W)`` (restricted, Laplace approximation if nonlinear).
    converged : bool
    n_iter : int
        Gauss-Newton iterations (KKT solves).
    max_defect : float
        Largest dynamics defect ``|Phi_k(x_k, d_k) - x_{k+1}|`` at the end.
    message : str
    rank_deficient : bool
        Some combination of the parameters is not determined by the data.
    nonfinite_trials : int
        Line-search trial steps at which the model blew up (stepped back).
    """

    W: np.ndarray
    x: np.ndarray
    d: np.ndarray
    lam: np.ndarray
    residuals: np.ndarray
    cost: float
    measurement_cost: float
    model_error_cost: float
    logdet: float
    neg2_log_likelihood: float
    converged: bool
    n_iter: int
    max_defect: float
    message: str
    theta: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rank_deficient: bool = False
    nonfinite_trials: int = 0
    _lin: Linearization | None = field(default=None, repr=False)
