"""A state nobody measured: the hysteretic force of a Bouc-Wen oscillator.

Run: ``python examples/hysteresis.py [--quick]``
(``--quick``: records of 4,096 samples instead of 8,192; about 15 s
instead of 30 s).

The machine (simulated, :func:`pysindy_mme.machines.hysteretic_oscillator`)
is a mass on a spring and a damper, ``m y'' + c y' + k y + F = u``, whose
restoring force ``F`` has memory (Bouc-Wen hysteresis, the constants of the
Bouc-Wen benchmark)::

    F' = alpha v - beta gamma |v| F - beta delta v |F|

Only the displacement ``y`` is measured; the force ``u`` is known. The model
a user writes first is the linear oscillator ``m v' = u - c v - k y`` on the
states ``[y, v]``, with ``m, c, k`` guessed 20 % off (grey box).

1. The study with the states the model has. No function of ``y, v, u`` can
   give a force with memory: the report says the model error of ``v'`` is
   predictable from the states' past but not from their present, names a
   missing state and the one-line fix.
2. The fix, ``hidden_states={"z": "v"}``: a state ``z`` entering ``v' = ...
   + z`` (so ``z = -F / m``), its law searched in a library of ``(v, z)``.
   The law found is converted back to the physical constants and printed
   next to the truth. Both studies measure their gain on a test record
   (``validation=``, another seed) that no fit has seen: the extended model
   runs free on it.
"""

import argparse
import warnings

import pysindy as ps

from pysindy_mme import MME, StudyOptions, discover
from pysindy_mme.feature_library.power import PowerLibrary
from pysindy_mme.machines import hysteretic_oscillator


def library(columns):
    """``v, |v|, z, |z|, v |z|, |v| z, ...`` of the given columns of
    ``(y, v, z, u)`` (first powers, signed and absolute, and the products of
    a power with an absolute value)."""
    power = PowerLibrary(
        powers=(1,), abs_powers=(1,), signed_abs_products=False, power_products=False
    )
    return ps.GeneralizedLibrary([power], inputs_per_library=[columns])


def show_conclusion(result):
    print(f"Conclusion: {result.conclusion}. {result.verdict}.")
    for reason in result.reasons:
        print(f"  because {reason}")
    for tip in result.advice:
        print(f"  try: {tip}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter records")
    args = parser.parse_args(argv)
    n_samples = 4096 if args.quick else 8192
    machine = hysteretic_oscillator()
    record = machine.record(seed=0, n_samples=n_samples)
    test = machine.record(seed=1000, n_samples=n_samples)  # never fitted
    options = StudyOptions(
        parameters=dict(machine.parameters),  # m, c, k guessed 20 % off
        feature_names=["y", "v", "u"],
    )
    common = dict(
        u=record.u,
        assumed_model=machine.assumed_model,  # f(x, t, u, p) on [y, v]
        n_states=2,
        measured=[0],
        noise_variance=float(record.noise_sd[0]) ** 2,
        mme=MME(input_hold="zoh"),  # the force is held between samples
        validation=(test.y, test.t, test.u),  # the gain out of sample
    )
    p = machine.true_parameters
    last = -p["beta"] * p["delta"]
    print(
        f"{machine.description}.\nTruth: m v' = u - c v - k y - F, F' = "
        f"{p['alpha']:g} v - {p['beta'] * p['gamma']:g} |v| F "
        f"{'+' if last >= 0 else '-'} {abs(last):g} v |F|\n"
    )

    # ---- 1. the states the model has: y, v
    print("1. The study on the states [y, v], a library of (y, v)\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        first = discover(
            record.y,
            record.t,
            error_states=[1],  # y' = v is a definition
            feature_library=library([0, 1]),
            options=options,
            **common,
        )
    show_conclusion(first)

    # ---- 2. the one-line fix: a hidden state entering v'
    print('\n2. The same study with hidden_states={"z": "v"}, a library of (v, z)\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = discover(
            record.y,
            record.t,
            feature_library=library([1, 2]),  # columns of (y, v, z, u)
            options=options.replace(hidden_states={"z": "v"}),
            **common,
        )
    result.extended_model.print()
    show_conclusion(result)

    # The law of z = -F/m in physical units:
    # z' = -(alpha/m) v - beta gamma |v| z + beta delta v |z|
    law = result.terms["z"]
    fitted = {name: p.value for name, p in result.parameters.items()}
    truth = machine.true_parameters
    found = {
        "m": fitted["m"],
        "c": fitted["c"],
        "k": fitted["k"],
        "alpha": -fitted["m"] * law.get("v", float("nan")),
        "beta gamma": -law.get("|v| z", float("nan")),
        "beta delta": law.get("v |z|", float("nan")),
    }
    true = dict(truth, **{"beta gamma": truth["beta"] * truth["gamma"]})
    true["beta delta"] = truth["beta"] * truth["delta"]
    print("\nThe machine's constants (alpha = -m * coef of v, beta gamma = -coef")
    print("of |v| z, beta delta = coef of v |z|):\n")
    print(f"  {'constant':<11} {'found':>11} {'truth':>11} {'error':>8}")
    for name, value in found.items():
        error = 100 * (value / true[name] - 1)
        print(f"  {name:<11} {value:>11.5g} {true[name]:>11.5g} {error:>+7.2f}%")

    # ---- the free run on the test record (validation=): never fitted
    gain, sd = result.gain, float(test.noise_sd[0])
    extended = float(gain.validation_rmse_extended[0])
    print(
        f"\nFree run on the test record (seed 1000; initial state from its first "
        f"{result.study.validation_window} samples, then free):\n"
        f"  RMSE extended {extended:.3g} m, assumed "
        f"{float(gain.validation_rmse_assumed[0]):.3g} m, noise sd {sd:.3g} m "
        f"(extended / noise = {extended / sd:.3f})"
    )
    return result


if __name__ == "__main__":
    main()
