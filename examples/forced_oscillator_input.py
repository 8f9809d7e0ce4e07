"""A forced oscillator whose actuator is stronger than the model says.

Run: ``python examples/forced_oscillator_input.py``

The assumed model x2' = -x1 - 0.2 x2 + u has the input gain 1.0; the truth is
1.5. The hidden effect 0.5 u depends on the input, so the library sees u as a
third variable (pysindy's control-input convention: state names, then input
names). Only the position is measured.
"""

import pysindy as ps

from pysindy_mme import discover
from pysindy_mme.systems import forced_oscillator

system = forced_oscillator()
data = system.measure(seed=3)
result = discover(
    data.y,
    data.t,
    assumed_model=system.assumed_model,
    n_states=2,
    measured=[0],
    noise_variance=system.noise_variance,
    error_states=[1],
    u=data.u,
    feature_library=ps.PolynomialLibrary(degree=2),
    feature_names=["x1", "x2", "u"],
    assumed_equations=["x2", "-x1 - 0.2 x2 + u"],
)
print(result)
print("true hidden effect in x2':", system.hidden_terms["x2"])
x_sim = result.extended_model.simulate(data.x[0], data.t, u=data.u)
print(
    "extended model simulation error against the true states (RMSE):",
    ((x_sim - data.x) ** 2).mean(axis=0) ** 0.5,
)
