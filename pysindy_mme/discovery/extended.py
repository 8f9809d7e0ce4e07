"""ExtendedModel: the assumed model plus an identified correction."""

from __future__ import annotations

import numpy as np

from ..core.features import SelectedFeatures
from ..core.model import as_model_function, simulate_model
from ..core.tables import sig

__all__ = ["ExtendedModel"]


def _format_terms(coefs, names, digits) -> str:
    """``-1.007 x1 + 0.0004213 x2``: significant digits, zeros left out."""
    parts = []
    for c, name in zip(coefs, names):
        if c == 0:
            continue
        sign = "-" if c < 0 else "+"
        body = sig(abs(c), digits) + ("" if name == "1" else f" {name}")
        parts.append((sign, body))
    if not parts:
        return ""
    first_sign, first = parts[0]
    text = ("-" if first_sign == "-" else "") + first
    return text + "".join(f" {s} {b}" for s, b in parts[1:])


class ExtendedModel:
    """Assumed model plus a correction ``Theta(x, u) @ coef.T``.

    ``dx/dt = f(x, t, u) + Theta(x, u) C^T + b``, where ``f`` is the user's
    assumed model, ``Theta`` a fitted pysindy feature library evaluated on the
    states followed by the inputs, ``C`` the correction coefficients and ``b``
    an optional constant (used when the optimizer fitted its own intercept).

    Parameters
    ----------
    assumed_model : callable, pysindy model or ExtendedModel
        ``f(x, t)`` or ``f(x, t, u)``, vectorised over rows.
    feature_library : fitted pysindy feature library
    coefficients : array-like (n_states, n_library_features)
        Correction coefficients; rows of states without error are zero.
    state_names : list of str
    input_names : list of str, optional
    intercept : array-like (n_states,), optional
    assumed_equations : list of str, optional
        Text of the assumed right-hand sides, shown by :meth:`equations`.
    z_reference : ndarray, optional
        Library input data used to check the fast evaluation of terms.

    Attributes
    ----------
    correction_coef_ : ndarray (n_states, n_library_features)
    correction_intercept_ : ndarray (n_states,)
    """

    def __init__(
        self,
        assumed_model,
        feature_library,
        coefficients,
        state_names,
        input_names=(),
        intercept=None,
        assumed_equations=None,
        z_reference=None,
    ):
        self.state_names = list(state_names)
        self.input_names = list(input_names)
        self.n_states = len(self.state_names)
        self.assumed_model = assumed_model
        self._assumed = as_model_function(assumed_model, self.n_states)
        self.feature_library = feature_library
        self.correction_coef_ = np.array(coefficients, dtype=float)
        n_vars = self.n_states + len(self.input_names)
        if self.correction_coef_.ndim != 2 or self.correction_coef_.shape[0] != (
            self.n_states
        ):
            raise ValueError(
                "coefficients must have shape (n_states, n_library_features), got "
                f"{self.correction_coef_.shape}"
            )
        self.correction_intercept_ = (
            np.zeros(self.n_states)
            if intercept is None
            else np.array(intercept, dtype=float).reshape(self.n_states)
        )
        self.assumed_equations = assumed_equations
        self.library_feature_names = list(
            feature_library.get_feature_names(self.state_names + self.input_names)
        )
        self.active_ = np.flatnonzero(np.any(self.correction_coef_ != 0, axis=0))
        if z_reference is None:
            z_reference = np.random.default_rng(0).uniform(-2, 2, (64, n_vars))
        self._features = SelectedFeatures(
            feature_library,
            self.state_names + self.input_names,
            self.active_,
            np.asarray(z_reference, dtype=float),
        )

    @property
    def n_inputs(self) -> int:
        return len(self.input_names)

    def correction(self, x, u=None) -> np.ndarray:
        """The identified correction ``Theta(x, u) C^T + b`` at each row."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        if self.n_inputs:
            if u is None:
                raise TypeError(
                    f"u is required: the model has inputs {self.input_names}"
                )
            u = np.asarray(u, dtype=float).reshape(x.shape[0], self.n_inputs)
            z = np.hstack([x, u])
        else:
            z = x
        out = np.tile(self.correction_intercept_, (x.shape[0], 1))
        if self.active_.size:
            out += self._features(z) @ self.correction_coef_[:, self.active_].T
        return out

    def predict(self, x, u=None, t=None) -> np.ndarray:
        """``dx/dt`` of the extended model at states ``x`` (rows)."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        if self.n_inputs and u is None:
            raise TypeError(f"u is required: the model has inputs {self.input_names}")
        t = np.zeros(x.shape[0]) if t is None else t
        return self._assumed(x, t, u) + self.correction(x, u)

    def __call__(self, x, t, u=None) -> np.ndarray:
        return self.predict(x, u=u, t=t)

    def simulate(self, x0, t, u=None, **kwargs) -> np.ndarray:
        """Integrate the extended model from ``x0`` on the times ``t``.

        ``u`` is an array on ``t`` (interpolated linearly) or a callable
        ``u(t)``. Keyword arguments go to
        :func:`~pysindy_mme.core.model.simulate_model` (``rtol``, ``atol``,
        ``method``, ``max_evaluations``). It returns, or raises
        :class:`~pysindy_mme.DivergenceError` naming the time and the state
        where the model blew up (or turned so stiff that it exhausted its
        budget of evaluations: it never hangs); ``TypeError``/``ValueError``
        for bad arguments.
        """
        if self.n_inputs and u is None:
            raise TypeError(f"u is required: the model has inputs {self.input_names}")
        kwargs.setdefault("on_divergence", "raise")
        return simulate_model(self, x0, t, u, n_states=self.n_states, **kwargs)

    def equations(self, precision: int = 4) -> list:
        """Right-hand sides, the assumed part and the correction shown apart.

        Coefficients to ``precision`` significant digits (never rounded away).
        """
        out = []
        for i, name in enumerate(self.state_names):
            assumed = (
                self.assumed_equations[i]
                if self.assumed_equations is not None
                else f"f_{name}(x, t)"
            )
            names = ["1"] + self.library_feature_names
            coefs = np.concatenate(
                [[self.correction_intercept_[i]], self.correction_coef_[i]]
            )
            corr = _format_terms(coefs, names, precision)
            if corr:
                out.append(f"[assumed] {assumed}  +  [correction] {corr}")
            else:
                out.append(f"[assumed] {assumed}")
        return out

    def print(self, precision: int = 4, **kwargs) -> None:
        """Print the equations like ``pysindy.SINDy.print``."""
        for name, eq in zip(self.state_names, self.equations(precision)):
            print(f"({name})' = {eq}", **kwargs)

    def __repr__(self) -> str:
        n_terms = int(np.count_nonzero(self.correction_coef_))
        return (
            f"ExtendedModel(states={self.state_names}, inputs={self.input_names}, "
            f"correction_terms={n_terms})"
        )
