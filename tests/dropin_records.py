"""Records as ``benchmarks/bench_dropin.py`` builds them, for the tests.

Full state, Gaussian noise relative to each state's standard deviation,
``ps.SmoothedFiniteDifference()``, ``ps.PolynomialLibrary(degree)``; shared
by ``tests/optimizers/test_generalisation.py`` and
``tests/optimizers/test_errors_in_variables.py``.
"""

from __future__ import annotations

import numpy as np
import pysindy as ps
from scipy.integrate import solve_ivp


def record(rhs, x0, dt, t_end, degree, level, seed):
    """``(library, derivatives, true support)`` of one noisy record."""
    t = np.arange(int(round(t_end / dt)) + 1) * dt
    sol = solve_ivp(
        rhs, (0, t[-1]), x0, t_eval=t, method="DOP853", rtol=1e-11, atol=1e-12
    )
    x = sol.y.T
    rng = np.random.default_rng([seed, int(level * 1e6)])
    y = x + level * x.std(axis=0) * rng.standard_normal(x.shape)
    dx = ps.SmoothedFiniteDifference()._differentiate(y, t)
    lib = ps.PolynomialLibrary(degree).fit(y)
    theta = np.asarray(lib.transform(y))
    # the true support, read off the right-hand side by exact least squares
    points = np.random.default_rng(0).standard_normal((400, x.shape[1])) * 3
    plib = ps.PolynomialLibrary(degree).fit(points)
    rhs_values = np.array([rhs(0.0, p) for p in points])
    coef = np.linalg.lstsq(plib.transform(points), rhs_values, rcond=None)[0].T
    return theta, dx, np.abs(coef) > 1e-9
