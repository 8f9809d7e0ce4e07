"""Every argument of :func:`discover`, checked in one place, before any solve.

:func:`check_study` turns what the user passed into a :class:`Study`: the
data, the names, the noise covariance, an unfitted :class:`MME` that holds
every estimator setting (built from the keywords, or the user's own
``mme=``), the library, the optimizer and the validation record. The MME
problem is checked here too (:meth:`MME.check`: shapes, observability, the
first evaluation of the model), so a bad argument never waits for a solver.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from sklearn.base import clone

from ..core import validation as val
from ..core.constraints import check_parameter
from ..core.integrate import InputSignal
from ..core.libraries import fresh_library
from ..core.noise import describe_noise, estimate_noise_variance
from ..core.sensors import Clipping, check_ranges, clipped_at, clipped_samples
from ..differentiation import MME
from ..differentiation.error_models import resolve_error_model
from ..differentiation.mme_checks import PARAMETER_CONSTRAINTS as MME_CONSTRAINTS
from ..protocols import HeldOut, LeadingWindow, ValidationProtocol
from ..protocols.base import check_window
from .hidden import HiddenStates, add_hidden_states
from .options import settings_into_estimator
from .parameters import parameter_spec
from .placement import default_error_states

__all__ = [
    "Study",
    "Record",
    "check_study",
    "MIN_RECORD_SAMPLES",
]

#: fewest samples of one record among several
MIN_RECORD_SAMPLES = 10


@dataclass(frozen=True)
class Record:
    """One experiment: measurements ``y``, times ``t``, inputs ``u`` (or None).

    ``discover([Record(y1, t1), Record(y2, t2)], assumed_model=...)`` fits
    several records at once: each has its own initial state, all share the
    grey-box parameters and the correction terms; ``validation=`` takes a
    list of them too. ``t`` is a time array (or the time step); each
    record's times start anywhere.
    """

    y: object
    t: object
    u: object = None


@dataclass
class Study:
    """A checked study: everything :func:`discover`'s steps need.

    Attributes
    ----------
    y : ndarray (N, m); t : ndarray (N,); u : ndarray (N, n_inputs) or None
    inputs : InputSignal
    mme : MME
        Unfitted estimator with every setting (noise covariance resolved).
    model : ModelFunction
        The assumed model, checked.
    n_states : int
    measurement : ndarray (m, n) or callable
    measured : ndarray of int or None
        Measured state per channel (None for a general measurement).
    error_states : ndarray of int
    state_names, input_names, channel_names : list of str
    noise_cov : ndarray (m, m)
    library : unfitted pysindy feature library
    optimizer : unfitted optimizer
    alpha : float
    refit : bool
    validation : tuple (y, t, u) or None
    assumed_equations : list of str or None
    x_init : ndarray (N, n)
        Starting trajectory from the data alone: measured states as measured
        (interpolated over gaps), the others zero.
    validation_window : int
    raw_model : callable or None
        The grey-box ``f(x, t, u, p)`` when ``parameter_names`` are given.
    parameter_names : list of str; parameter_init : ndarray
        The assumed model's parameters to estimate, and their initial guesses.
    parameter_bounds : ndarray (n_parameters, 2)
        ``[lower, upper]`` per parameter (``-inf`` / ``inf``: no bound); every
        output-error fit keeps the parameters inside.
    offsets : bool
        Estimate a constant offset per measured channel.
    clipped : Clipping
        Readings of the fitting record on the sensor's limits
        (:mod:`pysindy_mme.core.sensors`); ``y`` holds NaN there unless
        ``clipped_option`` is ``"keep"``.
    validation_clipped : Clipping or None
        The same for the validation record (censored in ``validation``).
    clipped_option : "auto", "keep" or list of (low, high)
        What the user asked (ranges checked, one per channel).
    readings : ndarray (N, m) or None
        The fitting record as the sensors reported it (``y`` before the
        clipped readings were set to NaN).
    clipped_cut, validation_clipped_cut : (int, int)
        Samples cut from the start and the end of each record because every
        reading there is clipped (:func:`clipped_edges`); ``y``, ``t``,
        ``u``, ``readings`` and the clipping masks are the rows between.
    """

    @property
    def n_parameters(self) -> int:
        return len(self.parameter_names)

    def assumed_at(self, values):
        """The assumed model ``f(x, t[, u])`` with its parameters at ``values``."""
        if not self.parameter_names:
            return self.mme.assumed_model
        return AtParameters(self.raw_model, self.parameter_names, values)

    def model_at(self, values):
        """:meth:`assumed_at` as a checked :class:`ModelFunction`."""
        if not self.parameter_names:
            return self.model
        from ..core.model import as_model_function

        return as_model_function(self.assumed_at(values), self.n_states)

    y: np.ndarray
    t: np.ndarray
    u: np.ndarray | None
    inputs: InputSignal
    mme: MME
    model: object
    n_states: int
    measurement: object
    measured: np.ndarray | None
    error_states: np.ndarray
    state_names: list
    input_names: list
    channel_names: list
    noise_cov: np.ndarray
    library: object
    optimizer: object
    alpha: float
    refit: bool
    validation: tuple | None
    assumed_equations: list | None
    x_init: np.ndarray
    validation_window: int = 50
    raw_model: object = None
    parameter_names: list = field(default_factory=list)
    parameter_init: np.ndarray = field(default_factory=lambda: np.zeros(0))
    offsets: bool = False
    min_effect: float = 0.01
    parameter_bounds: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    error_states_note: str = ""
    noise_description: str = ""
    noise_doubt: str | None = None
    clipped: Clipping | None = None
    validation_clipped: Clipping | None = None
    clipped_option: object = "auto"
    readings: np.ndarray | None = None
    clipped_cut: tuple = (0, 0)
    validation_clipped_cut: tuple = (0, 0)
    #: samples where a new record starts (empty: one record); the records
    #: are concatenated on the sample axis with no dynamics link between
    starts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    #: every validation record ``(y, t, u)`` (``validation`` is the first)
    validation_records: list | None = None
    #: states added by ``hidden_states`` (None without)
    hidden: HiddenStates | None = None
    #: how the models are scored out of sample (:mod:`pysindy_mme.protocols`):
    #: a record protocol with validation records, a :class:`HeldOut` without
    protocol: ValidationProtocol | None = None
    #: a state estimate of the validation record when the study has one
    #: already (a stretch held out of its own record: MME's states there);
    #: None: :func:`~pysindy_mme.protocols.runs.record_guess` estimates it
    states_guess: np.ndarray | None = None
    #: each model's own trajectory over that record, where the study has one
    #: (its in-sample free run over the held-out stretch: a trajectory of
    #: the same model at nearly the refitted parameters): where Newton's
    #: method starts that model's free run (``{"assumed": x, "extended":
    #: x}``; the run does not depend on it, only its cost does)
    run_guesses: dict | None = None

    @property
    def validation_protocol(self) -> ValidationProtocol:
        """:attr:`protocol`, or the default one (a result loaded from a file)."""
        if self.protocol is not None:
            return self.protocol
        if self.validation is not None:
            return LeadingWindow(window=self.validation_window)
        return HeldOut(window=self.validation_window)

    #: exact trade-offs among the grey-box parameters at the guesses, each
    #: fixed by holding one parameter (``TradeOff.gauge``) at its guess in
    #: every fit (:func:`~.steps.fix_gauges`); empty: none
    gauges: list = field(default_factory=list)

    @property
    def parameter_gauge(self) -> np.ndarray:
        """Which grey-box parameters are held at their guesses as gauges."""
        held = {t.gauge for t in self.gauges}
        return np.array([name in held for name in self.parameter_names], dtype=bool)

    @property
    def fit_bounds(self) -> np.ndarray:
        """``parameter_bounds`` with each gauge held at its guess
        (``[guess, guess]``): the bounds every output-error fit keeps."""
        k = self.n_parameters
        bounds = np.asarray(self.parameter_bounds, dtype=float)
        if bounds.shape != (k, 2):
            bounds = np.tile([-np.inf, np.inf], (k, 1))
        bounds = bounds.copy()
        gauge = self.parameter_gauge
        if gauge.any():
            guess = np.asarray(self.parameter_init, dtype=float)[gauge]
            bounds[gauge] = np.column_stack([guess, guess])
        return bounds

    @property
    def n_records(self) -> int:
        return 1 + len(self.starts)

    @property
    def record_slices(self) -> list:
        """The rows of each record, in order."""
        bounds = [0, *(int(k) for k in self.starts), self.t.size]
        return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]

    @property
    def record_sizes(self) -> list:
        return [s.stop - s.start for s in self.record_slices]

    @property
    def censored(self) -> bool:
        """Clipped readings are left out of the fits and the RMSEs."""
        return not (
            isinstance(self.clipped_option, str) and self.clipped_option == "keep"
        )

    @property
    def n_inputs(self) -> int:
        return len(self.input_names)

    @property
    def feature_names(self) -> list:
        return self.state_names + self.input_names


# pysindy libraries built for other problems than an ODE's right-hand side
_NOT_FOR_ODES = {
    "PDELibrary": "describes partial differential equations (spatial derivatives)",
    "WeakPDELibrary": "is the weak (integral) form, which needs no derivatives",
    "SINDyPILibrary": "is for implicit equations (SINDy-PI)",
    "ParameterizedLibrary": "needs control parameters as a second input",
}


def _library(feature_library):
    if feature_library is None:
        import pysindy as ps

        return ps.PolynomialLibrary(degree=3)
    if not (hasattr(feature_library, "fit") and hasattr(feature_library, "transform")):
        raise TypeError(
            "feature_library must be a pysindy feature library, got "
            f"{type(feature_library).__name__}"
        )
    kind = type(feature_library).__name__
    if kind in _NOT_FOR_ODES:
        raise TypeError(
            f"feature_library: {kind} {_NOT_FOR_ODES[kind]}; discover needs "
            "functions of the state (and inputs), such as ps.PolynomialLibrary, "
            "ps.FourierLibrary, ps.CustomLibrary or their sums and products"
        )
    return feature_library


def _optimizer(optimizer):
    if optimizer is None:
        # The paper's modified stepwise regression: its floating threshold
        # keeps the strongest terms of d(t) as proposals; the confirmation
        # then settles them and searches the library for what is missing.
        from ..optimizers import FloatingFStepwise

        paper = getattr(FloatingFStepwise, "paper", None)
        return FloatingFStepwise() if paper is None else paper()
    if not (hasattr(optimizer, "fit") and hasattr(optimizer, "get_params")):
        raise TypeError(
            f"optimizer must be a pysindy optimizer, got {type(optimizer).__name__}"
        )
    return optimizer


def _estimator(mme, given: dict, u, input_hold, parameters: dict):
    """The user's MME (discover's keywords already moved into it by
    :func:`~.options.settings_into_estimator`), or one built from them.

    With grey-box ``parameters`` the estimator gets the model at their
    initial values (step 2 moves them to the fitted ones).
    """
    if mme is not None:
        est = clone(mme)
        if u is not None:
            est.set_params(u=u)
        if parameters:
            # a grey box with the user's own MME configuration (n_substeps,
            # W, error_model ...): its model is f(x, t, u, p)
            raw = mme.assumed_model
            if not callable(raw) or hasattr(raw, "predict"):
                raise TypeError(
                    "with parameters, the MME's assumed_model must be a callable "
                    "f(x, t, u, p)"
                )
            est.set_params(
                assumed_model=AtParameters(raw, parameters, parameters.values())
            )
        return est
    for name in ("assumed_model", "n_states", "noise_variance"):
        if given[name] is None:
            raise TypeError(f"discover() needs {name}= (or mme=MME(...))")
    noise = given["noise_variance"]
    if isinstance(noise, str) and noise != "auto":
        raise ValueError(
            f"noise_variance must be a number, an array or 'auto', got {noise!r}"
        )
    if parameters:
        given = dict(given)
        raw = given["assumed_model"]
        if not callable(raw):
            raise TypeError(
                "with parameters, assumed_model must be a callable f(x, t, u, p)"
            )
        given["assumed_model"] = AtParameters(raw, parameters, parameters.values())
    return MME(u=u, input_hold=input_hold, **given)


def _with_hidden(spec, mme, given, feature_names, equations, grey, u, t):
    """Discover's arguments with the hidden states appended to the model.

    The model, ``n_states``, ``error_states`` (default: the hidden states
    only), ``feature_names`` and ``assumed_equations`` all get the new
    states; see :mod:`.hidden`.
    """
    source = mme.get_params() if mme is not None else given
    n = source["n_states"]
    if n is None or isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise TypeError("hidden_states needs n_states= (the assumed model's states)")
    n = int(n)
    n_inputs = _count_inputs(u if u is not None or mme is None else mme.u, t)
    names = list(feature_names) if feature_names is not None else None
    if names is not None and len(names) != n + n_inputs:
        raise ValueError(
            f"feature_names has {len(names)} names but there are {n} states and "
            f"{n_inputs} inputs (before the hidden states)"
        )
    visible = names[:n] if names is not None else [f"x{i}" for i in range(n)]
    model, hidden = add_hidden_states(
        source["assumed_model"], n, spec, visible, grey=grey
    )
    errors = source["error_states"]
    errors = (
        hidden.indices
        if errors is None
        else list(
            dict.fromkeys([int(i) for i in np.atleast_1d(errors)] + hidden.indices)
        )
    )
    inputs = names[n:] if names is not None else [f"u{i}" for i in range(n_inputs)]
    feature_names = visible + hidden.names + inputs
    if equations is None:
        equations = [f"f_{name}(x, t)" for name in visible]
    elif len(equations) != n:
        raise ValueError(
            f"assumed_equations has {len(equations)} entries, expected {n} "
            "(one per state of the assumed model, before the hidden states)"
        )
    equations = list(equations) + ["0"] * len(hidden.names)
    for name, j in zip(hidden.names, hidden.enters):
        equations[j] = f"{equations[j]} + {name}"
    update = dict(
        assumed_model=model, n_states=n + len(hidden.names), error_states=errors
    )
    if mme is not None:
        mme = clone(mme).set_params(**update)
    else:
        given = {**given, **update}
    return mme, given, feature_names, equations, hidden


def _parameters(parameters) -> tuple:
    """``({name: initial guess}, bounds (n, 2))``, checked.

    Each value is a number (unbounded), ``(guess, lower, upper)`` with None
    for a missing bound, or a :class:`~.parameters.Parameter`; the bounds
    are ``-inf`` / ``inf`` where there are none (:func:`parameter_spec`).
    """
    if parameters is None:
        return {}, np.zeros((0, 2))
    if not isinstance(parameters, dict) or not parameters:
        raise TypeError(
            "parameters must be a non-empty dict {name: initial guess}, e.g. "
            f"{{'k': 1.0, 'c': 0.1}} or {{'M': (90.0, 0, None)}}; got {parameters!r}"
        )
    out, bounds = {}, []
    for name, value in parameters.items():
        if not isinstance(name, str) or not name:
            raise TypeError(f"parameters: names must be strings, got {name!r}")
        out[name], lower, upper = parameter_spec(name, value)
        bounds.append((lower, upper))
    return out, np.array(bounds, dtype=float)


class AtParameters:
    """The user's grey-box ``f(x, t, u, p)`` at fixed parameter values.

    A plain ``f(x, t, u)`` for the estimator and the simulations; ``p`` is a
    dict ``{name: value}``.
    """

    def __init__(self, model, names, values):
        self.model = model
        self.values = dict(zip(names, (float(v) for v in values)))

    def __call__(self, x, t, u):
        return self.model(x, t, u, self.values)

    @property
    def parameter_values(self) -> dict:
        """The values (read by the exporter, which knows no study)."""
        return self.values


def _columns(frame):
    """Column names of a pandas DataFrame (or anything with ``.columns``)."""
    cols = getattr(frame, "columns", None)
    return None if cols is None else [str(c) for c in cols]


def _names(feature_names, n_states, n_inputs, measured=None, y_cols=None, u_cols=None):
    """State and input names: given, else from DataFrame columns, else x0, u0."""
    if feature_names is None:
        states = [f"x{i}" for i in range(n_states)]
        if y_cols is not None and measured is not None and len(y_cols) == len(measured):
            for name, i in zip(y_cols, measured):
                states[i] = name
        inputs = (
            u_cols
            if u_cols is not None and len(u_cols) == n_inputs
            else [f"u{i}" for i in range(n_inputs)]
        )
        feature_names = states + inputs
    feature_names = [str(n) for n in feature_names]
    if len(feature_names) != n_states + n_inputs:
        raise ValueError(
            f"feature_names has {len(feature_names)} names but there are {n_states} "
            f"states and {n_inputs} inputs"
        )
    if len(set(feature_names)) != len(feature_names):
        raise ValueError(f"feature_names repeats a name: {feature_names}")
    return feature_names[:n_states], feature_names[n_states:]


def check_record(study, y, t, u=None, name="validation y"):
    """Another record of the study's system, checked: ``(y, t, u)``, its
    clipped readings censored as the study's (:func:`censor_record`)."""
    record = (y, t) if u is None else (y, t, u)
    y_v, t_v, u_v = _validation(record, study.y.shape[1], study.n_inputs, name)
    found, y_v = censor_record(y_v, study.clipped_option, study.clipped)
    rows, _ = clipped_edges(y_v, found)
    return y_v[rows], t_v[rows], None if u_v is None else u_v[rows]


def clipped_edges(y, found: Clipping) -> tuple:
    """``(rows to keep, (leading, trailing) rows cut)``: the record without
    the stretches at its start and end where every reading is censored.

    Such a stretch tells the fit nothing once its readings are left out
    (no reading before or after it anchors the states there), and a free
    trajectory with nothing to follow can only destabilise the estimators;
    the study runs on the rows between. Rows that were missing (NaN) in
    the record itself are cut only together with clipped ones.
    """
    n = y.shape[0]
    if not found:
        return slice(0, n), (0, 0)
    empty = ~np.any(np.isfinite(y), axis=1)
    clipped = np.any(found.mask, axis=1)

    def edge(empty, clipped):
        k = int(np.argmin(empty)) if not empty.all() else empty.size
        return k if clipped[:k].any() else 0

    lead = edge(empty, clipped)
    trail = edge(empty[::-1], clipped[::-1])
    return slice(lead, n - trail), (lead, trail)


def _clipped_option(clipped, m):
    """``"auto"``, ``"keep"`` or the checked ranges, one per channel."""
    if isinstance(clipped, str):
        if clipped not in ("auto", "keep"):
            raise ValueError(
                f"clipped must be 'auto', 'keep' or a (low, high) range, got "
                f"{clipped!r}"
            )
        return clipped
    if clipped is None:
        raise TypeError(
            "clipped must be 'auto', 'keep' or a (low, high) range (None for a "
            "missing limit), got None"
        )
    return check_ranges(clipped, m, "clipped")


def censor_record(y, option, fitting: Clipping | None = None):
    """``(Clipping, y with the clipped readings NaN)`` of a record (a copy).

    ``option``: ``"auto"`` (detected on this record; a level found on the
    fitting record, ``fitting``, is the same sensor's: readings exactly on
    it count too), ``"keep"`` (found and named, left in) or the user's
    ranges (readings at or beyond them).
    """
    if isinstance(option, str):
        found = clipped_samples(y)
        if fitting is not None and fitting:
            found = clipped_at(y, fitting.ranges(), beyond=False).merged(found)
        if option == "keep":
            return found, y
    else:
        found = clipped_at(y, option)
    return found, found.censor(y) if found else y


def _is_record_list(value) -> bool:
    """A list of records (Record or (y, t[, u]) tuples), not one (y, t) pair."""
    if isinstance(value, Record):
        return False
    return (
        isinstance(value, (list, tuple))
        and len(value) > 0
        and all(
            isinstance(r, Record)
            or (isinstance(r, tuple) and len(r) in (2, 3) and np.ndim(r[0]) >= 1)
            for r in value
        )
        and (isinstance(value, list) or all(isinstance(r, Record) for r in value))
    )


def _as_tuple(record):
    if isinstance(record, Record):
        return (
            (record.y, record.t) if record.u is None else (record.y, record.t, record.u)
        )
    return record


def _validation(validation, m, n_inputs, name="validation y"):
    if validation is None:
        return None
    validation = _as_tuple(validation)
    if not isinstance(validation, (tuple, list)) or len(validation) not in (2, 3):
        raise TypeError("validation must be a tuple (y, t) or (y, t, u)")
    y_v = val.as_float_array(validation[0], name, ndim=(1, 2), allow_nan=True)
    if y_v.ndim == 1:
        y_v = y_v[:, None]
    if y_v.shape[1] != m:
        raise ValueError(
            f"{name} has {y_v.shape[1]} columns but {m} channels are measured"
        )
    t_v = val.check_time(validation[1], y_v.shape[0], name[:-1] + "t")
    u_v = None
    if n_inputs:
        if len(validation) != 3:
            raise ValueError("validation must be (y, t, u): the model has inputs")
        u_v = val.as_float_array(validation[2], "validation u", ndim=(1, 2))
        u_v = u_v.reshape(y_v.shape[0], -1)
    return y_v, t_v, u_v


def _training_records(y, t, u):
    """Several fitting records, checked and concatenated, or None for one.

    Returns ``(y, t, u, starts, y_columns, u_columns)``: the records on one
    sample axis (``t`` checked within each record), and the samples where
    each record after the first starts.
    """
    listed = isinstance(y, (list, tuple)) and len(y) > 0
    if listed and all(isinstance(r, Record) for r in y):
        if t is not None or u is not None:
            raise TypeError(
                "y is a list of Record: give t and u inside each Record, not as "
                "t= or u="
            )
        ys, ts, us = [r.y for r in y], [r.t for r in y], [r.u for r in y]
    elif (
        listed
        and all(hasattr(r, "shape") and np.ndim(r) >= 1 for r in y)
        and isinstance(t, (list, tuple))
    ):
        ys, ts = list(y), list(t)
        if len(ts) != len(ys):
            raise ValueError(
                f"t has {len(ts)} time arrays but y has {len(ys)} records: one "
                "time array (or time step) per record"
            )
        if u is None:
            us = [None] * len(ys)
        elif isinstance(u, (list, tuple)) and len(u) == len(ys):
            us = list(u)
        else:
            given = len(u) if isinstance(u, (list, tuple)) else "one array"
            raise ValueError(
                f"u must be a list of {len(ys)} input arrays, one per record of y "
                f"(got {given})"
            )
    else:
        if listed and any(isinstance(r, Record) for r in y):
            raise TypeError("y mixes Record and other entries: give a list of Record")
        return None
    if any(r is None for r in us) and not all(r is None for r in us):
        raise ValueError("u: give inputs for every record of y or for none")
    y_cols, u_cols = _columns(ys[0]), _columns(us[0])
    y_out, t_out, u_out = [], [], []
    for i, (yi, ti, ui) in enumerate(zip(ys, ts, us)):
        yi = val.as_float_array(yi, f"y[{i}]", ndim=(1, 2), allow_nan=True)
        yi = yi[:, None] if yi.ndim == 1 else yi
        if yi.shape[0] < MIN_RECORD_SAMPLES:
            raise ValueError(
                f"y[{i}] has {yi.shape[0]} samples: each record needs at least "
                f"{MIN_RECORD_SAMPLES}"
            )
        if y_out and yi.shape[1] != y_out[0].shape[1]:
            raise ValueError(
                f"y[{i}] has {yi.shape[1]} columns but y[0] has "
                f"{y_out[0].shape[1]}: every record measures the same channels"
            )
        if np.all(np.isnan(yi)):
            raise ValueError(f"y[{i}] contains no finite measurement")
        ti = val.check_time(ti, yi.shape[0], f"t[{i}]")
        if ui is not None:
            ui = val.as_float_array(ui, f"u[{i}]", ndim=(1, 2))
            ui = ui[:, None] if ui.ndim == 1 else ui
            if ui.shape[0] != yi.shape[0]:
                raise ValueError(
                    f"u[{i}] has {ui.shape[0]} rows but y[{i}] has {yi.shape[0]} "
                    "samples"
                )
            if u_out and ui.shape[1] != u_out[0].shape[1]:
                raise ValueError(
                    f"u[{i}] has {ui.shape[1]} columns but u[0] has {u_out[0].shape[1]}"
                )
            u_out.append(ui)
        y_out.append(yi)
        t_out.append(ti)
    starts = np.cumsum([r.shape[0] for r in y_out])[:-1]
    return (
        np.vstack(y_out),
        np.concatenate(t_out),
        np.vstack(u_out) if u_out else None,
        starts.astype(int),
        y_cols,
        u_cols,
    )


def _record_edges(y, clipping, starts):
    """:func:`clipped_edges` per record: ``(rows kept, cut, new starts)``."""
    bounds = [0, *starts.tolist(), y.shape[0]]
    keep, lead, trail, sizes = [], 0, 0, []
    for a, b in zip(bounds[:-1], bounds[1:]):
        part = clipping.rows(slice(a, b)) if clipping else clipping
        rows, (ld, tr) = clipped_edges(y[a:b], part)
        idx = np.arange(a, b)[rows]
        if idx.size < MIN_RECORD_SAMPLES:
            raise ValueError(
                f"y[{len(sizes)}] has {idx.size} samples left once the clipped "
                f"readings at its ends are cut: each record needs at least "
                f"{MIN_RECORD_SAMPLES}"
            )
        keep.append(idx)
        sizes.append(idx.size)
        lead, trail = lead + ld, trail + tr
    return np.concatenate(keep), (lead, trail), np.cumsum(sizes)[:-1].astype(int)


def _validation_records(validation, m, n_inputs, clipped, levels, window):
    """Each validation record checked and censored: ``(records, clippings,
    cuts)`` (lists); a single ``(y, t[, u])`` is a list of one."""
    if validation is None:
        return None, [None], [(0, 0)]
    listed = _is_record_list(validation)
    items = list(validation) if listed else [validation]
    records, clippings, cuts = [], [], []
    for i, item in enumerate(items):
        name = f"validation[{i}] y" if listed else "validation y"
        y_v, t_v, u_v = _validation(item, m, n_inputs, name)
        if listed and y_v.shape[0] <= window + 1:
            raise ValueError(
                f"validation[{i}] has {y_v.shape[0]} samples: it needs more than "
                f"validation_window + 1 = {window + 1} (the initial state comes "
                "from the first validation_window samples)"
            )
        found, y_c = censor_record(y_v, clipped, levels)
        if np.all(np.isnan(y_c)):
            raise ValueError(
                f"every reading of the {name} is on the sensor's limits "
                "(clipped): nothing is left to validate on"
            )
        rows_v, cut = clipped_edges(y_c, found)
        records.append((y_c[rows_v], t_v[rows_v], None if u_v is None else u_v[rows_v]))
        clippings.append(found.rows(rows_v))
        cuts.append(cut)
    return records, clippings, cuts


def _inputs_array(u, n_samples):
    if u is None:
        return None
    u = val.as_float_array(u, "u", ndim=(1, 2))
    if u.ndim == 1:
        u = u[:, None]
    if u.shape[0] != n_samples:
        raise ValueError(f"u has {u.shape[0]} rows but y has {n_samples} samples")
    return u


def _count_inputs(u, t) -> int:
    if u is None:
        return 0
    if callable(u):
        return int(np.asarray(u(t[:1]), dtype=float).reshape(1, -1).shape[1])
    return int(np.asarray(u, dtype=float).reshape(t.size, -1).shape[1])


def _check_size(library, y, n_vars):
    """The library size bounds what a record can support: fail now, not later."""
    probe = np.zeros((min(y.shape[0], 8), n_vars)) + 0.5
    lib = fresh_library(library).fit(probe)
    n_features = np.asarray(lib.transform(probe)).shape[1]
    n_finite = int(np.sum(np.all(np.isfinite(y), axis=1)))
    needed = n_features + 2
    if n_finite < needed:
        raise ValueError(
            f"y has {n_finite} complete samples but the feature library has "
            f"{n_features} terms: at least {needed} samples are needed"
        )


def _check_options(alpha, min_effect, refit, input_hold, offsets, window):
    """The study's own scalar options: ``(alpha, min_effect, window)``."""
    alpha = val.check_probability(alpha, "alpha")
    min_effect = val.check_positive_number(min_effect, "min_effect", strict=False)
    if min_effect >= 1:
        raise ValueError(f"min_effect must be a share in [0, 1), got {min_effect}")
    for name, flag in (("refit", refit), ("offsets", offsets)):
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"{name} must be True or False, got {flag!r}")
    check_parameter("input_hold", input_hold, MME_CONSTRAINTS["input_hold"])
    return alpha, min_effect, check_window(window, "validation_window")


def _protocol(validation, window):
    """``(protocol, records, window)`` from ``validation=``: a protocol object
    carries its records and window; records alone get the benchmarks' free
    run (:class:`LeadingWindow`) with ``validation_window``."""
    if not isinstance(validation, ValidationProtocol):
        return LeadingWindow(window=window), validation, window
    validation._check()
    if window != 50 and window != validation.window:
        raise ValueError(
            f"validation_window={window!r} and {validation!r} disagree: give the "
            "window to the protocol only"
        )
    return validation, validation.records, validation.window


def _held_out(protocol) -> HeldOut:
    """The protocol without validation records: a :class:`HeldOut` stretch,
    scored the way ``protocol`` scores a record."""
    if isinstance(protocol, HeldOut):
        return protocol
    return HeldOut(window=protocol.window, method=protocol)


def _noise_record(problem) -> dict:
    """How the noise was found (the report's first lines) and, when the data
    cannot tell it (a quantised channel at its quantisation level), why."""
    diagnostics = getattr(problem, "noise_diagnostics", None)
    variance = np.diag(np.asarray(problem.noise_covariance, dtype=float))
    description = describe_noise(variance, diagnostics)
    doubt = None
    if diagnostics:
        undetermined = [d for d in diagnostics if not d.determined]
        if undetermined:
            doubt = "the measurement noise cannot be told from the data: " + "; ".join(
                f"channel {d.channel} is quantised with step "
                f"{d.quantisation_step:.3g} and its noise estimate is at the "
                "quantisation level"
                for d in undetermined
            )
    elif doubt is None:
        doubt = _stated_noise_doubt(problem, variance)
    return {"noise_description": description, "noise_doubt": doubt}


# A stated noise this many times the data's own estimate is not the sensor's:
# the estimate can be a few times too small (coloured noise) or too large
# (a rough signal), never two orders of magnitude too small for white noise.
STATED_NOISE_FACTOR = 100.0


def _stated_noise_doubt(problem, stated) -> str | None:
    """A stated noise far above what the data show: every test is then blunt
    (the misfit is counted in units of the stated noise) and the study can
    keep too few terms, or none, where the data hold more."""
    y, t = getattr(problem, "y", None), getattr(problem, "t", None)
    if y is None or y.shape[0] < 64:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            estimate = np.atleast_1d(estimate_noise_variance(y, t, warn=False))
    except (ValueError, ArithmeticError):
        return None
    high = [
        k
        for k in range(min(estimate.size, stated.size))
        if estimate[k] > 0 and stated[k] > STATED_NOISE_FACTOR * estimate[k]
    ]
    if not high:
        return None
    return (
        "the stated noise is far above what the data show: "
        + "; ".join(
            f"channel {k} stated sd {np.sqrt(stated[k]):.3g}, the data's own "
            f"estimate {np.sqrt(estimate[k]):.3g} ({stated[k] / estimate[k]:.3g}x "
            "the variance)"
            for k in high
        )
        + (
            "; every test counts the misfit in units of the stated noise, so terms "
            "the data hold can go unseen: check the sensor's noise, or give "
            'noise_variance="auto"'
        )
    )


def _place_model_error(est, y, t, u, n_states, state_names) -> str:
    """With ``error_states`` omitted, every equation but kinematic identities
    (:mod:`.placement`); the sentence the report shows ("" if all)."""
    if est.error_states is not None:
        return ""
    from ..core.model import as_model_function

    model = as_model_function(est.assumed_model, n_states)
    scale = np.full(n_states, float(np.nanstd(y)) or 1.0)
    if est.measured is not None:
        for col, i in enumerate(np.atleast_1d(est.measured)):
            scale[int(i)] = float(np.nanstd(y[:, col])) or 1.0
    if callable(u):
        u = np.asarray(u(t), dtype=float).reshape(t.size, -1)
    elif u is not None:
        u = np.asarray(u, dtype=float).reshape(t.size, -1)
    states, note = default_error_states(model, n_states, t, u, scale, state_names)
    if note:
        est.set_params(error_states=states)
    return note


def _check_estimator(est, y) -> int:
    """The estimator's settings that the study reads itself; ``n_states``."""
    # MME's own check of n_states, so the message is the same from both doors
    check_parameter("n_states", est.n_states, MME_CONSTRAINTS["n_states"])
    n_states = est.n_states
    if est.measured is not None:
        idx = val.check_indices(est.measured, n_states, "measured")
        if y.shape[1] != idx.size:
            raise ValueError(
                f"y has {y.shape[1]} columns but measured names {idx.size} states "
                f"({idx.tolist()})"
            )
    if est.error_states is not None:
        val.check_indices(est.error_states, n_states, "error_states")
    resolve_error_model(est.error_model)
    return int(n_states)


def _channels(est, n_states, state_names, m):
    """``(measured state per channel or None, channel names)``."""
    if est.measured is None and (
        est.measurement_matrix is not None or est.measurement_function is not None
    ):
        return None, [f"y{j}" for j in range(m)]
    measured = val.check_indices(
        est.measured if est.measured is not None else range(n_states),
        n_states,
        "measured",
    )
    return measured, [state_names[i] for i in measured]


def check_study(
    y,
    t,
    *,
    mme=None,
    feature_library=None,
    optimizer=None,
    feature_names=None,
    u=None,
    validation=None,
    alpha=0.001,
    refit=True,
    assumed_equations=None,
    input_hold="linear",
    validation_window=50,
    parameters=None,
    offsets=False,
    min_effect=0.01,
    clipped="auto",
    hidden_states=None,
    **mme_keywords,
) -> Study:
    """Check :func:`discover`'s arguments; see there for their meaning."""
    protocol, validation, validation_window = _protocol(validation, validation_window)
    mme, mme_keywords = settings_into_estimator(mme, mme_keywords)
    several = _training_records(y, t, u)
    starts = np.zeros(0, dtype=int)
    if several is not None:
        y, t, u, starts, y_cols, u_cols = several
    else:
        if t is None:
            raise TypeError("discover() needs t (the sample times or the time step)")
        y_cols, u_cols = _columns(y), _columns(u)
    y = val.as_float_array(y, "y", ndim=(1, 2), allow_nan=True)
    if y.ndim == 1:
        y = y[:, None]
    if np.all(np.isnan(y)):
        raise ValueError("y contains no finite measurement")
    clipped = _clipped_option(clipped, y.shape[1])
    readings = y
    clipping, y = censor_record(readings, clipped)
    if np.all(np.isnan(y)):
        raise ValueError(
            "every reading of y is on the sensor's limits (clipped): nothing is "
            "left to fit; give clipped='keep' to fit them as readings"
        )
    n_samples = y.shape[0]
    if not starts.size:
        t = val.check_time(t, n_samples, "t")
    alpha, min_effect, window = _check_options(
        alpha, min_effect, refit, input_hold, offsets, validation_window
    )
    u = _inputs_array(u, n_samples)
    if starts.size:
        rows, cut, starts = _record_edges(y, clipping, starts)
        if rows.size == n_samples:
            rows, cut = slice(0, n_samples), (0, 0)
    else:
        rows, cut = clipped_edges(y, clipping)
    levels = clipping  # the sensor's limits, found on the whole record
    if cut != (0, 0):
        y, readings, t = y[rows], readings[rows], t[rows]
        u = None if u is None else u[rows]
        clipping = clipping.rows(rows)
    params, bounds = _parameters(parameters)
    hidden = None
    if hidden_states is not None:
        mme, mme_keywords, feature_names, assumed_equations, hidden = _with_hidden(
            hidden_states,
            mme,
            mme_keywords,
            feature_names,
            assumed_equations,
            bool(params),
            u,
            t,
        )
    est = _estimator(mme, mme_keywords, u, input_hold, params)
    if cut != (0, 0) and u is None and est.u is not None and not callable(est.u):
        est.set_params(u=np.asarray(est.u, dtype=float).reshape(n_samples, -1)[rows])
    n_states = _check_estimator(est, y)
    u_est = est.u if u is None else u
    n_inputs = _count_inputs(u_est, t)
    default_measured = (
        est.measured
        if est.measured is not None
        else (range(n_states) if est.measurement_matrix is None else None)
    )
    state_names, input_names = _names(
        feature_names,
        int(n_states),
        n_inputs,
        None if default_measured is None else list(default_measured),
        y_cols,
        u_cols,
    )
    library = _library(feature_library)
    optimizer = _optimizer(optimizer)
    validation_records, v_clippings, v_cuts = _validation_records(
        validation, y.shape[1], n_inputs, clipped, levels, window
    )
    validation = None if validation_records is None else validation_records[0]
    validation_clipping, validation_cut = v_clippings[0], v_cuts[0]
    if assumed_equations is not None and len(assumed_equations) != n_states:
        raise ValueError(
            f"assumed_equations has {len(assumed_equations)} entries, expected "
            f"{n_states} (one per state)"
        )
    _check_size(library, y, n_states + n_inputs)
    placement = _place_model_error(est, y, t, u_est, int(n_states), state_names)
    # shapes, observability, first evaluation
    problem = (
        est.check(y, t, u_est, starts=starts) if starts.size else est.check(y, t, u_est)
    )
    est.set_params(noise_variance=problem.noise_covariance)  # 'auto' resolved once
    measured, channel_names = _channels(est, n_states, state_names, y.shape[1])
    u_grid = None if u_est is None else np.asarray(problem.smoother.u_grid(), float)
    return Study(
        y=problem.y,
        t=problem.t,
        u=u_grid,
        inputs=InputSignal(u_est, problem.t, input_hold),
        mme=est,
        model=problem.model,
        n_states=int(n_states),
        measurement=problem.measurement,
        measured=measured,
        error_states=np.asarray(problem.error_states, dtype=int),
        state_names=state_names,
        input_names=input_names,
        channel_names=channel_names,
        noise_cov=np.asarray(problem.noise_covariance, dtype=float),
        library=library,
        optimizer=optimizer,
        alpha=alpha,
        refit=bool(refit),
        validation=validation,
        assumed_equations=None
        if assumed_equations is None
        else list(assumed_equations),
        x_init=problem.smoother.initial_guess()[0][:, : int(n_states)],
        validation_window=int(window),
        raw_model=(
            (mme.assumed_model if mme is not None else mme_keywords["assumed_model"])
            if params
            else None
        ),
        parameter_names=list(params),
        parameter_init=np.array(list(params.values()), dtype=float),
        offsets=bool(offsets),
        min_effect=float(min_effect),
        parameter_bounds=bounds,
        error_states_note=placement,
        clipped=clipping,
        validation_clipped=validation_clipping,
        clipped_option=clipped,
        readings=readings,
        clipped_cut=cut,
        validation_clipped_cut=validation_cut,
        starts=starts,
        validation_records=validation_records,
        hidden=hidden,
        protocol=protocol if validation is not None else _held_out(protocol),
        **_noise_record(problem),
    )
