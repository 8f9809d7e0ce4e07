"""discover_many (issue 20): many studies on a Dask cluster or local processes
give the results of as many serial discover calls, to the last bit.

Fifty short records of the paper's Van der Pol case (``tests/many_case.py``)
run once serially through :func:`discover`, then through
:func:`discover_many` on a ``LocalCluster`` of two worker processes on the
loopback interface, and on local processes (joblib: six records on two
processes; all fifty, on one process per core, in a ``slow`` test); every
result must be identical, and the warnings re-issued must be the serial
calls' warnings, each prefixed with its record. Failures of single
studies, the kinds of entry and the progress line are checked on a few
records. Bad input is in ``test_bad_input_many.py``.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import warnings

import numpy as np
import pytest
from many_case import (
    BrokenOptimizer,
    records,
    same_result,
    shared_keywords,
)

from pysindy_mme import (
    Discovery,
    StudiesFailedError,
    StudyFailure,
    discover,
    discover_many,
)

N_RECORDS = 50


def _serial(entries, **overrides):
    """discover on each record in turn, with the warnings each one gave."""
    out, caught_all = [], []
    for y, t in entries:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            out.append(discover(y, t, **shared_keywords(**overrides)))
        caught_all.append([str(w.message) for w in caught])
    return out, caught_all


def _many(entries, **engine):
    """discover_many with the warnings it re-issued."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = discover_many(entries, **engine, **shared_keywords())
    return out, [str(w.message) for w in caught]


def _prefixed(serial_warnings) -> list:
    """What discover_many re-issues for these serial calls' warnings."""
    return [
        f"records[{i}]: {message}"
        for i, messages in enumerate(serial_warnings)
        for message in messages
    ]


@pytest.fixture(scope="module")
def fifty():
    entries = records(N_RECORDS)
    return (entries, *_serial(entries))


@pytest.fixture(scope="module")
def cluster_client():
    pytest.importorskip(
        "distributed",
        reason="the cluster tests need dask's distributed: "
        "pip install pysindy-mme[distributed]",
    )
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


@pytest.mark.slow  # a whole study: keeps the edit loop under 2 minutes
def test_fifty_records_on_a_local_cluster_match_fifty_serial_calls(
    fifty, cluster_client, capsys
):
    entries, serial, serial_warnings = fifty
    many, caught = _many(entries, client=cluster_client)
    assert len(many) == N_RECORDS
    for one, other in zip(serial, many):
        assert isinstance(other, Discovery)
        assert same_result(one, other)
    assert caught == _prefixed(serial_warnings)
    assert f"discover_many: {N_RECORDS}/{N_RECORDS} studies done" in (
        capsys.readouterr().err
    )
    # the results came back from the workers, and pickle again
    assert str(pickle.loads(pickle.dumps(many[0]))) == str(serial[0])


def test_local_processes_match_serial_calls():
    """Two local processes (joblib), on six records (seeds 25-30: two of
    them warn). Not from the fifty: under pytest-xdist each worker would
    rebuild them."""
    entries = records(6, first=25)
    serial, serial_warnings = _serial(entries)
    many, caught = _many(entries, n_jobs=2, progress=False)
    for one, other in zip(serial, many):
        assert same_result(one, other)
    assert caught and caught == _prefixed(serial_warnings)


@pytest.mark.slow
def test_fifty_records_on_local_processes_match_fifty_serial_calls(fifty):
    entries, serial, serial_warnings = fifty
    many, caught = _many(entries, progress=False)  # one process per core
    for one, other in zip(serial, many):
        assert same_result(one, other)
    assert caught == _prefixed(serial_warnings)


def test_in_this_process_with_the_warnings_of_serial_calls():
    """n_jobs=1: the same results, each study's warnings re-issued with its
    record, in the order of the records (seeds 26-28: one of them warns)."""
    entries = records(3, first=26)
    serial, serial_warnings = _serial(entries)
    many, caught = _many(entries, n_jobs=1, progress=False)
    for one, other in zip(serial, many):
        assert same_result(one, other)
    assert caught and caught == _prefixed(serial_warnings)


def test_every_kind_of_entry_gives_the_same_study():
    """A Record, a tuple, an array with a shared t, a dict, and a list of
    records (one study of several): each is what discover would run."""
    from pysindy_mme import Record

    (y, t), (y2, t2) = records(2)
    many = discover_many(
        [Record(y, t), {"y": y, "t": t}, [Record(y, t), Record(y2, t2)]],
        n_jobs=1,
        progress=False,
        **shared_keywords(),
    )
    alone = discover(y, t, **shared_keywords())
    same_result(alone, many[0])
    same_result(alone, many[1])
    several = discover([Record(y, t), Record(y2, t2)], **shared_keywords())
    same_result(several, many[2])
    shared_t = discover_many([y], t=t, n_jobs=1, progress=False, **shared_keywords())
    same_result(alone, shared_t[0])


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_a_failed_study_is_named_and_the_others_are_kept(n_jobs):
    entries = records(3)
    broken = {"y": entries[1][0], "t": entries[1][1], "optimizer": BrokenOptimizer()}
    with pytest.raises(StudiesFailedError, match=r"1 of 3 studies failed") as info:
        discover_many(
            [entries[0], broken, entries[2]],
            n_jobs=n_jobs,
            progress=False,
            **shared_keywords(),
        )
    assert "records[1]: RuntimeError: this optimizer breaks on purpose" in str(
        info.value
    )
    results = info.value.results
    assert isinstance(results[0], Discovery) and isinstance(results[2], Discovery)
    (failure,) = info.value.failures
    assert results[1] is failure and failure.index == 1
    assert isinstance(failure.exception, RuntimeError)
    assert "fit" in failure.traceback
    # on_error="return": the same list, returned
    kept = discover_many(
        [entries[0], broken],
        n_jobs=n_jobs,
        progress=False,
        on_error="return",
        **shared_keywords(),
    )
    assert isinstance(kept[0], Discovery) and isinstance(kept[1], StudyFailure)


def test_progress_line_counts_the_studies(capsys):
    discover_many(records(2), n_jobs=1, **shared_keywords())
    err = capsys.readouterr().err
    assert "discover_many: 0/2 studies done" in err
    assert "discover_many: 2/2 studies done" in err
    discover_many(records(1), n_jobs=1, progress=False, **shared_keywords())
    assert "discover_many" not in capsys.readouterr().err


def test_the_inputs_are_not_modified():
    entries = records(2)
    keywords = shared_keywords()
    before = [(y.copy(), t.copy()) for y, t in entries]
    options = dict(keywords["options"])
    discover_many(entries, n_jobs=1, progress=False, **keywords)
    for (y, t), (y0, t0) in zip(entries, before):
        assert (y == y0).all() and (t == t0).all()
    assert keywords["options"] == options


def test_dask_is_imported_only_for_a_client():
    """dask stays an optional extra: importing the package and running on
    this process or local processes never imports it."""
    code = (
        "import sys, pysindy_mme\n"
        "from many_case import records, shared_keywords\n"
        "pysindy_mme.discover_many(records(1), n_jobs=1, progress=False,\n"
        "                          **shared_keywords())\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in\n"
        "             ('dask', 'distributed')))\n"
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_a_client_without_distributed_installed(monkeypatch, no_long_computation):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails
    with pytest.raises(TypeError, match=r"pip install pysindy-mme\[distributed\]"):
        discover_many(records(1), client=object(), **shared_keywords())


def test_a_lambda_model_travels_by_value():
    """cloudpickle sends a lambda (or a function defined in a function) by
    value, so local processes run it; the results are the serial ones."""

    def model(x, t):
        return np.column_stack([x[:, 1], np.zeros(len(x))])

    entries = records(2)
    keywords = shared_keywords(assumed_model=lambda x, t: model(x, t))
    serial = [discover(y, t, **keywords) for y, t in entries]
    many = discover_many(entries, n_jobs=2, progress=False, **keywords)
    for one, other in zip(serial, many):
        assert same_result(one, other)


def test_warnings_of_the_checks_come_first_with_their_record(monkeypatch):
    """A warning of a study's checks is issued before that study's own, as
    discover gives them; when a later record is refused, the warnings of
    the records checked before it are still issued."""
    from pysindy_mme.discovery import many as many_module

    real = many_module.prepare_study

    def warning_check(y, t, **keywords):
        warnings.warn("checked", UserWarning, stacklevel=2)
        return real(y, t, **keywords)

    monkeypatch.setattr(many_module, "prepare_study", warning_check)
    (y, t), (y2, t2) = records(2, first=26)
    _, caught = _many([(y, t), (y2, t2)], n_jobs=1, progress=False)
    assert caught[0] == "records[0]: checked"
    assert caught.index("records[1]: checked") > 0
    with warnings.catch_warnings(record=True) as refused:
        warnings.simplefilter("always")
        with pytest.raises(ValueError, match=r"records\[1\]: t has 5 entries"):
            discover_many([(y, t), (y2, t2[:5])], n_jobs=1, **shared_keywords())
    assert [str(w.message) for w in refused] == [
        "records[0]: checked",
        "records[1]: checked",
    ]
