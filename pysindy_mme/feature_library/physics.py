"""PhysicsLibrary: a pysindy feature library of named physical effects.

The effects (Coulomb friction, saturation, Torricelli outflow ...) and a
worked example of each are in :mod:`pysindy_mme.feature_library.effects`;
this module lays their columns out as a pysindy library. Backlash is not
among them on purpose: it has memory (a hidden state), see ``effects``.

Beyond pysindy's ``fit``/``transform``/``get_feature_names`` the library
evaluates chosen columns and their exact derivatives directly
(:meth:`PhysicsLibrary.evaluate`, :meth:`PhysicsLibrary.gradient`): the
integrators of the extended model call them at every stage on a handful of
rows, where ``transform`` would cost a millisecond a call.

Kinks and integrators. ``transform`` (what a regression sees) is always the
exact effect. ``evaluate`` and ``gradient`` (what the integrators of the
study and of :class:`~pysindy_mme.ExtendedModel` see) smooth each kink over
a width of ``smoothing`` times the spread (sd) of its variable in the data
the library was fitted on: ``sign`` becomes ``tanh``, ``max(s, 0)`` a
softplus (see :mod:`.effects`). Why: a jump in the right-hand side makes
the flow over an integration step jump with its start state, so an
output-error fit (a trajectory that must join from step to step) has no
consistent linearisation there and stalls, and a sticking slide chatters.
A positioning axis with Coulomb friction 20 N: exact ``sign(v)``, the fit
did not converge in 50 iterations; smoothed over 0.1 % of the velocity's
spread, it converged to Coulomb 20.09 N and offset 2.99 N (truth 20, 3).
The study refits at half the width to show the width does not move the
result, and reports it. ``smoothing=0`` keeps the exact kinks everywhere.
"""

from __future__ import annotations

import operator
from collections.abc import Sequence

import numpy as np
from pysindy.feature_library.base import BaseFeatureLibrary, x_sequence_or_item
from pysindy.utils import AxesArray, comprehend_axes
from scipy import sparse
from sklearn.utils.validation import check_is_fitted

from .effects import Effect, Overflow

__all__ = ["PhysicsLibrary"]


def _label(effect: Effect) -> str:
    return f"{type(effect).__name__}({effect.variable!r})"


class PhysicsLibrary(BaseFeatureLibrary):
    """Columns of physical effects, each on the variable the user chooses.

    The columns, in this order: ``1`` if ``include_bias``, then each
    effect's columns in the order the effects are given (an effect with
    several ``levels`` gives one column per level, in their order). A
    variable that no effect names appears in no column.

    Parameters
    ----------
    effects : sequence of Effect
        E.g. ``[Coulomb("v"), ViscousSplit("v"), Saturation("u", [1, 2])]``
        (classes in :mod:`pysindy_mme.feature_library.effects`). May be empty
        only with ``include_bias=True``.
    include_bias : bool, default False
        Add a column of ones first (``"1"``, as pysindy's libraries do): a
        constant force or offset. Off by default because
        :class:`~pysindy_mme.FloatingFStepwise` fits the intercept itself and
        because a ``PolynomialLibrary`` concatenated with this one has its
        own; set it for ``STLSQ`` and the like used alone.
    names : sequence of str, optional
        Names of the library's input columns (states, then inputs), against
        which effects given by name are resolved. Without it, names are
        resolved against the ``input_features`` given to
        :meth:`get_feature_names`, and :meth:`transform` needs every effect
        given by column index (or a copy from :meth:`with_names`). Inside a
        ``GeneralizedLibrary`` with ``inputs_per_library``, indices and
        ``names`` refer to the columns this library receives.
    smoothing : float, default 1e-3
        Width of the kinks as integrators see them (:meth:`evaluate`,
        :meth:`gradient`), relative to the sd of each effect's variable in
        the data given to :meth:`fit`; 0 keeps them exact. :meth:`transform`
        is always exact. See the module notes.

    Attributes
    ----------
    n_features_in_ : int
        Number of input columns (states plus control inputs).
    n_output_features_ : int
        Number of library columns.
    variables_ : list of (int or None)
        Column index of each effect's variable; None for a name that could
        not be resolved (no ``names``).
    widths_ : ndarray (n_output_features_,)
        Smoothing width of each column in its variable's units (0 for the
        bias and smooth columns, and for all with ``smoothing=0``).

    Examples
    --------
    >>> import numpy as np
    >>> from pysindy_mme import PhysicsLibrary
    >>> from pysindy_mme.feature_library import Coulomb, Saturation, ViscousSplit
    >>> lib = PhysicsLibrary([Coulomb("v"), ViscousSplit("v"), Saturation("u", 2)],
    ...                      include_bias=True, names=["q", "v", "u"])
    >>> lib.fit(np.zeros((4, 3))).get_feature_names()
    ['1', 'sign(v)', 'v+', 'v-', 'sat(u, 2)']
    >>> lib.transform(np.array([[0.0, -0.5, 3.0]]))
    AxesArray([[ 1. , -1. ,  0. , -0.5,  2. ]])
    """

    def __init__(self, effects, include_bias=False, names=None, smoothing=1e-3):
        self.effects = effects
        self.include_bias = include_bias
        self.names = names
        self.smoothing = smoothing
        # Stored as given (scikit-learn's clone compares them by identity);
        # checked here too, so that a typo fails at construction.
        self._check_params()

    # ------------------------------------------------------------ checks
    def _check_params(self):
        """Validate the parameters; return ``(effects, names)`` as lists."""
        effects = self.effects
        if isinstance(effects, Effect) or not isinstance(effects, Sequence):
            raise TypeError(
                "effects must be a list of effects (Coulomb('v'), ...), "
                f"got {effects!r}"
            )
        effects = list(effects)
        for i, effect in enumerate(effects):
            if not isinstance(effect, Effect):
                raise TypeError(
                    f"effects[{i}] must be an effect (Coulomb, SmoothCoulomb, "
                    "Stribeck, ViscousSplit, Saturation, DeadZone, Torricelli, "
                    f"Overflow), got {effect!r}"
                )
        if not isinstance(self.include_bias, (bool, np.bool_)):
            raise TypeError(
                f"include_bias must be True or False, got {self.include_bias!r}"
            )
        smoothing = self.smoothing
        if (
            isinstance(smoothing, (bool, np.bool_))
            or not isinstance(smoothing, (int, float, np.number))
            or not np.isfinite(smoothing)
            or smoothing < 0
        ):
            raise ValueError(
                "smoothing must be a number >= 0 (a width relative to each "
                f"variable's spread; 0 keeps kinks exact), got {smoothing!r}"
            )
        if not effects and not self.include_bias:
            raise ValueError(
                "effects is empty and include_bias is False: the library would "
                "have no columns"
            )
        names = self.names
        if names is not None:
            if isinstance(names, str) or not isinstance(names, Sequence | np.ndarray):
                raise TypeError(f"names must be a list of str, got {names!r}")
            names = list(names)
            if not all(isinstance(n, str) and n for n in names):
                raise TypeError(f"names must be non-empty strings, got {names!r}")
            if len(set(names)) != len(names):
                raise ValueError(f"names contains duplicates: {names}")
            for effect in effects:
                self._index(effect, names, len(names), "names")
        return effects, names

    @staticmethod
    def _index(effect, names, n, source):
        """Column index of ``effect``'s variable (None if not resolvable)."""
        var = effect.variable
        if isinstance(var, str):
            if names is None:
                return None
            if var not in names:
                raise ValueError(
                    f"{source} has no variable {var!r} (effect {_label(effect)}); "
                    f"{source} are {list(names)}"
                )
            return list(names).index(var)
        if var >= n:
            raise ValueError(
                f"variable {var} of effect {_label(effect)} is out of range: "
                f"the library has {n} input columns (0 to {n - 1})"
            )
        return var

    def _layout(self, effects):
        """``[(effect number, effect, k)]`` per column; ``(None, None, 0)`` bias."""
        cols = [(None, None, 0)] if self.include_bias else []
        for i, effect in enumerate(effects):
            cols += [(i, effect, k) for k in range(effect.n_columns)]
        return cols

    # --------------------------------------------------------------- fit
    @staticmethod
    def _n_inputs(x_full) -> int:
        if any(sparse.issparse(x) for x in x_full):
            raise TypeError(
                "x must be a dense array; PhysicsLibrary has no sparse path"
            )
        shapes = [np.shape(x) for x in x_full]
        if any(len(shape) == 0 or shape[-1] == 0 for shape in shapes):
            raise ValueError(f"x must have at least one feature column, got {shapes}")
        widths = {shape[-1] for shape in shapes}
        if len(widths) != 1:
            raise ValueError(
                "x: all trajectories must have the same number of features, "
                f"got {sorted(widths)}"
            )
        return widths.pop()

    @x_sequence_or_item
    def fit(self, x_full, y=None):
        """Check the effects against the data and lay out the columns.

        Parameters
        ----------
        x_full : array-like, shape (n_samples, n_features), or a list of them
            Data (only the number of features is used): states, then any
            control inputs pysindy appends.
        y : ignored

        Returns
        -------
        self : PhysicsLibrary
        """
        effects, names = self._check_params()
        n = self._n_inputs(x_full)
        if names is not None and len(names) != n:
            raise ValueError(
                f"names has {len(names)} names {names} but x has {n} feature columns"
            )
        variables = [self._index(e, names, n, "names") for e in effects]
        columns = self._layout(effects)
        # the same column twice (Coulomb("v") and Coulomb(1)) is singular in
        # any regression: refuse it here rather than in the optimizer
        seen = {}
        for i, effect, k in columns:
            if effect is None:
                continue
            var = variables[i]
            key = effect.column_name(
                f"#{var}" if var is not None else repr(effect.variable), k
            )
            if key in seen:
                column = effect.column_name(str(effect.variable), k)
                raise ValueError(
                    f"effects: {_label(effect)} repeats a column of "
                    f"{_label(seen[key])} ({column})"
                )
            seen[key] = effect
        self.variables_ = variables
        self._columns = [
            (None, 0, 0) if e is None else (e, k, variables[i]) for i, e, k in columns
        ]
        self.widths_ = self._widths(x_full, n)
        self._plans = {}  # evaluation plans of the previous fit are stale
        self.n_features_in_ = n
        self.n_output_features_ = len(columns)
        return self

    def _widths(self, x_full, n) -> np.ndarray:
        """Each column's smoothing width: ``smoothing`` x its variable's sd."""
        widths = np.zeros(len(self._columns))
        if self.smoothing == 0:
            return widths
        rows = np.concatenate(
            [np.asarray(x, dtype=float).reshape(-1, n) for x in x_full]
        )
        for j, (effect, _, var) in enumerate(self._columns):
            if effect is None or not effect.nonsmooth or var is None:
                continue
            values = rows[:, var][np.isfinite(rows[:, var])]
            spread = float(np.std(values)) if values.size else 0.0
            # a constant variable has no spread to measure: its kink is not
            # crossed in the data, so any small width will do
            widths[j] = self.smoothing * (spread if spread > 0 else 1.0)
        return widths

    # ---------------------------------------------------------- evaluate
    def _fitted_columns(self, indices):
        """The ``(effect, k, variable)`` of each wanted column, checked."""
        columns = self.__dict__.get("_columns")
        if columns is None:
            check_is_fitted(self)  # raises NotFittedError with sklearn's text
        if indices is None:
            chosen = columns
        else:
            try:
                chosen = [columns[operator.index(i)] for i in indices]
            except IndexError:
                raise IndexError(
                    f"indices must be column numbers below {len(columns)}, "
                    f"got {list(indices)}"
                ) from None
        for effect, _, var in chosen:
            if effect is not None and var is None:
                raise ValueError(
                    f"effect {_label(effect)} names its variable, but the library "
                    "has no names to resolve it: pass names= to PhysicsLibrary "
                    "(the states then inputs), give the variable as a column "
                    "index, or use lib.with_names(names)"
                )
        return chosen

    def _rows(self, z) -> np.ndarray:
        z = np.asarray(z, dtype=float)
        if z.ndim == 1:
            z = z[None, :]
        if z.ndim != 2 or z.shape[1] != self.n_features_in_:
            raise ValueError(
                f"z must have shape (n_rows, {self.n_features_in_}) (states then "
                f"inputs), got {z.shape}"
            )
        return z

    def evaluate(self, z, indices=None, exact=False) -> np.ndarray:
        """Library columns ``indices`` at the rows of ``z``.

        Parameters
        ----------
        z : array-like, shape (n_rows, n_features_in_)
            States then inputs (the library's input columns).
        indices : sequence of int, optional
            Library columns (default all).
        exact : bool, default False
            Exact kinks (as :meth:`transform`) instead of the smoothed ones
            integrators use (``widths_``).

        Returns
        -------
        ndarray, shape (n_rows, len(indices))
        """
        chosen, widths = self._plan(indices, exact)
        return self._values(chosen, self._rows(z), widths)

    def _plan(self, indices, exact):
        """The checked columns and widths for ``indices``, cached per fit:
        integrators ask for the same few columns at every stage."""
        cache = self.__dict__.setdefault("_plans", {})
        if indices is None or isinstance(indices, tuple):
            key = (indices, exact)  # integrators pass a tuple: hashed as it is
        else:
            key = (tuple(int(i) for i in indices), exact)
        plan = cache.get(key)
        if plan is None:
            chosen = self._fitted_columns(indices)
            widths = None if exact else self._chosen_widths(indices)
            plan = cache[key] = (chosen, widths)
        return plan

    def _chosen_widths(self, indices):
        widths = self.__dict__.get("widths_")
        if widths is None:  # fitted before widths existed: exact
            return None
        return widths if indices is None else widths[np.asarray(indices, dtype=int)]

    @staticmethod
    def _values(chosen, z, widths=None) -> np.ndarray:
        # transform's path too (exact: widths None)
        out = np.empty((z.shape[0], len(chosen)))
        for j, (effect, k, var) in enumerate(chosen):
            w = 0.0 if widths is None else float(widths[j])
            out[:, j] = 1.0 if effect is None else effect.value(z[:, var], k, w)
        return out

    def gradient(self, z, indices=None, exact=False) -> np.ndarray:
        """Derivatives of columns ``indices`` (as :meth:`evaluate` gives them).

        Of the smoothed columns, or with ``exact=True`` of the exact ones,
        which hold almost everywhere: ``sign`` has derivative 0, a kink
        takes its one-sided value from above, Torricelli's infinite slope at
        0 is 0 (see :mod:`~pysindy_mme.feature_library.effects`).

        Returns
        -------
        ndarray, shape (n_rows, len(indices), n_features_in_)
            Nonzero only in each column's own variable.
        """
        chosen, widths = self._plan(indices, exact)
        z = self._rows(z)
        out = np.zeros((z.shape[0], len(chosen), z.shape[1]))
        for j, (effect, k, var) in enumerate(chosen):
            if effect is not None:
                w = 0.0 if widths is None else float(widths[j])
                out[:, j, var] = effect.derivative(z[:, var], k, w)
        return out

    def switching(self, z, indices=None) -> np.ndarray:
        """Switching function of each column: it changes sign at the kinks.

        ``v`` for ``sign(v)``, ``h1 - 10`` for ``over(h1, 10)``, ``|u| - L``
        for ``sat(u, L)``; ones (never zero) for smooth columns and the bias.
        Finite wherever ``z`` is.

        Returns
        -------
        ndarray, shape (n_rows, len(indices))
        """
        chosen = self._fitted_columns(indices)
        z = self._rows(z)
        out = np.ones((z.shape[0], len(chosen)))
        for j, (effect, k, var) in enumerate(chosen):
            if effect is not None:
                out[:, j] = effect.switching(z[:, var], k)
        return out

    def overflow_columns(self) -> dict:
        """``{column: (variable, level)}`` of the :class:`Overflow` columns.

        An integrator solves these exactly where the variable is a state
        (:mod:`~pysindy_mme.core.relaxation`): a wall that keeps a tank
        below its rim is the limit of ever larger coefficients, which RK4 on
        the whole right-hand side cannot follow.
        """
        columns = self.__dict__.get("_columns")
        if columns is None:
            check_is_fitted(self)
        return {
            j: (int(var), float(effect.levels[k]))
            for j, (effect, k, var) in enumerate(columns)
            if isinstance(effect, Overflow) and var is not None
        }

    # -------------------------------------------------------- smoothness
    @property
    def has_kinks(self) -> bool:
        """Whether any column has a kink or a jump."""
        effects, _ = self._check_params()
        return any(effect.nonsmooth for effect in effects)

    def kinked_columns(self, indices=None) -> list:
        """The columns among ``indices`` (default all) that are not smooth."""
        effects, _ = self._check_params()
        columns = self._layout(effects)
        chosen = range(len(columns)) if indices is None else indices
        out = []
        for i in chosen:
            i = operator.index(i)
            if not 0 <= i < len(columns):
                raise IndexError(
                    f"indices must be column numbers below {len(columns)}, got {i}"
                )
            effect = columns[i][1]
            if effect is not None and effect.nonsmooth:
                out.append(i)
        return out

    # --------------------------------------------------------- transform
    def _transform_one(self, x):
        if sparse.issparse(x):
            raise TypeError(
                "x must be a dense array; PhysicsLibrary has no sparse path"
            )
        try:
            arr = np.asarray(x, dtype=float)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"x must be a numeric array: {exc}") from None
        n = self.n_features_in_
        if arr.ndim == 0 or arr.shape[-1] != n:
            raise ValueError(
                f"x must have {n} feature columns (as in fit), got shape {arr.shape}"
            )
        lead = arr.shape[:-1]
        rows = arr.reshape(int(np.prod(lead)), n)  # explicit: 0 rows reshape too
        out = self._values(self._fitted_columns(None), rows)
        out = out.reshape(*lead, self.n_output_features_)
        axes = x.axes if isinstance(x, AxesArray) else comprehend_axes(out)
        return AxesArray(out, axes)

    @x_sequence_or_item
    def transform(self, x_full):
        """Evaluate every column.

        Parameters
        ----------
        x_full : array-like, shape (..., n_features), or a list of them
            Data, features on the last axis (pysindy's convention).

        Returns
        -------
        xp : AxesArray, shape (..., n_output_features_), or a list of them
        """
        check_is_fitted(self)
        self._fitted_columns(None)  # unresolved names: say so before any work
        return [self._transform_one(x) for x in x_full]

    # ------------------------------------------------------------- names
    def get_feature_names(self, input_features=None):
        """Names of the columns: ``"1"``, ``"sign(v)"``, ``"sat(u, 2)"`` ...

        Parameters
        ----------
        input_features : list of str, length n_features_in_, optional
            Names of the inputs (pysindy passes its ``feature_names``); they
            label the columns and resolve effects given by name when the
            library has no ``names``. Default: ``names``, else ``"x0",
            "x1", ...`` (an unresolved name is then shown as given).

        Returns
        -------
        list of str, length n_output_features_
        """
        check_is_fitted(self)
        n = self.n_features_in_
        names = None if self.names is None else list(self.names)
        if input_features is not None:
            labels = [str(name) for name in input_features]
            if len(labels) != n:
                raise ValueError(
                    f"input_features must have {n} names, got {len(labels)}"
                )
        else:
            labels = names if names is not None else [f"x{i}" for i in range(n)]
        out = []
        for effect, k, var in self._columns:
            if effect is None:
                out.append("1")
                continue
            name = effect.variable
            if isinstance(name, str) and input_features is not None:
                if var is None:
                    var = self._index(effect, labels, n, "input_features")
                elif name in labels and labels.index(name) != var:
                    raise ValueError(
                        f"names and input_features disagree on {name!r} (effect "
                        f"{_label(effect)}): column {var} in names, "
                        f"{labels.index(name)} in input_features"
                    )
            out.append(effect.column_name(name if var is None else labels[var], k))
        return out

    def with_names(self, names):
        """A copy (unfitted) whose effects given by name resolve against ``names``.

        Parameters
        ----------
        names : sequence of str
            The library's input columns, states then inputs.

        Returns
        -------
        PhysicsLibrary
        """
        params = self.get_params(deep=False)
        params["effects"] = list(self.effects)
        params["names"] = list(names) if not isinstance(names, str) else names
        return type(self)(**params)
