"""MME's priors on the model error ``d(t)``, and their registry.

``MME(error_model=...)`` (and ``discover(error_model=...)``, the command
line's ``--error-model``) takes an :class:`ErrorModel` object, or the name
(or an alias) of one listed in :data:`ERROR_MODELS`, the one place that
lists them: the checks of MME, of discover and of the command line, their
messages and the command line's help all read it. A new error model is one
module here (a subclass of :class:`ErrorModel`, or of
:class:`AugmentedErrorModel` when ``d`` becomes extra states) and one entry
in :data:`ERROR_MODELS`.
"""

from __future__ import annotations

import copy

from .base import (
    AugmentedErrorModel,
    AugmentedModel,
    ErrorModel,
    ErrorReading,
    SolverInputs,
)
from .gauss_markov import GaussMarkov
from .random_walk import RandomWalk
from .white import WhiteNoise

#: Every registered error model, in the order help texts list them.
ERROR_MODELS = (WhiteNoise, RandomWalk, GaussMarkov)

__all__ = [
    "ERROR_MODELS",
    "AugmentedErrorModel",
    "AugmentedModel",
    "ErrorModel",
    "ErrorReading",
    "SolverInputs",
    "error_model_names",
    "names_text",
    "resolve_error_model",
    *(cls.__name__ for cls in ERROR_MODELS),
]


def error_model_names() -> dict:
    """``{name or alias: class}`` of the registered error models."""
    names = {}
    for cls in ERROR_MODELS:
        for key in (cls.name, *cls.aliases):
            if key in names:
                raise RuntimeError(
                    f"error model name {key!r} is registered twice "
                    f"({names[key].__name__} and {cls.__name__})"
                )
            names[key] = cls
    return names


def names_text(quote: str = "'") -> str:
    """The accepted names for a message: ``'white', 'random_walk' or ...``."""
    parts = []
    for cls in ERROR_MODELS:
        text = f"{quote}{cls.name}{quote}"
        if cls.aliases:
            alias = ", ".join(f"{quote}{a}{quote}" for a in cls.aliases)
            text += f" (alias {alias})"
        parts.append(text)
    return ", ".join(parts[:-1]) + " or " + parts[-1] if len(parts) > 1 else parts[0]


def resolve_error_model(spec, argument: str = "error_model") -> ErrorModel:
    """A fresh, checked :class:`ErrorModel` for ``spec`` (a name or an object).

    An object is copied (the caller's stays as given, unfitted); a name
    makes the registered model with its default settings.
    """
    if isinstance(spec, ErrorModel):
        model = copy.deepcopy(spec)
    elif isinstance(spec, str) and spec in error_model_names():
        model = error_model_names()[spec]()
    else:
        raise ValueError(
            f"{argument} must be an ErrorModel object or a registered name "
            f"({names_text()}); got {spec!r}"
        )
    model.check()
    return model
