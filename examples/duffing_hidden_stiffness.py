"""A Duffing oscillator modelled as a linear one: find the cubic stiffness.

Run: ``python examples/duffing_hidden_stiffness.py [--quick]``
(``--quick``: a 10 s record instead of 20 s).

Only the position is measured. The assumed model is the damped linear
oscillator x2' = -x1 - 0.1 x2; the truth adds -x1^3. Only x2's equation is
named as possibly wrong (``error_states=[1]``): x1' = x2 is a definition,
and an error allowed there could not be told apart from one in x2'. A
second record from another initial state validates the extended model out
of sample.
"""

import argparse

import pysindy as ps

from pysindy_mme import StudyOptions, discover
from pysindy_mme.systems import duffing


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a shorter record")
    args = parser.parse_args(argv)
    system = duffing()
    t = system.time(t_end=10.0) if args.quick else None
    data = system.measure(seed=1, t=t)
    validation = system.measure(seed=2, x0=(-1.0, 1.0), t=t)
    result = discover(
        data.y,
        data.t,
        assumed_model=system.assumed_model,
        n_states=2,
        measured=[0],
        noise_variance=system.noise_variance,
        error_states=[1],
        feature_library=ps.PolynomialLibrary(degree=3),
        validation=(validation.y, validation.t),
        options=StudyOptions(
            feature_names=["x1", "x2"], assumed_equations=["x2", "-x1 - 0.1 x2"]
        ),
    )
    print(result)
    print("true hidden effect in x2':", system.hidden_terms["x2"])
    return result


if __name__ == "__main__":
    main()
