"""The extended model outside pysindy-mme: sympy expressions and Python source.

:meth:`ExtendedModel.to_sympy <.extended.ExtendedModel.to_sympy>` gives the
right-hand sides as sympy expressions; :meth:`ExtendedModel.to_python
<.extended.ExtendedModel.to_python>` gives the source of a module that needs
numpy only: the correction, the right-hand side and the fixed-step RK4 of
``ExtendedModel.simulate(method="rk4")``.

The assumed model is the user's code, which neither form can contain: sympy
shows it as an undefined function ``f_v(x1, x2, t)`` per equation (or as the
expression parsed from ``assumed_equations`` when the study was given their
text), and the Python module takes it as an argument (with the fitted
grey-box parameters and the hidden states of the study built in).

A correction term is exported exactly when its library column is a product
of powers its name spells (``x1^2 x2``, ``|v|^-1``, ``1``: what
:mod:`pysindy_mme.core.features` parses) and the name's value agrees with
what the extended model computes (checked on data). Other columns (a
``CustomLibrary`` function, a ``PhysicsLibrary`` effect integrated with its
kink smoothed) are library code: sympy reads their names as expressions
where it can (``sign(v)``, ``sin(x1)``) and shows an undefined ``phi_<k>``
(``k`` the library column) where it cannot, and :meth:`to_python` refuses
them, naming them.
"""

from __future__ import annotations

import re

import numpy as np

from .features import _agrees, _parse, _power

__all__ = ["to_sympy", "to_python", "exportable_terms"]


def _require_sympy():
    try:
        import sympy
    except ImportError as exc:
        raise ImportError(
            "sympy expressions need sympy, an optional dependency: "
            "pip install 'pysindy-mme[sympy]'"
        ) from exc
    return sympy


def _variables(model) -> list:
    return model.state_names + model.input_names


def _reference(model) -> np.ndarray:
    z = getattr(model, "_z_reference", None)
    if z is None:
        z = np.random.default_rng(0).uniform(-2, 2, (64, len(_variables(model))))
    return np.asarray(z, dtype=float)


def exportable_terms(model) -> dict:
    """``{library column: [(variable, power, absolute), ...] or None}`` for
    every column the correction uses; None for a column that is not a
    product of powers its name spells (module docstring)."""
    variables = _variables(model)
    active = [int(c) for c in model.active_]
    if not active:
        return {}
    names = model.library_feature_names
    parsed = {c: _parse(names[c], variables) for c in active}
    z = _reference(model)
    with np.errstate(all="ignore"):
        try:
            actual = model._features(z)
        except Exception:  # a column that cannot be evaluated: none checked
            actual = None
    out = {}
    for k, c in enumerate(active):
        factors = parsed[c]
        if factors is not None and actual is not None:
            with np.errstate(all="ignore"):
                value = np.ones(z.shape[0])
                for var, power, absolute in factors:
                    base = np.abs(z[:, var]) if absolute else z[:, var]
                    value = value * _power(base, power)
            if not _agrees(value[:, None], actual[:, [k]]):
                factors = None
        out[c] = factors
    return out


# ---------------------------------------------------------------- sympy
def _sympy_factors(sympy, factors, symbols):
    expr = sympy.Integer(1)
    for var, power, absolute in factors:
        base = sympy.Abs(symbols[var]) if absolute else symbols[var]
        expr = expr * base ** sympy.Integer(power)
    return expr


def _parse_text(sympy, text, local):
    """``text`` as a sympy expression (``^`` a power, ``|a|`` ``Abs(a)``,
    implicit products), or None."""
    from sympy.parsing.sympy_parser import (
        convert_xor,
        implicit_multiplication_application,
        parse_expr,
        standard_transformations,
    )

    text = re.sub(r"\|([^|]+)\|", r"Abs(\1)", str(text))
    transformations = standard_transformations + (
        convert_xor,
        implicit_multiplication_application,
    )
    try:
        expr = parse_expr(text, local_dict=dict(local), transformations=transformations)
    except Exception:  # sympy raises many kinds on text it cannot read
        return None
    return expr if isinstance(expr, sympy.Basic) else None


class _Constant:
    """A callable that ignores its arguments: ``f_v(x, t)`` in an equation's
    text parses to the undefined function of every state, input and ``t``."""

    def __init__(self, value):
        self.value = value

    def __call__(self, *args):
        return self.value


def to_sympy(model) -> list:
    """The right-hand sides as sympy expressions (module docstring)."""
    sympy = _require_sympy()
    variables = _variables(model)
    symbols = [sympy.Symbol(v) for v in variables]
    t = sympy.Symbol("t")
    local = {v: s for v, s in zip(variables, symbols)}
    local["t"] = t
    undefined = {
        name: sympy.Function(f"f_{name}")(*symbols, t) for name in model.state_names
    }
    # the placeholder text f_v(x, t) of equations stands for the undefined f_v
    local.update({f"f_{name}": _Constant(f) for name, f in undefined.items()})
    exact = exportable_terms(model)
    names = model.library_feature_names
    out = []
    for i, name in enumerate(model.state_names):
        assumed = None
        if model.assumed_equations is not None:
            assumed = _parse_text(sympy, model.assumed_equations[i], local)
        if assumed is None:
            assumed = undefined[name]
        expr = assumed
        b = float(model.correction_intercept_[i])
        if b != 0:
            expr = expr + sympy.Float(b)
        for c in np.flatnonzero(model.correction_coef_[i]):
            c = int(c)
            factors = exact.get(c)
            if factors is not None:
                term = _sympy_factors(sympy, factors, symbols)
            else:
                term = _parse_text(sympy, names[c], local)
                if term is None:
                    term = sympy.Function(f"phi_{c}")(*symbols)
            expr = expr + sympy.Float(float(model.correction_coef_[i, c])) * term
        out.append(expr)
    return out


# --------------------------------------------------------------- python
_TEMPLATE = '''"""An extended model found by pysindy-mme {version}, as plain Python.

    dx/dt = assumed_model(x, t[, u]) + correction(x, u)

Needs numpy only. The assumed model is your code and is not in here: pass it
to rates() or simulate(), vectorised over rows as discover() took it
({call}).{hidden_doc}

States: {state_list}; inputs: {input_list}.
Correction:
{equations}
"""

import inspect

import numpy as np

STATE_NAMES = {state_names!r}
INPUT_NAMES = {input_names!r}
#: the grey-box parameters the extended model runs with (None: no parameters)
PARAMETERS = {parameters}
#: hidden states appended to yours: name -> index of the equation it enters
HIDDEN = {hidden}
N_VISIBLE = {n_visible}
#: RK4 steps per sample interval (the study's)
SUBSTEPS = {substeps}


def correction(x, u=None):
    """The identified correction at states x (n_rows, n_states), inputs u."""
    x = np.atleast_2d(np.asarray(x, dtype=float))
{unpack}    out = np.zeros(x.shape)
{body}    return out


def _takes_input(func):
    try:
        params = inspect.signature(func).parameters.values()
    except (TypeError, ValueError):
        return False
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    if any(p.kind == inspect.Parameter.VAR_POSITIONAL for p in params):
        return True
    return sum(p.kind in kinds for p in params) >= 3


def assumed(assumed_model, x, t, u=None):
    """Your model's dx/dt on the states (with the hidden states added)."""
    x = np.atleast_2d(np.asarray(x, dtype=float))
    visible = x[:, :N_VISIBLE]
    if PARAMETERS is not None:
        dx = assumed_model(visible, t, u, dict(PARAMETERS))
    elif _takes_input(assumed_model):
        dx = assumed_model(visible, t, u)
    else:
        dx = assumed_model(visible, t)
    dx = np.asarray(dx, dtype=float).reshape(x.shape[0], N_VISIBLE)
    if not HIDDEN:
        return dx
    out = np.zeros(x.shape)
    out[:, :N_VISIBLE] = dx
    for k, equation in enumerate(HIDDEN.values()):
        out[:, equation] += x[:, N_VISIBLE + k]
    return out


def rates(assumed_model, x, t, u=None):
    """dx/dt of the extended model at rows x, times t (n_rows,), inputs u."""
    return assumed(assumed_model, x, t, u) + correction(x, u)


def _input(u, t, k, frac, hold):
    """u at t[k] + frac (t[k+1] - t[k]), as one row (or None)."""
    if u is None:
        return None
    if callable(u):
        s = np.array([t[k] + frac * (t[k + 1] - t[k])])
        return np.asarray(u(s), dtype=float).reshape(1, -1)
    u = np.asarray(u, dtype=float)
    u = u[:, None] if u.ndim == 1 else u
    if hold == "zoh":
        return u[k][None, :]
    if hold == "cubic":
        last = u.shape[0] - 1
        p0, p1 = u[max(k - 1, 0)], u[k]
        p2, p3 = u[k + 1], u[min(k + 2, last)]
        s = frac
        return (
            0.5
            * (
                2 * p1
                + (p2 - p0) * s
                + (2 * p0 - 5 * p1 + 4 * p2 - p3) * s**2
                + (3 * p1 - p0 - 3 * p2 + p3) * s**3
            )
        )[None, :]
    return ((1.0 - frac) * u[k] + frac * u[k + 1])[None, :]


def simulate(assumed_model, x0, t, u=None, substeps=SUBSTEPS, input_hold="linear"):
    """Fixed-step RK4 from x0 over the times t, substeps steps per interval.

    u: None, an array (n_samples, n_inputs) on t held between samples as
    input_hold says ("linear", "zoh" or "cubic"), or a callable u(s) ->
    (len(s), n_inputs). A run that leaves 1e6 times its initial scale (or
    the finite range) is NaN from there. Returns (n_samples, n_states).
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x0, dtype=float).reshape(1, -1)
    out = np.full((t.size, x.shape[1]), np.nan)
    out[0] = x[0]
    limit = 1e6 * max(1.0, float(np.max(np.abs(x))))
    with np.errstate(all="ignore"):
        for k in range(t.size - 1):
            h = (t[k + 1] - t[k]) / substeps
            for s in range(substeps):
                s0 = t[k] + s * h
                ua, um, ub = (
                    _input(u, t, k, f / substeps, input_hold)
                    for f in (s, s + 0.5, s + 1)
                )
                mid, end = np.array([s0 + 0.5 * h]), np.array([s0 + h])
                k1 = rates(assumed_model, x, np.array([s0]), ua)
                k2 = rates(assumed_model, x + 0.5 * h * k1, mid, um)
                k3 = rates(assumed_model, x + 0.5 * h * k2, mid, um)
                k4 = rates(assumed_model, x + h * k3, end, ub)
                x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            if not np.all(np.isfinite(x) & (np.abs(x) < limit)):
                break
            out[k + 1] = x[0]
    return out
'''


def _python_factor(var_name, power, absolute) -> str:
    base = f"np.abs({var_name})" if absolute else var_name
    if power == 1:
        return base
    return f"{base}**{power}" if power > 0 else f"{base}**({power})"


def _hidden(model):
    """``(hidden states or None, grey parameters or None)`` of the model's
    assumed part.

    This floor knows no study, so the study's wrappers of the user's model
    say what they are by attributes: a model at fixed grey-box parameters
    has ``parameter_values`` (a dict) and ``model`` (the user's
    ``f(x, t, u, p)``); a model with hidden states appended has
    ``hidden_states`` (``names``, ``enters``, ``n_visible``).
    """
    assumed = model.assumed_model
    parameters = getattr(assumed, "parameter_values", None)
    if parameters is not None:
        parameters = dict(parameters)
        assumed = assumed.model
    return getattr(assumed, "hidden_states", None), parameters


def to_python(model) -> str:
    """Source of a module simulating the model with numpy only (module
    docstring); ValueError naming the terms that are library code."""
    from .._version import __version__

    exact = exportable_terms(model)
    names = model.library_feature_names
    missing = [names[c] for c, f in exact.items() if f is None]
    if missing:
        raise ValueError(
            f"the correction terms {missing} are not products of powers their "
            "names spell, so their code is the library's and cannot be exported; "
            "to_sympy() shows them by name"
        )
    variables = _variables(model)
    idents = [_identifier(v, k) for k, v in enumerate(variables)]
    used = sorted({var for f in exact.values() for var, _, _ in f})
    n = model.n_states
    unpack = ""
    for var in used:
        source = f"x[:, {var}]" if var < n else f"u[:, {var - n}]"
        unpack += f"    {idents[var]} = {source}\n"
    if any(var >= n for var in used):
        unpack = (
            "    u = np.atleast_2d(np.asarray(u, dtype=float))\n"
            "    u = u.reshape(x.shape[0], -1)\n" + unpack
        )
    body, equations = "", []
    for i, state in enumerate(model.state_names):
        parts = []
        b = float(model.correction_intercept_[i])
        if b != 0:
            parts.append(repr(b))
        for c in np.flatnonzero(model.correction_coef_[i]):
            factors = exact[int(c)]
            coef = repr(float(model.correction_coef_[i, c]))
            if factors:
                product = " * ".join(
                    _python_factor(idents[v], p, a) for v, p, a in factors
                )
                parts.append(f"({coef}) * {product}")
            else:
                parts.append(f"({coef})")
        if parts:
            body += f"    out[:, {i}] = " + " + ".join(parts) + "\n"
        text = model.equations()[i].split("[correction] ")
        equations.append(f"    ({state})' += {text[1] if len(text) > 1 else 0}")
    hidden, parameters = _hidden(model)
    n_visible = n if hidden is None else hidden.n_visible
    hidden_map = (
        {}
        if hidden is None
        else {name: int(j) for name, j in zip(hidden.names, hidden.enters)}
    )
    call = (
        "f(x, t, u, p) with p a dict of the parameters"
        if parameters is not None
        else "f(x, t) or f(x, t, u)"
    )
    hidden_doc = (
        f"\nIts states are the first {n_visible}; the hidden states "
        f"{list(hidden_map)} are added to the equations in HIDDEN."
        if hidden_map
        else ""
    )
    return _TEMPLATE.format(
        version=__version__,
        call=call,
        hidden_doc=hidden_doc,
        state_list=", ".join(model.state_names),
        input_list=", ".join(model.input_names) or "none",
        equations="\n".join(equations),
        state_names=list(model.state_names),
        input_names=list(model.input_names),
        parameters=repr(parameters),
        hidden=repr(hidden_map),
        n_visible=n_visible,
        substeps=int(model.substeps),
        unpack=unpack,
        body=body,
    )


def _identifier(name: str, k: int) -> str:
    """A Python name for variable ``name`` (``v_<k>`` if it is none)."""
    import keyword

    ok = name.isidentifier() and not keyword.iskeyword(name)
    ok = ok and name not in ("np", "x", "u", "out", "inspect")
    return name if ok else f"v_{k}"
