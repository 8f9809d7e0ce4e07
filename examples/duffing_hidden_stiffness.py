"""A Duffing oscillator modelled as a linear one: find the cubic stiffness.

Run: ``python examples/duffing_hidden_stiffness.py``

Only the position is measured. The assumed model is the damped linear
oscillator x2' = -x1 - 0.1 x2; the truth adds -x1^3. A second record from
another initial state validates the extended model out of sample.
"""

import pysindy as ps

from pysindy_mme import discover
from pysindy_mme.systems import duffing

system = duffing()
data = system.measure(seed=1)
validation = system.measure(seed=2, x0=(-1.0, 1.0))
result = discover(
    data.y,
    data.t,
    assumed_model=system.assumed_model,
    n_states=2,
    measured=[0],
    noise_variance=system.noise_variance,
    error_states=[1],
    feature_library=ps.PolynomialLibrary(degree=3),
    feature_names=["x1", "x2"],
    validation=(validation.y, validation.t),
    assumed_equations=["x2", "-x1 - 0.1 x2"],
)
print(result)
print("true hidden effect in x2':", system.hidden_terms["x2"])
