"""Shared machinery of the bad-input tables (one table per entry point).

Each table lives with the tests of its package (``tests/<package>/
test_bad_input.py``) and is a list of :class:`Bad` cases: a call that must
raise, the exception type and a phrase of its message. (The command line's
table is ``tests/cli/test_cli_slips.py``, a list of slips with their own
mechanics, run under the same tripwires.) Every case runs with
the tripwires of :func:`install_tripwires` in place (the ``no_long_computation``
fixture of ``conftest.py``): the argument checks must come before any long
computation, so a case that reaches a solver fails with
:class:`LongComputationStarted` instead of its documented error.

``tests/test_bad_input_coverage.py`` checks that every entry point has its
table and that the tables are big enough.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest
from reliability_support import readonly

__all__ = [
    "Bad",
    "LongComputationStarted",
    "assert_raises_as_documented",
    "install_tripwires",
    "params",
    "readonly",
    "with_value",
]


@dataclass(frozen=True)
class Bad:
    """One bad input: ``call(tmp_path)`` must raise ``exc`` matching ``match``.

    ``xfail`` names a known defect (the case is then a strict xfail, so it
    turns into a failure as soon as the defect is fixed).
    """

    id: str
    call: Callable
    exc: type
    match: str
    xfail: str | None = None


class LongComputationStarted(BaseException):
    """Raised by the tripwires: validation must come before any solver runs.

    A BaseException, so that no ``except Exception`` in the code under test
    can swallow it.
    """


def install_tripwires(monkeypatch) -> None:
    """Replace the entry points' long computations by a tripwire.

    MME's solver (``MMESmoother.solve``), the stepwise regression's first
    step over the library (``optimizers.preparation.screen_columns``, looked up
    there at call time) and the output-error fit of the study
    (``OutputErrorModel.fit``).
    """
    import pysindy_mme.optimizers.preparation as preparation_module
    from pysindy_mme.solver import MMESmoother
    from pysindy_mme.solver.output_error import OutputErrorModel

    def tripwire(*args, **kwargs):
        raise LongComputationStarted

    monkeypatch.setattr(MMESmoother, "solve", tripwire)
    monkeypatch.setattr(preparation_module, "screen_columns", tripwire)
    monkeypatch.setattr(OutputErrorModel, "fit", tripwire)


def params(table):
    """``pytest.param`` per case, with its id and (strict) xfail marker."""
    return [
        pytest.param(
            case,
            id=case.id,
            marks=[pytest.mark.xfail(strict=True, reason=case.xfail)]
            if case.xfail
            else [],
        )
        for case in table
    ]


def assert_raises_as_documented(case: Bad, tmp_path) -> None:
    """Run one case: its exception type and message phrase, nothing else."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # e.g. pysindy's own notices
        with pytest.raises(case.exc, match=case.match):
            case.call(tmp_path)


def with_value(arr, index, value) -> np.ndarray:
    """A read-only copy of ``arr`` with ``arr[index] = value``."""
    out = np.array(arr, dtype=float)
    out[index] = value
    return readonly(out)
