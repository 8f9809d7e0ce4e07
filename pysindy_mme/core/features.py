"""Fast evaluation of a few selected library columns.

Simulating an extended model calls its correction term at every integrator
stage on a handful of rows. A pysindy library's ``transform`` costs about a
millisecond per call whatever the row count, which makes a simulation of a
few hundred steps take seconds. Monomial-like feature names (``"x1^2 x2"``,
``"|x2|^-1"``, ``"x2 |x2|"``, ``"u"``, ``"1"``) say exactly how a column is
computed, so we parse them into products of powers and evaluate those
directly. A library that evaluates its own columns and their exact
derivatives (methods ``evaluate(z, indices)`` and ``gradient(z, indices)``,
as :class:`~pysindy_mme.PhysicsLibrary` has: duck typing, since ``core``
imports nothing from the rest of the package) is used directly instead of
parsing. Either fast evaluator is checked against ``transform`` on reference
data; any mismatch (or a name we cannot parse) falls back to ``transform``.
"""

from __future__ import annotations

import re

import numpy as np

from .jacobian import rowwise_jacobian

__all__ = ["SelectedFeatures"]

_FACTOR = re.compile(r"^(\|)?([^\s|^]+)(\|)?(?:\^(-?\d+))?$")


def _parse(name: str, variables: list) -> list | None:
    """``"x1^2 |x2|^-1"`` -> ``[(0, 2, False), (1, -1, True)]``; None if unknown."""
    if name.strip() == "1":
        return []
    factors = []
    for token in name.split(" "):
        match = _FACTOR.match(token)
        if match is None:
            return None
        bar_open, var, bar_close, power = match.groups()
        if bool(bar_open) != bool(bar_close) or var not in variables:
            return None
        factors.append((variables.index(var), int(power or 1), bool(bar_open)))
    return factors


def _has_own_evaluator(library) -> bool:
    """Whether the library evaluates chosen columns and their gradients itself."""
    return callable(getattr(library, "evaluate", None)) and callable(
        getattr(library, "gradient", None)
    )


def _exact_evaluation(library, z, indices):
    """``library.evaluate`` with its kinks exact where it can smooth them."""
    try:
        return library.evaluate(z, indices, exact=True)
    except TypeError:  # an evaluator without smoothing
        return library.evaluate(z, indices)


def _agrees(fast, slow) -> bool:
    """Fast values equal ``transform``'s to 1e-9 (relative), non-finite alike."""
    fast = np.asarray(fast, dtype=float)
    if fast.shape != slow.shape:
        return False
    ok = np.isfinite(slow)
    scale = np.maximum(np.abs(slow), 1.0)
    with np.errstate(invalid="ignore"):
        close = np.abs(fast - slow) <= 1e-9 * scale
    return bool(np.all(close[ok])) and np.array_equal(ok, np.isfinite(fast))


def _power(base, power: int):
    """``base ** power`` for a small integer power, by multiplication."""
    if power == 1:
        return base
    if power == 0:
        return np.ones_like(base)
    if power < 0:
        return 1.0 / _power(base, -power)
    out = base
    for _ in range(power - 1):
        out = out * base
    return out


#: rows per block when the fast paths are checked against ``transform``
_CHECK_ROWS = 1 << 16


class SelectedFeatures:
    """Evaluate columns ``indices`` of a fitted pysindy library on new data.

    Parameters
    ----------
    library : fitted pysindy feature library
    variables : list of str
        Names of the library's input columns (states, then inputs).
    indices : sequence of int
        The library columns wanted.
    z_reference : ndarray (n_samples, n_variables)
        Data on which the fast path is checked against ``library.transform``.
    """

    def __init__(self, library, variables, indices, z_reference):
        self.library = library
        self.variables = list(variables)
        self.indices = np.asarray(indices, dtype=int)
        names = library.get_feature_names(self.variables)
        self.names = [names[i] for i in self.indices]
        self._own = False  # the library's own evaluate/gradient are used
        z_reference = np.asarray(z_reference, dtype=float)
        if len(self.indices) and _has_own_evaluator(library):
            # the exact kinks: integrators get the library's smoothed ones
            # (PhysicsLibrary.smoothing), transform not
            self._own = self._agrees_on(
                z_reference,
                lambda z: _exact_evaluation(library, z, self.indices),
                (ValueError, TypeError, IndexError, AttributeError),
            )
        if self._own:
            self._factors = None
            # a tuple of ints: the library's cache of evaluation plans hashes
            # it directly (integrators call this at every stage)
            self._all = tuple(int(i) for i in self.indices)
            return
        parsed = [_parse(n, self.variables) for n in self.names]
        self._factors = None if any(p is None for p in parsed) else parsed
        if self._factors is not None and len(self.indices):
            if not self._agrees_on(z_reference, self._fast):
                self._factors = None

    def _agrees_on(self, z, fast, refused=()) -> bool:
        """Whether ``fast(z)`` equals ``transform``'s columns on all of ``z``
        (:func:`_agrees`); False if ``fast`` raises one of ``refused`` (an
        evaluator that cannot resolve the names: the other paths).

        Compared by blocks of rows: on a record of 10^6 samples the whole
        library, its selected copy and the comparison's temporaries were
        six library-sized arrays (460 MiB for a cubic library in two
        states), the peak of the study's proposal step.
        """
        for lo in range(0, max(z.shape[0], 1), _CHECK_ROWS):
            block = z[lo : lo + _CHECK_ROWS]
            try:
                with np.errstate(all="ignore"):
                    values = fast(block)
            except refused:
                return False
            if not _agrees(values, self._transform(block)):
                return False
        return True

    def overflow_columns(self) -> dict:
        """``{position: (variable, level)}`` of the library's overflow columns
        among ``indices`` (see ``PhysicsLibrary.overflow_columns``)."""
        own = getattr(self.library, "overflow_columns", None)
        if not callable(own):
            return {}
        found = own()
        return {k: found[int(c)] for k, c in enumerate(self.indices) if int(c) in found}

    @property
    def is_fast(self) -> bool:
        return self._own or self._factors is not None

    def _positions(self, chosen):
        """Library column numbers of the positions ``chosen`` of ``indices``."""
        return self.indices if chosen is None else self.indices[list(chosen)]

    def _fast(self, z, subset=None):
        chosen = range(len(self._factors)) if subset is None else subset
        out = np.empty((z.shape[0], len(chosen)))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            for j, k in enumerate(chosen):
                col = None
                for var, power, absolute in self._factors[k]:
                    term = _power(np.abs(z[:, var]) if absolute else z[:, var], power)
                    col = term if col is None else col * term
                out[:, j] = 1.0 if col is None else col
        return out

    def gradient(self, z, subset=None) -> np.ndarray:
        """``d column / d z`` for the chosen columns: ``(n_rows, n_cols, n_vars)``.

        Exact: the library's own ``gradient`` when it has one, the product
        rule on the parsed powers on the parsed path; central differences of
        the library otherwise.
        """
        z = np.atleast_2d(np.asarray(z, dtype=float))
        chosen = list(range(len(self.indices)) if subset is None else subset)
        out = np.zeros((z.shape[0], len(chosen), z.shape[1]))
        if not chosen:
            return out
        if self._own:
            return np.asarray(
                self.library.gradient(z, self._positions(chosen)), dtype=float
            )
        if self._factors is None:
            return rowwise_jacobian(lambda zz: self(zz, chosen), z)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            for j, k in enumerate(chosen):
                factors = self._factors[k]
                values = [
                    _power(np.abs(z[:, v]) if a else z[:, v], p) for v, p, a in factors
                ]
                for f, (var, power, absolute) in enumerate(factors):
                    base = np.abs(z[:, var]) if absolute else z[:, var]
                    d = power * _power(base, power - 1)
                    if absolute:
                        d = d * np.sign(z[:, var])
                    for g, other in enumerate(values):
                        if g != f:
                            d = d * other
                    out[:, j, var] += d
        return out

    def _transform(self, z):
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            theta = np.asarray(self.library.transform(np.asarray(z, dtype=float)))
        return theta[:, self.indices]

    def __call__(self, z, subset=None) -> np.ndarray:
        """Columns ``indices`` (or the positions ``subset`` of them) at ``z``."""
        z = np.atleast_2d(np.asarray(z, dtype=float))
        if len(self.indices) == 0 or (subset is not None and len(subset) == 0):
            return np.zeros((z.shape[0], 0))
        if self._own:
            columns = self._all if subset is None else self._positions(subset)
            return np.asarray(self.library.evaluate(z, columns), dtype=float)
        if self._factors is not None:
            return self._fast(z, subset)
        out = self._transform(z)
        return out if subset is None else out[:, list(subset)]
