"""ExtendedModel: the assumed model plus an identified correction."""

from __future__ import annotations

import re

import numpy as np

from .features import SelectedFeatures
from .jacobian import rowwise_jacobian
from .model import as_model_function, simulate_model
from .relaxation import Overflows
from .tables import sig

__all__ = ["ExtendedModel"]

# Library column names that announce a kink or a jump, for libraries that do
# not say so themselves (no ``kinked_columns``: a pysindy CustomLibrary, or a
# PhysicsLibrary inside a GeneralizedLibrary): sign, absolute values
# (``abs(x)``, ``|x|``), max, min, clip, floor, ceil, round, heaviside, and
# PhysicsLibrary's own names (``sat(u, 2)``, ``dz(u, 0.1)``, ``over(h1, 10)``,
# the parts ``v+`` and ``v-``, ``sqrt(h1+)``). A false alarm costs little: the
# model is then integrated with fixed-step RK4, accurate on smooth models too.
_KINKED_NAME = re.compile(
    r"sign\(|abs\(|\||max\(|min\(|clip|floor|ceil|round|heaviside"
    r"|sat\(|dz\(|over\(|\w[+-](?=$|[\s)])"
)


def _bare_assumed(assumed, n_states, n_inputs):
    """The assumed model without checks, if it is safe on a probe; else checked.

    The probe has ``n_states + 1`` rows (so that equations stacked as rows
    cannot pass for states); a one-state model may return ``(n_rows,)``.
    """
    raw = assumed.unchecked()
    rows = n_states + 1
    x = np.zeros((rows, n_states))
    u = np.zeros((rows, n_inputs)) if n_inputs else None
    try:
        with np.errstate(all="ignore"):
            probe = raw(x, np.zeros(rows), u)
    except Exception:  # the checked model says what is wrong when it is used
        return assumed
    if not isinstance(probe, np.ndarray) or probe.dtype != np.float64:
        return assumed
    if probe.shape == x.shape:
        return raw
    if n_states == 1 and probe.shape == (rows,):
        return _Column(raw)
    return assumed


class _Column:
    """A one-state model's ``(n_rows,)`` answer as a column (not a closure:
    what holds it pickles when the model does)."""

    def __init__(self, raw):
        self.raw = raw

    def __call__(self, x, t, u=None):
        return self.raw(x, t, u).reshape(-1, 1)


class _Rates:
    """:meth:`ExtendedModel.unchecked`: ``assumed(x, t, u) + Theta(z) C + b``.

    With ``split`` (the overflow terms, solved exactly around each RK4 step:
    :mod:`~pysindy_mme.core.relaxation`), ``C`` lacks them and ``full`` is
    the whole right-hand side (for adaptive integrators).
    """

    def __init__(self, assumed, features, coef, intercept, split=None, full=None):
        self.assumed, self.features = assumed, features
        self.coef, self.intercept = coef, intercept
        self.split = split
        self.full = self if full is None else full

    def __call__(self, x, t, u=None):
        if self.coef is None:
            return self.assumed(x, t, u) + self.intercept
        z = x if u is None else np.concatenate((x, u), axis=1)
        return self.assumed(x, t, u) + self.features(z) @ self.coef + self.intercept

    def jacobian(self, x, t, u=None, scale=None):
        """``d (rates) / dx``, ``(n_rows, n_states, n_states)``: central
        differences of the assumed model (steps as
        :func:`~pysindy_mme.core.jacobian.rowwise_jacobian` with ``scale``)
        and the correction's exact gradient.

        Differencing the whole right-hand side evaluated the library
        ``2 n`` times per Jacobian, most of a free run's Newton iteration
        when the correction is a polynomial and the assumed model a few
        products (the held-out runs of a study at 10^6 samples).
        """
        out = rowwise_jacobian(lambda z: self.assumed(z, t, u), x, scale=scale)
        if self.coef is None:
            return out
        n = x.shape[1]
        z = x if u is None else np.concatenate((x, u), axis=1)
        grad = self.features.gradient(z)  # (rows, columns, variables)
        for col, state in zip(*np.nonzero(self.coef)):
            c = self.coef[col, state]
            # element by element: each operation runs over the rows
            for j in range(n):
                out[:, state, j] += grad[:, col, j] * c
        return out


def _format_terms(coefs, names, digits) -> str:
    """``-1.007 x1 + 0.0004213 x2``: significant digits, zeros left out."""
    parts = []
    for c, name in zip(coefs, names):
        if c == 0:
            continue
        sign = "-" if c < 0 else "+"
        body = sig(abs(c), digits) + ("" if name == "1" else f" {name}")
        parts.append((sign, body))
    if not parts:
        return ""
    first_sign, first = parts[0]
    text = ("-" if first_sign == "-" else "") + first
    return text + "".join(f" {s} {b}" for s, b in parts[1:])


class ExtendedModel:
    """Assumed model plus a correction ``Theta(x, u) @ coef.T``.

    ``dx/dt = f(x, t, u) + Theta(x, u) C^T + b``, where ``f`` is the user's
    assumed model, ``Theta`` a fitted pysindy feature library evaluated on the
    states followed by the inputs, ``C`` the correction coefficients and ``b``
    an optional constant (used when the optimizer fitted its own intercept).

    Parameters
    ----------
    assumed_model : callable, pysindy model or ExtendedModel
        ``f(x, t)`` or ``f(x, t, u)``, vectorised over rows.
    feature_library : fitted pysindy feature library
    coefficients : array-like (n_states, n_library_features)
        Correction coefficients; rows of states without error are zero.
    state_names : list of str
    input_names : list of str, optional
    intercept : array-like (n_states,), optional
    assumed_equations : list of str, optional
        Text of the assumed right-hand sides, shown by :meth:`equations`.
    z_reference : ndarray, optional
        Library input data used to check the fast evaluation of terms.
    substeps : int, default 4
        RK4 steps per sample interval of :meth:`simulate` when it integrates
        with fixed steps; a study sets the number its own free runs used.

    Attributes
    ----------
    correction_coef_ : ndarray (n_states, n_library_features)
    correction_intercept_ : ndarray (n_states,)
    """

    def __init__(
        self,
        assumed_model,
        feature_library,
        coefficients,
        state_names,
        input_names=(),
        intercept=None,
        assumed_equations=None,
        z_reference=None,
        substeps=4,
    ):
        if (
            isinstance(substeps, bool)
            or not isinstance(substeps, (int, np.integer))
            or substeps < 1
        ):
            raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
        self.substeps = int(substeps)
        self.state_names = list(state_names)
        self.input_names = list(input_names)
        self.n_states = len(self.state_names)
        self.assumed_model = assumed_model
        self._assumed = as_model_function(assumed_model, self.n_states)
        self.feature_library = feature_library
        self.correction_coef_ = np.array(coefficients, dtype=float)
        n_vars = self.n_states + len(self.input_names)
        if self.correction_coef_.ndim != 2 or self.correction_coef_.shape[0] != (
            self.n_states
        ):
            raise ValueError(
                "coefficients must have shape (n_states, n_library_features), got "
                f"{self.correction_coef_.shape}"
            )
        self.correction_intercept_ = (
            np.zeros(self.n_states)
            if intercept is None
            else np.array(intercept, dtype=float).reshape(self.n_states)
        )
        self.assumed_equations = assumed_equations
        self.library_feature_names = list(
            feature_library.get_feature_names(self.state_names + self.input_names)
        )
        self.active_ = np.flatnonzero(np.any(self.correction_coef_ != 0, axis=0))
        if z_reference is None:
            z_reference = np.random.default_rng(0).uniform(-2, 2, (64, n_vars))
        self._z_reference = np.asarray(z_reference, dtype=float)
        self._features = SelectedFeatures(
            feature_library,
            self.state_names + self.input_names,
            self.active_,
            np.asarray(z_reference, dtype=float),
        )

    @property
    def n_inputs(self) -> int:
        return len(self.input_names)

    def correction(self, x, u=None) -> np.ndarray:
        """The identified correction ``Theta(x, u) C^T + b`` at each row."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        if self.n_inputs:
            if u is None:
                raise TypeError(
                    f"u is required: the model has inputs {self.input_names}"
                )
            u = np.asarray(u, dtype=float).reshape(x.shape[0], self.n_inputs)
            z = np.hstack([x, u])
        else:
            z = x
        out = np.tile(self.correction_intercept_, (x.shape[0], 1))
        if self.active_.size:
            out += self._features(z) @ self.correction_coef_[:, self.active_].T
        return out

    def predict(self, x, u=None, t=None) -> np.ndarray:
        """``dx/dt`` of the extended model at states ``x`` (rows)."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        if self.n_inputs and u is None:
            raise TypeError(f"u is required: the model has inputs {self.input_names}")
        t = np.zeros(x.shape[0]) if t is None else t
        return self._assumed(x, t, u) + self.correction(x, u)

    def __call__(self, x, t, u=None) -> np.ndarray:
        return self.predict(x, u=u, t=t)

    @property
    def kinked_terms(self) -> list:
        """Names of the correction's terms with a kink or a jump (``sign(v)``).

        The library's own ``kinked_columns`` says which of the active
        columns are not smooth (:class:`~pysindy_mme.PhysicsLibrary` has
        it); any other library is judged by its column names (``sign(``,
        ``abs(``, ``|``, ``max(``, ``min(``, ``clip``, ``floor``, ``round``
        ...). Only terms with a nonzero coefficient count.
        """
        active = [int(i) for i in self.active_]
        if not active:
            return []
        own = getattr(self.feature_library, "kinked_columns", None)
        if callable(own):
            kinked = {int(i) for i in own(active)}
        else:
            names = self.library_feature_names
            kinked = {i for i in active if _KINKED_NAME.search(names[i])}
        return [self.library_feature_names[i] for i in active if i in kinked]

    def unchecked(self):
        """The right-hand side as a bare ``f(x, t, u)`` for integrator loops.

        The same values as :meth:`predict` without its checks and
        conversions: ``x`` ``(n_rows, n_states)``, ``t`` ``(n_rows,)``, ``u``
        ``(n_rows, n_inputs)`` or None, all float arrays.
        """
        assumed = _bare_assumed(self._assumed, self.n_states, self.n_inputs)
        b = self.correction_intercept_.copy()
        if not self.active_.size:
            return _Rates(assumed, None, None, b)
        coef = np.ascontiguousarray(self.correction_coef_[:, self.active_].T)
        full = _Rates(assumed, self._features, coef, b)
        # the overflow terms of states: solved exactly around each RK4 step
        slots = [(int(i), int(k)) for k, i in zip(*np.nonzero(coef))]
        overflows = Overflows(slots, self._features.overflow_columns(), self.n_states)
        if not overflows:
            return full
        smooth = coef.copy()
        for position in overflows.positions:
            i, k = slots[position]
            smooth[k, i] = 0.0
        values = np.array([coef[k, i] for i, k in slots])
        return _Rates(assumed, self._features, smooth, b, overflows.bound(values), full)

    def split_form(self):
        """:meth:`unchecked` if the model has overflow terms of states, which
        integrators solve exactly around each RK4 step
        (:mod:`~pysindy_mme.core.relaxation`); else None."""
        bare = self.unchecked()
        return bare if getattr(bare, "split", None) is not None else None

    def simulate(
        self,
        x0,
        t,
        u=None,
        method="auto",
        *,
        substeps: int | None = None,
        input_hold: str = "linear",
        **kwargs,
    ) -> np.ndarray:
        """Integrate the extended model from ``x0`` on the times ``t``.

        Parameters
        ----------
        x0 : array-like (n_states,)
        t : array-like (n_samples,)
        u : array-like (n_samples, n_inputs) or callable ``u(t)``, optional
            Required when the model has inputs. An array is taken between
            samples as ``input_hold`` says.
        method : {"auto", "rk4"} or a solve_ivp method, default "auto"
            ``"auto"``: fixed-step RK4 when a term of the correction has a
            kink or a jump (:attr:`kinked_terms`, e.g. Coulomb friction
            ``sign(v)``), LSODA otherwise. Adaptive steppers stall at a
            discontinuity: they halve the step until the error estimate
            passes, at every crossing, and a carriage that sticks at
            ``v = 0`` makes ``sign(v)`` switch at every step, so LSODA at
            ``rtol = 1e-9`` took minutes on a 25,000-sample record. RK4 with
            ``substeps`` steps per sample interval costs a fixed
            ``4 substeps`` evaluations per sample (its error is ``O(h)``,
            ``h`` the step, where the right-hand side jumps, ``O(h^4)``
            elsewhere), and it is the integrator of the study's own free
            runs (:func:`~pysindy_mme.core.integrate.simulate`): with the
            study's ``substeps`` the simulation reproduces the study's
            numbers, and the user sees what the study saw. If LSODA exhausts
            its budget of evaluations (``max_evaluations``) on a model not
            known to have a kink (an ``np.sign`` inside the assumed model,
            say), ``"auto"`` integrates once more with RK4 and issues a
            :class:`~pysindy_mme.DiscoveryWarning` instead of raising.
            ``"rk4"``, ``"LSODA"`` (or another solve_ivp method) force one.
        substeps : int, optional
            RK4 steps per sample interval (default :attr:`substeps`, 4
            unless the model was built with another number).
        input_hold : {"linear", "zoh", "cubic"}, default "linear"
            Inputs between samples: linear interpolation, zero-order hold
            (``u[k]`` on ``[t[k], t[k+1])``: a controller's output), or a
            cubic through the neighbouring samples.
        **kwargs
            To :func:`~pysindy_mme.core.model.simulate_model`: ``rtol``,
            ``atol``, ``max_evaluations`` (the adaptive methods),
            ``on_divergence`` (default ``"raise"``).

        Returns
        -------
        ndarray (n_samples, n_states)

        Raises
        ------
        DivergenceError
            Naming the time and the state where the model blew up (or,
            under an explicit adaptive method, turned so stiff that it
            exhausted its budget of evaluations: it never hangs).
        TypeError, ValueError
            Bad arguments.
        """
        if self.n_inputs and u is None:
            raise TypeError(f"u is required: the model has inputs {self.input_names}")
        kwargs.setdefault("on_divergence", "raise")
        if isinstance(method, str) and method.lower() == "auto" and self.kinked_terms:
            method = "rk4"
        return simulate_model(
            self,
            x0,
            t,
            u,
            n_states=self.n_states,
            method=method,
            substeps=self.substeps if substeps is None else substeps,
            input_hold=input_hold,
            **kwargs,
        )

    def equations(self, precision: int = 4) -> list:
        """Right-hand sides, the assumed part and the correction shown apart.

        Coefficients to ``precision`` significant digits (never rounded away).
        """
        out = []
        for i, name in enumerate(self.state_names):
            assumed = (
                self.assumed_equations[i]
                if self.assumed_equations is not None
                else f"f_{name}(x, t)"
            )
            names = ["1"] + self.library_feature_names
            coefs = np.concatenate(
                [[self.correction_intercept_[i]], self.correction_coef_[i]]
            )
            corr = _format_terms(coefs, names, precision)
            if corr:
                out.append(f"[assumed] {assumed}  +  [correction] {corr}")
            else:
                out.append(f"[assumed] {assumed}")
        return out

    def to_sympy(self) -> list:
        """The right-hand sides as sympy expressions (needs sympy).

        One expression per state, in the order of ``state_names``, in the
        symbols ``sympy.Symbol(name)`` of the states and inputs and
        ``sympy.Symbol("t")``. The assumed part is the user's code: an
        undefined function ``f_<state>(states, inputs, t)``, or the
        expression parsed from ``assumed_equations`` when given (``^`` is a
        power). Correction terms that are products of powers are exact
        (``-1.008*x1**3``); others are read from their names (``sign(v)``)
        or shown as an undefined ``phi_<library column>``
        (:mod:`pysindy_mme.core.export`).

        Returns
        -------
        list of sympy.Expr
        """
        from .export import to_sympy

        return to_sympy(self)

    def to_python(self) -> str:
        """Source of a standalone module that simulates this model (numpy only).

        The module defines ``correction(x, u=None)``, ``rates(assumed_model,
        x, t, u=None)`` and ``simulate(assumed_model, x0, t, u=None,
        substeps=SUBSTEPS, input_hold="linear")``: the fixed-step RK4 of
        :meth:`simulate` with ``method="rk4"``, to rounding. The assumed
        model cannot be exported (it is the user's code): pass it in, as
        ``discover`` took it; the fitted grey-box parameters (``PARAMETERS``)
        and hidden states (``HIDDEN``) are built in. Write the text to a
        ``.py`` file and import it, or ``exec`` it.

        Raises
        ------
        ValueError
            A correction term is library code (not a product of powers its
            name spells), named in the message.
        """
        from .export import to_python

        return to_python(self)

    def print(self, precision: int = 4, **kwargs) -> None:
        """Print the equations like ``pysindy.SINDy.print``."""
        for name, eq in zip(self.state_names, self.equations(precision)):
            print(f"({name})' = {eq}", **kwargs)

    def __repr__(self) -> str:
        n_terms = int(np.count_nonzero(self.correction_coef_))
        return (
            f"ExtendedModel(states={self.state_names}, inputs={self.input_names}, "
            f"correction_terms={n_terms})"
        )
