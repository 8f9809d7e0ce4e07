"""The confirmation does not refit a group it has already fitted and pruned.

On long records the regression of d(t) proposes false terms next to the true
ones (Van der Pol: ``x1^3`` and ``x2^3`` beside ``x1^2 x2`` and ``x2``). The
joint start fits them all, a forward step adds ``x1``, and the backward step
removes the two false ones. The group step (proposals that failed alone,
fitted together on top of the kept terms) used to fit exactly that model
again, from two starts and from MME's states, and prune it by the same
backward step: a third of the confirmation's time at 10^5 samples (40.6 ->
27.2 s CPU for the whole study, the same terms to the last digit).
"""

from __future__ import annotations

import warnings

from paper_case import paper_discover

from pysindy_mme.discovery import confirm
from pysindy_mme.systems import van_der_pol


def test_a_pruned_group_is_not_fitted_again(monkeypatch):
    pruned, fitted_after_pruning = set(), []
    refit, backward = confirm._Search.refit, confirm._Search.backward

    def watched_backward(self, slots, fit):
        before = frozenset(slots)
        kept, out, removed = backward(self, slots, fit)
        if removed:
            pruned.add((before, frozenset(kept)))
        return kept, out, removed

    def watched_refit(self, slots, coefs, start, polish=False):
        if (frozenset(slots), frozenset(self.slots)) in pruned:
            fitted_after_pruning.append(sorted(slots))
        return refit(self, slots, coefs, start, polish)

    monkeypatch.setattr(confirm._Search, "backward", watched_backward)
    monkeypatch.setattr(confirm._Search, "refit", watched_refit)
    system = van_der_pol()
    data = system.measure(0, t=system.time(100.0, 40.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = paper_discover(data.y, data.t)  # default: PolynomialLibrary(3)
    log = "\n".join(res.confirmation.log)
    # the case this test is about: a joint start whose false terms are pruned
    assert "joint fit of 4 proposals" in log, log
    assert "removed x2: x1^3" in log and "removed x2: x2^3" in log, log
    assert fitted_after_pruning == []
    # and the answer is the true law
    assert set(res.terms["x2"]) == {"x1", "x2", "x1^2 x2"}
