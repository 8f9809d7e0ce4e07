"""A level read on an unmeasured state whose scale a gauge fixes says so.

On the cascaded tanks only the lower level is measured; the pump gain ``b``
and the upper level's scale trade off exactly, so the study holds ``b`` at
its guess (a gauge). The upper tank's rim, found as ``over(h1, 14)``, is then
at 14 in the scale the gauge gives ``h1`` (the plant's rim is at 10: 14 x
0.036 / 0.05). The report's wall line must not read as "the upper tank
overflows at 14 V".
"""

from __future__ import annotations

from types import SimpleNamespace

from pysindy_mme.discovery.identifiability import TradeOff
from pysindy_mme.discovery.report import wall_lines

WALL = {
    "state": "h1",
    "level": 14.0,
    "term": "over(h1, 14)",
    "coefficient": -2.5,
    "routes": {"h2": 0.716},
}
GAUGE = TradeOff(["b", "a2"], [1.0, -1.0], ["h1"], ["b*a2"], gauge="b")


def _result(gauges=(), trade_offs=()):
    return SimpleNamespace(
        walls=[WALL],
        study=SimpleNamespace(gauges=list(gauges)),
        trade_offs=list(trade_offs),
    )


def test_a_wall_on_a_gauged_state_is_in_the_gauges_scale():
    (line,) = wall_lines(_result(gauges=[GAUGE]))
    assert line.startswith("Wall: h1 stays at or below 14")
    assert "The level is in the scale of h1 that the gauge sets (b held" in line
    assert "not in h1's own units" in line


def test_a_gauge_among_the_final_trade_offs_counts_too():
    (line,) = wall_lines(_result(trade_offs=[GAUGE]))
    assert "the gauge sets (b held" in line


def test_a_wall_on_a_measured_or_ungauged_state_says_nothing_more():
    (line,) = wall_lines(_result())
    assert "gauge" not in line
    other = TradeOff(["b", "a2"], [1.0, -1.0], ["h3"], ["b*a2"], gauge="b")
    undetermined = TradeOff(["b", "a2"], [1.0, -1.0], ["h1"], ["b*a2"])
    (line,) = wall_lines(_result(gauges=[other], trade_offs=[undetermined]))
    assert "gauge" not in line
