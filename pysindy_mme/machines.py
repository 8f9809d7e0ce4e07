"""Simulated real machines: records with the flaws of measured data.

:mod:`pysindy_mme.systems` gives clean textbook systems with Gaussian noise.
The machines here add what measured records of real plants have: a
controller or pump that computes the input at each sample and holds it
(zero-order hold), encoders and ADCs that quantise, sensors that clip at the
end of their range, friction that sticks, tanks that overflow. Each
:class:`Machine` pairs the true model with the grey-box model a user would
write down (``assumed_model(x, t, u, p)``, with deliberately wrong initial
guesses in ``parameters``) and says in ``missing`` what that model lacks.

The simulations are accurate to far below the sensor noise and quantisation:

* :func:`positioning_axis` is solved exactly. The input is held between
  samples, so between velocity reversals the motion is a linear ODE with
  constant forcing, solved in closed form; a reversal's time is found
  analytically, and at zero velocity the carriage sticks while the applied
  force is within the static friction.
* :func:`cascaded_tanks` uses RK4 with ``substeps`` steps per sample (the
  pump voltage is constant over a sample); the overflow is part of the
  right-hand side, and any level above the rim at the end of a step is moved
  to the lower tank, so no water is lost.
* :func:`damped_pendulum` and :func:`clipped_oscillator` have no input and a
  smooth right-hand side: ``scipy.integrate.solve_ivp`` (DOP853) with
  ``rtol = atol = 1e-12``.

Every record's grid is ``t_k = k / rate`` for ``k = 0 .. N-1`` with
``N = round(duration * rate)``; the noise and any random input come from
``numpy.random.default_rng(seed)`` (no global random state is touched), so a
seed reproduces a record exactly.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.integrate import solve_ivp

__all__ = [
    "MachineRecord",
    "Machine",
    "positioning_axis",
    "cascaded_tanks",
    "damped_pendulum",
    "clipped_oscillator",
    "asymmetric_damper",
    "hysteretic_oscillator",
]


@dataclass(frozen=True, eq=False)
class MachineRecord:
    """One simulated record of a machine.

    Attributes
    ----------
    t : ndarray (N,)
        Sample times (s).
    y : ndarray (N, m)
        What the sensors report: noise, quantisation and clipping applied.
    u : ndarray (N, n_inputs) or None
        The input on the sample grid, as the user knows it; ``u[k]`` is held
        over ``[t[k], t[k+1])``.
    x : ndarray (N, n)
        True, noise-free states.
    measured : list of int
        State index of each sensor channel.
    state_names, input_names : list of str
    noise_sd : ndarray (m,)
        The true white sensor noise sd per channel, before quantisation.
    quantisation_step : float or None
        Sensor resolution; every reading is an integer multiple of it.
    clip : tuple (low, high) or None
        Sensor range; readings beyond it are reported as the limit.
    """

    t: np.ndarray
    y: np.ndarray
    u: np.ndarray | None
    x: np.ndarray
    measured: list
    state_names: list
    input_names: list
    noise_sd: np.ndarray
    quantisation_step: float | None
    clip: tuple | None

    @property
    def n_clipped(self) -> int:
        """Readings on the clip limits (0 without clipping)."""
        if self.clip is None:
            return 0
        low, high = self.clip
        return int(np.count_nonzero((self.y <= low) | (self.y >= high)))

    def split(self, fraction: float = 0.5) -> tuple[MachineRecord, MachineRecord]:
        """The leading ``fraction`` of the samples and the rest.

        The trailing part keeps its times (not shifted to start at 0), so the
        two parts together are the record, e.g. for estimation on the first
        and validation on the second.

        Parameters
        ----------
        fraction : float, default 0.5
            Share of the samples in the leading part, in (0, 1).

        Returns
        -------
        lead, trail : MachineRecord
        """
        if not 0.0 < fraction < 1.0:
            raise ValueError(f"fraction must be in (0, 1), got {fraction!r}")
        n = self.t.size
        k = int(round(fraction * n))
        if k < 2 or n - k < 2:
            raise ValueError(
                f"split at {fraction} of {n} samples leaves a part with fewer "
                "than 2 samples"
            )

        def part(rows):
            return replace(
                self,
                t=self.t[rows],
                y=self.y[rows],
                u=None if self.u is None else self.u[rows],
                x=self.x[rows],
            )

        return part(slice(0, k)), part(slice(k, n))


@dataclass(frozen=True, eq=False)
class Machine:
    """A simulated machine: its true model, the model a user writes, records.

    Attributes
    ----------
    name, description : str
    state_names, input_names : list of str
    measured : list of int
        State index of each sensor channel.
    true_model : callable ``f(x, t, u)``
        The true right-hand side, vectorised over the rows of ``x`` (``u``
        rows match ``x`` rows; ignored without inputs).
    assumed_model : callable
        The user's grey-box model ``f(x, t, u, p)`` with ``p`` a dict of
        :attr:`parameters`, vectorised like ``true_model``; ``f(x, t)`` for
        a machine without inputs and parameters.
    parameters : dict
        The user's initial guesses for ``p`` (deliberately off).
    true_parameters : dict
        Every constant of the true model. Keys shared with
        :attr:`parameters` are their true values; the others belong to the
        effects the assumed model lacks. (The linear tanks model shares no
        keys: its coefficients have no true value.)
    missing : str
        What the assumed model lacks.
    options : dict
        Recording defaults; :meth:`record` accepts any of them as keywords.
    seed : int
        Seed used by :meth:`record` when none is given.
    recorder, simulator : callable
        The machine's own ``recorder(seed, options) -> MachineRecord`` and
        ``simulator(t, u, x0) -> x``, behind :meth:`record` and
        :meth:`simulate`.
    """

    name: str
    description: str
    state_names: list
    input_names: list
    measured: list
    true_model: Callable
    assumed_model: Callable
    parameters: dict
    true_parameters: dict
    missing: str
    options: dict
    seed: int = 0
    recorder: Callable = field(default=None, repr=False)
    simulator: Callable = field(default=None, repr=False)

    def record(self, seed: int | None = None, **options) -> MachineRecord:
        """Run the machine and return what was measured.

        Parameters
        ----------
        seed : int, optional
            Seed of the noise and of any random input (default
            :attr:`seed`).
        **options
            Overrides of :attr:`options`, e.g. ``duration`` or ``noise_sd``.

        Returns
        -------
        MachineRecord
        """
        unknown = sorted(set(options) - set(self.options))
        if unknown:
            raise TypeError(
                f"{self.name}.record: unknown option(s) {unknown}; "
                f"known: {sorted(self.options)}"
            )
        seed = self.seed if seed is None else seed
        return self.recorder(seed, {**self.options, **options})

    def simulate(self, t, u=None, x0=None) -> np.ndarray:
        """Noise-free true states on the grid ``t`` for a given input.

        Open loop: ``u[k]`` (shape ``(N, n_inputs)``) is held over
        ``[t[k], t[k+1])``, with no controller in the loop.

        Parameters
        ----------
        t : array_like (N,)
            Increasing sample times.
        u : array_like (N, n_inputs), optional
            Input samples; zeros when omitted for a machine with inputs.
        x0 : array_like (n,), optional
            Initial state (default ``options["x0"]``).

        Returns
        -------
        ndarray (N, n)
        """
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or t.size < 1 or np.any(np.diff(t) <= 0):
            raise ValueError("t must be a 1-D increasing array")
        x0 = np.asarray(self.options["x0"] if x0 is None else x0, dtype=float)
        if self.input_names:
            u = np.zeros((t.size, len(self.input_names))) if u is None else u
            u = np.asarray(u, dtype=float).reshape(t.size, len(self.input_names))
        return self.simulator(t, u, x0)


# ---------------------------------------------------------------------------
# helpers


def _grid(duration: float, rate: float) -> np.ndarray:
    n = int(round(duration * rate))
    if n < 2:
        raise ValueError(f"duration * rate must give >= 2 samples, got {n}")
    return np.arange(n) / rate


def _sensor(x, rng, noise_sd, step, clip):
    """Readings of the signal ``x``: white noise, then quantisation, then the
    range (so a clipped reading is exactly the limit)."""
    y = np.array(x, dtype=float)
    if noise_sd > 0:
        y = y + noise_sd * rng.standard_normal(y.shape)
    if step is not None:
        y = step * np.round(y / step)
    if clip is not None:
        y = np.clip(y, clip[0], clip[1])
    return y


def _input_column(u, n):
    """Column 0 of the input as a vector of ``n`` rows."""
    return np.asarray(u, dtype=float).reshape(n, -1)[:, 0]


def _held(step, t, u, x0):
    """States on ``t`` from ``step(x, u_k, dt)``, one call per sample interval."""
    x = np.empty((t.size, len(x0)))
    x[0] = x0
    for k in range(t.size - 1):
        x[k + 1] = step(x[k], u[k], t[k + 1] - t[k])
    return x


def _smooth(f, x0, t):
    """Accurate trajectory of a smooth autonomous ``f(x, t)`` (rows) on ``t``."""

    def rhs(tt, xx):
        return f(xx[None, :], np.array([tt]))[0]

    sol = solve_ivp(
        rhs,
        (t[0], t[-1]),
        np.asarray(x0, dtype=float),
        method="DOP853",
        t_eval=t,
        rtol=1e-12,
        atol=1e-12,
    )
    if not sol.success:  # pragma: no cover - smooth systems on short records
        raise RuntimeError(sol.message)
    return sol.y.T


# ---------------------------------------------------------------------------
# 1. positioning axis


def _axis_interval(q, v, force, dt, M, c, Fc, Fs):
    """Exact motion over ``dt`` under a constant applied force.

    ``M v' = force - c v - Fc sign(v)``; at ``v = 0`` the carriage stays
    stuck while ``|force| <= Fs``, and otherwise starts in the direction of
    the force. With the sign of ``v`` fixed the equation is linear:
    ``v(s) = v_end + (v - v_end) exp(-c s / M)``, ``v_end = (force - sign Fc)
    / c``; a reversal happens only when ``v_end`` has the other sign, at the
    time ``v(s) = 0`` solved in closed form.
    """
    lam = c / M
    left = dt
    # at most three pieces: to a stop, then sticking or sliding the other way
    for _ in range(3):
        if left <= 0.0:
            break
        if v == 0.0:
            if abs(force) <= Fs:
                return q, 0.0  # stuck: the force is constant for the rest
            s = math.copysign(1.0, force)
        else:
            s = math.copysign(1.0, v)
        v_end = (force - s * Fc) / c
        t_stop = math.inf
        if s * v_end < 0.0:
            t_stop = math.log1p(-v / v_end) / lam
        h = min(left, t_stop)
        decay = -math.expm1(-lam * h)  # 1 - exp(-lam h), accurate for small h
        q = q + v_end * h + (v - v_end) * decay / lam
        if t_stop <= left:
            v = 0.0  # exactly: the next pass decides between sticking and slip
        else:
            v_new = v_end + (v - v_end) * (1.0 - decay)
            # rounding must not turn a stop just after the interval into a
            # reversal without the friction switching sign
            v = v_new if v_new * s > 0.0 else 0.0
        left -= h
    return q, v


def _min_jerk(s):
    """Minimum-jerk profile ``p(s)`` and ``p'(s)`` for ``s`` in [0, 1]."""
    s = np.clip(s, 0.0, 1.0)
    p = s**3 * (10.0 - 15.0 * s + 6.0 * s**2)
    dp = 30.0 * s**2 * (1.0 - s) ** 2
    return p, dp


def _axis_reference(rng, t, q0, stroke, accel):
    """Smooth point-to-point moves between random setpoints, with dwells."""
    r = np.full(t.size, float(q0))
    rd = np.zeros(t.size)
    time, pos = 0.0, float(q0)
    while True:
        start = time + rng.uniform(0.3, 1.2)
        if start >= t[-1]:
            break
        target = rng.uniform(-stroke, stroke)
        dist = target - pos
        # minimum jerk peaks at 5.77 dist / T^2: keep it within accel
        T = max(0.2, math.sqrt(5.7735 * abs(dist) / accel))
        after = t >= start
        p, dp = _min_jerk((t[after] - start) / T)
        r[after] = pos + dist * p
        rd[after] = dist / T * dp
        time, pos = start + T, target
    return r, rd


def _multisine(rng, t, rms, f_low, f_high, n=15):
    """Sum of ``n`` sines, log-spaced frequencies, random phases, given rms."""
    if rms == 0:
        return np.zeros(t.size)
    freqs = np.geomspace(f_low, f_high, n)
    phases = rng.uniform(0.0, 2.0 * np.pi, n)
    s = np.sin(2.0 * np.pi * freqs[None, :] * t[:, None] + phases).sum(axis=1)
    return rms * math.sqrt(2.0 / n) * s


def positioning_axis(
    *,
    M: float = 95.0,
    c: float = 200.0,
    Fc: float = 20.0,
    F0: float = 3.0,
    Fs: float | None = None,
    K_u: float = 100.0,
    seed: int = 0,
    duration: float = 25.0,
    rate: float = 1000.0,
    noise_sd: float = 0.0,
    resolution: float = 5e-8,
    dither: float = 0.5,
    stroke: float = 0.2,
    accel: float = 4.0,
    gains: tuple = (1000.0, 40.0),
    u_max: float = 10.0,
    x0: tuple = (0.0, 0.0),
) -> Machine:
    """A motor-driven carriage under PD position control.

    Truth ``q' = v``, ``M v' = K_u u - c v - Fc sign(v) + F0``: viscous
    friction, Coulomb friction (sticking at ``v = 0`` while
    ``|K_u u + F0| <= Fs``) and a constant force offset ``F0`` (cable drag,
    a tilt). The assumed model is ``q' = v``, ``v' = (K_u u - c v) / M`` with
    ``p = {"M", "c"}`` (guesses 90 kg and 150 N s/m) and ``K_u`` known.

    The input ``u`` is the controller's voltage, computed at each sample
    from the *encoder reading* ``y`` (not the true position)::

        v_est[k] = a v_est[k-1] + (1 - a) (y[k] - y[k-1]) / T,  a = exp(-T/2ms)
        u[k] = clip(Kp (r[k] - y[k]) + Kd (r'[k] - v_est[k]) + dither[k],
                    -u_max, u_max)

    and held until the next sample. The reference ``r`` moves between random
    setpoints in ``[-stroke, stroke]`` with minimum-jerk profiles (peak
    acceleration ``accel``); ``dither`` is the rms (V) of a 15-tone
    multisine (0.3-30 Hz) added to the voltage, which keeps the carriage
    reversing so friction shows. Position is measured by an encoder with
    ``resolution`` (50 nm) and, beyond its quantisation, white noise
    ``noise_sd`` (0: an encoder has none). The motion is integrated exactly
    (see the module notes).

    Parameters
    ----------
    M, c, Fc, F0, K_u : float
        Mass (kg), viscous (N s/m) and Coulomb (N) friction, force offset
        (N), motor constant (N/V).
    Fs : float, optional
        Static (breakaway) friction, ``>= Fc`` (default ``Fc``).
    seed : int
        Default seed of :meth:`Machine.record`.
    duration, rate, noise_sd, resolution, dither, stroke, accel, gains, u_max,
    x0
        Recording defaults (s, Hz, m, m, V, m, m/s^2, (V/m, V s/m), V,
        (m, m/s)); each can be overridden in :meth:`Machine.record`.

    Returns
    -------
    Machine
    """
    Fs = Fc if Fs is None else Fs
    if M <= 0 or c <= 0:
        raise ValueError("M and c must be positive")
    if Fc < 0 or Fs < Fc:
        raise ValueError("need 0 <= Fc <= Fs")

    def true_model(x, t, u):
        v = x[:, 1]
        force = K_u * _input_column(u, len(x)) + F0
        stuck = (v == 0.0) & (np.abs(force) <= Fs)
        # at v = 0 the carriage starts in the direction of the force
        direction = np.where(v != 0.0, np.sign(v), np.sign(force))
        friction = np.where(stuck, force, Fc * direction)
        return np.column_stack([v, (force - c * v - friction) / M])

    def assumed_model(x, t, u, p):
        v = x[:, 1]
        uu = _input_column(u, len(x))
        return np.column_stack([v, (K_u * uu - p["c"] * v) / p["M"]])

    def simulator(t, u, x0):
        return _held(step, t, u, x0)

    def step(x, u, dt):
        return _axis_interval(x[0], x[1], K_u * u[0] + F0, dt, M, c, Fc, Fs)

    def recorder(seed, o):
        rng = np.random.default_rng(seed)
        t = _grid(o["duration"], o["rate"])
        T = 1.0 / o["rate"]
        q, v = (float(a) for a in o["x0"])
        r, rd = _axis_reference(rng, t, q, o["stroke"], o["accel"])
        dith = _multisine(rng, t, o["dither"], 0.3, 30.0)
        # the encoder: noise (if any) before the quantiser, drawn up front
        noise = o["noise_sd"] * rng.standard_normal(t.size)
        step = o["resolution"]
        kp, kd = o["gains"]
        a = math.exp(-T / 2e-3)
        x = np.empty((t.size, 2))
        y = np.empty(t.size)
        u = np.empty(t.size)
        v_est = 0.0
        for k in range(t.size):
            x[k] = q, v
            y[k] = step * round((q + noise[k]) / step)
            if k:
                v_est = a * v_est + (1.0 - a) * (y[k] - y[k - 1]) / T
            uk = kp * (r[k] - y[k]) + kd * (rd[k] - v_est) + dith[k]
            u[k] = min(max(uk, -o["u_max"]), o["u_max"])
            if k + 1 < t.size:
                q, v = _axis_interval(q, v, K_u * u[k] + F0, T, M, c, Fc, Fs)
        return MachineRecord(
            t=t,
            y=y[:, None],
            u=u[:, None],
            x=x,
            measured=[0],
            state_names=["q", "v"],
            input_names=["u"],
            noise_sd=np.array([float(o["noise_sd"])]),
            quantisation_step=float(step),
            clip=None,
        )

    return Machine(
        name="positioning_axis",
        description="PD-controlled carriage with Coulomb friction and an offset "
        "force, encoder position at 1 kHz",
        state_names=["q", "v"],
        input_names=["u"],
        measured=[0],
        true_model=true_model,
        assumed_model=assumed_model,
        parameters={"M": 90.0, "c": 150.0},
        true_parameters={"M": M, "c": c, "Fc": Fc, "F0": F0, "Fs": Fs, "K_u": K_u},
        missing=f"Coulomb friction -Fc/M sign(v) (Fc = {Fc:g} N, sticking at "
        f"v = 0) and an offset F0/M in v' (F0 = {F0:g} N)",
        options=dict(
            duration=duration,
            rate=rate,
            noise_sd=noise_sd,
            resolution=resolution,
            dither=dither,
            stroke=stroke,
            accel=accel,
            gains=tuple(gains),
            u_max=u_max,
            x0=tuple(x0),
        ),
        seed=seed,
        recorder=recorder,
        simulator=simulator,
    )


# ---------------------------------------------------------------------------
# 2. cascaded tanks


def _tanks_linear(x, t, u, p):
    uu = _input_column(u, len(x))
    h1, h2 = x[:, 0], x[:, 1]
    return np.column_stack([-p["a1"] * h1 + p["b"] * uu, p["a2"] * h1 - p["a3"] * h2])


def _tanks_sqrt(x, t, u, p):
    uu = _input_column(u, len(x))
    # estimated levels may dip below zero; an empty tank has no outflow
    o1 = p["k1"] * np.sqrt(np.maximum(x[:, 0], 0.0))
    o2 = p["k2"] * np.sqrt(np.maximum(x[:, 1], 0.0))
    return np.column_stack([-o1 + p["kp"] * uu, o1 - o2])


def cascaded_tanks(
    *,
    k1: float = 0.1,
    k2: float = 0.09,
    kp: float = 0.036,
    h_max: float = 10.0,
    overflow_fraction: float = 1.0,
    assumed: str = "linear",
    seed: int = 0,
    duration: float = 4096.0,
    rate: float = 0.25,
    noise_sd: float = 0.02,
    quantisation_step: float = 10.0 / 4096,
    sensor_range: tuple = (0.0, 10.0),
    u_range: tuple = (0.0, 10.0),
    hold: tuple = (50.0, 200.0),
    substeps: int = 20,
    x0: tuple = (2.0, 2.0),
) -> Machine:
    """Two tanks in series fed by a pump; only the lower level is measured.

    Truth (levels in volts of the level sensors)::

        h1' = -k1 sqrt(h1) + kp u
        h2' =  k1 sqrt(h1) - k2 sqrt(h2) + overflow_fraction * overflow

    Torricelli outflows; the upper tank overflows at ``h1 = h_max``: its
    level stays there and the excess inflow ``kp u - k1 sqrt(h_max)`` goes to
    the lower tank (``overflow_fraction`` of it; the rest is spilled). The
    lower tank's sensor reads ``h2`` plus white noise ``noise_sd``, through a
    12-bit ADC (``quantisation_step = 10/4096`` V) and clipped to
    ``sensor_range`` (``h2`` itself can exceed 10). The pump voltage is a
    random multi-level signal: levels uniform in ``u_range`` held for
    ``hold`` seconds (uniform, rounded to samples); with the defaults, levels
    above about 7.9 V push ``h2`` beyond the sensor and above about 8.8 V
    the upper tank overflows (about a tenth of the readings are clipped).
    RK4 with ``substeps`` steps per sample.

    Parameters
    ----------
    k1, k2, kp : float
        Outflow coefficients (V^0.5/s) and pump gain (1/s).
    h_max : float
        Upper tank's rim (V).
    overflow_fraction : float
        Share of the overflow caught by the lower tank.
    assumed : {"linear", "sqrt"}
        The user's model. ``"linear"``: ``h1' = -a1 h1 + b u``,
        ``h2' = a2 h1 - a3 h2`` with ``p = {"a1", "b", "a2", "a3"}``; the
        hidden level's scale is unidentifiable from ``h2`` (only ``b a2``
        is determined). ``"sqrt"``: the square-root outflows without the
        overflow, ``p = {"k1", "k2", "kp"}``.
    seed : int
        Default seed of :meth:`Machine.record`.
    duration, rate, noise_sd, quantisation_step, sensor_range, u_range, hold,
    substeps, x0
        Recording defaults (s, Hz, V, V, (V, V), (V, V), (s, s), -, (V, V));
        each can be overridden in :meth:`Machine.record`.

    Returns
    -------
    Machine
    """
    if min(k1, k2, kp) <= 0 or h_max <= 0 or not 0 <= overflow_fraction <= 1:
        raise ValueError("need k1, k2, kp, h_max > 0 and 0 <= overflow_fraction <= 1")
    if assumed not in ("linear", "sqrt"):
        raise ValueError(f"assumed must be 'linear' or 'sqrt', got {assumed!r}")

    def rates(h1, h2, uu):
        """``(h1', h2')`` for scalars; the overflow is part of the flow."""
        q_in = kp * uu
        out1 = k1 * math.sqrt(h1) if h1 > 0.0 else 0.0
        out2 = k2 * math.sqrt(h2) if h2 > 0.0 else 0.0
        if h1 >= h_max and q_in > out1:
            return 0.0, out1 + overflow_fraction * (q_in - out1) - out2
        return q_in - out1, out1 - out2

    def true_model(x, t, u):
        uu = _input_column(u, len(x))
        h1, h2 = x[:, 0], x[:, 1]
        q_in = kp * uu
        out1 = k1 * np.sqrt(np.maximum(h1, 0.0))
        out2 = k2 * np.sqrt(np.maximum(h2, 0.0))
        over = np.where((h1 >= h_max) & (q_in > out1), q_in - out1, 0.0)
        return np.column_stack(
            [q_in - out1 - over, out1 + overflow_fraction * over - out2]
        )

    def integrate(h1, h2, uu, dt, n):
        h = dt / n
        for _ in range(n):
            a1, a2 = rates(h1, h2, uu)
            b1, b2 = rates(h1 + 0.5 * h * a1, h2 + 0.5 * h * a2, uu)
            c1, c2 = rates(h1 + 0.5 * h * b1, h2 + 0.5 * h * b2, uu)
            d1, d2 = rates(h1 + h * c1, h2 + h * c2, uu)
            h1 += h / 6.0 * (a1 + 2.0 * b1 + 2.0 * c1 + d1)
            h2 += h / 6.0 * (a2 + 2.0 * b2 + 2.0 * c2 + d2)
            if h1 > h_max:  # the step that reaches the rim: excess overflows
                h2 += overflow_fraction * (h1 - h_max)
                h1 = h_max
            # a tank that empties within a step stays empty, never negative
            h1, h2 = max(h1, 0.0), max(h2, 0.0)
        return h1, h2

    def simulator(t, u, x0):
        return _held(step, t, u, x0)

    def step(x, u, dt):
        return integrate(x[0], x[1], float(u[0]), dt, int(substeps))

    def pump(rng, t, rate, u_range, hold):
        """Levels uniform in ``u_range``, each held ``hold`` s (uniform)."""
        u = np.empty(t.size)
        k = 0
        while k < t.size:
            n = max(1, int(round(rng.uniform(*hold) * rate)))
            u[k : k + n] = rng.uniform(*u_range)
            k += n
        return u

    def recorder(seed, o):
        rng = np.random.default_rng(seed)
        t = _grid(o["duration"], o["rate"])
        u = pump(rng, t, o["rate"], o["u_range"], o["hold"])
        x = np.empty((t.size, 2))
        x[0] = o["x0"]
        for k in range(t.size - 1):
            x[k + 1] = integrate(
                x[k, 0], x[k, 1], u[k], t[k + 1] - t[k], int(o["substeps"])
            )
        step = o["quantisation_step"]
        clip = tuple(float(c) for c in o["sensor_range"])
        y = _sensor(x[:, [1]], rng, o["noise_sd"], step, clip)
        return MachineRecord(
            t=t,
            y=y,
            u=u[:, None],
            x=x,
            measured=[1],
            state_names=["h1", "h2"],
            input_names=["u"],
            noise_sd=np.array([float(o["noise_sd"])]),
            quantisation_step=None if step is None else float(step),
            clip=clip,
        )

    options = dict(
        duration=duration,
        rate=rate,
        noise_sd=noise_sd,
        quantisation_step=quantisation_step,
        sensor_range=tuple(sensor_range),
        u_range=tuple(u_range),
        hold=tuple(hold),
        substeps=substeps,
        x0=tuple(x0),
    )
    overflow = (
        f"the upper tank's overflow at h1 = {h_max:g} into the lower tank "
        "(h1 stays at the rim)"
    )
    if assumed == "linear":
        model, guesses = _tanks_linear, {"a1": 0.03, "b": 0.05, "a2": 0.03, "a3": 0.03}
        missing = (
            "square-root (Torricelli) outflows k1 sqrt(h1), k2 sqrt(h2) instead "
            f"of linear ones, and {overflow}"
        )
    else:
        model, guesses = _tanks_sqrt, {"k1": 0.08, "k2": 0.07, "kp": 0.045}
        missing = overflow
    return Machine(
        name="cascaded_tanks",
        description="Two tanks in series, pump input, lower level measured by a "
        "clipping 12-bit sensor every 4 s",
        state_names=["h1", "h2"],
        input_names=["u"],
        measured=[1],
        true_model=true_model,
        assumed_model=model,
        parameters=guesses,
        true_parameters={
            "k1": k1,
            "k2": k2,
            "kp": kp,
            "h_max": h_max,
            "overflow_fraction": overflow_fraction,
        },
        missing=missing,
        options=options,
        seed=seed,
        recorder=recorder,
        simulator=simulator,
    )


# ---------------------------------------------------------------------------
# 3. damped pendulum, 4. clipped oscillator


def damped_pendulum(
    *,
    g_over_L: float = 4.0,
    damping: float = 0.2,
    seed: int = 0,
    duration: float = 20.0,
    rate: float = 100.0,
    noise_sd: float = 0.01,
    x0: tuple = (1.0, 0.0),
) -> Machine:
    """A damped pendulum whose assumed model forgot gravity.

    Truth ``theta' = omega``, ``omega' = -(g/L) sin(theta) - damping
    omega``; assumed ``omega' = -damping omega`` as ``f(x, t)`` with no
    parameters. The angle is measured with white noise ``noise_sd`` (rad),
    2000 samples over 20 s from ``theta = 1`` rad, where ``sin(theta)``
    differs from ``theta`` by 16%.

    Parameters
    ----------
    g_over_L, damping : float
        ``g / L`` (1/s^2) and the damping rate (1/s).
    seed : int
        Default seed of :meth:`Machine.record`.
    duration, rate, noise_sd, x0
        Recording defaults (s, Hz, rad, (rad, rad/s)).

    Returns
    -------
    Machine
    """

    def true_model(x, t, u=None):
        th, om = x[:, 0], x[:, 1]
        return np.column_stack([om, -g_over_L * np.sin(th) - damping * om])

    def assumed_model(x, t):
        return np.column_stack([x[:, 1], -damping * x[:, 1]])

    def simulator(t, u, x0):
        return _smooth(true_model, x0, t)

    def recorder(seed, o):
        rng = np.random.default_rng(seed)
        t = _grid(o["duration"], o["rate"])
        x = _smooth(true_model, o["x0"], t)
        y = _sensor(x[:, [0]], rng, o["noise_sd"], None, None)
        return MachineRecord(
            t=t,
            y=y,
            u=None,
            x=x,
            measured=[0],
            state_names=["theta", "omega"],
            input_names=[],
            noise_sd=np.array([float(o["noise_sd"])]),
            quantisation_step=None,
            clip=None,
        )

    return Machine(
        name="damped_pendulum",
        description="Damped pendulum, angle measured; the model has no gravity",
        state_names=["theta", "omega"],
        input_names=[],
        measured=[0],
        true_model=true_model,
        assumed_model=assumed_model,
        parameters={},
        true_parameters={"g_over_L": g_over_L, "damping": damping},
        missing=f"gravity -(g/L) sin(theta) in omega' (g/L = {g_over_L:g})",
        options=dict(duration=duration, rate=rate, noise_sd=noise_sd, x0=tuple(x0)),
        seed=seed,
        recorder=recorder,
        simulator=simulator,
    )


def clipped_oscillator(
    *,
    k: float = 1.0,
    mu: float = 1.0,
    seed: int = 0,
    duration: float = 30.0,
    rate: float = 20.0,
    noise_sd: float = 0.05,
    ceiling: float = 1.6,
    x0: tuple = (0.5, 0.0),
) -> Machine:
    """A Van der Pol oscillator seen by a sensor that clips at a ceiling.

    Truth ``x1' = x2``, ``x2' = -k x1 + mu (1 - x1^2) x2``: it settles on a
    limit cycle of amplitude about 2, so the position sensor (white noise
    ``noise_sd``, range ``(-inf, ceiling)``) reports ``ceiling`` near every
    positive peak. The assumed model is the undamped oscillator
    ``x2' = -k x1`` with ``p = {"k"}`` (guess 0.8).

    Parameters
    ----------
    k, mu : float
        Stiffness (1/s^2) and the Van der Pol damping.
    seed : int
        Default seed of :meth:`Machine.record`.
    duration, rate, noise_sd, ceiling, x0
        Recording defaults.

    Returns
    -------
    Machine
    """

    def true_model(x, t, u=None):
        x1, x2 = x[:, 0], x[:, 1]
        return np.column_stack([x2, -k * x1 + mu * (1.0 - x1**2) * x2])

    def assumed_model(x, t, u, p):
        return np.column_stack([x[:, 1], -p["k"] * x[:, 0]])

    def simulator(t, u, x0):
        return _smooth(true_model, x0, t)

    def recorder(seed, o):
        rng = np.random.default_rng(seed)
        t = _grid(o["duration"], o["rate"])
        x = _smooth(true_model, o["x0"], t)
        clip = (-math.inf, float(o["ceiling"]))
        y = _sensor(x[:, [0]], rng, o["noise_sd"], None, clip)
        return MachineRecord(
            t=t,
            y=y,
            u=None,
            x=x,
            measured=[0],
            state_names=["x1", "x2"],
            input_names=[],
            noise_sd=np.array([float(o["noise_sd"])]),
            quantisation_step=None,
            clip=clip,
        )

    return Machine(
        name="clipped_oscillator",
        description="Van der Pol oscillator, position sensor clipping at a ceiling",
        state_names=["x1", "x2"],
        input_names=[],
        measured=[0],
        true_model=true_model,
        assumed_model=assumed_model,
        parameters={"k": 0.8},
        true_parameters={"k": k, "mu": mu},
        missing=f"the Van der Pol damping mu (1 - x1^2) x2 in x2' (mu = {mu:g})",
        options=dict(
            duration=duration,
            rate=rate,
            noise_sd=noise_sd,
            ceiling=ceiling,
            x0=tuple(x0),
        ),
        seed=seed,
        recorder=recorder,
        simulator=simulator,
    )


# ---------------------------------------------------------------------------
# 5. mass-spring-damper with a direction-dependent damper


def _reversal(t, x, *args):
    return x[1]


_reversal.terminal = True


def _damper_interval(rhs, x, uk, dt):
    """``x`` after ``dt`` under ``rhs`` with the input ``uk`` held: DOP853 at
    ``rtol = atol = 1e-12``, restarted at each velocity reversal (the kink
    of the damper force) so that no step straddles it."""
    t0, x = 0.0, np.asarray(x, dtype=float)
    for _ in range(100):  # reversals within one sample: a handful at most
        events = _reversal if x[1] != 0.0 else None
        sol = solve_ivp(
            rhs,
            (t0, dt),
            x,
            method="DOP853",
            args=(uk,),
            events=events,
            rtol=1e-12,
            atol=1e-12,
        )
        if not sol.success:  # pragma: no cover - a smooth linear flow
            raise RuntimeError(sol.message)
        x = sol.y[:, -1]
        if sol.status != 1:  # reached dt
            return x
        t0 = float(sol.t[-1])
        x = np.array([x[0], 0.0])  # on the switch: the next phase starts here
        if dt - t0 <= 1e-15:
            return x
    raise RuntimeError("too many velocity reversals in one sample")  # pragma: no cover


def asymmetric_damper(
    *,
    m: float = 1.0,
    k: float = 40.0,
    c_up: float = 1.2,
    c_down: float = 0.6,
    seed: int = 0,
    duration: float = 20.0,
    rate: float = 100.0,
    noise_sd: float = 1e-4,
    u_rms: float = 1.0,
    band: tuple = (0.2, 5.0),
    x0: tuple = (0.0, 0.0),
) -> Machine:
    """A mass on a spring with a damper that differs by direction.

    Truth ``q' = v``, ``m v' = u - k q - c_up max(v, 0) - c_down min(v, 0)``:
    a damper stiffer moving up (``v > 0``) than down, as a shock absorber
    is stiffer in rebound than in compression. The assumed model has one
    symmetric damper, ``m v' = u - k q - c v``, with ``p = {"k", "c"}``
    (guesses 36 N/m and 0.8 N s/m) and ``m`` known. The input force ``u``
    is a 15-tone multisine (``band`` Hz, random phases, rms ``u_rms``)
    computed at each sample and held (zero-order hold); the position is
    measured with white noise ``noise_sd``. The right-hand side is
    continuous with a kink at ``v = 0``: each sample interval is integrated
    by ``solve_ivp`` (DOP853, ``rtol = atol = 1e-12``), restarted at every
    velocity reversal.

    Parameters
    ----------
    m, k, c_up, c_down : float
        Mass (kg), stiffness (N/m), damping for ``v > 0`` and ``v < 0``
        (N s/m).
    seed : int
        Default seed of :meth:`Machine.record`.
    duration, rate, noise_sd, u_rms, band, x0
        Recording defaults (s, Hz, m, N, (Hz, Hz), (m, m/s)).

    Returns
    -------
    Machine
    """
    if m <= 0 or k <= 0 or c_up < 0 or c_down < 0:
        raise ValueError("need m, k > 0 and c_up, c_down >= 0")

    def force(q, v, uu):
        return uu - k * q - c_up * np.maximum(v, 0.0) - c_down * np.minimum(v, 0.0)

    def true_model(x, t, u):
        q, v = x[:, 0], x[:, 1]
        return np.column_stack([v, force(q, v, _input_column(u, len(x))) / m])

    def assumed_model(x, t, u, p):
        q, v = x[:, 0], x[:, 1]
        uu = _input_column(u, len(x))
        return np.column_stack([v, (uu - p["k"] * q - p["c"] * v) / m])

    def rhs(t, x, uk):
        return [x[1], force(x[0], x[1], uk) / m]

    def step(x, u, dt):
        return _damper_interval(rhs, x, float(u[0]), dt)

    def simulator(t, u, x0):
        return _held(step, t, u, x0)

    def recorder(seed, o):
        rng = np.random.default_rng(seed)
        t = _grid(o["duration"], o["rate"])
        low, high = o["band"]
        u = _multisine(rng, t, o["u_rms"], low, high)[:, None]
        x = _held(step, t, u, np.asarray(o["x0"], dtype=float))
        y = _sensor(x[:, [0]], rng, o["noise_sd"], None, None)
        return MachineRecord(
            t=t,
            y=y,
            u=u,
            x=x,
            measured=[0],
            state_names=["q", "v"],
            input_names=["u"],
            noise_sd=np.array([float(o["noise_sd"])]),
            quantisation_step=None,
            clip=None,
        )

    return Machine(
        name="asymmetric_damper",
        description="Mass-spring-damper, damping differs by direction, multisine "
        "force, position measured at 100 Hz",
        state_names=["q", "v"],
        input_names=["u"],
        measured=[0],
        true_model=true_model,
        assumed_model=assumed_model,
        parameters={"k": 36.0, "c": 0.8},
        true_parameters={"m": m, "k": k, "c_up": c_up, "c_down": c_down},
        missing=f"direction-dependent damping: -(c_up - c) max(v, 0)/m - (c_down - "
        f"c) min(v, 0)/m in v' (c_up = {c_up:g}, c_down = {c_down:g} N s/m)",
        options=dict(
            duration=duration,
            rate=rate,
            noise_sd=noise_sd,
            u_rms=u_rms,
            band=tuple(band),
            x0=tuple(x0),
        ),
        seed=seed,
        recorder=recorder,
        simulator=simulator,
    )


# ---------------------------------------------------------------------------
# 6. hysteretic oscillator (Bouc-Wen)


def _bouc_wen_interval(x, uk, dt, n, m, c, k, alpha, beta, gamma, delta):
    """RK4 over one held-input sample interval in ``n`` steps (plain floats:
    a three-state step is far cheaper without array overhead)."""
    bg, bd = beta * gamma, beta * delta

    def rhs(y, v, z):
        return (
            v,
            (uk - c * v - k * y - z) / m,
            alpha * v - bg * abs(v) * z - bd * v * abs(z),
        )

    y, v, z = x
    h = dt / n
    for _ in range(n):
        a1, b1, c1 = rhs(y, v, z)
        a2, b2, c2 = rhs(y + 0.5 * h * a1, v + 0.5 * h * b1, z + 0.5 * h * c1)
        a3, b3, c3 = rhs(y + 0.5 * h * a2, v + 0.5 * h * b2, z + 0.5 * h * c2)
        a4, b4, c4 = rhs(y + h * a3, v + h * b3, z + h * c3)
        y += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        v += h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
        z += h / 6.0 * (c1 + 2.0 * c2 + 2.0 * c3 + c4)
    return np.array([y, v, z])


def hysteretic_oscillator(
    *,
    m: float = 2.0,
    c: float = 10.0,
    k: float = 5e4,
    alpha: float = 5e4,
    beta: float = 1e3,
    gamma: float = 0.8,
    delta: float = -1.1,
    seed: int = 0,
    n_samples: int = 8192,
    rate: float = 750.0,
    noise_share: float = 0.05,
    u_rms: float = 50.0,
    band: tuple = (5.0, 150.0),
    n_tones: int = 60,
    substeps: int = 20,
    x0: tuple = (0.0, 0.0, 0.0),
) -> Machine:
    """A mass-spring-damper whose restoring force has memory (Bouc-Wen).

    Truth ``y' = v``, ``m v' = u - c v - k y - z`` with the hysteretic force
    ``z' = alpha v - beta gamma |v| z - beta delta v |z|`` (Bouc-Wen with
    exponent 1; the defaults are those of the Bouc-Wen benchmark of Noel and
    Schoukens, 2016: ``z' = 5e4 v - 800 |v| z + 1100 v |z|``). Only ``y``
    is measured, with white noise of sd ``noise_share`` times the sd of the
    noise-free ``y``. The assumed model is the linear oscillator on the two
    states ``[y, v]`` a user writes first, ``m v' = u - c v - k y``, with
    ``p = {"m", "c", "k"}`` guessed 20 % off (2.4 kg, 8 N s/m, 6e4 N/m);
    ``z`` is a state nobody measured and the assumed model does not have
    (:attr:`MachineRecord.x` holds it as a third column).

    The input force is a multisine of ``n_tones`` log-spaced tones in
    ``band`` Hz (random phases, rms ``u_rms``), computed at each sample and
    held (zero-order hold). Each sample interval is integrated by RK4 in
    ``substeps`` steps (the benchmark's 15 kHz at the defaults; the
    right-hand side has kinks at ``v = 0`` and ``z = 0`` only in its
    derivative, and halving the step moves ``y`` by under 1e-2 of the noise).

    Parameters
    ----------
    m, c, k : float
        Mass (kg), viscous damping (N s/m), linear stiffness (N/m).
    alpha, beta, gamma, delta : float
        Bouc-Wen constants (N/m, 1/m, -, -).
    seed, n_samples, rate, noise_share, u_rms, band, n_tones, substeps, x0
        Recording defaults (-, -, Hz, -, N, (Hz, Hz), -, -, (m, m/s, N)).

    Returns
    -------
    Machine
    """
    if m <= 0 or k <= 0 or c < 0 or beta < 0:
        raise ValueError("need m, k > 0 and c, beta >= 0")
    const = (m, c, k, alpha, beta, gamma, delta)

    def hysteresis(v, z):
        return alpha * v - beta * gamma * np.abs(v) * z - beta * delta * v * np.abs(z)

    def true_model(x, t, u):
        y, v, z = x[:, 0], x[:, 1], x[:, 2]
        uu = _input_column(u, len(x))
        return np.column_stack([v, (uu - c * v - k * y - z) / m, hysteresis(v, z)])

    def assumed_model(x, t, u, p):
        y, v = x[:, 0], x[:, 1]
        uu = _input_column(u, len(x))
        return np.column_stack([v, (uu - p["c"] * v - p["k"] * y) / p["m"]])

    def stepper(n):
        def step(x, u, dt):
            return _bouc_wen_interval(x, float(u[0]), dt, n, *const)

        return step

    def simulator(t, u, x0):
        return _held(stepper(substeps), t, u, x0)

    def recorder(seed, o):
        rng = np.random.default_rng(seed)
        t = np.arange(int(o["n_samples"])) / float(o["rate"])
        low, high = o["band"]
        u = _multisine(rng, t, o["u_rms"], low, high, int(o["n_tones"]))[:, None]
        x = _held(stepper(int(o["substeps"])), t, u, np.asarray(o["x0"], float))
        sd = float(o["noise_share"]) * float(np.std(x[:, 0]))
        y = _sensor(x[:, [0]], rng, sd, None, None)
        return MachineRecord(
            t=t,
            y=y,
            u=u,
            x=x,
            measured=[0],
            state_names=["y", "v", "z"],
            input_names=["u"],
            noise_sd=np.array([sd]),
            quantisation_step=None,
            clip=None,
        )

    return Machine(
        name="hysteretic_oscillator",
        description="Bouc-Wen hysteretic oscillator, multisine force, displacement "
        "measured at 750 Hz; the hysteretic force is a state nobody measured",
        state_names=["y", "v", "z"],
        input_names=["u"],
        measured=[0],
        true_model=true_model,
        assumed_model=assumed_model,
        parameters={"m": 1.2 * m, "c": 0.8 * c, "k": 1.2 * k},
        true_parameters={
            "m": m,
            "c": c,
            "k": k,
            "alpha": alpha,
            "beta": beta,
            "gamma": gamma,
            "delta": delta,
        },
        missing=(
            "a hysteretic force F with memory (a state nobody measured): m v' "
            f"gains -F, F' = {alpha:g} v {-beta * gamma:+g} |v| F "
            f"{-beta * delta:+g} v |F|"
        ),
        options=dict(
            n_samples=n_samples,
            rate=rate,
            noise_share=noise_share,
            u_rms=u_rms,
            band=tuple(band),
            n_tones=n_tones,
            substeps=substeps,
            x0=tuple(x0),
        ),
        seed=seed,
        recorder=recorder,
        simulator=simulator,
    )
