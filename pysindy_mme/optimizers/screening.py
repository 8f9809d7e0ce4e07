"""Library screening: which columns can ever be selected, and why not.

Before selection starts, one blockwise pass over the library sets aside the
columns that can never be selected (non-finite values, all zero, a second
constant, collinear with the constant or with an earlier column, too large
or too small for double precision) with the reason for each, finds the
constant column that carries the intercept, and computes the weighted column
statistics the incremental QR state starts from.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ._numeric import (
    CACHE_BLOCK_ELEMENTS,
    column_blocks,
    one_blas_thread,
    pow2_scale,
    safe_ratio,
)
from .design import is_streamed

__all__ = ["Screen", "screen_columns", "xt"]

# Columns whose raw products x^T v could overflow (|x| * n beyond 2**1000) or
# whose values are deep in the subnormal range cannot be used reliably.
_HUGE = 2.0**1000
_TINY = 2.0**-960
# Columns whose largest magnitude is in this range are scaled after their
# sums of squares (exact there: no square leaves the double range).
_LATE_MIN = 2.0**-400
_LATE_MAX = 2.0**400
# Fixed random directions whose |products| with the unit centred columns
# must all agree for a pair to be checked for collinearity.
N_FINGERPRINTS = 2


@dataclass
class Screen:
    """Which library columns may be selected, and their weighted statistics."""

    carrier: int | None  # exactly constant column that carries the intercept
    carrier_value: float
    excluded: dict  # column -> reason
    eligible: np.ndarray  # bool (p,): may be selected
    mean: np.ndarray  # (p,) weighted column means
    cn2: np.ndarray  # (p,) squared norms of the centred weighted columns
    un2: np.ndarray  # (p,) squared norms of the weighted columns
    scale: np.ndarray  # (p,) power of two each column is multiplied by
    # (t, p) x^T v of the vectors ``products`` given to screen_columns (zero
    # where not eligible), where the screen's pass computed them; else None
    products: np.ndarray | None = None


def xt(x, v, eligible):
    """``x.T @ v`` with the columns that are not eligible (maybe non-finite) zeroed.

    ``x`` is an array or a :class:`~.design.StreamedDesign` (one pass over
    its blocks).
    """
    if is_streamed(x):
        out = x.xt(v)
    else:
        with np.errstate(all="ignore"):  # inf * 0 in set-aside columns
            out = x.T @ v
    return np.where(eligible, out, 0.0)


def _fingerprint_rows(n: int) -> np.ndarray:
    """Fixed random directions: collinear columns have equal |fingerprints|.

    The first is the one the screen has always used (it orders the pairs to
    check); the others only rule out pairs that the first lets through.
    """
    first = np.random.default_rng(20240601).standard_normal(n)
    more = np.random.default_rng(20260601).standard_normal((N_FINGERPRINTS - 1, n))
    return np.vstack([first, more])


def _block_statistics(B, w, sw, n_eff, G):
    """Column statistics of one block (see :func:`screen_columns`).

    Few passes over the block: its largest and smallest values (which also
    tell non-finite and exactly constant columns apart), one product for the
    weighted means, one for the centred squares and one for the fingerprints.
    The power-of-two scale is applied after the sums where that is exact
    (values of moderate magnitude), which gives the same digits as scaling
    first.
    """
    # Column-major: each column's passes run over contiguous memory (a
    # reduction down a row-major block of few columns is many times slower).
    B = np.asfortranarray(B, dtype=float)
    with np.errstate(invalid="ignore"):
        hi, lo = B.max(axis=0), B.min(axis=0)
    fin = np.isfinite(hi) & np.isfinite(lo)  # NaN and inf reach max or min
    if not np.all(fin):
        B = np.where(fin, B, 0.0)
        hi, lo = B.max(axis=0), B.min(axis=0)
    top = np.maximum(hi, -lo)
    sc = pow2_scale(top)
    exact_const = fin & (hi == lo)
    with np.errstate(over="ignore", invalid="ignore"):  # "huge" columns
        m = (w @ B) / n_eff
        C = np.subtract(B, m, order="F")  # centred: accurate for near-constants
    if not _unit_weights(sw):
        C *= sw[:, None]
    # Scaling after squaring is exact unless squares leave the double range.
    late = (top >= _LATE_MIN) & (top <= _LATE_MAX)
    if not np.all(late):
        C[:, ~late] *= sc[~late]
    with np.errstate(over="ignore", invalid="ignore"):
        cn2 = np.einsum("ij,ij->j", C, C)
        # one matrix-vector product per direction (the first as it always
        # was; a product with a few rows is much slower than that in BLAS)
        fprint = np.vstack([g @ C for g in G])
    # (the scale of a column scaled before squaring may square past the
    # double range: only the late columns' scales are squared)
    late_sc = np.where(late, sc, 1.0)
    cn2 = np.where(late, cn2 * late_sc**2, cn2)
    fprint = np.where(late, fprint * late_sc, fprint)
    # a copy: a view would keep the whole block alive with the statistics
    first = B[0].copy() if B.shape[0] else np.zeros(B.shape[1])
    return dict(
        finite=fin,
        exact_const=exact_const,
        max_abs=top,
        scale=sc,
        mean=m * sc,
        cn2=cn2,
        fprint=fprint,
        first=first,
    )


def _unit_weights(sw) -> bool:
    return bool(np.all(sw == 1.0))


def _row_chunk_statistics(x, w, sw, n_eff, G, V=None) -> dict:
    """:func:`_block_statistics` of a row-major array, in one fused pass.

    A wide array in row-major order is read once, by tiles of whole row
    segments (a few rows of a block of columns, small enough to stay in a
    core's cache while it is read four times): largest and smallest values,
    the raw weighted sums ``w^T x`` and ``w^T x^2`` and the raw fingerprint
    products ``(g * sw)^T x``. The blocks of columns are shared among the
    cores. The centred statistics then follow from the raw sums,

        ||sw (x - m)||^2 = w^T x^2 - m w^T x,  g^T (sw (x - m)) = (g sw)^T x - m g^T sw,

    which is accurate wherever the centred sum of squares is not much smaller
    than the raw one (at most ``2**-RAW_MAX_BITS_LOST`` of it: at most that
    many bits lost to cancellation). The other columns (near-constant,
    non-finite, all zero, or so large or small that squares could leave the
    double range) are read again by :func:`_centred_statistics`, the
    accurate two-pass arithmetic.

    ``V`` (t, n), optional: vectors whose raw products ``x^T v`` the same
    pass also computes (key ``"products"``, (t, p)).
    """
    n, p = x.shape
    unit = _unit_weights(sw)
    n_g = G.shape[0]
    M = np.vstack([w[None, :], G * sw] + ([] if V is None else [V]))
    hi, lo, ss, MR = _fused_pass(x, M, None if unit else w)
    total, raw_fprint = MR[0], MR[1 : 1 + n_g]
    fin = np.isfinite(hi) & np.isfinite(lo)
    # set-aside columns: any finite numbers (they are never used)
    hi, lo, total = (np.where(fin, v, 0.0) for v in (hi, lo, total))
    top = np.maximum(hi, -lo)
    sc = pow2_scale(top)
    with np.errstate(over="ignore", invalid="ignore"):
        m = total / n_eff
        raw_cn2 = ss - total * m
        late = (top >= _LATE_MIN) & (top <= _LATE_MAX)
        raw = fin & late & (raw_cn2 > ss * 2.0**-RAW_MAX_BITS_LOST)
        cn2 = np.where(raw, raw_cn2, 0.0)
        fprint = np.where(raw, raw_fprint - np.outer(G @ sw, m), 0.0)
    redo = np.flatnonzero(~raw)
    if redo.size:
        exact_cn2, exact_fprint = _centred_statistics(
            x, redo, fin, m, sw, unit, late, sc, G
        )
        cn2[redo] = exact_cn2
        fprint[:, redo] = exact_fprint
    # (only the late columns' scales are squared: an early one may square
    # past the double range)
    late_sc = np.where(late, sc, 1.0)
    return dict(
        finite=fin,
        exact_const=fin & (hi == lo),
        max_abs=top,
        scale=sc,
        mean=m * sc,
        cn2=cn2 * late_sc**2,
        fprint=fprint * late_sc,
        first=np.array(x[0], dtype=float) if n else np.zeros(p),
        products=None if V is None else MR[1 + n_g :],
    )


def _fused_pass(x, M, w):
    """Column extremes, ``M @ x`` and the weighted sums of squares of ``x``.

    ``w`` None: unit weights. One read of ``x`` (row-major), by tiles of
    ``rows x FUSED_BLOCK_COLUMNS``; the column blocks are shared among
    ``FUSED_WORKERS`` threads (numpy and BLAS release the GIL; BLAS itself
    runs on one thread meanwhile, see :func:`_column_statistics`).
    """
    n, p = x.shape
    # At least two blocks (one per core of a 2-core machine); the tiles do not
    # depend on the number of threads, so neither do the sums.
    width = max(1, min(FUSED_BLOCK_COLUMNS, -(-p // 2)))
    rows = max(1, CACHE_BLOCK_ELEMENTS // width)
    hi = np.full(p, -np.inf)
    lo = np.full(p, np.inf)
    ss = np.zeros(p)
    MR = np.zeros((M.shape[0], p))

    def block(start):
        cs = slice(start, min(start + width, p))
        h, lw, s, mr = hi[cs], lo[cs], ss[cs], MR[:, cs]  # views: written in place
        with np.errstate(over="ignore", invalid="ignore"):
            for a in range(0, n, rows):
                R = x[a : a + rows, cs]
                np.maximum(h, R.max(axis=0), out=h)  # NaN propagates
                np.minimum(lw, R.min(axis=0), out=lw)
                if w is None:
                    s += np.einsum("ij,ij->j", R, R)
                else:
                    s += w[a : a + rows] @ (R * R)
                mr += M[:, a : a + rows] @ R

    starts = range(0, p, width)
    workers = min(FUSED_WORKERS, len(starts))
    if workers > 1:
        with ThreadPoolExecutor(workers) as pool:
            list(pool.map(block, starts))
    else:
        for start in starts:
            block(start)
    return hi, lo, ss, MR


def _centred_statistics(x, cols, fin, m, sw, unit, late, sc, G):
    """Centred sums of squares and fingerprints of columns ``cols``, two-pass.

    The accurate arithmetic for the columns the raw sums cannot give (see
    :func:`_row_chunk_statistics`): each column minus its mean, weighted,
    and multiplied by its power-of-two scale first where the squares could
    leave the double range; by chunks of rows of ``x`` (row-major).
    Returns ``(cn2, fprint)`` before the late scaling.
    """
    n, p = x.shape
    every = cols.size == p
    m, fin, late, sc = m[cols], fin[cols], late[cols], sc[cols]
    early_scale = None if np.all(late) else np.where(late, 1.0, sc)
    all_fin = bool(np.all(fin))
    rows = max(ROW_CHUNK_MIN_ROWS, CACHE_BLOCK_ELEMENTS // p)
    cn2 = np.zeros(cols.size)
    fprint = np.zeros((G.shape[0], cols.size))
    with np.errstate(over="ignore", invalid="ignore"):
        for a in range(0, n, rows):
            c = slice(a, min(a + rows, n))
            R = x[c] if every else x[c][:, cols]
            if not all_fin:
                R = np.where(fin, R, 0.0)
            C = R - m
            if not unit:
                C *= sw[c, None]
            if early_scale is not None:
                C *= early_scale
            cn2 += np.einsum("ij,ij->j", C, C)
            fprint += G[:, c] @ C  # one read of the chunk for all directions
    return cn2, fprint


# At most this many vectors' products x^T v are computed in the screen's pass
# (each adds a row to its matrix product).
MAX_PRODUCTS = 8
# Row-major arrays at least this wide are screened by chunks of rows.
ROW_CHUNK_MIN_COLUMNS = 64
ROW_CHUNK_MIN_ROWS = 16
# The fused pass reads tiles of this many columns (times a few rows) ...
FUSED_BLOCK_COLUMNS = 4096
# ... on this many threads.
FUSED_WORKERS = max(1, min(2, os.cpu_count() or 1))
# The centred statistics come from the raw sums where cancellation loses at
# most this many bits (relative error below 2**(RAW_MAX_BITS_LOST - 52) times
# the rounding of the sums); the other columns are read again.
RAW_MAX_BITS_LOST = 6


def _column_statistics(x, w, sw, n_eff, G, V=None) -> dict:
    """:func:`_block_statistics` of every column, block by block."""
    n, p = x.shape
    if is_streamed(x):
        parts = x.map_blocks(_block_statistics, w, sw, n_eff, G)
    elif x.flags.c_contiguous and p >= ROW_CHUNK_MIN_COLUMNS:
        with one_blas_thread():
            return _row_chunk_statistics(x, w, sw, n_eff, G, V)
    else:
        with one_blas_thread():
            parts = [
                _block_statistics(x[:, blk], w, sw, n_eff, G)
                for blk in column_blocks(n, p, CACHE_BLOCK_ELEMENTS)
            ]
    return {
        key: np.concatenate([part[key] for part in parts], axis=-1) for key in parts[0]
    }


def screen_columns(x, sw, n_eff, tolerance, products=None) -> Screen:
    """Set aside columns that can never be selected; find the intercept carrier.

    Set aside: non-finite values, all-zero columns, constant columns other than
    the first (which carries the intercept), columns collinear with the
    constant, and columns collinear with an earlier column (exact duplicates
    included; the first one is kept), and columns too large or too small for
    double precision. One blockwise pass over ``x`` (an array or a
    :class:`~.design.StreamedDesign`), then the few candidate pairs of
    collinear columns are read again to be verified.

    All statistics refer to the columns multiplied by ``scale`` (a power of
    two per column bringing its largest magnitude into ``[0.5, 1)``).

    ``products`` (t, n), optional: vectors ``v`` whose products ``x^T v``
    (the unscaled columns; zero where not eligible) are wanted, such as the
    first step's ``X^T e``. The pass of a wide row-major array computes them
    for up to ``MAX_PRODUCTS`` vectors (:attr:`Screen.products`; None
    otherwise), saving a read of the array.
    """
    n, p = x.shape
    w = sw**2
    G = _fingerprint_rows(n)
    V = None
    if products is not None and len(products) <= MAX_PRODUCTS:
        V = np.asarray(products, dtype=float).reshape(-1, n)
    stats = _column_statistics(x, w, sw, n_eff, G, V)
    finite = stats["finite"]
    exact_const = stats["exact_const"]
    mean, cn2, max_abs, scale = (
        stats["mean"],
        stats["cn2"],
        stats["max_abs"],
        stats["scale"],
    )
    un2 = np.where(finite, cn2 + n_eff * mean**2, 0.0)
    allzero = finite & (un2 == 0)
    excluded = {}
    carrier = None
    carrier_value = 0.0
    for j in np.flatnonzero(~finite):
        excluded[int(j)] = "non-finite values"
    for j in np.flatnonzero(allzero):
        excluded[int(j)] = "all zero"
    huge = finite & (max_abs * max(n, 1) > _HUGE)
    tiny = finite & ~allzero & (max_abs < _TINY)
    for j in np.flatnonzero(huge):
        excluded[int(j)] = (
            f"values too large for double precision (max |value| "
            f"{max_abs[j]:.3g}); rescale the data"
        )
    for j in np.flatnonzero(tiny):
        excluded[int(j)] = (
            f"values too small for double precision (max |value| "
            f"{max_abs[j]:.3g}); rescale the data"
        )
    for j in np.flatnonzero(exact_const & ~allzero):
        if carrier is None:
            carrier = int(j)
            carrier_value = float(stats["first"][j])
        else:
            excluded[int(j)] = f"constant (the intercept is carried by f{carrier})"
    near_const = finite & ~allzero & ~exact_const & (cn2 <= tolerance**2 * un2)
    for j in np.flatnonzero(near_const):
        excluded[int(j)] = "collinear with the constant"
    ok = finite & ~allzero & ~exact_const & ~near_const & ~huge & ~tiny
    fprints = np.abs(safe_ratio(stats["fprint"], np.sqrt(cn2)))
    _set_aside_collinear(x, sw, G, fprints, ok, mean, scale, cn2, tolerance, excluded)
    eligible = ok.copy()
    eligible[list(excluded)] = False
    return Screen(
        carrier=carrier,
        carrier_value=carrier_value,
        excluded=dict(sorted(excluded.items())),
        eligible=eligible,
        mean=mean,
        cn2=np.where(eligible, cn2, 0.0),
        un2=np.where(eligible, un2, 0.0),
        scale=scale,
        products=(
            None
            if stats.get("products") is None
            else np.where(eligible, stats["products"], 0.0)
        ),
    )


def _pairs_within(a, window):
    """Index pairs ``(s, t)``, ``s < t``, with ``a[t] - a[s] <= window[s]`` (``a``
    sorted), in the order of a double loop over ``s`` then ``t``."""
    hi = np.searchsorted(a, a + window, side="right")
    counts = np.maximum(hi - np.arange(a.size) - 1, 0)
    s = np.repeat(np.arange(a.size), counts)
    start = np.cumsum(counts) - counts
    t = s + 1 + (np.arange(s.size) - np.repeat(start, counts))
    return s, t


def _set_aside_collinear(x, sw, G, fprints, ok, mean, scale, cn2, tol, excluded):
    """Add the columns collinear with an earlier one to ``excluded``.

    Collinear columns have equal |fingerprint| along every direction of
    ``G`` (within ``||g|| * 4 * tolerance``, plus rounding). Pairs close in
    the first fingerprint (sorted) are candidates; those the other
    fingerprints rule out could not pass the check either, so they are
    skipped (wide libraries have many near pairs in one fingerprint and
    almost none in two). Each remaining pair is verified on the centred
    columns, in the order of the first fingerprint.
    """
    idx = np.flatnonzero(ok)
    order = idx[np.argsort(fprints[0, idx], kind="stable")]
    a = fprints[0, order]
    g_norm = np.linalg.norm(G, axis=1)
    window = g_norm[0] * 4.0 * tol + 1e-9 * (1.0 + a)
    s_of, t_of = _pairs_within(a, window)
    for row in range(1, G.shape[0]):
        f = fprints[row]
        fs, ft = f[order[s_of]], f[order[t_of]]
        win = g_norm[row] * 4.0 * tol + 1e-9 * (1.0 + np.maximum(fs, ft))
        keep = np.abs(fs - ft) <= win
        s_of, t_of = s_of[keep], t_of[keep]
    current, skip = -1, False
    for s, t in zip(s_of.tolist(), t_of.tolist()):
        if s != current:
            current = s
            skip = int(order[s]) in excluded
        if skip:
            continue  # its partners are found from the column it repeats
        i, j = sorted((int(order[s]), int(order[t])))
        if j in excluded:
            continue
        pair = x[:, [i, j]]
        ui = (pair[:, 0] * scale[i] - mean[i]) * sw / np.sqrt(cn2[i])
        uj = (pair[:, 1] * scale[j] - mean[j]) * sw / np.sqrt(cn2[j])
        resid = uj - (ui @ uj) * ui
        if np.linalg.norm(resid) < tol:
            if np.array_equal(pair[:, 0], pair[:, 1]):
                excluded[j] = f"duplicate of f{i}"
            else:
                excluded[j] = f"collinear with f{i}"
