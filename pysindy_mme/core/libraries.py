"""Copies of pysindy feature libraries that work for every library type.

``sklearn.base.clone`` rebuilds an estimator from ``get_params()``; pysindy
2.1's ``CustomLibrary`` stores its functions under another name than its
``__init__`` argument, so ``clone`` fails on it (and on every
``GeneralizedLibrary``, ``TensoredLibrary`` ... holding one). A user whose
effect needs ``sign(v)`` or ``sin(x)`` must still be able to run the study,
so :func:`fresh_library` falls back to a deep copy.
"""

from __future__ import annotations

import copy

from sklearn.base import clone

__all__ = ["fresh_library"]


def fresh_library(library):
    """An independent copy of ``library`` (unfitted when ``clone`` works)."""
    try:
        return clone(library)
    except (AttributeError, TypeError, RuntimeError):
        return copy.deepcopy(library)
