"""A grey-box parameter the correction replaces is a finding, not a doubt.

The tanks' linear outflow rates go to zero beside the square-root law
(4e-5 +- 1.5e-4 where the assumed model alone needed 0.03): the data pin
them at zero, so "its standard error is larger than its value" and "it
changed sign" would misreport a determined quantity. A parameter whose
standard error is large against its own scale stays a doubt.
"""

from types import SimpleNamespace

import numpy as np

from pysindy_mme.discovery.conclusion import Evidence, conclude
from pysindy_mme.discovery.study import (
    PINNED_SHARE,
    _parameter_doubts,
    _undetermined,
    _vanished,
)


def _fit(values, se):
    values, se = np.asarray(values, float), np.asarray(se, float)
    return SimpleNamespace(
        physical=values,
        theta=values,
        std_errors=se,
        covariance=np.diag(se**2),
        held=np.zeros(values.size, dtype=bool),
        at_bound=np.zeros(values.size, dtype=bool),
    )


STUDY = SimpleNamespace(
    parameter_names=["a1", "b", "m"],
    parameter_init=np.array([0.03, 0.05, 95.0]),
    parameter_gauge=np.zeros(3, dtype=bool),
    parameter_bounds=np.zeros((0, 2)),
)
ALONE = _fit([0.0301, 0.05, 94.0], [1e-4, 1e-4, 0.1])


def test_a_parameter_pinned_at_zero_is_named_as_replaced():
    # a1 at zero within 1.5e-4 (0.5 % of 0.03); m at zero but with an error
    # of 30 % of its scale (not pinned); b well away from zero
    extended = _fit([-5e-5, 0.0501, 0.01], [1.5e-4, 1e-4, 30.0])
    found = _vanished(STUDY, extended, ALONE)
    assert list(found) == [0]
    assert "a1 = -5e-05 +- 0.00015 is zero within its standard error" in found[0]
    assert "0.5 % of the 0.0301 the assumed model alone needed" in found[0]
    names = ["a1", "b", "m"]
    doubts = _undetermined(extended, names, set(found))
    assert len(doubts) == 1 and doubts[0].startswith("m = 0.01 has a standard error")
    assert _undetermined(extended, names)[0].startswith("a1 = ")  # without: a doubt
    # a sign change within a standard error of zero is none; m's runaway stays
    sentences, _ = _parameter_doubts(STUDY, extended, found)
    assert not any(s.startswith("a1") for s in sentences)
    assert any(s.startswith("m moved from the guess") for s in sentences)
    assert any(
        s.startswith("a1 changed sign") for s in _parameter_doubts(STUDY, extended)[0]
    )


def test_the_share_is_the_boundary():
    scale = 0.0301
    inside = _fit([1e-6, 0.05, 95.0], [0.99 * PINNED_SHARE * scale, 1e-4, 0.1])
    outside = _fit([1e-6, 0.05, 95.0], [1.01 * PINNED_SHARE * scale, 1e-4, 0.1])
    assert list(_vanished(STUDY, inside, ALONE)) == [0]
    assert _vanished(STUDY, outside, ALONE) == {}
    assert _vanished(STUDY, ALONE, ALONE) == {}  # no extended fit: nothing replaced


def test_the_conclusion_names_it_among_its_reasons():
    sentence = "a1 = -5e-05 +- 0.00015 is zero within its standard error"
    ev = Evidence(
        contradicted=True,
        consistency="chi2 = 1e5 on 900 dof",
        terms=["sqrt(h1+) in h1'"],
        assumed_converged=True,
        extended_converged=True,
        rmse_assumed=np.array([1.0]),
        rmse_extended=np.array([0.02]),
        noise_floor=np.array([0.02]),
        channel_names=["h2"],
        out_assumed=np.array([1.1]),
        out_extended=np.array([0.021]),
        out_source="the validation record",
        vanished=[sentence],
    )
    found = conclude(ev)
    assert found.label == "explained"
    assert sentence in found.reasons
