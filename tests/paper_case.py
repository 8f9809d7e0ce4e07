"""The paper's Van der Pol case, shared by the tests of MME and discover.

One record (``van_der_pol().measure(0)``: x1 measured at 40 Hz for 10 s with
noise variance 0.01), kept as read-only arrays so that code modifying its
input fails, and the calls the tests build on it: :func:`paper_mme`,
:func:`paper_mme_fit` and :func:`paper_discover` take the paper's arguments,
any of which a test may override by keyword.
"""

from __future__ import annotations

import numpy as np
from bad_input_support import readonly

from pysindy_mme import MME, discover
from pysindy_mme.discovery.options import grouped_keywords
from pysindy_mme.systems import van_der_pol

__all__ = [
    "DATA",
    "T",
    "VDP",
    "Y",
    "paper_discover",
    "paper_mme",
    "paper_mme_fit",
    "three_states",
]

VDP = van_der_pol()
DATA = VDP.measure(0)
Y = readonly(DATA.y)  # (401, 1): x1 measured, noise variance 0.01
T = readonly(DATA.t)  # 40 Hz for 10 s


def _paper_args(**overrides):
    """MME's arguments in the paper's case, built afresh for every call."""
    args = dict(
        assumed_model=VDP.assumed_model,
        n_states=2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
    )
    args.update(overrides)
    return args


def three_states(x, t):
    """A three-state model whose x3 is unobservable.

    x3 is neither measured nor driving anything measured.
    """
    return np.column_stack([x[:, 1], -x[:, 0], np.zeros(len(x))])


def paper_mme(**overrides):
    """An MME with the paper's arguments, ``overrides`` replacing any of them."""
    return MME(**_paper_args(**overrides))


def paper_mme_fit(y=Y, t=T, **overrides):
    """:func:`paper_mme` fitted to ``y`` at ``t`` (the paper's record by default)."""
    return paper_mme(**overrides).fit(y, t)


def paper_discover(y=Y, t=T, **overrides):
    """discover on ``y`` at ``t`` with the paper's arguments, feature names x1, x2."""
    args = _paper_args(feature_names=["x1", "x2"])
    args.update(overrides)
    return discover(y, t, **grouped_keywords(args))
