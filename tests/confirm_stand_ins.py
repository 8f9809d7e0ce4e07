"""Stand-ins for the confirmation search's fits, with chosen costs.

The confirmation rules (``discovery/confirm.py``) read a few attributes of an
``OutputErrorFit``; these stand-ins give them directly, so that a rule can be
tested alone at the costs a whole study produced.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pysindy_mme.discovery.confirm import _Search

__all__ = ["StandInFit", "stand_in_fit", "stand_in_search"]


@dataclass
class StandInFit:
    """What the search reads of an OutputErrorFit (a dataclass, as the fit
    is, so that ``dataclasses.replace`` works on it)."""

    slots: tuple
    coefficients: np.ndarray
    cost: float
    joined: bool
    p_values: np.ndarray
    n_free: int
    physical: np.ndarray = field(default_factory=lambda: np.zeros(3))
    offsets: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ok: bool = True
    n_iter: int = 5
    message: str = ""
    residual_variance: float = 1.0
    inflation: float = 1.0
    dof: int = 900
    n_residuals: int = 917
    theta: object = None
    x: object = None

    @property
    def converged(self) -> bool:
        return self.joined

    def coefficient_p_values(self) -> np.ndarray:
        return self.p_values

    def bic(self, c: float = 1.0) -> float:
        return self.cost / c + self.n_free * np.log(self.n_residuals)


def stand_in_fit(slots, cost, joined=True, p=None) -> StandInFit:
    """A stand-in fit of ``slots`` at transcription cost ``cost``."""
    k = len(slots)
    return StandInFit(
        slots=tuple(slots),
        coefficients=np.full(k, 0.44),
        cost=float(cost),
        joined=joined,
        p_values=np.full(k, 1e-12) if p is None else np.asarray(p, float),
        n_free=2 + k,
    )


def stand_in_search(fits: dict, assumed_cost=9204.0):
    """A search whose every fit of a set of terms is ``fits[frozenset]``."""
    search = _Search(
        engine=None,
        assumed=stand_in_fit((), assumed_cost),
        alpha_term=1e-4,
        describe=lambda slot: f"c{slot[1]} in x{slot[0]}'",
        pool=[],
        progress=None,
    )
    search.effects = lambda fit: np.ones(len(fit.slots))  # large: p decides
    calls = []

    def refit(slots, coefs, start, polish=False):
        calls.append(frozenset(slots))
        return fits[frozenset(slots)]

    search.refit = refit
    search.calls = calls
    return search
