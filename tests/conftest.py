"""Shared test configuration: hypothesis profile, case counts, tripwires.

The property-based tests (``tests/properties/``) run under a fixed
hypothesis profile, ``"ci"``: derandomised (the same examples on every run and
every machine, so CI is reproducible), no deadline (timings on a loaded
2-core runner vary), no example database written to disk, and each test sets
its own ``max_examples`` so that the whole file stays within its time budget.
Set ``HYPOTHESIS_PROFILE=dev`` for a randomised search (new examples on each
run, same counts) when hunting for bugs locally.

Every property test counts the inputs it generated per public entry point
through the ``case_counter`` fixture; the counts are printed in the terminal
summary, so they show in normal CI output.

The ``no_long_computation`` fixture puts the tripwires of
``bad_input_support.py`` in place for the bad-input tables
(``tests/<package>/test_bad_input.py``; the command line's is
``tests/cli/test_cli_slips.py``).
"""

from __future__ import annotations

import os
from collections import Counter

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "ci",
    derandomize=True,
    deadline=None,
    database=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.register_profile(
    "dev",
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

if os.environ.get("PYTEST_XDIST_WORKER"):
    # One BLAS thread per worker: with a worker per core, threaded BLAS in
    # each would oversubscribe the cores (small solves then run 100x slower).
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)

_CASES = pytest.StashKey[Counter]()


def pytest_configure(config):
    config.stash[_CASES] = Counter()


@pytest.fixture
def no_long_computation(monkeypatch):
    """Any solver reached raises ``LongComputationStarted``: checks come first."""
    from bad_input_support import install_tripwires

    install_tripwires(monkeypatch)


@pytest.fixture(scope="session")
def case_counter(pytestconfig) -> Counter:
    """``case_counter[entry_point] += 1`` for every generated input."""
    return pytestconfig.stash[_CASES]


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    _audit_summary(terminalreporter)
    counts = config.stash.get(_CASES, None)
    if not counts:
        return
    terminalreporter.section("hypothesis: generated cases per entry point")
    width = max(len(name) for name in counts)
    for name, count in sorted(counts.items()):
        terminalreporter.write_line(f"{name:<{width}}  {count:>6}")
    terminalreporter.write_line(f"{'total':<{width}}  {sum(counts.values()):>6}")


@pytest.fixture(autouse=True)
def audited_studies(monkeypatch):
    """Every study a test runs is audited as it returns (``report_audit``):
    its report's claims against its result, its RMSEs against free runs
    written in the tests (before the test can change the result)."""
    import report_audit

    from pysindy_mme.discovery import study as study_module

    original = study_module.run_study

    def audited(study, progress):
        res = original(study, progress)
        report_audit.audit(res)
        return res

    monkeypatch.setattr(study_module, "run_study", audited)


def _audit_summary(terminalreporter):
    import report_audit

    if report_audit.audited_runs:
        terminalreporter.section("studies audited against independent free runs")
        for what, count in sorted(report_audit.audited_runs.items()):
            terminalreporter.write_line(f"{what}: {count}")
