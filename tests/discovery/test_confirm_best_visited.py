"""Confirmation: the search does not end on a model an earlier one beats.

Found on the linear-model cascaded tanks, seed 5: the search kept the
square-root law (with ramps and a constant in ``h2'``, transcription cost
6474), then a wall in ``h1'`` (a fit that does not join, taken because its
model improved), then swapped, merged and dropped its way to the wall alone
beside a ramp, whose transcription cost (836) is no model's cost: run as a
model it does not even join (6.5e8). The study ended with 400x the true
model's test error. :func:`~pysindy_mme.discovery.confirm._best_visited`
returns to the best visited model whose fit joined. Stand-in fits with that
study's costs drive the rule alone (``tests/confirm_stand_ins.py``).
"""

from __future__ import annotations

from types import SimpleNamespace

from confirm_stand_ins import stand_in_fit as _fit
from confirm_stand_ins import stand_in_search as _search

from pysindy_mme.discovery.confirm import _best_visited

LAW = [(0, 0), (1, 1), (1, 2), (1, 5), (1, 7), (1, 0)]
WALL = [(0, 6), (1, 4)]


def _with_engine(search, held):
    search.engine = SimpleNamespace(fit_held=lambda slots, theta, x: held)
    return search


def _final(cost=836.0, joined=False):
    return _fit(WALL, cost, joined=joined)


def test_a_final_model_that_cannot_be_run_gives_way_to_the_best_visited():
    search = _with_engine(_search({}), _fit(WALL, 6.5e8, joined=False))
    law = _fit(LAW, 6473.5)
    search.visited = [(LAW[:1], _fit(LAW[:1], 130787.0)), (LAW, law)]
    search.slots, search.fit = list(WALL), _final()
    assert _best_visited(search)
    assert search.slots == LAW and search.fit is law
    assert "its model cannot be run" in search.log[-1]
    assert {slot for slot, _ in search.rejected} == set(WALL)


def test_a_runnable_final_model_is_judged_by_its_model_run_as_a_model():
    law = _fit(LAW, 6473.5)
    # run as a model the final costs 9000 with two terms: the law's four
    # more terms remove far more than the search asks of four additions
    search = _with_engine(_search({}), _fit(WALL, 9000.0))
    search.visited = [(LAW, law)]
    search.slots, search.fit = list(WALL), _final()
    assert _best_visited(search) and search.slots == LAW
    assert "for its 4 more" in search.log[-1]
    # ... but not when the extra terms would not pass as additions
    search = _with_engine(_search({}), _fit(WALL, 6474.0))
    search.visited = [(LAW, law)]
    search.slots, search.fit = list(WALL), _final()
    assert not _best_visited(search) and search.slots == WALL


def test_a_final_model_that_beats_every_visited_one_stays():
    final = _fit(WALL, 900.0)  # joined: its cost is its model's
    search = _search({})
    search.visited = [(LAW, _fit(LAW, 904.0)), (LAW[:1], _fit(LAW[:1], 950.0))]
    search.slots, search.fit = list(WALL), final
    assert not _best_visited(search)
    assert search.slots == WALL and search.fit is final and search.log == []


def test_fewer_terms_and_a_lower_cost_win_without_a_test():
    few = _fit(LAW[:1], 899.0)
    search = _search({})
    search.visited = [(LAW[:1], few)]
    search.slots, search.fit = list(WALL), _fit(WALL, 900.0)
    assert _best_visited(search) and search.fit is few
    assert "no more terms" in search.log[-1] and "p = " not in search.log[-1]
