"""Hidden states: a state nobody measured, added to the assumed model in one line.

``discover(..., hidden_states={"z": "v"})`` gives the assumed model a new
state ``z`` that enters the equation of ``v`` additively and whose own law is
unknown (``z' = 0`` assumed, every term of it searched in the library)::

    x' = f(x, t, u)              (the user's model, states x)
    v' = f_v(x, t, u) + z        (z enters the equation it names)
    z' = 0 + d_z(t)              (the model error lives here)

Why this form. A state that is never measured has no scale of its own: any
multiple of it, with its law rescaled, predicts the same measurements. Letting
it enter its equation with gain one fixes the scale, and gives it a meaning a
user can read: ``z`` is the part of ``v'`` that has memory, in the units of
``v'`` (a hysteretic force ``F`` on a mass ``m`` in ``m v' = ... - F``
appears as ``z = -F / m``). A law in ``z`` is then found in those units: a
term linear in ``z`` keeps its coefficient under any rescaling, a term
without ``z`` scales with it.

By default the model error is placed on the hidden states only (the study
estimates ``z`` by MME from what ``v'`` misses, then searches ``z'``'s law);
``error_states`` may add others. ``z``'s initial value is fitted with the
other initial states.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..core.model import ModelFunction

__all__ = ["HiddenStates", "add_hidden_states"]


class HiddenStates:
    """The checked ``hidden_states`` option: names and the equations they enter.

    Parameters
    ----------
    spec : dict
        ``{hidden name: equation}``, the equation a state name (from
        ``feature_names``) or index of the assumed model.
    state_names : list of str
        Names of the assumed model's states.
    """

    def __init__(self, spec, state_names):
        if not isinstance(spec, Mapping) or not spec:
            raise TypeError(
                "hidden_states must be a non-empty dict {name: equation it enters}, "
                f"e.g. {{'z': 'v'}}; got {spec!r}"
            )
        names = list(state_names)
        self.names, self.enters = [], []
        for name, target in spec.items():
            if not isinstance(name, str) or not name.isidentifier():
                raise ValueError(
                    f"hidden_states: the name {name!r} must be an identifier "
                    "(it is printed in the equations)"
                )
            if name in names or name in self.names:
                raise ValueError(f"hidden_states: {name!r} is already a state name")
            if isinstance(target, str):
                if target not in names:
                    raise ValueError(
                        f"hidden_states: {name!r} enters {target!r}, which is not a "
                        f"state of the assumed model (states: {names})"
                    )
                index = names.index(target)
            elif isinstance(target, (int, np.integer)) and not isinstance(target, bool):
                if not 0 <= int(target) < len(names):
                    raise ValueError(
                        f"hidden_states: {name!r} enters state {target}, out of "
                        f"range for {len(names)} states"
                    )
                index = int(target)
            else:
                raise TypeError(
                    f"hidden_states: the equation {name!r} enters must be a state "
                    f"name or index, got {target!r}"
                )
            self.names.append(name)
            self.enters.append(index)
        self.n_visible = len(names)

    @property
    def indices(self) -> list:
        """Indices of the hidden states in the augmented state vector."""
        return list(range(self.n_visible, self.n_visible + len(self.names)))

    def augment(self, dx: np.ndarray, x: np.ndarray) -> np.ndarray:
        """``[dx + (each hidden state added to its equation), 0 per hidden]``."""
        out = np.zeros((x.shape[0], self.n_visible + len(self.names)))
        out[:, : self.n_visible] = dx
        for k, j in enumerate(self.enters):
            out[:, j] += x[:, self.n_visible + k]
        return out


def add_hidden_states(model, n_states, hidden_states, state_names=None, grey=False):
    """The assumed model with hidden states appended (see module docstring).

    Parameters
    ----------
    model : callable, pysindy model or ExtendedModel
        The user's ``f(x, t[, u])``, or ``f(x, t, u, p)`` when ``grey``.
    n_states : int
        States of ``model``.
    hidden_states : dict or HiddenStates
        ``{name: equation it enters}``.
    state_names : list of str, optional
        Names of ``model``'s states (default ``x0, x1, ...``).
    grey : bool
        ``model`` takes grey-box parameters ``p``.

    Returns
    -------
    augmented : callable
        ``f(x, t, u)`` (``f(x, t, u, p)`` when ``grey``) on the augmented
        states ``[x, hidden]``.
    hidden : HiddenStates
    """
    names = (
        list(state_names)
        if state_names is not None
        else [f"x{i}" for i in range(int(n_states))]
    )
    hidden = (
        hidden_states
        if isinstance(hidden_states, HiddenStates)
        else HiddenStates(hidden_states, names)
    )
    n = hidden.n_visible
    if grey:
        if not callable(model):
            raise TypeError(
                "with parameters, assumed_model must be a callable f(x, t, u, p)"
            )

        return _AugmentedGrey(model, hidden), hidden
    return _Augmented(ModelFunction(model, n), hidden), hidden


class _Augmented:
    """``f(x, t, u)`` on ``[x, hidden]``: the user's model on ``x``, each
    hidden state added to its equation (a class, not a closure: a result
    holding it pickles when the user's model does)."""

    def __init__(self, inner, hidden: HiddenStates):
        self.inner, self.hidden = inner, hidden

    @property
    def hidden_states(self) -> HiddenStates:
        """The states appended (read by the exporter, which knows no study)."""
        return self.hidden

    def __call__(self, x, t, u=None):
        x = np.asarray(x, dtype=float)
        n = self.hidden.n_visible
        return self.hidden.augment(self.inner(x[:, :n], t, u), x)


class _AugmentedGrey:
    """:class:`_Augmented` for a grey-box ``f(x, t, u, p)``."""

    def __init__(self, model, hidden: HiddenStates):
        self.model, self.hidden = model, hidden

    @property
    def hidden_states(self) -> HiddenStates:
        """The states appended (read by the exporter, which knows no study)."""
        return self.hidden

    def __call__(self, x, t, u, p):
        x = np.asarray(x, dtype=float)
        n = self.hidden.n_visible
        dx = np.asarray(self.model(x[:, :n], t, u, p), dtype=float)
        return self.hidden.augment(dx.reshape(x.shape[0], n), x)
