"""Saving a :class:`~.result.Discovery` to one file and loading it back.

``result.save("study.npz")`` writes, ``Discovery.load("study.npz")`` reads.
The file holds numbers and text, never code: no pickle (the loader reads it
with ``allow_pickle=False``), so it can be shared and opened anywhere
pysindy-mme is installed, whatever the user's model was.

Format, version 1
-----------------
A NumPy ``.npz`` archive (a zip of ``.npy`` files):

``__meta__``
    A 0-d unicode array: a JSON document (as Python's :mod:`json` writes
    it, so ``NaN`` and ``Infinity`` appear as such)::

        {"format": "pysindy-mme discovery", "version": 1,
         "package_version": "0.1.0", "report": "<str(result) when saved>",
         "result": {...}}

every other entry
    One numeric or boolean array of the result, named by its place in
    ``result`` (``study.y``, ``gain.in_sample_runs.extended.x``); the JSON
    stands for it as ``{"__array__": "<entry name>"}``.

Inside ``result`` a tuple is ``{"__tuple__": [...]}``, a dict whose keys are
not all strings is ``{"__items__": [[key, value], ...]}``, and a record of
the package is ``{"__type__": "<class name>", "fields": {...}}``, its
fields named as the class's attributes; only the classes in
:data:`RECORD_TYPES` are read back, so a file cannot make the loader build
anything else. ``result`` has these parts:

``fields``
    The :class:`~.result.Discovery`'s own fields: ``terms``,
    ``term_estimates``, ``verdict``, ``conclusion``, ``reasons``,
    ``advice``, ``warnings``, ``trade_offs``, ``smoothing``, ``memory``,
    ``substeps``, ``kink_misfit`` (version 2; a version-1 file reads as
    None).
``study``
    The checked study's data (:data:`STUDY_FIELDS`: records, names, noise,
    clipping, grey-box parameters and bounds, ...), ``input_hold``, the
    measurement matrix (None for a measurement function), the hidden states
    (``names``, ``enters``, ``n_visible``) or None.
``mme``
    MME's ``smoothed_x_``, ``d_``, ``W_``, ``covariance_ratio_``,
    ``residuals_`` and ``n_substeps``.
``assumed``, ``confirmation``
    Step 1 (chi-square test, substeps, notes) and step 4 (kept slots,
    rejections, F-test, log; its rivals since version 4), each with its
    output-error fit: ``theta``,
    ``x``, ``cost``, counts, ``covariance``, ``x0_covariance``,
    ``inflation``, ``at_bound`` ... (:data:`FIT_FIELDS`), from which the
    standard errors, intervals and tests are recomputed exactly.
``estimate``
    Step 2: ``x``, ``d``, ``summary``, ``notes``, ``physical``.
``proposals``
    Step 3: the library's column names and kinked columns, the regression
    coefficients and intercepts, the proposed slots and values, the
    candidates and rejections, and the optimizer: its class name, its
    summary as the report showed it (text and HTML) and its step history.
``gain``
    Step 5: the :class:`~.gain.Gain` with its free runs (without the models
    that ran); its ``rounding_set`` since version 3 (a file of version 1 or
    2 reads with none); each free run's ``determined_until`` since version 4
    and its ``uncertainty`` since version 5 (older files read with None).
``extended_model``
    Coefficients, intercept, ``substeps``, the assumed equations' text and
    the grey-box parameter values it runs with.
``derived``
    What the user's code computed that a loaded result cannot:
    ``assumed_output`` (the assumed model's run as the sensors see it) and
    ``extended_correction`` (the correction along the extended run).

``version`` is raised whenever a reader of the old version would misread a
new file; :func:`load` reads its own and older versions and refuses newer
ones, asking for a newer pysindy-mme.

What a loaded result can do
---------------------------
Everything that reads numbers: ``print`` (the same report),
``summary()``, ``to_frame()``, ``terms``, ``term_estimates``,
``parameters``, ``gain``, ``plot()`` (from the stored runs), the extended
model's ``equations()``, ``to_sympy()``, ``to_python()`` and, for
correction terms that are products of powers (``x1^2 x2``, ``|v|``), its
``correction()``. What runs the user's model needs it: pass
``Discovery.load(path, assumed_model=f)`` and the extended model simulates;
without it, and for ``validate()``, the fitted ``mme`` and ``optimizer`` and
the library, a :class:`~pysindy_mme.NotSavedError` names what is missing.
"""

from __future__ import annotations

import json
from dataclasses import fields, is_dataclass
from pathlib import Path

import numpy as np

from ..core.relaxation import overflow_columns_of
from ..exceptions import NotSavedError

__all__ = [
    "save",
    "load",
    "read",
    "FORMAT",
    "VERSION",
    "RECORD_TYPES",
    "STUDY_FIELDS",
]

FORMAT = "pysindy-mme discovery"
VERSION = 5

#: the :class:`~.inputs.Study` attributes saved (data, not code)
STUDY_FIELDS = (
    "y",
    "t",
    "u",
    "n_states",
    "measured",
    "error_states",
    "state_names",
    "input_names",
    "channel_names",
    "noise_cov",
    "alpha",
    "refit",
    "validation",
    "assumed_equations",
    "x_init",
    "validation_window",
    "parameter_names",
    "parameter_init",
    "offsets",
    "min_effect",
    "parameter_bounds",
    "error_states_note",
    "noise_description",
    "noise_doubt",
    "clipped",
    "validation_clipped",
    "clipped_option",
    "readings",
    "clipped_cut",
    "validation_clipped_cut",
    "starts",
    "validation_records",
    "gauges",
)

#: the :class:`~.output_error.OutputErrorFit` attributes saved
FIT_FIELDS = (
    "slots",
    "theta",
    "x",
    "cost",
    "n_residuals",
    "n_free",
    "converged",
    "message",
    "rank_deficient",
    "n_iter",
    "n_physical",
    "n_offsets",
    "at_bound",
    "at_wall",
    "joined",
)

#: the MME attributes saved
MME_FIELDS = ("smoothed_x_", "d_", "W_", "covariance_ratio_", "residuals_")

#: attributes of records that are code, not data (left out)
_SKIP = {"FreeRun": {"model"}, "RunUncertainty": {"columns"}}


def _record_types() -> dict:
    from ..core.sensors import ClippedChannel, Clipping
    from ..optimizers.selection import Step
    from ..protocols.runs import FreeRun
    from ..protocols.uncertainty import RunUncertainty
    from .estimates import ParameterEstimate, TermEstimate
    from .gain import Gain
    from .identifiability import TradeOff
    from .memory import MemoryEvidence

    types = (
        TermEstimate,
        ParameterEstimate,
        MemoryEvidence,
        TradeOff,
        Step,
        ClippedChannel,
        Clipping,
        FreeRun,
        RunUncertainty,
        Gain,
    )
    return {cls.__name__: cls for cls in types}


#: the record classes a file may name (filled on first use)
RECORD_TYPES: dict = {}


def _types() -> dict:
    if not RECORD_TYPES:
        RECORD_TYPES.update(_record_types())
    return RECORD_TYPES


# ------------------------------------------------------------------ writing
class _Writer:
    """Turns the result's parts into JSON, collecting the arrays apart."""

    def __init__(self):
        self.arrays = {}

    def array(self, value: np.ndarray, path: str) -> dict:
        if value.dtype.kind not in "biufcU":
            raise TypeError(f"cannot save {path}: an array of {value.dtype}")
        key, k = path, 1
        while key in self.arrays or key == "__meta__":
            k += 1
            key = f"{path}~{k}"
        self.arrays[key] = value
        return {"__array__": key}

    def encode(self, value, path: str):
        if value is None or isinstance(value, (bool, str)):
            return value
        if isinstance(value, np.bool_):
            return bool(value)
        if isinstance(value, (int, np.integer)):
            return int(value)
        if isinstance(value, (float, np.floating)):
            return float(value)
        if isinstance(value, np.ndarray):
            return self.array(value, path)
        if is_dataclass(value) and not isinstance(value, type):
            name = type(value).__name__
            if _types().get(name) is not type(value):
                raise TypeError(f"cannot save {path}: a {name}")
            skip = _SKIP.get(name, set())
            return {
                "__type__": name,
                "fields": {
                    f.name: self.encode(getattr(value, f.name), f"{path}.{f.name}")
                    for f in fields(value)
                    if f.name not in skip
                },
            }
        if isinstance(value, tuple):
            return {
                "__tuple__": [
                    self.encode(v, f"{path}.{k}") for k, v in enumerate(value)
                ]
            }
        if isinstance(value, list):
            return [self.encode(v, f"{path}.{k}") for k, v in enumerate(value)]
        if isinstance(value, dict):
            plain = all(isinstance(k, str) and not k.startswith("__") for k in value)
            if plain:
                return {k: self.encode(v, f"{path}.{k}") for k, v in value.items()}
            return {
                "__items__": [
                    [self.encode(k, f"{path}.key{j}"), self.encode(v, f"{path}.{j}")]
                    for j, (k, v) in enumerate(value.items())
                ]
            }
        raise TypeError(f"cannot save {path}: a {type(value).__name__}")


def _fit_dict(fit) -> dict | None:
    if fit is None:
        return None
    out = {name: getattr(fit, name) for name in FIT_FIELDS}
    out["covariance"] = fit.covariance
    out["x0_covariance"] = fit.x0_covariance
    out["inflation"] = float(fit.inflation)
    return out


def _study_dict(study) -> dict:
    out = {name: getattr(study, name) for name in STUDY_FIELDS}
    out["input_hold"] = study.inputs.hold
    measurement = study.measurement
    out["measurement"] = None if callable(measurement) else np.asarray(measurement)
    hidden = study.hidden
    out["hidden"] = (
        None
        if hidden is None
        else {
            "names": list(hidden.names),
            "enters": [int(j) for j in hidden.enters],
            "n_visible": int(hidden.n_visible),
        }
    )
    return out


def _optimizer_dict(res) -> dict:
    from .report import optimizer_summary

    opt = res.optimizer
    summary = optimizer_summary(res)
    html = getattr(summary, "as_html", None)
    steps = getattr(opt, "steps_", None)
    return {
        "class": type(opt).__name__,
        "summary": None if summary is None else str(summary),
        "summary_html": html() if callable(html) else None,
        "steps_": None if steps is None else [list(s) for s in steps],
    }


def _library_dict(res) -> dict:
    model = res.extended_model
    names = list(res.library_feature_names)
    own = getattr(res.proposals.library, "kinked_columns", None)
    if callable(own):
        kinked = [int(i) for i in own(list(range(len(names))))]
    else:
        from ..core.extended import _KINKED_NAME

        kinked = [i for i, n in enumerate(names) if _KINKED_NAME.search(n)]
    return {
        "class": type(model.feature_library).__name__,
        "feature_names": names,
        "kinked_columns": kinked,
        # {column: [variable, level]}: a loaded result still names its walls
        "overflow_columns": {
            str(c): [int(v), float(level)]
            for c, (v, level) in overflow_columns_of(res.proposals.library).items()
        },
    }


def _result_dict(res) -> dict:
    model = res.extended_model
    assumed = model.assumed_model
    values = getattr(assumed, "values", None)
    return {
        "fields": {
            "terms": res.terms,
            "term_estimates": list(res.term_estimates),
            "verdict": res.verdict,
            "warnings": list(res.warnings),
            "substeps": int(res.substeps),
            "conclusion": res.conclusion,
            "reasons": list(res.reasons),
            "advice": list(res.advice),
            "trade_offs": list(res.trade_offs),
            "smoothing": res.smoothing,
            "memory": list(res.memory),
            "kink_misfit": res.kink_misfit,
        },
        "study": _study_dict(res.study),
        "mme": {
            **{name: getattr(res.mme, name, None) for name in MME_FIELDS},
            "n_substeps": int(getattr(res.mme, "n_substeps", 1)),
        },
        "assumed": {
            "fit": _fit_dict(res.assumed.fit),
            "chi2": res.assumed.chi2,
            "dof": res.assumed.dof,
            "p_value": res.assumed.p_value,
            "substeps": res.assumed.substeps,
            "notes": list(res.assumed.notes),
        },
        "estimate": {
            "x": res.estimate.x,
            "d": res.estimate.d,
            "summary": res.estimate.summary,
            "notes": list(res.estimate.notes),
            "physical": res.estimate.physical,
        },
        "proposals": {
            "library": _library_dict(res),
            "optimizer": _optimizer_dict(res),
            "coefficients": res.proposals.coefficients,
            "intercepts": res.proposals.intercepts,
            "slots": list(res.proposals.slots),
            "start_values": list(res.proposals.start_values),
            "candidates": list(res.proposals.candidates),
            "singular": res.proposals.singular,
            "nonsmooth": res.proposals.nonsmooth,
            "rejected": list(res.proposals.rejected),
        },
        "confirmation": {
            "slots": list(res.confirmation.slots),
            "fit": _fit_dict(res.confirmation.fit),
            "rejected": list(res.confirmation.rejected),
            "correction_p_value": res.confirmation.correction_p_value,
            "log": list(res.confirmation.log),
            "rivals": [
                [list(slots), float(delta)]
                for slots, delta in getattr(res.confirmation, "rivals", [])
            ],
        },
        "gain": res.gain,
        "extended_model": {
            "coefficients": model.correction_coef_,
            "intercept": model.correction_intercept_,
            "substeps": int(model.substeps),
            "assumed_equations": model.assumed_equations,
            "parameters": None if values is None else dict(values),
        },
        "derived": {
            "assumed_output": np.asarray(res.assumed_output, dtype=float),
            "extended_correction": np.asarray(res.extended_correction, dtype=float),
        },
    }


def save(res, path) -> None:
    """Write ``res`` to ``path`` in the format of the module docstring."""
    from .._version import __version__

    writer = _Writer()
    result = {k: writer.encode(v, k) for k, v in _result_dict(res).items()}
    meta = {
        "format": FORMAT,
        "version": VERSION,
        "package_version": __version__,
        "report": str(res),
        "result": result,
    }
    text = json.dumps(meta)
    with open(Path(path), "wb") as fh:
        np.savez_compressed(fh, __meta__=np.array(text), **writer.arrays)


# ------------------------------------------------------------------ reading
class _Reader:
    def __init__(self, arrays):
        self.arrays = arrays

    def decode(self, value):
        if isinstance(value, list):
            return [self.decode(v) for v in value]
        if not isinstance(value, dict):
            return value
        if "__array__" in value:
            return np.array(self.arrays[value["__array__"]])
        if "__tuple__" in value:
            return tuple(self.decode(v) for v in value["__tuple__"])
        if "__items__" in value:
            return {
                _hashable(self.decode(k)): self.decode(v) for k, v in value["__items__"]
            }
        if "__type__" in value:
            cls = _types().get(value["__type__"])
            if cls is None:
                raise ValueError(
                    f"the file names a record type {value['__type__']!r} this "
                    "version of pysindy-mme does not know"
                )
            return cls(**{k: self.decode(v) for k, v in value["fields"].items()})
        return {k: self.decode(v) for k, v in value.items()}


def _hashable(key):
    if isinstance(key, list):
        return tuple(_hashable(k) for k in key)
    return key


def read(path) -> tuple:
    """``(meta without result, result dict)`` of a saved file, checked."""
    with np.load(Path(path), allow_pickle=False) as data:
        if "__meta__" not in data.files:
            raise ValueError(f"{path} is not a saved pysindy-mme discovery")
        meta = json.loads(str(data["__meta__"]))
        arrays = {k: data[k] for k in data.files if k != "__meta__"}
    if meta.get("format") != FORMAT:
        raise ValueError(f"{path} is not a saved pysindy-mme discovery")
    version = meta.get("version")
    if not isinstance(version, int) or version > VERSION:
        raise ValueError(
            f"{path} was saved in format version {version} by pysindy-mme "
            f"{meta.get('package_version')}; this version reads up to {VERSION}: "
            "upgrade pysindy-mme"
        )
    result = _Reader(arrays).decode(meta.pop("result"))
    return meta, result


# --------------------------------------------------- what stands in for code
class _Stored:
    """Base of the stand-ins of a loaded result: a missing attribute raises
    :class:`~pysindy_mme.NotSavedError` saying what was not saved."""

    _what = "this part"
    _why = "a saved result keeps numbers, not code"

    def __getattr__(self, name):
        if name.startswith("__") and name.endswith("__"):
            raise AttributeError(name)
        raise NotSavedError(
            f"{self._what} of a loaded result has no {name!r}: {self._why}"
        )


class StoredMME(_Stored):
    """MME's estimates as saved (``smoothed_x_``, ``d_``, ``W_``, ...)."""

    _what = "the MME estimator"
    _why = (
        "save() keeps its estimates (smoothed_x_, d_, W_, covariance_ratio_, "
        "residuals_), not the fitted estimator: run discover() again for the rest"
    )

    def __init__(self, values: dict):
        self.__dict__.update(values)


class _Returns:
    """A callable returning a stored value (a saved method's answer)."""

    def __init__(self, value):
        self.value = value

    def __call__(self, *args, **kwargs):
        return self.value


class StoredOptimizer(_Stored):
    """The optimizer's summary and step history as saved."""

    _what = "the optimizer"
    _why = (
        "save() keeps its summary and step history (steps_), not the fitted "
        "estimator: run discover() again for the rest"
    )

    def __init__(self, values: dict):
        from ..optimizers.summary import StepwiseSummary

        self.class_name = values["class"]
        if values["summary"] is not None:
            text = StepwiseSummary(values["summary"], values["summary_html"] or "")
            self.summary = _Returns(text)
        if values["steps_"] is not None:
            self.steps_ = values["steps_"]


class StoredLibrary(_Stored):
    """A fitted library's column names and kinks, evaluating products of powers.

    ``transform`` computes the columns whose names say how
    (``x1^2 x2``, ``|v|^-1``, ``1``: :mod:`pysindy_mme.core.features`),
    NaN for the others, and raises :class:`~pysindy_mme.NotSavedError` if
    one of ``needed`` (the columns the extended model uses) is not such.
    """

    _what = "the feature library"
    _why = (
        "save() keeps its column names, not the library object (user code "
        "may define its functions)"
    )

    def __init__(self, values: dict, variables, needed=()):
        self.class_name = values["class"]
        self.feature_names = list(values["feature_names"])
        self.kinked = {int(i) for i in values["kinked_columns"]}
        self.overflow = {
            int(c): (int(v), float(level))
            for c, (v, level) in values.get("overflow_columns", {}).items()
        }
        self.variables = list(variables)
        self.needed = [int(i) for i in needed]

    def get_feature_names(self, input_features=None):
        return list(self.feature_names)

    def kinked_columns(self, columns):
        return [c for c in columns if int(c) in self.kinked]

    def overflow_columns(self) -> dict:
        """``{column: (variable, level)}`` as the library declared them."""
        return dict(self.overflow)

    def transform(self, z):
        from ..core.features import _parse, _power

        z = np.atleast_2d(np.asarray(z, dtype=float))
        parsed = [_parse(n, self.variables) for n in self.feature_names]
        missing = [self.feature_names[i] for i in self.needed if parsed[i] is None]
        if missing:
            raise NotSavedError(
                f"the extended model's terms {missing} are functions of "
                f"{self.class_name}, which was not saved (only products of powers "
                "evaluate from their names): rebuild the ExtendedModel with the "
                "library, or run discover() again"
            )
        out = np.full((z.shape[0], len(parsed)), np.nan)
        with np.errstate(all="ignore"):
            for j, factors in enumerate(parsed):
                if factors is None:
                    continue
                col = np.ones(z.shape[0])
                for var, power, absolute in factors:
                    base = np.abs(z[:, var]) if absolute else z[:, var]
                    col = col * _power(base, power)
                out[:, j] = col
        return out


class _Missing:
    """Stands for user code a loaded result does not have; calling it raises."""

    def __init__(self, what: str, how: str):
        self.what, self.how = what, how

    def __call__(self, x, t=None, u=None, p=None):
        raise NotSavedError(f"{self.what} is user code and was not saved: {self.how}")

    def __repr__(self) -> str:
        return f"<not saved: {self.what}>"


_MODEL_HOW = "load the result with Discovery.load(path, assumed_model=f)"


# ------------------------------------------------------------------ loading
def _fit(values):
    from ..solver.output_error import OutputErrorFit

    if values is None:
        return None
    cov = (values.pop("covariance"), values.pop("x0_covariance"))
    inflation = values.pop("inflation")
    # its statistics, not its solver: score tests refuse it, and say why
    return OutputErrorFit(**values, _cov=cov, _inflation=inflation, _released=True)


def _user_model(assumed_model, study: dict, hidden: dict | None):
    """The model the study ran: the user's (or the stand-in that says it was
    not saved), with its hidden states."""
    if hidden is None:
        return assumed_model
    from .hidden import add_hidden_states

    n = hidden["n_visible"]
    visible = study["state_names"][:n]
    spec = {name: int(j) for name, j in zip(hidden["names"], hidden["enters"])}
    return add_hidden_states(
        assumed_model, n, spec, visible, grey=bool(study["parameter_names"])
    )[0]


def _study(values: dict, mme, library, optimizer, model):
    from ..core.integrate import InputSignal
    from ..core.model import as_model_function
    from .hidden import HiddenStates
    from .inputs import AtParameters, Study

    values = dict(values)
    hold = values.pop("input_hold")
    measurement = values.pop("measurement")
    hidden = values.pop("hidden")
    n = int(values["n_states"])
    names = values["parameter_names"]
    if names:
        raw = model
        checked = as_model_function(
            AtParameters(model, names, values["parameter_init"]), n
        )
    else:
        raw, checked = None, as_model_function(model, n)
    if hidden is not None:
        visible = values["state_names"][: hidden["n_visible"]]
        hidden = HiddenStates(dict(zip(hidden["names"], hidden["enters"])), visible)
    return Study(
        **values,
        inputs=InputSignal(values["u"], values["t"], hold),
        mme=mme,
        model=checked,
        measurement=(
            _Missing(
                "the measurement function",
                "a loaded result has its simulated measurements, not the function",
            )
            if measurement is None
            else measurement
        ),
        library=library,
        optimizer=optimizer,
        raw_model=raw if names else None,
        hidden=hidden,
    )


def _extended(values: dict, study, library, model):
    from ..core.extended import ExtendedModel
    from .inputs import AtParameters

    coef = np.asarray(values["coefficients"], dtype=float)
    library.needed = [int(i) for i in np.flatnonzero(np.any(coef != 0, axis=0))]
    if values["parameters"] is not None:
        params = values["parameters"]
        assumed = AtParameters(model, list(params), list(params.values()))
    else:
        assumed = model
    return ExtendedModel(
        assumed,
        library,
        coef,
        study.state_names,
        study.input_names,
        intercept=values["intercept"],
        assumed_equations=values["assumed_equations"],
        substeps=int(values["substeps"]),
    )


def load(path, result_class, assumed_model=None):
    """A ``result_class`` (:class:`~.result.SavedDiscovery`: this module
    does not import the result) from a file written by :func:`save`."""
    from .confirm import Confirmation
    from .propose import Proposals
    from .steps import AssumedFit, ErrorEstimate

    meta, r = read(path)
    s = r["study"]
    if assumed_model is None:
        assumed_model = _Missing("the assumed model", _MODEL_HOW)
    model = _user_model(assumed_model, s, s["hidden"])
    mme = StoredMME(r["mme"])
    p = r["proposals"]
    library = StoredLibrary(p["library"], s["state_names"] + s["input_names"])
    optimizer = StoredOptimizer(p["optimizer"])
    study = _study(s, mme, library, optimizer, model)
    a = r["assumed"]
    assumed = AssumedFit(
        fit=_fit(a["fit"]),
        chi2=a["chi2"],
        dof=a["dof"],
        p_value=a["p_value"],
        substeps=a["substeps"],
        notes=a["notes"],
    )
    estimate = ErrorEstimate(mme=mme, **r["estimate"])
    proposals = Proposals(
        library=library,
        feature_names=list(p["library"]["feature_names"]),
        features=_Missing("the library's columns", "run discover() again"),
        optimizer=optimizer,
        coefficients=p["coefficients"],
        intercepts=p["intercepts"],
        slots=p["slots"],
        start_values=p["start_values"],
        candidates=p["candidates"],
        singular=p["singular"],
        nonsmooth=p["nonsmooth"],
        rejected=p["rejected"],
    )
    c = r["confirmation"]
    confirmation = Confirmation(
        slots=c["slots"],
        fit=_fit(c["fit"]),
        rejected=c["rejected"],
        correction_p_value=c["correction_p_value"],
        log=c["log"],
        # since version 4
        rivals=[(list(slots), float(d)) for slots, d in c.get("rivals", [])],
    )
    extended = _extended(r["extended_model"], study, library, model)
    result = result_class(
        study=study,
        assumed=assumed,
        estimate=estimate,
        proposals=proposals,
        confirmation=confirmation,
        gain=r["gain"],
        extended_model=extended,
        extended_fit=confirmation.fit,
        **r["fields"],
    )
    result.saved = {
        "path": str(path),
        "package_version": meta.get("package_version"),
        "version": meta["version"],
        "report": meta.get("report"),
        **r["derived"],
    }
    return result
