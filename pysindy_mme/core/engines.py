"""Where independent tasks run: this process, local processes, or a Dask cluster.

An engine maps a function over items and yields ``(index, value, error)``
as each task finishes (``error`` the exception a task raised, ``value``
then None), so a caller can report progress and keep the other tasks'
results when one fails. Three engines:

- :class:`Serial`: one after another in this process (``n_jobs=1``);
- :class:`LocalProcesses`: joblib's loky processes (scikit-learn brings
  joblib, so this needs nothing more);
- :class:`DaskCluster`: one task per item on a ``distributed.Client``.
  ``dask`` and ``distributed`` are an optional extra
  (``pip install pysindy-mme[distributed]``), imported only here, only when
  a client is given.

Items for another process travel as bytes made by :func:`dumps`
(cloudpickle: functions defined in ``__main__`` or in a function travel by
value, module-level ones by reference), so every engine sends the same
bytes and a payload that cannot be read is one task's error, not the run's.
"""

from __future__ import annotations

import uuid

__all__ = ["DaskCluster", "LocalProcesses", "Serial", "choose", "dumps"]


def dumps(obj) -> bytes:
    """``obj`` as cloudpickle bytes (read back with :func:`pickle.loads`)."""
    # joblib needs cloudpickle (scikit-learn needs joblib): its own copy
    # before joblib 1.5, the package since
    try:
        import cloudpickle
    except ImportError:  # pragma: no cover - joblib < 1.5
        from joblib.externals import cloudpickle

    return cloudpickle.dumps(obj)


class Serial:
    """Every task in this process, in order; items are not copied."""

    remote = False

    def run(self, fn, items):
        for i, item in enumerate(items):
            try:
                value = fn(i, item)
            except Exception as exc:  # noqa: BLE001 - one task's error
                yield i, None, exc
            else:
                yield i, value, None


class LocalProcesses:
    """Tasks on ``n_jobs`` local processes (joblib, loky backend).

    ``fn`` must be importable by the processes (a module-level function)."""

    remote = True

    def __init__(self, n_jobs: int):
        self.n_jobs = n_jobs

    def run(self, fn, items):
        from joblib import Parallel, delayed

        items = list(items)
        try:  # results as they finish (joblib >= 1.4), else in order
            parallel = Parallel(
                n_jobs=self.n_jobs, backend="loky", return_as="generator_unordered"
            )
        except ValueError:
            parallel = Parallel(
                n_jobs=self.n_jobs, backend="loky", return_as="generator"
            )
        pending = set(range(len(items)))
        tasks = (delayed(_indexed)(fn, i, item) for i, item in enumerate(items))
        try:
            for i, value in parallel(tasks):
                pending.discard(i)
                yield i, value, None
        except Exception as exc:  # noqa: BLE001 - the pool broke: the rest failed
            for i in sorted(pending):
                yield i, None, exc


def _indexed(fn, i, item):
    """``(i, fn(i, item))``: the index travels with the result, so results
    can come back in any order."""
    return i, fn(i, item)


class DaskCluster:
    """One task per item on a Dask ``distributed.Client``.

    Items are scattered to the workers first (large records do not sit in
    the task graph); every task not yet finished is cancelled when the
    caller stops early (an interrupt, an error)."""

    remote = True

    def __init__(self, client):
        self.client = client

    def run(self, fn, items):
        from distributed import as_completed

        client = self.client
        data = client.scatter(list(items), hash=False)
        run = uuid.uuid4().hex[:8]
        futures = [
            client.submit(fn, i, d, key=f"{fn.__name__}-{run}-{i}")
            for i, d in enumerate(data)
        ]
        index = {f.key: i for i, f in enumerate(futures)}
        try:
            for future in as_completed(futures):
                i = index[future.key]
                try:
                    value = future.result()
                except Exception as exc:  # noqa: BLE001 - one task's error
                    yield i, None, exc
                else:
                    yield i, value, None
                future.release()
        finally:
            client.cancel(futures + data)


def choose(client=None, n_jobs=None):
    """The engine for ``client=`` / ``n_jobs=`` (checked; see
    :func:`~pysindy_mme.discover_many`)."""
    if client is not None:
        if n_jobs is not None:
            raise ValueError(
                "give client (a Dask cluster) or n_jobs (local processes), not both"
            )
        return DaskCluster(_checked_client(client))
    if n_jobs is None:
        return LocalProcesses(-1)
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or n_jobs == 0:
        raise ValueError(
            "n_jobs must be a nonzero integer (1: this process; k: k processes; "
            f"-1: one per core) or None, got {n_jobs!r}"
        )
    return Serial() if n_jobs == 1 else LocalProcesses(n_jobs)


def _checked_client(client):
    try:
        import distributed
    except ImportError:
        raise TypeError(
            f"client must be a distributed.Client, got {type(client).__name__} "
            "(and dask's distributed is not installed: pip install "
            "pysindy-mme[distributed])"
        ) from None
    if not isinstance(client, distributed.Client):
        raise TypeError(
            f"client must be a distributed.Client, got {type(client).__name__}; "
            "for local processes give n_jobs instead"
        )
    if client.status not in ("running", "newly-created"):
        raise ValueError(f"client is not connected (status {client.status!r})")
    return client
