"""Library screening: which columns can ever be selected, and why not.

Before selection starts, one blockwise pass over the library sets aside the
columns that can never be selected (non-finite values, all zero, a second
constant, collinear with the constant or with an earlier column, too large
or too small for double precision) with the reason for each, finds the
constant column that carries the intercept, and computes the weighted column
statistics the incremental QR state starts from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._numeric import column_blocks, pow2_scale, safe_ratio

__all__ = ["Screen", "screen_columns", "xt"]

# Columns whose raw products x^T v could overflow (|x| * n beyond 2**1000) or
# whose values are deep in the subnormal range cannot be used reliably.
_HUGE = 2.0**1000
_TINY = 2.0**-960


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


def xt(x, v, eligible):
    """``x.T @ v`` with the columns that are not eligible (maybe non-finite) zeroed."""
    with np.errstate(all="ignore"):  # inf * 0 in set-aside columns
        out = x.T @ v
    return np.where(eligible, out, 0.0)


def screen_columns(x, sw, n_eff, tolerance) -> Screen:
    """Set aside columns that can never be selected; find the intercept carrier.

    Set aside: non-finite values, all-zero columns, constant columns other than
    the first (which carries the intercept), columns collinear with the
    constant, and columns collinear with an earlier column (exact duplicates
    included; the first one is kept), and columns too large or too small for
    double precision. One blockwise pass over ``x``.

    All statistics refer to the columns multiplied by ``scale`` (a power of
    two per column bringing its largest magnitude into ``[0.5, 1)``).
    """
    n, p = x.shape
    w = sw**2
    finite = np.ones(p, dtype=bool)
    exact_const = np.zeros(p, dtype=bool)
    mean = np.zeros(p)
    cn2 = np.zeros(p)
    fprint = np.zeros(p)
    max_abs = np.zeros(p)
    scale = np.ones(p)
    # A fixed random direction: collinear columns have equal |fingerprint|.
    g = np.random.default_rng(20240601).standard_normal(n)
    for blk in column_blocks(n, p):
        B = x[:, blk]
        fin = np.all(np.isfinite(B), axis=0)
        finite[blk] = fin
        if not np.all(fin):
            B = np.where(fin, B, 0.0)
        top = np.maximum(B.max(axis=0), -B.min(axis=0))
        sc = pow2_scale(top)
        max_abs[blk] = top
        scale[blk] = sc
        exact_const[blk] = fin & np.all(B == B[:1], axis=0)
        with np.errstate(over="ignore", invalid="ignore"):  # "huge" columns
            m = (w @ B) / n_eff
            C = B - m  # centred: accurate for near-constants
        C *= sw[:, None]
        C *= sc  # scaled before squaring (exact: powers of two)
        mean[blk] = m * sc
        cn2[blk] = np.einsum("ij,ij->j", C, C)
        fprint[blk] = g @ C
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
            carrier_value = float(x[0, j])
        else:
            excluded[int(j)] = f"constant (the intercept is carried by f{carrier})"
    near_const = finite & ~allzero & ~exact_const & (cn2 <= tolerance**2 * un2)
    for j in np.flatnonzero(near_const):
        excluded[int(j)] = "collinear with the constant"
    ok = finite & ~allzero & ~exact_const & ~near_const & ~huge & ~tiny
    fprint = np.abs(safe_ratio(fprint, np.sqrt(cn2)))

    # Pairwise collinearity: candidate pairs have close fingerprints (within
    # ||g|| * 4 * tolerance, plus rounding); each candidate pair is then
    # verified on the centred columns.
    idx = np.flatnonzero(ok)
    order = idx[np.argsort(fprint[idx], kind="stable")]
    a = fprint[order]
    window = np.linalg.norm(g) * 4.0 * tolerance + 1e-9 * (1.0 + a)
    hi = np.searchsorted(a, a + window, side="right")
    for s in np.flatnonzero(hi > np.arange(a.size) + 1):
        if int(order[s]) in excluded:
            continue  # its partners are found from the column it repeats
        for t in range(s + 1, hi[s]):
            i, j = sorted((int(order[s]), int(order[t])))
            if j in excluded:
                continue
            ui = (x[:, i] * scale[i] - mean[i]) * sw / np.sqrt(cn2[i])
            uj = (x[:, j] * scale[j] - mean[j]) * sw / np.sqrt(cn2[j])
            resid = uj - (ui @ uj) * ui
            if np.linalg.norm(resid) < tolerance:
                if np.array_equal(x[:, i], x[:, j]):
                    excluded[j] = f"duplicate of f{i}"
                else:
                    excluded[j] = f"collinear with f{i}"
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
    )
