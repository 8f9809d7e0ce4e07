"""A library the optimizer never holds whole: column blocks made on demand.

:class:`StreamedDesign` describes a library of ``n_columns`` functions on
``n_rows`` samples by a callable ``block(start, stop)`` that returns columns
``start:stop`` as an ``(n_rows, stop - start)`` array. Every pass of the
selection (the screen, then one product ``X^T v`` per step) asks for the
blocks one after the other, so the memory is one block (plus, in the state,
a few numbers per column and ``O(n_rows * k)`` for the ``k`` selected
columns), not the library. A ``dask.array`` is read the same way
(:meth:`StreamedDesign.from_dask`), and a pysindy polynomial library from
its inputs (:meth:`StreamedDesign.from_library` for a fitted library,
:meth:`StreamedDesign.polynomial` for one too wide to fit).

With a ``distributed.Client`` (``client=``) the per-block work of a pass
(the screen's column statistics, ``X^T v``) runs as Dask tasks on the
cluster: the callable is sent to the workers, each task makes its blocks
there and sends back only a few numbers per column. The blocks and the
arithmetic on them are the same as in the serial pass, so the results are
identical. Dask is imported only on that path (``pip install
pysindy-mme[distributed]``).
"""

from __future__ import annotations

import itertools
import numbers

import numpy as np

from ._checks import InvalidParameterError, check_data
from ._numeric import BLOCK_ELEMENTS, one_blas_thread
from .partial import check_partial_out

__all__ = ["StreamedDesign", "as_streamed", "check_library", "is_streamed"]

# Blocks of a pass sent to one Dask task: a task per block would cost more in
# scheduling (about a millisecond each) than the block's arithmetic.
BLOCKS_PER_TASK = 32


def is_streamed(x) -> bool:
    """Whether ``x`` is a :class:`StreamedDesign` (read by blocks, never whole)."""
    return isinstance(x, StreamedDesign)


def as_streamed(x):
    """``x`` as a :class:`StreamedDesign` if it is one or a ``dask.array``, else None.

    (A dask array is recognised by its type's module, so that dask is never
    imported here.)
    """
    if is_streamed(x):
        return x
    if type(x).__module__.split(".")[0] == "dask" and hasattr(x, "chunks"):
        return StreamedDesign.from_dask(x)
    return None


def check_library(x, y, sample_weight, feature_names):
    """``(x, y, w, feature_names)`` checked, for an array or a streamed library.

    An array goes through :func:`~._checks.check_data`. For a streamed one
    (:func:`as_streamed`) the targets and weights are checked the same way
    against a stand-in library of one zero column, so nothing of the library
    is read: rows whose targets are all NaN are dropped, and the design's
    with them. (Rows whose library values are all NaN cannot be seen without
    a pass; they make their columns non-finite, which the screen sets aside.)
    The design's names are the default ``feature_names``.
    """
    design = as_streamed(x)
    if design is None:
        x, y, w, _ = check_data(x, y, sample_weight)
        return x, y, w, feature_names
    _, y, w, kept = check_data(np.zeros((design.n_rows, 1)), y, sample_weight)
    if kept is not None:
        design = design.take_rows(kept)
    return design, y, w, design.names if feature_names is None else feature_names


def check_fit_inputs(x, y, sample_weight, feature_names, target_names, partial_out):
    """``(x, y, w, feature_names, nuisance)`` of ``FloatingFStepwise.fit``.

    The library, targets and weights as :func:`check_library` checks them
    (``partial_out`` needs an in-memory library: see
    :func:`with_partial_out`), and the names' counts against them.
    ``nuisance`` is None without ``partial_out``.
    """
    if partial_out is None:
        x, y, w, feature_names = check_library(x, y, sample_weight, feature_names)
        nuisance = None
    else:
        x, y, w, nuisance = with_partial_out(x, y, sample_weight, partial_out)
    for label, names, size, what in (
        ("feature_names", feature_names, x.shape[1], "x has"),
        ("target_names", target_names, y.shape[1], "y has"),
    ):
        if names is not None and len(names) != size:
            raise ValueError(
                f"{label} has {len(names)} names but {what} {size} columns"
            )
    return x, y, w, feature_names, nuisance


def with_partial_out(x_, y, sample_weight, partial_out):
    """``(x, y, w, nuisance)`` checked, the rows pysindy drops (all-NaN
    library or target rows) dropped from all four."""
    if as_streamed(x_) is not None:
        raise InvalidParameterError(
            "partial_out needs the library as an in-memory array; a streamed "
            "or dask design cannot be projected"
        )
    x, y, w, kept = check_data(x_, y, sample_weight)
    n_rows = x.shape[0] if kept is None else np.shape(x_)[0]
    nuisance = check_partial_out(partial_out, n_rows, y.shape[1])
    if kept is not None:
        nuisance = [n[kept] for n in nuisance]
    return x, y, w, nuisance


def _positive_int(value, name: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    if value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value}")
    return int(value)


class StreamedDesign:
    """A library given as column blocks generated on demand.

    Parameters
    ----------
    block : callable
        ``block(start, stop) -> array (n_rows, stop - start)``: library
        columns ``start:stop`` (real values; non-finite columns are set aside
        by the screen, as in an array). It is called several times for the
        same columns (once per pass) and must return the same values each
        time. With ``client`` it runs on the workers, so it must be picklable
        (cloudpickle: a lambda or closure is fine).
    n_rows, n_columns : int
        Shape of the library.
    block_columns : int, optional
        Columns per block; by default as many as keep a block near 8 MB of
        float64. The memory of a fit grows with it.
    names : sequence of str, optional
        Column names (``feature_names`` of ``fit`` when those are not given).
    client : distributed.Client, optional
        Run the per-block passes as Dask tasks on this client.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> base = rng.standard_normal((1000, 300))
    >>> pairs = np.array([(a, b) for a in range(300) for b in range(a, 300)])
    >>> design = StreamedDesign(
    ...     lambda i, j: base[:, pairs[i:j, 0]] * base[:, pairs[i:j, 1]],
    ...     n_rows=1000, n_columns=len(pairs))
    >>> FloatingFStepwise().fit(design, y)  # doctest: +SKIP
    """

    ndim = 2
    dtype = np.dtype(float)

    def __init__(
        self, block, n_rows, n_columns, *, block_columns=None, names=None, client=None
    ):
        if not callable(block):
            raise ValueError(
                f"block must be a callable block(start, stop), got {type(block)}"
            )
        self._block = block
        self.n_rows = _positive_int(n_rows, "n_rows")
        self.n_columns = _positive_int(n_columns, "n_columns")
        if block_columns is None:
            block_columns = max(1, BLOCK_ELEMENTS // self.n_rows)
        self.block_columns = _positive_int(block_columns, "block_columns")
        if names is not None:
            names = [str(s) for s in names]
            if len(names) != self.n_columns:
                raise ValueError(
                    f"names has {len(names)} entries but the design has "
                    f"{self.n_columns} columns"
                )
        self.names = names
        if client is not None and not hasattr(client, "submit"):
            raise ValueError(
                f"client must be a distributed.Client (with submit), got {client!r}"
            )
        self.client = client
        self._shipped = None  # (client, future of the callable on its workers)

    def __getstate__(self):
        # a copy or a pickle does not carry the client's future
        return {**self.__dict__, "_shipped": None}

    # ------------------------------------------------------------ the shape
    @property
    def shape(self):
        return (self.n_rows, self.n_columns)

    def __len__(self):
        return self.n_rows

    def __repr__(self):
        where = "" if self.client is None else ", on a Dask client"
        return (
            f"StreamedDesign({self.n_rows} rows x {self.n_columns} columns, "
            f"blocks of {self.block_columns}{where})"
        )

    def ranges(self):
        """``(start, stop)`` of the blocks of a pass, in column order."""
        step = self.block_columns
        return [
            (a, min(a + step, self.n_columns)) for a in range(0, self.n_columns, step)
        ]

    # ------------------------------------------------------------ the values
    def block(self, start: int, stop: int) -> np.ndarray:
        """Columns ``start:stop`` as a float array ``(n_rows, stop - start)``."""
        return _checked_block(self._block, self.n_rows, start, stop)

    def columns(self, cols) -> np.ndarray:
        """The columns ``cols`` (integer indices), in that order."""
        cols = np.atleast_1d(np.asarray(cols, dtype=np.intp))
        out = np.empty((self.n_rows, cols.size))
        if cols.size == 0:
            return out
        # one call per block that holds some of them
        blk = cols // self.block_columns
        for b in np.unique(blk):
            where = np.flatnonzero(blk == b)
            start = int(b) * self.block_columns
            stop = min(start + self.block_columns, self.n_columns)
            lo, hi = int(cols[where].min()), int(cols[where].max()) + 1
            if hi - lo < stop - start:
                start, stop = lo, hi  # only the span that is needed
            out[:, where] = self.block(start, stop)[:, cols[where] - start]
        return out

    def __getitem__(self, key):
        """``design[:, cols]`` (all rows, some columns), as for an array;
        ``design[mask]`` (a boolean mask of rows): :meth:`take_rows`."""
        if isinstance(key, np.ndarray) and key.dtype == bool and key.ndim == 1:
            return self.take_rows(np.flatnonzero(key))
        if not (
            isinstance(key, tuple)
            and len(key) == 2
            and isinstance(key[0], slice)
            and key[0] == slice(None)
        ):
            raise IndexError(
                "a StreamedDesign is indexed as design[:, columns] (all rows)"
            )
        cols = key[1]
        if isinstance(cols, slice):
            start, stop, step = cols.indices(self.n_columns)
            if step == 1:
                return self.block(start, max(start, stop))
            return self.columns(np.arange(start, stop, step))
        if np.ndim(cols) == 0:
            return self.columns([int(cols)])[:, 0]
        cols = np.asarray(cols)
        if cols.dtype == bool:
            cols = np.flatnonzero(cols)
        return self.columns(cols)

    def take_rows(self, rows) -> StreamedDesign:
        """The same library on the rows ``rows`` only (e.g. those of weight > 0)."""
        rows = np.asarray(rows, dtype=np.intp)
        return StreamedDesign(
            _RowsOf(self._block, rows),
            rows.size,
            self.n_columns,
            block_columns=self.block_columns,
            names=self.names,
            client=self.client,
        )

    # ----------------------------------------------------------- the passes
    def map_blocks(self, func, *args) -> list:
        """``[func(block, *args) for each block]`` in column order.

        Serially, or as Dask tasks on ``client`` (``args`` are sent to the
        workers once per pass). ``func`` must return small results (a few
        numbers per column): they are gathered here.
        """
        ranges = self.ranges()
        if self.client is None:
            with one_blas_thread():
                return [func(self.block(a, b), *args) for a, b in ranges]
        return _map_on_client(self, func, ranges, args)

    def xt(self, v) -> np.ndarray:
        """``X^T v`` by one pass over the blocks."""
        v = np.asarray(v, dtype=float)
        return np.concatenate(self.map_blocks(_block_xt, v))

    # -------------------------------------------------------- constructors
    @classmethod
    def from_dask(cls, array, *, names=None, client=None):
        """A ``dask.array`` library, read by its column chunks.

        Each block is ``array[:, start:stop].compute()`` (on the Dask
        scheduler in use, a ``distributed.Client`` if one is active).
        """
        if array.ndim != 2:
            raise ValueError(f"array must be 2-D, got shape {array.shape}")
        n, p = (int(s) for s in array.shape)
        widths = array.chunks[1]
        width = int(max(widths)) if len(widths) else 1
        return cls(
            _DaskBlocks(array),
            n,
            p,
            block_columns=width,
            names=names,
            client=client,
        )

    @classmethod
    def from_library(cls, library, x, *, block_columns=None, client=None):
        """A fitted pysindy ``PolynomialLibrary`` on the data ``x``, streamed.

        Column ``j`` is ``prod_i x[:, i] ** library.powers_[j, i]`` (pysindy's
        definition), made only when its block is read; the names are
        ``library.get_feature_names()``.
        """
        powers = getattr(library, "powers_", None)
        if powers is None:
            raise ValueError(
                "library must be a fitted pysindy PolynomialLibrary (with "
                "powers_): call library.fit(x) first"
            )
        x = np.asarray(x, dtype=float)
        powers = np.asarray(powers, dtype=int)
        if x.ndim != 2 or x.shape[1] != powers.shape[1]:
            raise ValueError(
                f"x must have {powers.shape[1]} columns (the library's inputs), "
                f"got shape {x.shape}"
            )
        return cls(
            _PowerBlocks(x, _PowerBlocks.from_powers(powers)),
            x.shape[0],
            powers.shape[0],
            block_columns=block_columns,
            names=list(library.get_feature_names()),
            client=client,
        )

    @classmethod
    def polynomial(
        cls, x, degree=2, *, include_bias=True, block_columns=None, client=None
    ):
        """pysindy's ``PolynomialLibrary(degree, include_bias)`` on ``x``, streamed.

        The same columns, order and names as the pysindy library (default
        options), without its ``powers_`` table: for a million columns of a
        thousand inputs that table alone is 11 GB, here a few numbers per
        column are kept.
        """
        x = np.asarray(x, dtype=float)
        if x.ndim != 2 or x.shape[1] == 0:
            raise ValueError(f"x must be 2-D with some columns, got shape {x.shape}")
        degree = _positive_int(degree, "degree")
        d = x.shape[1]
        factors = _polynomial_factors(d, degree, bool(include_bias))
        return cls(
            _PowerBlocks(x, factors),
            x.shape[0],
            factors.shape[0],
            block_columns=block_columns,
            names=[_factor_name(row, d) for row in factors],
            client=client,
        )


def _checked_block(make, n_rows: int, start: int, stop: int) -> np.ndarray:
    out = np.asarray(make(start, stop))
    if out.shape != (n_rows, stop - start):
        raise ValueError(
            f"block({start}, {stop}) returned shape {out.shape}, expected "
            f"{(n_rows, stop - start)}"
        )
    if np.iscomplexobj(out):
        raise ValueError(f"block({start}, {stop}) returned complex values")
    return np.asarray(out, dtype=float)


def _block_xt(block, v):
    with np.errstate(all="ignore"):  # non-finite columns are set aside later
        return block.T @ v


class _RowsOf:
    """``block`` restricted to some rows (picklable, unlike a closure)."""

    def __init__(self, block, rows):
        self.block, self.rows = block, rows

    def __call__(self, start, stop):
        return np.asarray(self.block(start, stop))[self.rows]


class _DaskBlocks:
    def __init__(self, array):
        self.array = array

    def __call__(self, start, stop):
        return np.asarray(self.array[:, start:stop].compute())


class _PowerBlocks:
    """Columns of a polynomial library from their factors.

    ``factors[j]`` lists the inputs whose product is column ``j`` (an input
    repeated by its power; the index ``d``, one past the inputs, reads a row
    of ones). A whole block is made by one gather and one product per slot.
    The inputs are kept as rows (``x.T``), so a gather copies contiguous rows
    and the block comes out in column-major order, as the passes read it.
    """

    def __init__(self, x, factors):
        n, _ = x.shape
        self.rows = np.vstack([x.T, np.ones((1, n))])
        self.factors = factors

    @staticmethod
    def from_powers(powers):
        """``factors`` of the columns with exponents ``powers`` (pysindy's)."""
        n_out, d = powers.shape
        degree = int(powers.sum(axis=1).max(initial=0))
        factors = np.full((n_out, max(degree, 1)), d, dtype=np.intp)
        for j, row in enumerate(powers):
            f = np.repeat(np.arange(d), row)
            factors[j, : f.size] = f
        return factors

    def __call__(self, start, stop):
        f = self.factors[start:stop]
        ones = self.rows.shape[0] - 1
        out = self.rows[f[:, 0]]
        for s in range(1, f.shape[1]):
            used = np.flatnonzero(f[:, s] != ones)
            if used.size == out.shape[0]:
                out *= self.rows[f[:, s]]
            elif used.size:
                out[used] *= self.rows[f[used, s]]
        return out.T


def _polynomial_factors(d: int, degree: int, include_bias: bool) -> np.ndarray:
    """Factors of pysindy's ``PolynomialLibrary`` columns, in its order.

    Degree by degree, and within a degree the combinations with replacement
    of the inputs in lexicographic order (pysindy's ``powers_`` order).
    """
    parts = [np.full((1, degree), d, dtype=np.intp)] if include_bias else []
    for k in range(1, degree + 1):
        combos = np.array(
            list(itertools.combinations_with_replacement(range(d), k)), dtype=np.intp
        ).reshape(-1, k)
        pad = np.full((combos.shape[0], degree - k), d, dtype=np.intp)
        parts.append(np.hstack([combos, pad]))
    return np.vstack(parts)


def _factor_name(row, d: int) -> str:
    """pysindy's name of a product: ``'x0^2 x1'``; ``'1'`` for the constant."""
    used = [int(i) for i in row if i != d]
    if not used:
        return "1"
    words = []
    for i in sorted(set(used)):
        power = used.count(i)
        words.append(f"x{i}" if power == 1 else f"x{i}^{power}")
    return " ".join(words)


def _run_task(make, n_rows, ranges, func, args):
    """One Dask task: several blocks of a pass, made and reduced on the worker."""
    with one_blas_thread():
        return [func(_checked_block(make, n_rows, a, b), *args) for a, b in ranges]


def _map_on_client(design, func, ranges, args):
    client = design.client
    # the arguments (vectors of n_rows) go to the workers once per pass
    shipped = [client.scatter(a, broadcast=True) for a in args]
    # the callable (maybe holding the data it makes columns from) once per
    # client, not once per pass
    cached = getattr(design, "_shipped", None)
    if cached is None or cached[0] is not client:
        design._shipped = (client, client.scatter(design._block, broadcast=True))
    make = design._shipped[1]
    groups = [
        ranges[i : i + BLOCKS_PER_TASK] for i in range(0, len(ranges), BLOCKS_PER_TASK)
    ]
    futures = [
        client.submit(_run_task, make, design.n_rows, g, func, shipped, pure=False)
        for g in groups
    ]
    out = []
    for part in client.gather(futures):
        out.extend(part)
    return out
