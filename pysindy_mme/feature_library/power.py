"""PowerLibrary: the function library of Kolodziej & Mook's Table I for pysindy.

Every library function is a product, over the input variables, of factors

.. math:: \\operatorname{sign}(x)^s \\, |x|^k, \\qquad s \\in \\{0, 1\\},

so ``x^i`` is ``(s, k) = (i mod 2, i)``, ``|x|^j`` is ``(0, j)`` and the
quadratic-drag shape ``x |x|`` is ``(1, 2)``. Two products are the same
function exactly when their ``(s, k)`` pairs agree in every variable, which is
how duplicates are recognised without numerical tests.
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable
from itertools import combinations

import numpy as np
from pysindy.feature_library.base import BaseFeatureLibrary, x_sequence_or_item
from pysindy.utils import AxesArray, comprehend_axes
from scipy import sparse
from sklearn.utils.validation import check_is_fitted

__all__ = ["PowerLibrary"]

_NONFINITE = ("keep", "nan", "zero")


def _check_int_tuple(value, name: str, *, odd: bool, allow_empty: bool):
    """Validate a sequence of distinct non-zero integer powers; return a tuple."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Iterable):
        raise TypeError(f"{name} must be a sequence of integers, got {value!r}")
    items = list(value)
    if not items and not allow_empty:
        raise ValueError(f"{name} must not be empty")
    out = []
    for item in items:
        if isinstance(item, (bool, np.bool_)) or not isinstance(item, numbers.Real):
            raise TypeError(f"{name} must contain integers, got {item!r}")
        if not np.isfinite(item) or int(item) != item:
            raise ValueError(f"{name} must contain integers, got {item!r}")
        item = int(item)
        if item == 0:
            raise ValueError(
                f"{name} must not contain 0 (x^0 is the constant; "
                "use include_constant=True)"
            )
        if odd and item % 2 == 0:
            raise ValueError(
                f"{name} must contain odd integers only (|x|^{item} is x^{item}), "
                f"got {item}"
            )
        out.append(item)
    if len(set(out)) != len(out):
        raise ValueError(f"{name} contains duplicates: {tuple(out)}")
    return tuple(out)


def _check_bool(value, name: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def _check_nonfinite(value) -> str:
    if not isinstance(value, str) or value not in _NONFINITE:
        raise ValueError(f"nonfinite must be one of {_NONFINITE}, got {value!r}")
    return value


def _factor_name(var: str, s: int, k: int) -> str:
    """Name of sign(var)^s |var|^k in pysindy's style ("x", "x^2", "|x|^-1")."""
    if s == k % 2:  # a plain signed power x^k
        return var if k == 1 else f"{var}^{k}"
    if s == 0:  # an odd absolute power
        return f"|{var}|" if k == 1 else f"|{var}|^{k}"
    # sign(x)|x|^k with k even: written x |x|^(k-1) or x^-1 |x|^(k+1), the
    # sign carried by the lowest power of x ("x |x|" for quadratic drag).
    i = 1 if k > 0 else -1
    return f"{_factor_name(var, 1, i)} {_factor_name(var, 0, k - i)}"


class PowerLibrary(BaseFeatureLibrary):
    """Signed and absolute integer powers and their products (paper's Table I).

    The columns, in this order, for input variables ``x0 ... x(n-1)`` (state
    columns first, then control inputs ``u``, which pysindy appends to ``x``
    and which are treated as further variables):

    1. ``1`` if ``include_constant``;
    2. single functions, grouped as in Table I: ``x_v^i`` for every variable
       ``v`` and ``i`` in ``powers``, then ``|x_v|^j`` for ``j`` in
       ``abs_powers``;
    3. same-variable products that are new functions (per variable):
       ``signed_abs_products`` adds ``x^i |x|^j`` (``i`` in ``powers``, ``j``
       in ``abs_powers``), ``power_products`` adds ``x^i x^j`` and
       ``|x|^i |x|^j`` (``i != j``). Rule: since ``x^i |x|^j = sign(x)^i
       |x|^(i+j)``, a product is kept only if it is a function not already in
       the library (``x^2 |x| = |x|^3`` is dropped; ``x |x|^3 = x^3 |x|`` is
       one column, named ``x |x|^3``: the sign rides on ``x^1`` or ``x^-1``),
       and products of total power 0, ``1`` and ``sign(x) = x |x|^-1``, are
       dropped, as Table I excludes the power 0. With the defaults these are, per
       variable, ``x^-1 |x|^-5, x^-1 |x|^-3, x^-1 |x|^-1, x |x|, x |x|^3,
       x |x|^5, |x|^-5, |x|^5`` and ``x^-5, x^-4, x^4, x^5`` (12);
    4. if ``cross_products``: for every pair of variables ``a < b``, every
       single function of ``x_a`` times every single function of ``x_b``.

    ``sign(x)`` (total power 0) is not offered, on purpose: it is the
    paper's excluded ``x^0`` family, and a jump is a physical effect (dry
    friction) better named as one, on the variable it acts on:
    :class:`~pysindy_mme.PhysicsLibrary` with ``[Coulomb("v")]`` (classes in
    :mod:`pysindy_mme.feature_library.effects`), concatenated with this
    library if both are wanted.

    With the defaults and ``n`` variables this is ``22 n + 100 n (n - 1) / 2``
    columns (+1 with the constant): 22 for one variable, **144 for two** and
    366 for three. With ``include_constant=True`` two variables give 145, the
    paper's count ("the number of possible model functions is 145"): the
    constant, the 20 functions of Table I and every distinct product of two of
    them except ``sign(x)`` (100 across the two variables, 24 within one).
    The paper's function numbers 1-20 (and the intercept 0) are the column
    indices here when ``include_constant=True``; its numbering of products is
    not published.

    Parameters
    ----------
    powers : sequence of int, default (-3, -2, -1, 1, 2, 3)
        Signed powers ``x^i``. Non-empty, distinct, no 0.
    abs_powers : sequence of int, default (-3, -1, 1, 3)
        Absolute powers ``|x|^j``. Distinct, odd (an even one equals a signed
        power), may be empty.
    cross_products : bool, default True
        Products of single functions of two different variables.
    signed_abs_products : bool, default True
        Same-variable products ``x^i |x|^j`` that are new functions (the
        quadratic-drag term ``x |x|`` is one).
    power_products : bool, default True
        Same-variable products ``x^i x^j`` and ``|x|^i |x|^j`` that are new
        functions (``x^-5, x^-4, x^4, x^5`` with the defaults).
    include_constant : bool, default False
        Add a column of ones first. Off by default because
        :class:`~pysindy_mme.FloatingFStepwise` fits the intercept itself; set
        it for optimizers such as pysindy's ``STLSQ``.
    nonfinite : {"keep", "nan", "zero"}, default "keep"
        What to do with non-finite values the library produces (``x^-1`` at
        ``x = 0``: ``inf``; ``0 * inf`` in a product: NaN; overflow: ``inf``).
        ``"keep"`` leaves them, so an optimizer can set such columns aside and
        say so; pysindy's own optimizers (``STLSQ`` ...) then refuse the
        library with scikit-learn's ``ValueError: Input X contains infinity``.
        ``"nan"`` turns every non-finite value into NaN. ``"zero"`` turns them
        into 0, which lets pysindy optimizers run and keeps ``predict`` and
        ``simulate`` finite where a term with a zero coefficient is singular
        (``0 * inf`` would be NaN); with ``"zero"`` a non-finite *input* raises
        ``ValueError`` instead of being hidden. The library never warns or
        raises because of singular values. Unlike the other parameters this
        one is read by :meth:`transform`, so it can be switched on a fitted
        model (e.g. before ``simulate``).

    Attributes
    ----------
    n_features_in_ : int
        Number of input variables (states plus control inputs).
    n_output_features_ : int
        Number of library columns.
    signs_ : ndarray of int, shape (n_output_features_, n_features_in_)
        ``s`` of each factor: column ``c`` is
        ``prod_v sign(x_v)**signs_[c, v] * |x_v|**exponents_[c, v]``.
    exponents_ : ndarray of int, shape (n_output_features_, n_features_in_)
        ``k`` of each factor (0 where a variable does not appear).

    Notes
    -----
    Negative powers are singular at 0: a model that uses one cannot be
    simulated through ``x = 0``, and with ``nonfinite="keep"`` even unused
    singular columns make ``predict`` NaN there (``0 * inf``). Values at
    exactly 0: ``x^-1`` is ``+inf`` at ``+0.0`` and ``-inf`` at ``-0.0``,
    ``|x|^-1`` is ``+inf``, ``sign(x)|x|^-2`` is ``+-inf`` like ``x^-1``.

    Examples
    --------
    >>> import numpy as np
    >>> from pysindy_mme import PowerLibrary
    >>> lib = PowerLibrary(powers=(1, 2), abs_powers=(1,)).fit(np.ones((3, 2)))
    >>> lib.get_feature_names(["x", "v"])  # doctest: +NORMALIZE_WHITESPACE
    ['x', 'x^2', 'v', 'v^2', '|x|', '|v|', 'x |x|', '|x|^3', 'x^3', 'v |v|',
     '|v|^3', 'v^3', 'x v', 'x v^2', 'x |v|', 'x^2 v', 'x^2 v^2', 'x^2 |v|',
     '|x| v', '|x| v^2', '|x| |v|']
    """

    def __init__(
        self,
        powers=(-3, -2, -1, 1, 2, 3),
        abs_powers=(-3, -1, 1, 3),
        cross_products=True,
        signed_abs_products=True,
        power_products=True,
        include_constant=False,
        nonfinite="keep",
    ):
        self.powers = powers
        self.abs_powers = abs_powers
        self.cross_products = cross_products
        self.signed_abs_products = signed_abs_products
        self.power_products = power_products
        self.include_constant = include_constant
        self.nonfinite = nonfinite

    # ------------------------------------------------------------------ fit
    def _function_table(self):
        """Validate the parameters; return the per-variable functions as (s, k).

        Returns ``(table, n_signed, n_single)``: ``table`` is an int array
        (q, 2) holding first the single functions (``powers`` then
        ``abs_powers``, as given), then the new same-variable products
        (signed-abs ones, then power ones, each sorted by ``k``).
        """
        powers = _check_int_tuple(self.powers, "powers", odd=False, allow_empty=False)
        abs_powers = _check_int_tuple(
            self.abs_powers, "abs_powers", odd=True, allow_empty=True
        )
        signed_abs = _check_bool(self.signed_abs_products, "signed_abs_products")
        power_prod = _check_bool(self.power_products, "power_products")
        singles = [(i % 2, i) for i in powers] + [(0, j) for j in abs_powers]
        known = set(singles)

        def new(candidates):
            # total power 0 is 1 or sign(x): excluded like x^0 in Table I
            found = {f for f in candidates if f[1] != 0 and f not in known}
            known.update(found)
            return sorted(found, key=lambda f: (f[1], f[0]))

        products = []
        if signed_abs:
            # x^i |x|^j = sign(x)^i |x|^(i+j)
            products += new((i % 2, i + j) for i in powers for j in abs_powers)
        if power_prod:
            pairs = list(combinations(powers, 2)) + list(combinations(abs_powers, 2))
            products += new(((a + b) % 2, a + b) for a, b in pairs)
        table = np.array(singles + products, dtype=int).reshape(-1, 2)
        return table, len(powers), len(singles)

    @staticmethod
    def _n_inputs(x_full) -> int:
        if any(sparse.issparse(x) for x in x_full):
            raise TypeError("x must be a dense array; PowerLibrary has no sparse path")
        shapes = [np.shape(x) for x in x_full]
        if any(len(shape) == 0 or shape[-1] == 0 for shape in shapes):
            raise ValueError(f"x must have at least one feature column, got {shapes}")
        n_inputs = {shape[-1] for shape in shapes}
        if len(n_inputs) != 1:
            raise ValueError(
                f"x: all trajectories must have the same number of features, "
                f"got {sorted(n_inputs)}"
            )
        return n_inputs.pop()

    @x_sequence_or_item
    def fit(self, x_full, y=None):
        """Validate the parameters and lay out the library columns.

        Parameters
        ----------
        x_full : array-like, shape (n_samples, n_features), or a list of them
            Data (only the number of features is used). pysindy passes the
            states with any control inputs appended as further columns.
        y : ignored

        Returns
        -------
        self : PowerLibrary
        """
        table, n_signed, n_single = self._function_table()
        cross = _check_bool(self.cross_products, "cross_products")
        constant = _check_bool(self.include_constant, "include_constant")
        _check_nonfinite(self.nonfinite)
        n = self._n_inputs(x_full)
        q = len(table)

        # Index into G.reshape(n * q, N) (G[v, f] = function f of variable v)
        # of every column that is one function of one variable, in output order.
        var_major = np.arange(n)[:, None] * q
        single_cols = np.concatenate(
            [
                (var_major + np.arange(n_signed)).ravel(),
                (var_major + np.arange(n_signed, n_single)).ravel(),
                (var_major + np.arange(n_single, q)).ravel(),
            ]
        )
        pairs = np.array(list(combinations(range(n), 2)) if cross else [], dtype=int)
        pairs = pairs.reshape(-1, 2)

        n_out = int(constant) + single_cols.size + len(pairs) * n_single**2
        signs = np.zeros((n_out, n), dtype=int)
        exponents = np.zeros((n_out, n), dtype=int)
        row = int(constant)
        for col in single_cols:
            v, f = divmod(int(col), q)
            signs[row, v], exponents[row, v] = table[f]
            row += 1
        for a, b in pairs:
            for fa in range(n_single):
                rows = slice(row, row + n_single)
                signs[rows, a], exponents[rows, a] = table[fa]
                signs[rows, b] = table[:n_single, 0]
                exponents[rows, b] = table[:n_single, 1]
                row += n_single

        self._sign_mask = table[:, 0].astype(bool)
        self._abs_exponent = table[:, 1].astype(float)
        self._single_cols = single_cols
        self._pairs = pairs
        self._n_single = n_single
        self._constant = constant
        self.signs_ = signs
        self.exponents_ = exponents
        self.n_features_in_ = n
        self.n_output_features_ = n_out
        return self

    # ------------------------------------------------------------ transform
    def _transform_one(self, x):
        mode = _check_nonfinite(self.nonfinite)
        if sparse.issparse(x):
            raise TypeError("x must be a dense array; PowerLibrary has no sparse path")
        try:
            arr = np.asarray(x, dtype=float)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"x must be a numeric array: {exc}") from None
        n = self.n_features_in_
        if arr.ndim == 0 or arr.shape[-1] != n:
            raise ValueError(
                f"x must have {n} feature columns (as in fit), got shape {arr.shape}"
            )
        if mode == "zero" and not np.all(np.isfinite(arr)):
            raise ValueError(
                "x contains NaN or inf; nonfinite='zero' only replaces values the "
                "library itself makes non-finite and would hide these"
            )
        lead = arr.shape[:-1]
        n_rows = int(np.prod(lead))
        xs = arr.reshape(n_rows, n)  # explicit: reshape(-1, n) fails on 0 rows
        m = self._n_single
        # Work feature-major, (column, sample): every product below is then a
        # contiguous row-by-row multiplication (several times faster than
        # broadcasting along the last axis of a sample-major array).
        out_t = np.empty((self.n_output_features_, n_rows), dtype=float)
        # Singular values (x^-1 at 0, 0 * inf, overflow) are expected results
        # here, handled by `nonfinite`, not errors: silence numpy's warnings.
        with np.errstate(all="ignore"):
            x_t = xs.T[:, None, :]  # (n, 1, N)
            G = np.power(np.abs(x_t), self._abs_exponent[:, None])  # (n, q, N)
            if self._sign_mask.any():
                # copysign keeps the sign of zero: x^-1 and x|x|^-3 agree at -0.0
                G[:, self._sign_mask] = np.copysign(G[:, self._sign_mask], x_t)
            col = 0
            if self._constant:
                out_t[0] = 1.0
                col = 1
            n_direct = self._single_cols.size
            flat = G.reshape(G.shape[0] * G.shape[1], n_rows)
            out_t[col : col + n_direct] = flat[self._single_cols]
            col += n_direct
            if len(self._pairs):
                np.multiply(
                    G[self._pairs[:, 0], :m, None, :],
                    G[self._pairs[:, 1], None, :m, :],
                    out=out_t[col:].reshape(len(self._pairs), m, m, n_rows),
                )
        out = out_t.T
        if mode != "keep":
            bad = ~np.isfinite(out)
            if bad.any():
                out[bad] = np.nan if mode == "nan" else 0.0
        out = out.reshape(*lead, self.n_output_features_)
        axes = x.axes if isinstance(x, AxesArray) else comprehend_axes(out)
        return AxesArray(out, axes)

    @x_sequence_or_item
    def transform(self, x_full):
        """Evaluate the library.

        Parameters
        ----------
        x_full : array-like, shape (..., n_features), or a list of them
            Data, features on the last axis (pysindy's convention).

        Returns
        -------
        xp : AxesArray, shape (..., n_output_features_), or a list of them
            Never raises or warns because of singular values; see
            ``nonfinite``.
        """
        check_is_fitted(self)
        return [self._transform_one(x) for x in x_full]

    # ---------------------------------------------------------------- names
    def get_feature_names(self, input_features=None):
        """Names of the columns, e.g. ``"x0^-1"``, ``"|x1|^3"``, ``"x0^2 x1"``.

        Parameters
        ----------
        input_features : list of str, length n_features_in_, optional
            Names of the inputs; default ``"x0", "x1", ...`` as in pysindy.

        Returns
        -------
        list of str, length n_output_features_
        """
        check_is_fitted(self)
        n = self.n_features_in_
        if input_features is None:
            input_features = [f"x{i}" for i in range(n)]
        input_features = [str(name) for name in input_features]
        if len(input_features) != n:
            raise ValueError(
                f"input_features must have {n} names, got {len(input_features)}"
            )
        names = []
        for s_row, k_row in zip(self.signs_, self.exponents_, strict=True):
            factors = [
                _factor_name(input_features[v], int(s_row[v]), int(k_row[v]))
                for v in range(n)
                if k_row[v] != 0 or s_row[v] != 0
            ]
            names.append(" ".join(factors) if factors else "1")
        return names
