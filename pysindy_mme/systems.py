"""Example systems with a known hidden effect.

Each :class:`HiddenEffectSystem` pairs a *true* model with the *assumed*
model a modeller would write down, which lacks one effect. The difference is
known exactly (``hidden_terms``), so examples, tests and benchmarks can check
that the effect is found, named and measured.

Feature names in ``hidden_terms`` follow pysindy's ``PolynomialLibrary``
with the state (and input) names as feature names, e.g. ``"x1^2 x2"``.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from .core.model import simulate_model

__all__ = [
    "HiddenEffectSystem",
    "Measurements",
    "van_der_pol",
    "duffing",
    "lotka_volterra",
    "quadratic_drag",
    "forced_oscillator",
    "lorenz",
    "rossler",
    "all_systems",
]


@dataclass(frozen=True)
class Measurements:
    """Simulated noisy measurements of a system.

    Attributes
    ----------
    t : ndarray (n_samples,)
    y : ndarray (n_samples, n_measured)
        Noisy measurements of the measured states.
    x : ndarray (n_samples, n_states)
        Noise-free true states.
    u : ndarray (n_samples, n_inputs) or None
        Input on the sample grid.
    d : ndarray (n_samples, n_states)
        True model error ``f_true - f_assumed`` along the true trajectory.
    """

    t: np.ndarray
    y: np.ndarray
    x: np.ndarray
    u: np.ndarray | None
    d: np.ndarray


@dataclass(frozen=True)
class HiddenEffectSystem:
    """A true model, the assumed model that misses an effect, and how it is seen.

    Attributes
    ----------
    name : str
    description : str
    state_names : tuple of str
    true_model, assumed_model : callable ``f(x, t)`` or ``f(x, t, u)``
        Vectorised right-hand sides.
    x0 : tuple of float
    t_end, rate_hz : float
        Record length (s) and sampling rate (Hz); the grid has
        ``round(t_end * rate_hz) + 1`` samples starting at 0.
    measured : tuple of int
        Indices of the measured states.
    error_states : tuple of int
        States whose equation the assumed model gets wrong.
    noise_variance : float
        Measurement noise variance used by :meth:`measure`.
    hidden_terms : mapping
        ``{state name: {feature name: coefficient}}``, the exact difference
        ``true_model - assumed_model``.
    input_signal : callable ``u(t)`` or None
        Known input, returning shape ``(n_samples, n_inputs)`` for ``t`` of
        shape ``(n_samples,)``.
    input_names : tuple of str
    """

    name: str
    description: str
    state_names: tuple
    true_model: Callable
    assumed_model: Callable
    x0: tuple
    t_end: float
    rate_hz: float
    measured: tuple
    error_states: tuple
    noise_variance: float
    hidden_terms: Mapping = field(default_factory=dict)
    input_signal: Callable | None = None
    input_names: tuple = ()

    @property
    def n_states(self) -> int:
        return len(self.state_names)

    @property
    def feature_names(self) -> list:
        """State names followed by input names (pysindy's ``feature_names``)."""
        return list(self.state_names) + list(self.input_names)

    def time(self, t_end: float | None = None, rate_hz: float | None = None):
        """The sample grid ``0, 1/rate, ..., t_end``."""
        t_end = self.t_end if t_end is None else t_end
        rate_hz = self.rate_hz if rate_hz is None else rate_hz
        n = int(round(t_end * rate_hz)) + 1
        return np.arange(n) / rate_hz

    def inputs(self, t) -> np.ndarray | None:
        if self.input_signal is None:
            return None
        return np.asarray(self.input_signal(np.asarray(t, dtype=float)), dtype=float)

    def simulate(self, t=None, x0=None, model: str = "true") -> np.ndarray:
        """Noise-free trajectory of the ``"true"`` or ``"assumed"`` model.

        Trajectories are cached per model function (the last few grids and
        initial states), so that many noise seeds on one grid integrate the
        system once; a copy is returned.
        """
        t = self.time() if t is None else np.asarray(t, dtype=float)
        x0 = self.x0 if x0 is None else x0
        f = self.true_model if model == "true" else self.assumed_model
        key = (tuple(np.asarray(x0, dtype=float).ravel()), t.size, hash(t.tobytes()))
        cache = _TRAJECTORIES.setdefault(f, {})
        if key not in cache:
            # The exact input signal (not its samples) drives the simulation.
            cache[key] = simulate_model(
                f,
                x0,
                t,
                self.input_signal,
                n_states=self.n_states,
                rtol=1e-10,
                atol=1e-12,
            )
            while len(cache) > 4:
                cache.pop(next(iter(cache)))
        return cache[key].copy()

    def measure(
        self,
        seed: int,
        *,
        noise_variance: float | None = None,
        t=None,
        x0=None,
        full_state: bool = False,
    ) -> Measurements:
        """Simulate the true system and add Gaussian noise to the measured states.

        The noise comes from ``numpy.random.default_rng(seed)``; no global
        random state is touched.
        """
        t = self.time() if t is None else np.asarray(t, dtype=float)
        x = self.simulate(t, x0)
        var = self.noise_variance if noise_variance is None else noise_variance
        cols = list(range(self.n_states)) if full_state else list(self.measured)
        rng = np.random.default_rng(seed)
        y = x[:, cols] + np.sqrt(var) * rng.standard_normal((t.size, len(cols)))
        u = self.inputs(t)
        d = self.true_correction(x, t, u)
        return Measurements(t=t, y=y, x=x, u=u, d=d)

    def true_correction(self, x, t, u=None) -> np.ndarray:
        """``f_true(x, t, u) - f_assumed(x, t, u)``."""
        return _call(self.true_model, x, t, u) - _call(self.assumed_model, x, t, u)


# model function -> {(x0, n, hash of t): trajectory}; weak keys, so a system's
# cache goes with its functions.
_TRAJECTORIES = weakref.WeakKeyDictionary()


def _call(f, x, t, u):
    if u is None:
        try:
            return f(x, t)
        except TypeError:
            return f(x, t, None)
    return f(x, t, u)


def van_der_pol(alpha: float = 1.0) -> HiddenEffectSystem:
    """The paper's example: Van der Pol with the *ignorance* assumed model.

    Truth ``x1' = x2, x2' = -x1 + alpha (1 - x1^2) x2``; assumed
    ``x1' = x2, x2' = 0``, so ``d = -x1 + alpha x2 - alpha x1^2 x2`` in x2'.
    Only x1 is measured, noise variance 0.01, 40 Hz for 10 s, ``x0 = [1, 0]``.
    """

    def true_model(x, t):
        x1, x2 = x[:, 0], x[:, 1]
        return np.column_stack([x2, -x1 + alpha * (1.0 - x1**2) * x2])

    def assumed_model(x, t):
        return np.column_stack([x[:, 1], np.zeros(len(x))])

    return HiddenEffectSystem(
        name="van_der_pol",
        description="Van der Pol oscillator, ignorance model x2' = 0 (the paper)",
        state_names=("x1", "x2"),
        true_model=true_model,
        assumed_model=assumed_model,
        x0=(1.0, 0.0),
        t_end=10.0,
        rate_hz=40.0,
        measured=(0,),
        error_states=(1,),
        noise_variance=0.01,
        hidden_terms={"x2": {"x1": -1.0, "x2": alpha, "x1^2 x2": -alpha}},
    )


def duffing(
    delta: float = 0.1, k: float = 1.0, beta: float = 1.0
) -> HiddenEffectSystem:
    """Duffing oscillator whose assumed model misses the cubic stiffness.

    Truth ``x2' = -k x1 - delta x2 - beta x1^3``; the assumed model is the
    linear damped oscillator. Only x1 (position) is measured.
    """

    def true_model(x, t):
        x1, x2 = x[:, 0], x[:, 1]
        return np.column_stack([x2, -k * x1 - delta * x2 - beta * x1**3])

    def assumed_model(x, t):
        x1, x2 = x[:, 0], x[:, 1]
        return np.column_stack([x2, -k * x1 - delta * x2])

    return HiddenEffectSystem(
        name="duffing",
        description="Duffing oscillator, assumed linear: cubic stiffness is hidden",
        state_names=("x1", "x2"),
        true_model=true_model,
        assumed_model=assumed_model,
        x0=(1.5, 0.0),
        t_end=20.0,
        rate_hz=40.0,
        measured=(0,),
        error_states=(1,),
        noise_variance=0.01,
        hidden_terms={"x2": {"x1^3": -beta}},
    )


def lotka_volterra(
    a: float = 1.0, b: float = 0.5, c: float = 1.0, e: float = 0.5
) -> HiddenEffectSystem:
    """Predator-prey model whose assumed model misses the predator's gain.

    Truth ``x1' = a x1 - b x1 x2, x2' = -c x2 + e x1 x2``; the assumed model
    has no coupling term ``e x1 x2`` in x2' (predators that do not feed).
    Both populations are measured.
    """

    def true_model(x, t):
        x1, x2 = x[:, 0], x[:, 1]
        return np.column_stack([a * x1 - b * x1 * x2, -c * x2 + e * x1 * x2])

    def assumed_model(x, t):
        x1, x2 = x[:, 0], x[:, 1]
        return np.column_stack([a * x1 - b * x1 * x2, -c * x2])

    return HiddenEffectSystem(
        name="lotka_volterra",
        description="Lotka-Volterra, the predator's feeding term x1 x2 is missing",
        state_names=("x1", "x2"),
        true_model=true_model,
        assumed_model=assumed_model,
        x0=(3.0, 1.0),
        t_end=15.0,
        rate_hz=20.0,
        measured=(0, 1),
        error_states=(1,),
        noise_variance=0.01,
        hidden_terms={"x2": {"x1 x2": e}},
    )


def quadratic_drag(k: float = 1.0, drag: float = 0.3) -> HiddenEffectSystem:
    """Oscillator with quadratic air drag ``-drag x2 |x2|`` the model omits.

    The drag term is not a polynomial: it needs :class:`PowerLibrary`
    (``x2 |x2|``). Only x1 is measured.
    """

    def true_model(x, t):
        x1, x2 = x[:, 0], x[:, 1]
        return np.column_stack([x2, -k * x1 - drag * x2 * np.abs(x2)])

    def assumed_model(x, t):
        return np.column_stack([x[:, 1], -k * x[:, 0]])

    return HiddenEffectSystem(
        name="quadratic_drag",
        description="Undamped oscillator model; quadratic drag x2|x2| is hidden",
        state_names=("x1", "x2"),
        true_model=true_model,
        assumed_model=assumed_model,
        x0=(2.0, 0.0),
        t_end=20.0,
        rate_hz=40.0,
        measured=(0,),
        error_states=(1,),
        noise_variance=0.01,
        hidden_terms={"x2": {"x2 |x2|": -drag}},
    )


def _forcing(t):
    t = np.asarray(t, dtype=float)
    return (np.sin(1.3 * t) + 0.6 * np.sin(3.1 * t + 0.4))[..., None]


def forced_oscillator(
    k: float = 1.0, c: float = 0.2, gain: float = 1.0, gain_error: float = 0.5
) -> HiddenEffectSystem:
    """Forced damped oscillator whose actuator is stronger than modelled.

    Truth ``x2' = -k x1 - c x2 + (gain + gain_error) u``; the assumed model
    uses ``gain``. The hidden effect ``gain_error u`` depends on the input, so
    the library must see ``u``. Only x1 is measured.
    """

    def true_model(x, t, u):
        x1, x2 = x[:, 0], x[:, 1]
        return np.column_stack([x2, -k * x1 - c * x2 + (gain + gain_error) * u[:, 0]])

    def assumed_model(x, t, u):
        x1, x2 = x[:, 0], x[:, 1]
        return np.column_stack([x2, -k * x1 - c * x2 + gain * u[:, 0]])

    return HiddenEffectSystem(
        name="forced_oscillator",
        description="Forced oscillator; the actuator gain is 50% higher than modelled",
        state_names=("x1", "x2"),
        true_model=true_model,
        assumed_model=assumed_model,
        x0=(0.0, 0.0),
        t_end=20.0,
        rate_hz=40.0,
        measured=(0,),
        error_states=(1,),
        noise_variance=0.01,
        hidden_terms={"x2": {"u": gain_error}},
        input_signal=_forcing,
        input_names=("u",),
    )


def lorenz(
    sigma: float = 10.0, rho: float = 28.0, beta: float = 8.0 / 3.0
) -> HiddenEffectSystem:
    """Lorenz system; the assumed model misses the ``-x1 x3`` coupling in x2'.

    All three states are measured (used for full-state comparisons with
    STLSQ, where the whole right-hand side is identified).
    """

    def true_model(x, t):
        x1, x2, x3 = x[:, 0], x[:, 1], x[:, 2]
        return np.column_stack(
            [sigma * (x2 - x1), x1 * (rho - x3) - x2, x1 * x2 - beta * x3]
        )

    def assumed_model(x, t):
        x1, x2, x3 = x[:, 0], x[:, 1], x[:, 2]
        return np.column_stack([sigma * (x2 - x1), rho * x1 - x2, x1 * x2 - beta * x3])

    return HiddenEffectSystem(
        name="lorenz",
        description="Lorenz system; the x1 x3 coupling in x2' is missing",
        state_names=("x1", "x2", "x3"),
        true_model=true_model,
        assumed_model=assumed_model,
        x0=(-8.0, 8.0, 27.0),
        t_end=10.0,
        rate_hz=200.0,
        measured=(0, 1, 2),
        error_states=(1,),
        noise_variance=0.01,
        hidden_terms={"x2": {"x1 x3": -1.0}},
    )


def rossler(a: float = 0.2, b: float = 0.2, c: float = 5.7) -> HiddenEffectSystem:
    """Rossler's chaotic flow; only ``y`` is measured and ``x z`` is missing in z'.

    Truth ``x' = -y - z``, ``y' = x + a y``, ``z' = b + z (x - c)``; the
    assumed model has ``z' = b - c z``. Thirty time units (about five
    orbits) at 20 Hz; ``x`` and ``z`` are never measured, so the missing
    coupling is seen only through ``y``.
    """

    def true_model(x, t):
        xx, yy, zz = x[:, 0], x[:, 1], x[:, 2]
        return np.column_stack([-yy - zz, xx + a * yy, b + zz * (xx - c)])

    def assumed_model(x, t):
        xx, yy, zz = x[:, 0], x[:, 1], x[:, 2]
        return np.column_stack([-yy - zz, xx + a * yy, b - c * zz])

    return HiddenEffectSystem(
        name="rossler",
        description="Rossler flow; the x z coupling in z' is missing, y measured",
        state_names=("x", "y", "z"),
        true_model=true_model,
        assumed_model=assumed_model,
        x0=(1.0, 1.0, 0.0),
        t_end=30.0,
        rate_hz=20.0,
        measured=(1,),
        error_states=(2,),
        noise_variance=0.04,
        hidden_terms={"z": {"x z": 1.0}},
    )


def all_systems() -> list:
    """Every example system with its default parameters."""
    return [
        van_der_pol(),
        duffing(),
        lotka_volterra(),
        quadratic_drag(),
        forced_oscillator(),
        lorenz(),
        rossler(),
    ]
