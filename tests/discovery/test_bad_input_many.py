"""discover_many: one table of bad inputs, each with its exception type and a
phrase of its message; every one raised before any study starts (under the
tripwires: no solver reached), naming the argument or ``records[i]``."""

from __future__ import annotations

import numpy as np
import pytest
from bad_input_support import Bad, assert_raises_as_documented, params
from many_case import LockedModel, records, shared_keywords

from pysindy_mme import Record, discover_many

ENTRY_POINT = "discover_many"

(Y, T), (Y2, T2) = records(2)


def _many(entries=None, **overrides):
    keywords = dict(progress=False, n_jobs=1)
    keywords.update(overrides)
    entries = [(Y, T), (Y2, T2)] if entries is None else entries
    shared = {k: v for k, v in keywords.items() if k in _OWN}
    rest = {k: v for k, v in keywords.items() if k not in _OWN}
    return discover_many(entries, **shared, **shared_keywords(**rest))


_OWN = ("client", "n_jobs", "progress", "on_error")


class _NotAClient:
    def submit(self, *args, **kwargs):
        raise AssertionError("never called")


BAD_INPUTS = [
    # ---- records
    Bad(
        "discover_many: records a tuple",
        lambda tmp: _many(((Y, T), (Y2, T2))),
        TypeError,
        r"records must be a list \(one entry per study\), got tuple",
    ),
    Bad(
        "discover_many: records one Record",
        lambda tmp: _many(Record(Y, T)),
        TypeError,
        r"got Record; for one study call discover",
    ),
    Bad(
        "discover_many: records an array",
        lambda tmp: _many(np.zeros((3, 401, 1))),
        TypeError,
        r"records must be a list",
    ),
    Bad(
        "discover_many: records empty",
        lambda tmp: _many([]),
        ValueError,
        r"records is empty",
    ),
    Bad(
        "discover_many: a record with t of the wrong length",
        lambda tmp: _many([(Y, T), (Y2, T2[:-5])]),
        ValueError,
        r"records\[1\]: t has 396 entries but the data have 401 samples",
    ),
    Bad(
        "discover_many: a record with too many columns",
        lambda tmp: _many([(Y, T), (np.hstack([Y2, Y2]), T2)]),
        ValueError,
        r"records\[1\]: .*2 columns",
    ),
    Bad(
        "discover_many: a tuple of four",
        lambda tmp: _many([(Y, T, None, None)]),
        ValueError,
        r"records\[0\] must be \(y, t\) or \(y, t, u\)",
    ),
    Bad(
        "discover_many: an entry that is a string",
        lambda tmp: _many([(Y, T), "record.csv"]),
        TypeError,
        r"records\[1\] must be a Record, a tuple",
    ),
    Bad(
        "discover_many: a dict without y",
        lambda tmp: _many([{"t": T}]),
        ValueError,
        r"records\[0\] is a dict without 'y'",
    ),
    Bad(
        "discover_many: a dict with an unknown keyword",
        lambda tmp: _many([{"y": Y, "t": T, "alpah": 0.01}]),
        TypeError,
        r"records\[0\] got unexpected keyword argument\(s\) \['alpah'\]",
    ),
    Bad(
        "discover_many: t in a record and shared",
        lambda tmp: _many([(Y, T)], t=T),
        ValueError,
        r"records\[0\] gives t and so does discover_many's t=",
    ),
    Bad(
        "discover_many: a keyword in a record and shared",
        lambda tmp: _many([{"y": Y, "t": T, "n_states": 2}]),
        ValueError,
        r"records\[0\] gives n_states and so does discover_many's n_states=",
    ),
    # ---- shared keywords and the engine
    Bad(
        "discover_many: an unknown shared keyword",
        lambda tmp: _many(noise_varaince=0.01),
        TypeError,
        r"discover_many\(\) got unexpected keyword argument\(s\) \['noise_varaince'\]",
    ),
    Bad(
        "discover_many: y as a shared keyword",
        lambda tmp: _many(y=Y),
        TypeError,
        r"discover_many\(\) got unexpected keyword argument\(s\) \['y'\]",
    ),
    Bad(
        "discover_many: a moved keyword",
        lambda tmp: _many(alpha=0.01),
        TypeError,
        r"discover_many\(\) got unexpected keyword argument\(s\) \['alpha'\]",
    ),
    Bad(
        "discover_many: client of the wrong type",
        lambda tmp: _many(client=_NotAClient(), n_jobs=None),
        TypeError,
        r"client must be a distributed.Client, got _NotAClient",
    ),
    Bad(
        "discover_many: client an address",
        lambda tmp: _many(client="tcp://127.0.0.1:8786", n_jobs=None),
        TypeError,
        r"client must be a distributed.Client, got str",
    ),
    Bad(
        "discover_many: client and n_jobs",
        lambda tmp: _many(client=_NotAClient(), n_jobs=2),
        ValueError,
        r"give client \(a Dask cluster\) or n_jobs \(local processes\), not both",
    ),
    Bad(
        "discover_many: n_jobs zero",
        lambda tmp: _many(n_jobs=0),
        ValueError,
        r"n_jobs must be a nonzero integer",
    ),
    Bad(
        "discover_many: n_jobs a float",
        lambda tmp: _many(n_jobs=2.0),
        ValueError,
        r"n_jobs must be a nonzero integer",
    ),
    Bad(
        "discover_many: progress not a bool",
        lambda tmp: _many(progress="yes"),
        TypeError,
        r"progress must be True or False",
    ),
    Bad(
        "discover_many: on_error unknown",
        lambda tmp: _many(on_error="ignore"),
        ValueError,
        r"on_error must be 'raise' or 'return'",
    ),
    Bad(
        "discover_many: a model that cannot travel to a process",
        lambda tmp: _many(n_jobs=2, assumed_model=LockedModel()),
        TypeError,
        r"assumed_model cannot be sent to another process \(.*\); "
        r"define it at module level",
    ),
    Bad(
        "discover_many: a per-record model that cannot travel",
        lambda tmp: discover_many(
            [{"y": Y, "t": T, "assumed_model": LockedModel()}],
            n_jobs=2,
            progress=False,
            **{k: v for k, v in shared_keywords().items() if k != "assumed_model"},
        ),
        TypeError,
        r"records\[0\]\['assumed_model'\] cannot be sent to another process",
    ),
]


@pytest.mark.parametrize("case", params(BAD_INPUTS))
def test_bad_input(case, tmp_path, no_long_computation):
    assert_raises_as_documented(case, tmp_path)
