"""A missing state is claimed only where a model without it falls short.

The memory test reads MME's states and ``d(t)``; their history reproduces
MME's own estimation error (an error state's increment over a lag is the
integral of ``d``), which at high sampling rates is most of ``d``. A static
extended model that runs free at the noise on its record and on held-out
data is the stronger evidence: the finding is then a reason, not the
verdict; where the extended model misses the held-out data, the verdict
still names the likely state.
"""

from __future__ import annotations

import numpy as np

from pysindy_mme.discovery.conclusion import Evidence, MissingState, conclude

MEMORY = MissingState(
    "x2",
    "the model error of x2' is 0% predictable from the present states and "
    "inputs, 63% with the states 64 samples earlier",
)


def _evidence(out_extended):
    return Evidence(
        contradicted=True,
        consistency="chi2 = 1e5 on 900 dof",
        terms=["x1^2 x2 in x2'"],
        assumed_converged=True,
        extended_converged=True,
        rmse_assumed=np.array([1.3]),
        rmse_extended=np.array([0.1001]),
        noise_floor=np.array([0.1]),
        channel_names=["x1"],
        out_assumed=np.array([1.6]),
        out_extended=np.array([out_extended]),
        out_source="a held-out stretch",
        memory=[MEMORY],
    )


def test_runs_at_the_noise_on_and_off_the_record_outweigh_the_memory_test():
    found = conclude(_evidence(0.1001))
    assert found.label == "explained"
    assert "does not have" not in found.verdict
    assert "hidden_states" not in " ".join(found.advice)
    (said,) = [r for r in found.reasons if MEMORY.evidence in r]
    assert "no state is missing" in said


def test_a_held_out_miss_keeps_the_missing_state_in_the_verdict():
    # 1.6x the noise out of sample (over the 1.5x an explanation may leave)
    found = conclude(_evidence(0.16))
    assert "a state the model does not have is likely" in found.verdict
    assert "hidden_states={'z': 'x2'}" in found.verdict
    assert found.advice[0].startswith("a hidden state entering x2'")
