"""A free run that rounding sets is reported as such (README, Known limits).

The Lotka-Volterra model without the predator's gain, fitted over 75 s: the
predators die out, the prey's fitted initial state is at rounding level and
grows as e^t, and the Newton-solved run's RMSE (2.26) is one run among many.
``perturbation_growth`` is checked against products of the maps taken one by
one and against the closed form of a scalar linear model; the claim in the
note is checked against an independent RK4 loop from a perturbed initial
state.
"""

import warnings

import numpy as np
import pysindy as ps
import pytest

from pysindy_mme import Discovery, Record, StudyOptions, discover
from pysindy_mme.core.integrate import GUIDED_TOL, perturbation_growth
from pysindy_mme.discovery.run_sensitivity import ROUNDING_SHARE
from pysindy_mme.systems import lotka_volterra, van_der_pol


@pytest.mark.parametrize("K", [1, 2, 60, 64, 1001])
def test_growth_is_the_largest_entry_of_the_products(K):
    # blocks of ceil(sqrt(K)) intervals: a last block short or full
    rng = np.random.default_rng(3)
    A = np.eye(3) + 0.3 * rng.standard_normal((K, 3, 3))
    expected = [1.0]
    P = np.eye(3)
    for Ak in A:
        P = Ak @ P
        expected.append(np.max(np.abs(P)))
    np.testing.assert_allclose(perturbation_growth(A), expected, rtol=1e-10)


def test_growth_of_a_scalar_linear_model_is_its_exponential():
    # RK4 on x' = a x: each interval multiplies by the quartic of a h
    a, h, K = 0.7, 0.05, 400
    z = a * h
    factor = 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    A = np.full((K, 1, 1), factor)
    np.testing.assert_allclose(
        perturbation_growth(A), factor ** np.arange(K + 1), rtol=1e-12
    )


def test_growth_beyond_floating_point_is_inf_from_there_on():
    A = np.full((40, 2, 2), 0.0)
    A[:, 0, 0] = A[:, 1, 1] = 1e10
    g = perturbation_growth(A)
    assert np.all(np.isfinite(g[:31])) and np.all(np.isinf(g[31:]))


def _lotka_volterra_study(t_end, cut=None):
    """The study of one record, or of two records cut at sample ``cut``."""
    system = lotka_volterra()
    t = system.time(t_end, 20.0)
    data = system.measure(0, t=t)
    records = (
        (data.y, t)
        if cut is None
        else ([Record(data.y[:cut], t[:cut]), Record(data.y[cut:], t[cut:])], None)
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = discover(
            *records,
            assumed_model=system.assumed_model,
            n_states=2,
            measured=[0, 1],
            noise_variance=0.01,
            error_states=[1],
            feature_library=ps.PolynomialLibrary(degree=2),
            options=StudyOptions(feature_names=["x1", "x2"]),
        )
    return system, t, res


def _rounding_notes(res):
    return [n for n in res.warnings if "set by rounding" in n]


def _named_time(note) -> float:
    """The time a rounding note says the run is set from."""
    return float(note.split("from t = ")[1].split(" on")[0])


def _rk4_run(f, x0, t):
    """An independent RK4 loop (one step per interval, as the study's runs)."""
    x = np.empty((t.size, x0.size))
    x[0] = x0
    for k in range(t.size - 1):
        h, xk = t[k + 1] - t[k], x[k][None, :]
        k1 = f(xk, t[k])
        k2 = f(xk + h / 2 * k1, t[k] + h / 2)
        k3 = f(xk + h / 2 * k2, t[k] + h / 2)
        k4 = f(xk + h * k3, t[k] + h)
        x[k + 1] = (xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4))[0]
        if not np.all(np.abs(x[k + 1]) < 1e12):
            x[k + 1 :] = np.inf
            break
    return x


def test_an_unstable_assumed_model_over_a_long_record_is_named():
    system, t, res = _lotka_volterra_study(75.0)
    notes = _rounding_notes(res)
    assert len(notes) == 1, res.warnings
    assert notes[0].startswith("the assumed model's free run")
    when = _named_time(notes[0])
    assert 5.0 < when < 70.0
    # the claim itself: from a change of the initial state at the run's
    # precision, an independent RK4 run leaves the reported one by more
    # than the share of the noise after that time, and not before it
    run = res.assumed_simulation
    assert run.shape == (t.size, 2)
    scale = max(1.0, float(np.max(np.abs(run))))
    sd = np.sqrt(0.01)
    x0 = run[0] + GUIDED_TOL * scale * np.array([1.0, -1.0])
    other = _rk4_run(system.assumed_model, x0, t)
    apart = np.max(np.abs(other - run), axis=1)
    assert np.nanmax(apart[t > when + 10.0]) > ROUNDING_SHARE * sd
    # the note's bound: the change is amplified by at most the growth there
    assert np.max(apart[t < when]) <= ROUNDING_SHARE * sd


def test_the_report_marks_the_run_and_a_saved_result_keeps_it(tmp_path):
    _, _, res = _lotka_volterra_study(75.0)
    assert set(res.gain.rounding_set) == {"assumed"}
    text = str(res).splitlines()
    line = [s for s in text if s.startswith("* SET BY ROUNDING")]
    assert len(line) == 1 and "the assumed model's in-sample run" in line[0]
    # the table's in-sample cells of that model, and the gain over it, starred
    first = text.index(
        "Free-run RMSE against the measurements (noise = a perfect model):"
    )
    x1 = text[first + 3].split()  # after the header and its rule
    assert x1[0] == "x1"
    assert x1[1].endswith("*") and not x1[2].endswith("*") and x1[3].endswith("x*")
    res.save(tmp_path / "lv")
    back = Discovery.load(tmp_path / "lv")
    assert back.gain.rounding_set == res.gain.rounding_set
    assert str(back) == str(res)
    assert back.gain.to_dict()["rounding_set"] == res.gain.rounding_set


def test_held_out_an_unstable_linear_model_is_named_and_its_fix_is_not():
    # not looked at while the rule was set: a decay the model has as growth
    rng = np.random.default_rng(11)
    t = np.linspace(0.0, 80.0, 1601)
    y = (4.0 * np.exp(-0.5 * t) + 1.0 + 0.05 * rng.standard_normal(t.size))[:, None]

    def assumed(x, t):
        return 0.5 * (x - 1.0)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = discover(
            y,
            t,
            assumed_model=assumed,
            n_states=1,
            measured=[0],
            noise_variance=0.0025,
            error_states=[0],
            feature_library=ps.PolynomialLibrary(degree=1),
            options=StudyOptions(feature_names=["x"]),
        )
    notes = _rounding_notes(res)
    assert [n.split(" free run")[0] for n in notes] == ["the assumed model's"]
    assert res.terms["x"], "the decay must be found"


def test_with_several_records_each_run_is_read_from_its_own_start():
    # 75 s cut in two records: the first (15 s) is too short for the growth
    # to matter, the second restarts from its own fitted state and is not
    k = 301  # t = 15
    _, t, res = _lotka_volterra_study(75.0, cut=k)
    notes = _rounding_notes(res)
    assert len(notes) == 1, res.warnings
    assert _named_time(notes[0]) > t[k]


def test_a_stable_run_gets_no_such_note():
    _, _, res = _lotka_volterra_study(15.0)
    assert _rounding_notes(res) == []


def test_the_paper_case_gets_no_such_note():
    system = van_der_pol()
    data = system.measure(0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = discover(
            data.y,
            data.t,
            assumed_model=system.assumed_model,
            n_states=2,
            measured=[0],
            noise_variance=0.01,
            error_states=[1],
            feature_library=ps.PolynomialLibrary(degree=3),
            options=StudyOptions(feature_names=["x1", "x2"]),
        )
    assert _rounding_notes(res) == []
