""":func:`discover_many`: many studies (records, seeds, bootstrap replicates) at once.

Every study is checked here first (:func:`~.study.prepare_study`, the
checks :func:`discover` makes), so a bad record or argument fails before
any study starts, with ``records[i]`` in the message. Each checked study
then runs exactly as :func:`discover` runs it (:func:`~.study.run_study`),
on one of three engines (:mod:`~pysindy_mme.core.engines`): this process
(``n_jobs=1``), local processes (joblib), or a Dask cluster (``client=``).
A study that fails does not stop the others; its failure is reported with
its record.
"""

from __future__ import annotations

import inspect
import pickle
import sys
import time
import traceback
import warnings
from dataclasses import dataclass, field

from ..core import engines
from ..core.progress import Progress
from ..exceptions import StudiesFailedError
from .inputs import Record
from .study import discover, prepare_study, run_study

__all__ = ["StudyFailure", "discover_many"]

#: discover's keywords (everything a study may be told)
_DISCOVER_KEYWORDS = tuple(
    name
    for name, p in inspect.signature(discover).parameters.items()
    if p.kind is p.KEYWORD_ONLY
)

#: the arguments that hold user code: the ones named when a study cannot
#: be sent to another process
_CODE_ARGUMENTS = (
    "assumed_model",
    "feature_library",
    "optimizer",
    "mme",
    "validation",
    "options",
    "u",
)


@dataclass
class StudyFailure:
    """A study of :func:`discover_many` that raised instead of returning.

    Attributes
    ----------
    index : int
        Its position in ``records``.
    exception : BaseException
        What it raised (a ``RuntimeError`` carrying the text when the
        original could not travel back from a worker).
    traceback : str
        The traceback where it was raised (in the worker).
    """

    index: int
    exception: BaseException
    traceback: str = ""

    def __str__(self) -> str:
        return (
            f"records[{self.index}]: {type(self.exception).__name__}: {self.exception}"
        )


@dataclass
class _Outcome:
    """What one study sends back: its result or its failure, and its warnings."""

    result: object = None
    failure: StudyFailure | None = None
    warnings: list = field(default_factory=list)


def discover_many(
    records,
    *,
    client=None,
    n_jobs=None,
    progress=True,
    on_error="raise",
    **discover_kwargs,
):
    """Run :func:`discover` on many records at once, on a cluster or locally.

    Parameters
    ----------
    records : list
        One entry per study: a :class:`~pysindy_mme.Record`, a tuple
        ``(y, t)`` or ``(y, t, u)``, an array ``y`` (``t`` then given once
        in ``discover_kwargs``, shared by all), a list of
        :class:`~pysindy_mme.Record` (one study of several records, as
        :func:`discover` takes them), or a dict of
        :func:`discover`'s keywords with ``"y"`` (what differs between the
        studies: ``{"y": y, "t": t, "options": {...}}``). A keyword given
        both in an entry and in ``discover_kwargs`` is an error.
    client : distributed.Client, optional
        Run the studies on this Dask cluster, one task per study (needs
        ``pip install pysindy-mme[distributed]``). The model and library
        travel to the workers by cloudpickle: functions from a module the
        workers can import, or defined in ``__main__``, both work.
    n_jobs : int, optional
        Without ``client``: the number of local processes (joblib's loky
        backend; -1 or None: one per core, -2: all but one, ...). ``1``
        runs the studies one after another in this process. Not with
        ``client``.
    progress : bool, default True
        A status line on standard error: studies done, failed, elapsed.
    on_error : {"raise", "return"}, default "raise"
        A study that raises does not stop the others. With ``"raise"``,
        after all have run, :class:`~pysindy_mme.StudiesFailedError` names
        every failed record with its exception and carries all the results
        (``.results``, a :class:`StudyFailure` in place of each failed
        study). With ``"return"`` that list is returned instead.
    **discover_kwargs
        :func:`discover`'s keywords, shared by every study
        (``assumed_model=``, ``n_states=``, ``measured=``,
        ``feature_library=``, ``options=``, ...).

    Returns
    -------
    list of Discovery
        In the order of ``records``; the same results as calling
        :func:`discover` on each record in turn (each study runs the same
        code on the same checked arguments, whatever the engine).

    Raises
    ------
    TypeError, ValueError
        Before any study starts: ``records`` is not a list, an entry or a
        keyword is invalid (the message names ``records[i]`` and the
        argument), ``client`` is not a ``distributed.Client``, or an
        argument cannot be sent to another process (a ``TypeError`` naming
        it; define the model as a module-level function, or use
        ``n_jobs=1``).
    StudiesFailedError
        After all studies ran, when some raised and ``on_error="raise"``.

    Notes
    -----
    Each study's warnings are re-issued here, in the order of ``records``,
    prefixed with ``records[i]:`` (from any engine alike). With
    ``options={"verbose": True}`` each study also prints its stages where
    it runs (a worker's standard error on a cluster).

    ``n_jobs=None`` means one process per core, not scikit-learn's "one
    job": this call exists to run studies side by side. Results from other
    processes hold copies of the model and library (unpickled there and
    back). Every study is checked, and held as bytes for the workers,
    before the first one starts, so memory grows with the records' total
    size.

    Examples
    --------
    >>> from pysindy_mme import discover_many
    >>> results = discover_many(
    ...     [(y1, t1), (y2, t2)], assumed_model=f, n_states=2, measured=[0],
    ...     noise_variance=0.01, error_states=[1], n_jobs=2,
    ... )  # doctest: +SKIP
    >>> from distributed import Client  # doctest: +SKIP
    >>> with Client("tcp://scheduler:8786") as client:  # doctest: +SKIP
    ...     results = discover_many(records, client=client, **keywords)
    """
    engine = engines.choose(client, n_jobs)
    _check_flags(progress, on_error)
    studies, checked = _prepared(_study_arguments(records, discover_kwargs))
    if engine.remote:  # the same bytes for every engine that sends them away
        studies = [
            _payload(i, s, records, discover_kwargs) for i, s in enumerate(studies)
        ]
    line = _ProgressLine(len(studies), progress)
    outcomes = [None] * len(studies)
    for index, value, error in engine.run(_run_one, studies):
        outcomes[index] = _outcome(index, value, error)
        line.update(outcomes[index].failure is not None)
    for outcome, warned in zip(outcomes, checked):  # as discover: checks first
        outcome.warnings[:0] = warned
    return _results(outcomes, on_error)


# ---------------------------------------------------------------- checks
def _check_flags(progress, on_error) -> None:
    if not isinstance(progress, bool):
        raise TypeError(f"progress must be True or False, got {progress!r}")
    if on_error not in ("raise", "return"):
        raise ValueError(f"on_error must be 'raise' or 'return', got {on_error!r}")


def _study_arguments(records, shared: dict) -> list:
    """``[(y, t, keywords)]``, one per study, from ``records`` and ``shared``."""
    if not isinstance(records, list):
        hint = (
            "; for one study call discover"
            if isinstance(records, (Record, tuple))
            else ""
        )
        raise TypeError(
            "records must be a list (one entry per study), got "
            f"{type(records).__name__}{hint}"
        )
    if not records:
        raise ValueError("records is empty: give at least one study")
    _check_keywords(shared, "discover_many()")
    shared = dict(shared)
    shared_t = shared.pop("t", None)
    out = []
    for i, entry in enumerate(records):
        where = f"records[{i}]"
        y, t, own = _entry(entry, where)
        for name in own:
            if shared.get(name) is not None:
                raise ValueError(
                    f"{where} gives {name} and so does discover_many's {name}=: "
                    "give it in one place"
                )
        if t is not None and shared_t is not None:
            raise ValueError(
                f"{where} gives t and so does discover_many's t=: give it in one place"
            )
        out.append((y, shared_t if t is None else t, {**shared, **own}))
    return out


def _check_keywords(keywords: dict, where: str, data=("t",)) -> None:
    """Only discover's keywords, and of its data the names in ``data``."""
    unknown = sorted(set(keywords) - set(_DISCOVER_KEYWORDS) - set(data))
    if unknown:
        raise TypeError(
            f"{where} got unexpected keyword argument(s) {unknown}; discover "
            f"takes {list(_DISCOVER_KEYWORDS)}"
        )


def _entry(entry, where: str):
    """``(y, t, own keywords)`` of one entry of ``records``."""
    if isinstance(entry, Record):
        own = {} if entry.u is None else {"u": entry.u}
        return entry.y, entry.t, own
    if isinstance(entry, tuple):
        if len(entry) not in (2, 3):
            raise ValueError(
                f"{where} must be (y, t) or (y, t, u), got a tuple of {len(entry)}"
            )
        own = {} if len(entry) == 2 or entry[2] is None else {"u": entry[2]}
        return entry[0], entry[1], own
    if isinstance(entry, dict):
        if "y" not in entry:
            raise ValueError(f"{where} is a dict without 'y': {sorted(entry)}")
        _check_keywords(entry, where, data=("y", "t"))
        own = {k: v for k, v in entry.items() if k not in ("y", "t")}
        return entry["y"], entry.get("t"), own
    if isinstance(entry, (str, bytes, set)) or entry is None:
        raise TypeError(
            f"{where} must be a Record, a tuple (y, t[, u]), an array y, a list "
            f"of Record or a dict of discover's keywords; got {type(entry).__name__}"
        )
    return entry, None, {}  # an array y, or a list of Record (one study)


def _prepared(arguments: list) -> tuple:
    """``([(Study, StudyOptions)], [warnings of each check])``: every study
    checked before any runs; the checks' warnings are kept to be issued
    with the study's own, in the order :func:`discover` gives them."""
    out, warned = [], []
    for i, (y, t, keywords) in enumerate(arguments):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                out.append(prepare_study(y, t, **keywords))
            except (TypeError, ValueError) as exc:
                error = exc
            else:
                error = None
        warned.append([(w.category, str(w.message)) for w in caught])
        if error is not None:
            _reissue(warned)
            try:  # the same class, the record named in front
                named = type(error)(f"records[{i}]: {error}")
            except Exception:  # noqa: BLE001 - a class that takes other arguments
                raise error from None
            raise named from error
    return out, warned


def _reissue(warned: list, stacklevel: int = 4) -> None:
    """Each record's warnings, prefixed with the record."""
    for i, caught in enumerate(warned):
        for category, message in caught:
            warnings.warn(f"records[{i}]: {message}", category, stacklevel=stacklevel)


def _payload(index: int, prepared, records, shared: dict) -> bytes:
    """One study as bytes for another process, or a TypeError naming what
    cannot travel (the argument, in the entry or the shared keywords)."""
    try:
        return engines.dumps(prepared)
    except Exception as exc:  # noqa: BLE001 - any pickling failure, named below
        raise TypeError(
            f"{_unpicklable(index, records[index], shared)} cannot be sent to "
            f"another process ({type(exc).__name__}: {exc}); define it at "
            "module level (a function or class in an importable module, or in "
            "__main__), or run here with n_jobs=1"
        ) from exc


def _unpicklable(index: int, entry, shared: dict) -> str:
    """Where the first argument that does not pickle was given."""
    own = entry if isinstance(entry, dict) else {}
    for name in _CODE_ARGUMENTS:
        for where, keywords in ((f"records[{index}][{name!r}]", own), (name, shared)):
            if name in keywords:
                try:
                    engines.dumps(keywords[name])
                except Exception:  # noqa: BLE001
                    return where
    return f"records[{index}]"


# ---------------------------------------------------------------- one study
def _run_one(index: int, prepared):
    """One study, where it runs: an :class:`_Outcome`, as bytes when
    ``prepared`` came as bytes (from another process)."""
    remote = isinstance(prepared, bytes)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            study, opts = pickle.loads(prepared) if remote else prepared
            outcome = _Outcome(result=run_study(study, Progress(opts.verbose)))
        except Exception as exc:  # noqa: BLE001 - reported per study
            outcome = _Outcome(failure=_failure(index, exc, remote))
    outcome.warnings = [(w.category, str(w.message)) for w in caught]
    if not remote:
        return outcome
    try:
        return engines.dumps(outcome)
    except Exception as exc:  # noqa: BLE001 - the result cannot travel back
        return engines.dumps(_Outcome(failure=_failure(index, exc, True)))


def _failure(index: int, exc: BaseException, remote: bool) -> StudyFailure:
    text = traceback.format_exc()
    if remote:
        try:  # an exception whose class cannot be rebuilt travels as text
            pickle.loads(engines.dumps(exc))
        except Exception:  # noqa: BLE001
            exc = RuntimeError(f"{type(exc).__name__}: {exc}")
    return StudyFailure(index, exc, text)


def _outcome(index: int, value, error) -> _Outcome:
    """An engine's answer for one study as an :class:`_Outcome`; ``error``
    is the task's own failure (a worker lost, a payload it could not read)."""
    if error is not None:
        text = "".join(traceback.format_exception(error))
        return _Outcome(failure=StudyFailure(index, error, text))
    return pickle.loads(value) if isinstance(value, bytes) else value


def _results(outcomes: list, on_error: str) -> list:
    results, failures = [], []
    _reissue([outcome.warnings for outcome in outcomes], stacklevel=4)
    for outcome in outcomes:
        if outcome.failure is not None:
            failures.append(outcome.failure)
            results.append(outcome.failure)
        else:
            results.append(outcome.result)
    if failures and on_error == "raise":
        raise StudiesFailedError(results, failures)
    return results


# ---------------------------------------------------------------- progress
class _ProgressLine:
    """``discover_many: 12/50 studies done, 1 failed [3.4 s]`` on standard
    error: one line kept updated on a terminal, a line per tenth otherwise."""

    def __init__(self, total: int, enabled: bool):
        self.total, self.enabled = total, enabled
        self.done = self.failed = self._shown = 0
        self.start = time.perf_counter()
        self.stream = sys.stderr
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._show()

    def update(self, failed: bool) -> None:
        self.done += 1
        self.failed += bool(failed)
        if (
            self._tty
            or self.done == self.total
            or (10 * self.done // self.total > 10 * self._shown // self.total)
        ):
            self._show()

    def _show(self) -> None:
        if not self.enabled:
            return
        self._shown = self.done
        failed = f", {self.failed} failed" if self.failed else ""
        text = (
            f"discover_many: {self.done}/{self.total} studies done{failed} "
            f"[{time.perf_counter() - self.start:.1f} s]"
        )
        end = "" if self._tty and self.done < self.total else "\n"
        print(("\r" if self._tty else "") + text, end=end, file=self.stream, flush=True)
