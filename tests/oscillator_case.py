"""A spring with a hidden effect, measured at one state: records and studies.

Shared by the discovery tests that build their own oscillator records
(adversarial studies, the study with each feature library): the truth
``x1' = x2, x2' = -x1 + effect``, only the position measured with white
noise, and ``discover`` with the linear oscillator as the assumed model.
"""

from __future__ import annotations

import warnings

import numpy as np
import pysindy as ps

from pysindy_mme import discover
from pysindy_mme.core.model import simulate_model
from pysindy_mme.discovery.options import grouped_keywords

__all__ = ["linear_oscillator", "oscillator", "record", "study"]


def oscillator(damping):
    """``x1' = x2, x2' = -x1 + damping(x2)``: a spring with a damping law."""

    def f(x, t):
        return np.column_stack([x[:, 1], -x[:, 0] + damping(x[:, 1])])

    return f


def linear_oscillator(x, t):
    return np.column_stack([x[:, 1], -x[:, 0]])


def record(model, x0, t_end=30.0, rate=20.0, noise=1e-3, seed=0, missing=0.0):
    """``(y, t, x)``: ``model`` from ``x0``, its position with noise of variance
    ``noise`` (a fraction ``missing`` of the samples NaN)."""
    t = np.arange(0, t_end + 1e-9, 1 / rate)
    x = simulate_model(model, x0, t, rtol=1e-10, atol=1e-12)
    rng = np.random.default_rng(seed)
    y = x[:, :1] + np.sqrt(noise) * rng.standard_normal((t.size, 1))
    if missing:
        y[rng.random(t.size) < missing] = np.nan
    return y, t, x


def study(y, t, model=linear_oscillator, noise=1e-3, **kwargs):
    """``discover`` with ``model`` assumed (warnings silenced); ``kwargs``
    replace any of its arguments."""
    options = dict(
        assumed_model=model,
        n_states=2,
        measured=[0],
        noise_variance=noise,
        error_states=[1],
        feature_library=ps.PolynomialLibrary(degree=3),
        feature_names=["x1", "x2"],
    )
    options.update(kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return discover(y, t, **grouped_keywords(options))
