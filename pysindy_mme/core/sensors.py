"""Sensors as they come: readings stuck on the end of a sensor's range.

A sensor that reads at most 10 V reports 10 V whenever the quantity is
higher: a run of samples exactly on a ceiling (or a floor). Such a reading
says only "at or beyond the limit" (it is *censored*), and fitting it as a
reading pulls a model down to the limit. :func:`clipped_samples` finds them
in a record; :func:`clipped_at` marks the readings at or beyond limits the
user knows. Both return a :class:`Clipping`: one :class:`ClippedChannel` per
channel and side, and the combined mask.

The detection rule (per channel and side; the ceiling is described, the
floor is its mirror image):

* the extreme value ``v`` (the channel's largest finite reading) sits in a
  run of at least ``min_run`` consecutive samples, and is hit by at least
  ``min_run`` samples in all;
* a continuous channel (its values on no quantisation grid, and the values
  next to ``v`` each read once) never repeats a value exactly: noise makes
  every reading different, so ``min_run`` equal readings at the extreme are
  clipping;
* a quantised channel (an ADC, an encoder) repeats values by design, so the
  count ``c0`` of ``v`` is compared with the mean count ``c`` of the
  ``NEIGHBOURS`` (3) distinct values next below it: a ceiling piles every
  reading beyond it onto one level, a smooth unclipped maximum cannot. Near
  a quadratic maximum ``x = A - b s^2`` the signal spends ``2 sqrt(q / b)``
  in the top bin of width ``q`` and ``2 (sqrt(k + 1) - sqrt(k)) sqrt(q / b)``
  in the ``k``-th below; the three below add up to ``2 (sqrt(4) - 1)
  sqrt(q / b)``, so the top level holds at most 3 times their mean
  (sampling moves each count by at most one per visit: ``c0 <= 3 c + 4``).
  Measurement noise spreads the top of an unclipped channel over several
  levels, which only lowers ``c0``. The rule asks for ``c0 >= EXCESS (c +
  1)`` with ``EXCESS = 5``, beyond that bound for any ``c``; a ceiling the
  signal stays beyond for a while gives tens to hundreds of readings on the
  level against a few on each level below (crossed on the way up). Runs
  cut by the record's start or end are no evidence on a quantised channel:
  the levels next to a truncated visit are seen on one side only, so the
  bound does not hold for them.

On 6000 random sines, damped sines and two-tone signals (4 in 5 quantised
with steps of ``10^-3.5`` to ``10^-0.7`` of the amplitude, noise from none
to 30 steps; the others continuous and noisy) the rule raised no false
alarm, and it found 84 % of the same signals clipped below their peak (the
misses: a grid so coarse that a few levels span the swing, or a ceiling so
close to the peak that the clipped top is a smooth maximum's).

Once a side is found clipped, every reading on the level is censored, not
only those in long runs: a lone reading at the ceiling, between two noisy
dips below it, is as much "at or beyond" as the others. What the rule
cannot tell apart: a noise-free quantised signal that settles on its
largest value for a long time (a plateau reached asymptotically) looks
like a ceiling; censoring it costs those samples, not a bias, and the study
names it so that ``clipped="keep"`` can restore them.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from .noise import quantisation_step

__all__ = [
    "CEILING",
    "FLOOR",
    "EXCESS",
    "NEIGHBOURS",
    "ClippedChannel",
    "Clipping",
    "clipped_samples",
    "clipped_at",
    "check_ranges",
]

CEILING, FLOOR = "ceiling", "floor"
#: a clipped level holds at least this many times the mean count of the
#: neighbouring levels (plus one) on a quantised channel (module docstring)
EXCESS = 5
#: distinct values next to the extreme whose counts are compared with it
NEIGHBOURS = 3


@dataclass(frozen=True, eq=False)
class ClippedChannel:
    """Readings of one channel sitting on one end of the sensor's range.

    Attributes
    ----------
    channel : int
        Column of ``y``.
    side : {"ceiling", "floor"}
    level : float
        The limit: the channel's largest (ceiling) or smallest (floor)
        reading when detected, or the limit the user gave.
    count : int
        Readings at (or, for a given limit, beyond) the level.
    mask : ndarray (n_samples,) of bool
        Which samples they are.
    longest_run : int
        The longest run of consecutive samples among them.
    n_observed : int
        Finite readings of the channel.
    given : bool
        The level was given (``clipped=(low, high)`` or another record's
        finding), not detected on this record.
    """

    channel: int
    side: str
    level: float
    count: int
    mask: np.ndarray
    longest_run: int
    n_observed: int
    given: bool = False

    @property
    def share(self) -> float:
        """``count`` over the channel's finite readings."""
        return self.count / self.n_observed if self.n_observed else float("nan")


@dataclass(frozen=True, eq=False)
class Clipping:
    """The clipped readings of a record: per channel and side, and combined.

    Attributes
    ----------
    channels : tuple of ClippedChannel
        One per clipped (channel, side), in channel order, ceiling first.
    mask : ndarray (n_samples, n_channels) of bool
        Every clipped reading.
    """

    channels: tuple
    mask: np.ndarray

    def __len__(self) -> int:
        return len(self.channels)

    def __iter__(self):
        return iter(self.channels)

    def __bool__(self) -> bool:
        return bool(self.channels)

    @property
    def count(self) -> int:
        """Clipped readings over all channels."""
        return int(self.mask.sum())

    def censor(self, y) -> np.ndarray:
        """A copy of ``y`` with the clipped readings set to NaN."""
        out = np.array(y, dtype=float, copy=True)
        shape = out.shape
        out = out.reshape(self.mask.shape)
        out[self.mask] = np.nan
        return out.reshape(shape)

    def ranges(self) -> list:
        """``[(low, high)]`` per channel, None where that side is not clipped."""
        out = [[None, None] for _ in range(self.mask.shape[1])]
        for c in self.channels:
            out[c.channel][0 if c.side == FLOOR else 1] = c.level
        return [tuple(r) for r in out]

    def on(self, channel: int, side: str) -> ClippedChannel | None:
        """The finding for ``channel`` and ``side``, or None."""
        for c in self.channels:
            if c.channel == channel and c.side == side:
                return c
        return None

    def rows(self, part: slice) -> Clipping:
        """These findings on the rows ``part`` of the record (a side with no
        clipped reading left there is dropped)."""
        mask = self.mask[part]
        found = []
        for c in self.channels:
            sub = c.mask[part]
            if not sub.any():
                continue
            # the rows left out held no reading of this channel but clipped ones
            gone = int(self.mask[:, c.channel].sum() - mask[:, c.channel].sum())
            found.append(
                ClippedChannel(
                    channel=c.channel,
                    side=c.side,
                    level=c.level,
                    count=int(sub.sum()),
                    mask=sub,
                    longest_run=_longest_run(sub),
                    n_observed=c.n_observed - gone,
                    given=c.given,
                )
            )
        return _clipping(found, mask.shape)

    def merged(self, other: Clipping) -> Clipping:
        """These findings, plus ``other``'s on the (channel, side) pairs that
        have none here (same record)."""
        extra = [c for c in other if self.on(c.channel, c.side) is None]
        return _clipping(list(self.channels) + extra, self.mask.shape)


def _as_2d(y) -> np.ndarray:
    arr = np.array(y, dtype=float, copy=True)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise ValueError(f"y must be 1-D or 2-D, got shape {arr.shape}")
    return arr


def _clipping(found, shape) -> Clipping:
    found = sorted(found, key=lambda c: (c.channel, c.side != CEILING))
    mask = np.zeros(shape, dtype=bool)
    for c in found:
        mask[:, c.channel] |= c.mask
    return Clipping(tuple(found), mask)


def _longest_run(hit) -> int:
    """Longest run of True in a boolean vector (NaN readings are False)."""
    if not hit.any():
        return 0
    edges = np.flatnonzero(np.diff(np.r_[0, hit.astype(np.int8), 0]))
    return int(np.max(edges[1::2] - edges[::2]))


def _finding(col, j, side, level, hit, given=False) -> ClippedChannel:
    return ClippedChannel(
        channel=j,
        side=side,
        level=float(level),
        count=int(hit.sum()),
        mask=hit,
        longest_run=_longest_run(hit),
        n_observed=int(np.isfinite(col).sum()),
        given=given,
    )


def _interior(hit) -> np.ndarray:
    """``hit`` without the runs that touch the record's first or last sample."""
    out = hit.copy()
    for end in (out, out[::-1]):
        k = int(np.argmin(end)) if not end.all() else end.size
        end[:k] = False
    return out


def _detect_side(col, j, side, values, counts, quantised, min_run):
    """The finding on one side of one channel, or None (module docstring)."""
    k = -1 if side == CEILING else 0
    level = values[k]
    hit = col == level  # NaN compares False
    neighbours = (
        counts[-1 - NEIGHBOURS : -1] if side == CEILING else counts[1 : 1 + NEIGHBOURS]
    )
    repeats = quantised or neighbours.max(initial=0) >= 2
    # on a quantised channel a run cut by the record's end is half a visit
    # (the levels next to it are seen on one side only): no evidence
    evidence = _interior(hit) if repeats else hit
    c0 = int(evidence.sum())
    if c0 < min_run or _longest_run(evidence) < min_run:
        return None
    c = float(neighbours.mean()) if neighbours.size else 0.0
    if repeats and c0 < EXCESS * (c + 1):
        return None
    return _finding(col, j, side, level, hit)


def clipped_samples(y, min_run: int = 3) -> Clipping:
    """Readings stuck on a channel's largest or smallest value (a sensor's
    range), found by the rule of the module docstring.

    Parameters
    ----------
    y : array-like (n_samples,) or (n_samples, n_channels)
        Readings; NaN marks a missing sample (never clipped, and it breaks a
        run).
    min_run : int, default 3
        Fewest consecutive samples on the extreme value, and fewest in all.

    Returns
    -------
    Clipping
        Empty (falsy) when no channel is clipped. A constant channel (one
        distinct value) is not called clipped: nothing tells a stuck sensor
        from a ceiling there.
    """
    if isinstance(min_run, bool) or not isinstance(min_run, (int, np.integer)):
        raise TypeError(f"min_run must be an integer, got {min_run!r}")
    if min_run < 2:
        raise ValueError(f"min_run must be at least 2, got {min_run}")
    y = _as_2d(y)
    found = []
    for j in range(y.shape[1]):
        col = y[:, j]
        finite = col[np.isfinite(col)]
        values, counts = np.unique(finite, return_counts=True)
        if values.size < 2:
            continue
        quantised = bool(np.isfinite(quantisation_step(finite)))
        for side in (CEILING, FLOOR):
            hit = _detect_side(col, j, side, values, counts, quantised, int(min_run))
            if hit is not None:
                found.append(hit)
    return _clipping(found, y.shape)


def clipped_at(y, ranges, beyond: bool = True) -> Clipping:
    """Readings at or beyond known limits of the sensor's range.

    Parameters
    ----------
    y : array-like (n_samples,) or (n_samples, n_channels)
    ranges : (low, high) or sequence of them, one per channel
        The range's ends; None (or an infinite value) for an end without a
        limit, None for a channel without limits. One pair applies to every
        channel.
    beyond : bool, default True
        Readings beyond a limit count too (False: only those exactly on it,
        for a level found on another record of the same sensor).

    Returns
    -------
    Clipping
        A side appears only when some reading is at or beyond its limit.
    """
    y = _as_2d(y)
    pairs = check_ranges(ranges, y.shape[1])
    found = []
    for j, (low, high) in enumerate(pairs):
        col = y[:, j]
        for side, level in ((CEILING, high), (FLOOR, low)):
            if level is None:
                continue
            if not beyond:
                hit = col == level
            elif side == CEILING:
                hit = col >= level
            else:
                hit = col <= level
            if hit.any():
                found.append(_finding(col, j, side, level, hit, given=True))
    return _clipping(found, y.shape)


def check_ranges(ranges, m: int, name: str = "clipped") -> list:
    """``[(low or None, high or None)] * m`` from one pair or one per channel."""
    example = "(0.0, 10.0), or one (low, high) per channel with None for no limit"
    try:
        items = list(ranges)
    except TypeError:
        raise TypeError(f"{name} must be a (low, high) pair, got {ranges!r}") from None
    if len(items) == 2 and all(v is None or np.ndim(v) == 0 for v in items):
        items = [tuple(items)] * m
    if len(items) != m:
        raise ValueError(
            f"{name} has {len(items)} ranges but there are {m} channels: give {example}"
        )
    out = []
    for pair in items:
        if pair is None:
            out.append((None, None))
            continue
        try:
            low, high = pair
        except (TypeError, ValueError):
            raise TypeError(
                f"{name}: each range is (low, high), got {pair!r}"
            ) from None
        ends = []
        for v in (low, high):
            if v is None:
                ends.append(None)
                continue
            if isinstance(v, bool) or not isinstance(v, numbers.Real):
                raise TypeError(f"{name}: a limit must be a number or None, got {v!r}")
            v = float(v)
            if np.isnan(v):
                raise ValueError(f"{name}: a limit is NaN; use None for no limit")
            ends.append(None if np.isinf(v) else v)
        if ends[0] is not None and ends[1] is not None and ends[0] >= ends[1]:
            raise ValueError(f"{name}: low must be below high, got {pair!r}")
        out.append(tuple(ends))
    return out
