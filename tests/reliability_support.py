"""Helpers of the reliability tests: read-only inputs and the global random state.

A read-only input makes any in-place modification by the code under test an
error; the global random state (numpy's legacy generator and ``random``)
must be left exactly as it was.
"""

from __future__ import annotations

import random

import numpy as np

__all__ = [
    "assert_same_global_random_state",
    "global_random_state",
    "readonly",
    "warning_types",
]


def readonly(arr) -> np.ndarray:
    """A float copy that cannot be written: code that modifies its input fails."""
    out = np.array(arr, dtype=float)
    out.setflags(write=False)
    return out


def global_random_state():
    return np.random.get_state(), random.getstate()  # noqa: NPY002 - the global state


def assert_same_global_random_state(before):
    after = global_random_state()
    np_before, np_after = before[0], after[0]
    assert np_before[0] == np_after[0]
    np.testing.assert_array_equal(np_before[1], np_after[1])
    assert np_before[2:] == np_after[2:]
    assert before[1] == after[1]


def warning_types(record) -> set:
    """Classes of the warnings caught by ``warnings.catch_warnings(record=True)``."""
    return {type(w.message) for w in record}
