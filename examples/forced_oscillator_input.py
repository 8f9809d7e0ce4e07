"""A forced oscillator whose actuator is stronger than the model says.

Run: ``python examples/forced_oscillator_input.py [--quick]``
(``--quick``: half the record).

The assumed model x2' = -x1 - 0.2 x2 + u has the input gain 1.0; the truth is
1.5. The hidden effect 0.5 u depends on the input, so the library sees u as a
third variable (pysindy's control-input convention: state names, then input
names). Only the position is measured. The input is applied by a digital
signal generator, held between samples in reality, but sampled finely
enough here that linear interpolation (the default ``input_hold``) is as good.
"""

import argparse

import numpy as np
import pysindy as ps

from pysindy_mme import StudyOptions, discover
from pysindy_mme.systems import forced_oscillator


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a shorter record")
    args = parser.parse_args(argv)
    system = forced_oscillator()
    t = system.time(t_end=system.t_end / 2) if args.quick else None
    data = system.measure(seed=3, t=t)
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
        options=StudyOptions(
            feature_names=["x1", "x2", "u"],
            assumed_equations=["x2", "-x1 - 0.2 x2 + u"],
        ),
    )
    print(result)
    print("true hidden effect in x2':", system.hidden_terms["x2"])
    x_sim = result.extended_model.simulate(data.x[0], data.t, u=data.u)
    rmse = np.sqrt(np.mean((x_sim - data.x) ** 2, axis=0))
    print("extended model simulation error against the true states (RMSE):", rmse)
    return result


if __name__ == "__main__":
    main()
