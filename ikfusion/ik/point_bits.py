"""The contact points as the bits of a Python int: bit ``i`` set is contact point ``i`` in.

The contact rules (:mod:`.contacts`, :mod:`.contact_tracker`) combine a dozen masks of the k
contact points a frame: planted, still, tilted, lifted, the other foot's... As NumPy (k,) boolean
arrays each ``&``, ``|`` or ``~`` costs about a microsecond on a few entries; on ints it costs
some tens of nanoseconds. :class:`PointBits` holds the groups of a :class:`FootLayout` as ints
(heels, toes, feet proper, the points of each point's other foot), built from the layout's
arrays (the model's topology, never names), and converts between (k,) boolean arrays and ints,
each pattern once. Only the genuinely numeric comparisons (heights, pitches, ages) stay in NumPy,
their boolean results turned into bits by one dictionary look-up.

On ints, ``~m`` is negative (``-m - 1``): ``a & ~m`` is right whenever ``a`` is not, and every
mask handed out here is ``0 <= m < 2**k``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, TypeVar

import numpy as np

if TYPE_CHECKING:
    from ..model.topology import FootLayout

_BOOL = np.dtype(bool)
_PATTERNS = 1 << 14  # at most this many patterns are kept per table (a few dozen in practice)
T = TypeVar("T")


class PointBits:
    """The contact points' groups as int bitmasks, and conversions from and to (k,) masks.

    Args:
        layout: The contact points' :class:`FootLayout`.

    Attributes:
        k: Number of contact points.
        heels: Points on their foot's segment itself (a heel, a knee, a palm).
        toes: Points on a segment below their foot (toes).
        stepping: Points of a foot proper (heel and toes), not a knee or palm.
        shares_segment: Points sharing their rigid segment with another point.
    """

    def __init__(self, layout: FootLayout) -> None:
        self.k = len(layout.on_foot)
        self._bits: dict[bytes, int] = {}
        self._masks: dict[int, np.ndarray] = {}
        self.heels = self.of(np.asarray(layout.on_foot, dtype=bool))
        self.toes = self.of(np.asarray(layout.below_foot, dtype=bool))
        self.stepping = self.of(np.asarray(layout.stepping, dtype=bool))
        self.shares_segment = self.of(np.asarray(layout.shares_segment, dtype=bool))
        #: per point, the points of every other foot (``FootLayout.other_foot``'s rows)
        self._other_foot_of = [self.of(row) for row in layout.other_foot]
        self._other: dict[int, int] = {}
        self._memos: dict[str, dict[object, object]] = {}

    def of(self, mask: np.ndarray) -> int:
        """The bits of a (k,) mask (a boolean array; others are taken as booleans)."""
        if mask.dtype is not _BOOL:
            mask = np.asarray(mask, dtype=bool)
        key = mask.tobytes()
        bits = self._bits.get(key)
        if bits is None:
            bits = sum(1 << i for i in np.flatnonzero(mask).tolist())
            if len(self._bits) < _PATTERNS:
                self._bits[key] = bits
        return bits

    def of_optional(self, mask: np.ndarray | None) -> int:
        """:meth:`of` a mask, no point for None."""
        return 0 if mask is None else self.of(np.asarray(mask))

    def mask(self, bits: int) -> np.ndarray:
        """The read-only (k,) boolean mask of ``bits`` (shared: never written to)."""
        out = self._masks.get(bits)
        if out is None:
            out = np.zeros(self.k, dtype=bool)
            out[list(indices(bits))] = True
            out.setflags(write=False)
            if len(self._masks) < _PATTERNS:
                self._masks[bits] = out
        return out

    def array(self, bits: int) -> np.ndarray:
        """A new (writable) (k,) boolean mask of ``bits``."""
        return self.mask(bits).copy()

    def other_foot(self, bits: int) -> int:
        """The points whose *other* foot has a point in ``bits``.

        ``other_foot`` is symmetric, so these are the union of the other feet of the points in
        ``bits`` (:func:`.foot_pairs.other_foot` on masks).
        """
        out = self._other.get(bits)
        if out is None:
            out = 0
            for i in indices(bits):
                out |= self._other_foot_of[i]
            self._other[bits] = out
        return out

    def memo(self, name: str, key: object, function: Callable[[], T]) -> T:
        """``function()`` kept under ``name`` for ``key`` (a pattern of bits, a bytes key)."""
        table = self._memos.setdefault(name, {})
        if key in table:
            return table[key]  # type: ignore[return-value]
        value = function()
        if len(table) < _PATTERNS:
            table[key] = value
        return value


def indices(bits: int) -> tuple[int, ...]:
    """The indices of the points in ``bits``, in increasing order."""
    out = _INDICES.get(bits)
    if out is None:
        out = tuple(i for i in range(bits.bit_length()) if bits >> i & 1)
        if len(_INDICES) < _PATTERNS:
            _INDICES[bits] = out
    return out


_INDICES: dict[int, tuple[int, ...]] = {}


def above(values: list[float], limit: float, rows: Sequence[int] | None = None) -> int:
    """The bits of ``values[i] > limit`` (NaN: not), over ``rows`` (None: every index).

    ``bits.of(np.array(values) > limit)`` on floats: the same comparisons, without NumPy's
    array and look-up for the few entries of a frame.
    """
    out = 0
    for i in range(len(values)) if rows is None else rows:
        if values[i] > limit:
            out |= 1 << i
    return out


def below(values: list[float], limit: float, rows: Sequence[int] | None = None) -> int:
    """The bits of ``values[i] < limit`` (NaN: not), over ``rows`` (None: every index)."""
    out = 0
    for i in range(len(values)) if rows is None else rows:
        if values[i] < limit:
            out |= 1 << i
    return out


def below_above(values: list[float], low: float, high: float) -> tuple[int, int]:
    """``(below(values, low), above(values, high))`` in one pass over every index (NaN: neither)."""
    under = over = 0
    for i, v in enumerate(values):
        if v < low:
            under |= 1 << i
        if v > high:
            over |= 1 << i
    return under, over


def first(bits: int) -> int:
    """The index of the lowest point in ``bits`` (non-zero): ``np.argmax(mask)``."""
    return (bits & -bits).bit_length() - 1


def has(bits: int, i: int) -> bool:
    """Is point ``i`` in ``bits``?"""
    return bool(bits >> i & 1)


def point_bits(layout: FootLayout) -> PointBits:
    """The :class:`PointBits` of ``layout``, made once and kept with it."""
    bits = layout.memos.get("bits")
    if bits is None:
        bits = layout.memos["bits"] = PointBits(layout)
    return bits  # type: ignore[no-any-return]
