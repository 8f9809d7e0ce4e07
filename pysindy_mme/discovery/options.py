"""The study's own options, in one object: ``discover(..., options=StudyOptions(...))``.

``discover`` keeps as keywords what every study needs (the model, the
measurements, the library, the optimizer, the inputs, the validation) and
takes the estimator's settings as an :class:`~pysindy_mme.MME` (``mme=``:
``W``, ``error_model``, ``input_hold``, ``n_substeps``, ...), how to
validate as a protocol (``validation=``, :mod:`pysindy_mme.protocols`), and
everything else here. Keywords of earlier versions raise a ``TypeError``
that says where each went (:data:`MOVED`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

from sklearn.base import clone

from ..differentiation import MME
from ..protocols import HeldOut, LeadingWindow, ValidationProtocol

__all__ = [
    "MOVED",
    "StudyOptions",
    "as_options",
    "grouped_keywords",
    "refuse_moved",
    "settings_into_estimator",
]


@dataclass(frozen=True)
class StudyOptions:
    """What the study may be told beyond the model, data, library and optimizer.

    Parameters
    ----------
    feature_names : list of str, optional
        Names of the states followed by the inputs (default ``x0, x1, ...``
        and ``u0, ...``).
    parameters : dict, optional
        Grey box: the assumed model's unknown parameters, ``{name: spec}``;
        ``assumed_model`` is then called as ``f(x, t, u, p)`` (``u`` None
        without inputs) with ``p`` a dict of their current values. Each spec
        is the initial guess (a number, unbounded: ``{"k": 1.0, "c": 0.1}``),
        a tuple ``(guess, lower, upper)`` with None for a missing bound
        (``{"M": (90.0, 0, None)}``), or a :class:`Parameter`
        (``Parameter(90.0, lower=1.0)``). Bounds are closed and every fit
        keeps the parameters inside them. The parameters are fitted to the
        measurements first (step 1), MME runs with the fitted values, and
        they are refitted jointly with the correction; the report gives them
        with confidence intervals apart from the missing effects. A
        parameter that ends on a bound is reported ``at_bound``: its value
        is a limit, not an estimate (no standard error; the others' are
        computed with it held there), and the conclusion names it, as it
        names a parameter that moved more than tenfold from its guess. A
        library term that only re-estimates a parameter cannot enter.
    hidden_states : dict, optional
        States nobody measured that the assumed model lacks, ``{name:
        equation it enters}`` (a state name from ``feature_names`` or an
        index): ``hidden_states={"z": "v"}`` adds a state ``z`` with
        ``v' = f_v + z`` and ``z' = 0`` assumed, and the study estimates
        ``z`` (MME) and searches its law in the library (give a library of
        the variables the law may use, ``z`` among them: the feature names
        are the states, then the hidden states, then the inputs). ``z`` is
        in the units of ``v'`` (a force ``F`` on a mass ``m`` shows as
        ``-F / m``), its initial value is fitted, MME estimates it at the
        guessed grey-box parameters (step 1's fit, made with ``z`` frozen,
        absorbs its effect into them), and the model error sits
        on the hidden states only unless ``error_states`` names others
        (indices of the original states keep their meaning). When the
        assumed model's error has memory no function of the states can
        give, the report says so and names this option
        (:mod:`pysindy_mme.discovery.hidden`).
    assumed_equations : list of str, optional
        Text of the assumed right-hand sides for the printed equations.
    alpha : float, default 0.001
        Significance level of the tests (consistency, terms, F-test of the
        extended against the assumed model). Each term is tested at
        ``alpha / n_candidates`` (Bonferroni over the library), so the chance
        that a study reports any term when the assumed model is right stays
        below ``alpha``: one in a thousand by default.
    min_effect : float, default 0.01
        Practical significance: every identified term must remove at least
        this share of the misfit of the model without it (on a long record
        a negligible term is still statistically significant; on a short
        one the significance test decides). 0 keeps every significant term.
    refit : bool, default True
        Settle the terms on the measurements by output error (recommended).
    offsets : bool, default False
        Estimate a constant offset per measured channel (``y = g(x) + o``)
        instead of letting the dynamics absorb it.
    clipped : "auto", "keep" or (low, high), default "auto"
        Readings on the end of a sensor's range (a level sensor that reads
        at most 10 V reports 10 V whenever the level is higher). ``"auto"``
        finds them (runs of readings exactly on a channel's largest or
        smallest value, :func:`pysindy_mme.core.sensors.clipped_samples`)
        on the fitting and the validation record and treats them as
        censored: they are left out of every fit, of the noise estimate and
        of every RMSE (a reading on the ceiling says only "at or above").
        ``"keep"`` finds and names them but fits them as readings. A range
        ``(low, high)`` (None for a missing limit; one pair per channel, or
        one for all) censors the readings at or beyond it. A censored
        stretch at the start or end of a record (nothing before or after it
        to anchor the fit) is cut from it. The report names them
        (``Discovery.clipped``), and says when a model's free run crosses a
        level the data never exceed.
    verbose : bool, default False
        Report each stage on standard error (stages are always logged to the
        ``"pysindy_mme"`` logger).

    Examples
    --------
    >>> from pysindy_mme import StudyOptions
    >>> StudyOptions(alpha=0.01, feature_names=["q", "v", "u"]).alpha
    0.01
    """

    feature_names: list | None = None
    parameters: dict | None = None
    hidden_states: dict | None = None
    assumed_equations: list | None = None
    alpha: float = 0.001
    min_effect: float = 0.01
    refit: bool = True
    offsets: bool = False
    clipped: object = "auto"
    verbose: bool = False

    def replace(self, **changes) -> StudyOptions:
        """A copy with ``changes`` (names checked)."""
        unknown = sorted(set(changes) - {f.name for f in fields(self)})
        if unknown:
            raise TypeError(f"StudyOptions has no option {unknown}")
        return StudyOptions(**{**asdict(self), **changes})


def as_options(options) -> StudyOptions:
    """``options`` as a :class:`StudyOptions` (None: the defaults; a dict:
    its keys are the options)."""
    if options is None:
        return StudyOptions()
    if isinstance(options, StudyOptions):
        return options
    if isinstance(options, dict):
        unknown = sorted(set(options) - {f.name for f in fields(StudyOptions)})
        if unknown:
            raise TypeError(
                f"options: unknown option(s) {unknown}; StudyOptions has "
                f"{[f.name for f in fields(StudyOptions)]}"
            )
        return StudyOptions(**options)
    raise TypeError(
        "options must be a StudyOptions (or a dict of its fields), got "
        f"{type(options).__name__}"
    )


#: keywords of discover before 0.2 -> where they are now
MOVED = {
    **{
        name: f"options=StudyOptions({name}=...)"
        for name in (
            "feature_names",
            "parameters",
            "hidden_states",
            "assumed_equations",
            "alpha",
            "min_effect",
            "refit",
            "offsets",
            "clipped",
            "verbose",
        )
    },
    **{
        name: f"mme=MME({name}=...) (discover fills in the model and the "
        "measurements it was given)"
        for name in ("W", "error_model", "input_hold", "n_substeps")
    },
    "validation_window": "validation=LeadingWindow(record, window=...) or "
    "HeldOut(window=...) (pysindy_mme.protocols)",
}


def refuse_moved(keywords: dict, function: str = "discover") -> None:
    """TypeError naming where each keyword of an earlier version went."""
    if not keywords:
        return
    moved = [f"{k} -> {MOVED[k]}" for k in keywords if k in MOVED]
    unknown = [k for k in keywords if k not in MOVED]
    if unknown:
        raise TypeError(
            f"{function}() got unexpected keyword argument(s) {unknown}"
            + (f"; and moved ones: {'; '.join(moved)}" if moved else "")
        )
    raise TypeError(
        f"{function}() no longer takes these keywords (grouped in 0.2): "
        + "; ".join(moved)
    )


#: the settings of discover's estimator (``mme=MME(...)``)
ESTIMATOR_SETTINGS = ("W", "error_model", "input_hold", "n_substeps")


def grouped_keywords(flat: dict) -> dict:
    """:func:`discover`'s keywords from settings kept flat, one name each.

    A configuration stored as one flat dict (the command line's flags, a
    scenario table, a JSON file) gives ``alpha``, ``W``,
    ``validation_window``... side by side; this puts each where ``discover``
    takes it: the estimator's settings into ``mme=MME(...)``, the window
    into the validation protocol, the rest of :class:`StudyOptions` into
    ``options=``. Keywords ``discover`` takes as they are pass through. When
    an ``options`` or ``mme`` object is given too, the flat settings fill in
    what it leaves at its default, and what it sets wins (a scenario's flat
    defaults, overridden by a test's explicit object).

    Examples
    --------
    >>> from pysindy_mme.discovery.options import grouped_keywords
    >>> kw = grouped_keywords({"alpha": 0.01, "n_states": 2})
    >>> kw["n_states"], kw["options"].alpha
    (2, 0.01)
    """
    out = dict(flat)
    names = {f.name for f in fields(StudyOptions)}
    options = {k: out.pop(k) for k in list(out) if k in names}
    estimator = {k: out.pop(k) for k in ESTIMATOR_SETTINGS if k in out}
    window = out.pop("validation_window", None)
    if options:
        given = as_options(out.get("options"))
        default = StudyOptions()
        kept = {
            k: getattr(given, k)
            for k in names
            if _differs(getattr(given, k), getattr(default, k))
        }
        out["options"] = StudyOptions(**{**options, **kept})
    if estimator:
        mme = out.get("mme")
        if mme is None:
            out["mme"] = MME(**estimator)
        else:
            default = MME().get_params()
            current = mme.get_params(deep=False)
            unset = {
                k: v
                for k, v in estimator.items()
                if not _differs(current[k], default[k])
            }
            out["mme"] = clone(mme).set_params(**unset)
    if window is not None:
        records = out.get("validation")
        if isinstance(records, ValidationProtocol):
            raise ValueError(
                "validation_window and a validation protocol both given: give "
                "the window to the protocol"
            )
        out["validation"] = (
            LeadingWindow(records, window=window)
            if records is not None
            else HeldOut(window=window)
        )
    return out


def settings_into_estimator(mme, given: dict):
    """``(mme, given)`` with discover's model and measurement keywords moved
    into the user's :class:`MME` where it leaves them at their defaults.

    ``mme=MME(error_model="ou", W=5.0)`` carries the estimator's settings;
    ``assumed_model``, ``n_states``, ``measured``, ``noise_variance`` and
    ``error_states`` given to discover fill it in. A setting given in both
    places raises, naming it (the two could disagree silently otherwise).
    """
    if mme is None:
        return None, given
    if not isinstance(mme, MME):
        raise TypeError(f"mme must be an MME estimator, got {type(mme).__name__}")
    default = MME().get_params()
    current = mme.get_params(deep=False)
    given = {name: value for name, value in given.items() if value is not None}
    both = [name for name in given if _differs(current[name], default[name])]
    if both:
        raise ValueError(
            f"give {', '.join(both)} either to MME (mme=...) or to discover, not both"
        )
    return clone(mme).set_params(**given), {}


def _differs(a, b) -> bool:
    """``a != b`` for settings (True when they cannot be compared)."""
    try:
        return bool(a != b)
    except (TypeError, ValueError):
        return True
