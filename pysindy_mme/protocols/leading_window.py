"""The system-identification benchmarks' protocol: one free run per record.

Each model's initial state is fitted to the record's first ``window``
samples only (more where they do not determine it); then it runs free over
the whole record (no correction from the data after the window), and the
RMSE is taken over the samples after the window. This is how the Silverbox,
cascaded-tanks and Wiener-Hammerstein benchmarks score a simulation model.
"""

from __future__ import annotations

from .base import ValidationProtocol
from .runs import measure_uncertainty, window_runs

__all__ = ["LeadingWindow"]


class LeadingWindow(ValidationProtocol):
    """Free run of each model on validation records, from the leading window.

    Parameters
    ----------
    records : tuple (y, t) or (y, t, u), Record, or a list of them, optional
        The validation records (checked by the study like its own data);
        None: the protocol is applied to a stretch held out of the fitting
        data (:class:`HeldOut`).
    window : int, default 50
        Leading samples each initial state is fitted to. Where they leave
        some model's initial state undetermined (its standard error larger
        than the state's spread over the record: 50 samples at a high
        sampling rate see a sliver of the motion), the window is doubled
        until they determine it to 5 % (at most a fifth of the record); the
        report gives the window used
        (:func:`~pysindy_mme.protocols.runs.determined_window`).

    Examples
    --------
    >>> from pysindy_mme.protocols import LeadingWindow
    >>> LeadingWindow(window=20)
    LeadingWindow(records=None, window=20)
    """

    label = "free run"

    def score(self, study, models, features, substeps, record, window) -> dict:
        return window_runs(study, models, features, substeps, record, window)

    def measure_uncertainty(
        self, study, runs, models, draws, features, substeps, record, *, every=False
    ) -> None:
        measure_uncertainty(
            study, runs, models, draws, features, substeps, record, every=every
        )

    def describe_method(self, window: int) -> str:
        return (
            f"initial state from its first {window} samples, then a free run; "
            "RMSE over the rest."
        )
