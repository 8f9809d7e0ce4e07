"""Confirmation: a flow between two states, and a smaller fit that does not join.

Found on the cascaded tanks with the right square-root model
(``cascaded_tanks(assumed="sqrt")``, record 1, only the overflow missing):
the joint fit of the proposals pruned to the true pair ``over(h1, 10)`` in
``h1'`` (-0.44) and in ``h2'`` (+0.44), chi2 904 on 917 residuals (the
noise level). The backward step then fitted the pair without its ``h2'``
half: the water over the weir taken out of the upper tank only is fitted
best as a wall (the coefficient walking towards -1e12), a trajectory that
did not join with a transcription cost of 903 - below the pair's, so the
half was "not needed" and dropped, and the search never found the pair
again. Two rules (``discovery/confirm.py``): a smaller fit that does not
join is no evidence against a term of a fit that does (polished, then
tried from MME's states; kept if neither joins), and a function proposed
in several equations is also tried in all of them at once (a flow).

The search is driven here by stand-in fits with the costs of that study, so
that each rule is tested alone; whole studies are in
``benchmarks/bench_physics.py --only tanks`` and, for the linear model's seed
3, ``test_physics_tanks.py::test_overflow_kept_as_a_wall_seed3``.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from confirm_stand_ins import stand_in_fit as _fit
from confirm_stand_ins import stand_in_search as _search

from pysindy_mme.discovery.confirm import _flow_step

WEIR_H1, WEIR_H2, OTHER = (0, 2), (1, 2), (1, 0)


def test_a_smaller_fit_that_does_not_join_is_no_evidence():
    pair = _fit([WEIR_H1, WEIR_H2], 904.075, p=[0.0093, 0.0084])
    wall = _fit([WEIR_H1], 903.137, joined=False)  # the wall: no model's cost
    search = _search({frozenset([WEIR_H1]): wall, frozenset([WEIR_H2]): wall})
    slots, fit, removed = search.backward([WEIR_H1, WEIR_H2], pair)
    assert slots == [WEIR_H1, WEIR_H2] and fit is pair and removed == []
    # looked for a joined fit once per smaller set, then remembered it
    search.calls.clear()
    search.backward([WEIR_H1, WEIR_H2], pair)
    assert all(len(c) == 1 for c in search.calls)
    assert len(search.calls) == 2  # the two trials, no polish again


def test_a_smaller_fit_that_joins_still_removes_a_weak_term():
    big = _fit([WEIR_H1, OTHER], 904.0, p=[1e-12, 0.5])
    small = _fit([WEIR_H1], 904.2)  # joins, and hardly worse
    search = _search({frozenset([WEIR_H1]): small})
    slots, fit, removed = search.backward([WEIR_H1, OTHER], big)
    assert slots == [WEIR_H1] and fit is small
    assert [r[0] for r in removed] == [OTHER]


def test_a_function_proposed_in_two_equations_is_tried_as_a_flow():
    wall = _fit([WEIR_H1], 1928.3, joined=False)
    pair = _fit([WEIR_H1, WEIR_H2], 904.075)
    search = _search({frozenset([WEIR_H1, WEIR_H2]): pair})
    search.slots, search.fit = [WEIR_H1], wall
    proposals = [WEIR_H1, OTHER, WEIR_H2]
    assert _flow_step(search, proposals, [-0.004, 0.002, -0.004])
    assert search.slots == [WEIR_H1, WEIR_H2] and search.fit is pair
    assert "a flow between states" in search.log[-1]
    # a column proposed in one equation only is no flow: nothing tried
    search = _search({})
    assert not _flow_step(search, [WEIR_H1, OTHER], [-0.004, 0.002])
    assert search.calls == []


def test_a_flow_that_stiffens_as_a_whole_is_a_wall_not_an_artefact():
    """At half the smoothing width a wall's rate doubles, its split stays."""
    from pysindy_mme.discovery.steps import _walls

    slots = [(0, 1), (1, 1), (1, 3), (0, 5)]
    before = np.array([-0.8045, 0.5646, -0.09, 0.02])
    moved = np.array([True, True, False, True])
    # the seed-1 tanks figures: x2.26 and x2.28; the lone term in x0' moved too
    after = np.array([-1.82, 1.286, -0.09, 0.05])
    assert _walls(slots, before, after, moved) == [0, 1]
    # a split that changes is no single flow; a flow that softens is no wall
    assert _walls(slots, before, np.array([-1.82, 0.9, -0.09, 0.05]), moved) == []
    assert _walls(slots, before, np.array([-0.4, 0.28, -0.09, 0.05]), moved) == []
    # one half not moved: the other half alone is judged as before
    assert _walls(slots, before, after, np.array([True, False, False, True])) == []


def test_a_term_the_merge_drops_is_said():
    """Seed 2 of the tanks: merging two terms of h1' into one let the merged
    fit's backward step drop the other half of a flow, with no word in the
    log or the report. Now it is recorded with its reason."""
    from pysindy_mme.discovery.confirm import _merge_round

    z = np.linspace(0.0, 14.0, 200)[:, None]

    def features(z, cols):
        h = z[:, 0]
        table = {
            1: np.maximum(h - 6.0, 0.0),
            2: np.maximum(h - 14.0, 0.0) + 0.01 * h,
            3: np.maximum(h - 8.0, 0.0),
        }
        return np.column_stack([table[c] for c in cols])

    a, b, half, cand = (0, 1), (0, 2), (1, 2), (0, 3)
    current = _fit([a, b, half], 950.0)
    merged = _fit([half, cand], 930.0, p=[0.5, 1e-12])
    alone = _fit([cand], 931.0)
    search = _search({frozenset([half, cand]): merged, frozenset([cand]): alone})
    search.engine = SimpleNamespace(features=features)
    search.pool = [a, b, half, cand, (1, 1), (1, 3)]
    search.slots, search.fit = [a, b, half], current
    current.coefficients = np.array([0.02, 0.01, 0.01])
    assert _merge_round(search, z)
    assert search.slots == [cand]
    reasons = dict(search.rejected)
    assert "merged" in reasons[half]
    assert any(line.startswith("removed c2 in x1'") for line in search.log)
