"""Every public entry point has a bad-input table, and the tables are sound.

The tables live with their packages; this check loads each by its path (the
same file pytest runs) and asks: is every entry point there, does each have
enough cases, are the case ids unique, and does every case name an
exception type and a message phrase. The command line's table,
``tests/cli/test_cli_slips.py``, keeps its own names: ``SLIPS``, a list of
``Slip`` cases (exit code 2 and the phrases of the message), run by
``test_command_line_slip_is_named``.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from bad_input_support import Bad

TESTS = Path(__file__).resolve().parent

# entry point -> (table file, fewest cases it must hold)
TABLES = {
    "MME": ("differentiation/test_bad_input.py", 25),
    "discover": ("discovery/test_bad_input.py", 20),
    "discover_many": ("discovery/test_bad_input_many.py", 15),
    "PowerLibrary": ("feature_library/test_bad_input.py", 15),
    "FloatingFStepwise": ("optimizers/test_bad_input.py", 30),
    "command line": ("cli/test_cli_slips.py", 35),
}

# entry point -> (table, test running it), where not BAD_INPUTS and test_bad_input
OWN_NAMES = {"command line": ("SLIPS", "test_command_line_slip_is_named")}


def _load(relative):
    path = TESTS / relative
    name = "_bad_input_table_" + relative.replace("/", "_").removesuffix(".py")
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _table(entry_point, module):
    name = OWN_NAMES.get(entry_point, ("BAD_INPUTS",))[0]
    return getattr(module, name)


@pytest.mark.parametrize("entry_point", sorted(TABLES))
def test_every_entry_point_has_a_sound_table(entry_point):
    relative, minimum = TABLES[entry_point]
    module = _load(relative)
    assert module.ENTRY_POINT == entry_point
    table = _table(entry_point, module)
    assert len(table) >= minimum
    ids = [case.id for case in table]
    assert len(set(ids)) == len(ids), "case ids must be unique"
    if entry_point in OWN_NAMES:  # command-line slips: exit code 2, phrases
        assert all(isinstance(case, module.Slip) for case in table)
        assert all(case.phrases and all(case.phrases) for case in table)
    else:
        assert all(isinstance(case, Bad) for case in table)
        for case in table:
            assert isinstance(case.exc, type) and issubclass(case.exc, Exception)
            assert case.match, case.id
    # each table runs under the tripwires
    test = getattr(module, OWN_NAMES.get(entry_point, (None, "test_bad_input"))[1])
    assert "no_long_computation" in test.__code__.co_varnames


def test_the_tables_together_cover_enough_cases():
    total = sum(
        len(_table(entry_point, _load(relative)))
        for entry_point, (relative, _) in TABLES.items()
    )
    assert total >= 25
