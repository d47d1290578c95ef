"""Functions of the contact points' boolean masks, worked out once per pattern.

Which points are planted, which feet stand still, which points the IMUs say move: these (k,)
boolean masks change at steps only, while the contact rules ask the same questions of them every
frame (the other foot's points, the groups planted). A :class:`MaskMemo` keeps the answer for each
pattern met (keyed by the mask's bytes, at most ``2**k`` patterns and in practice a few dozen), so
a frame pays a dictionary look-up instead of NumPy products on arrays of a few entries. The
answers are read-only arrays shared by every caller; the numbers are those of the function.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Generic, TypeVar, cast

import numpy as np

if TYPE_CHECKING:
    from ..model.topology import FootLayout

_BOOL = np.dtype(bool)
T = TypeVar("T")


class MaskMemo(Generic[T]):
    """``function(mask)`` of (k,) boolean masks, computed once per mask pattern.

    Args:
        function: A pure function of the mask returning an array or a tuple (its arrays are
            made read-only here).
    """

    def __init__(self, function: Callable[[np.ndarray], T]) -> None:
        self._function = function
        self._known: dict[bytes, T] = {}

    def __call__(self, mask: np.ndarray) -> T:
        """``function(mask)`` (read-only), from the memo when the pattern was seen before."""
        if mask.dtype is not _BOOL:  # (only boolean masks are kept: bytes say the pattern)
            return self._function(mask)
        key = mask.tobytes()
        out = self._known.get(key)
        if out is None:
            out = self._known[key] = _read_only(self._function(mask), mask)
        return out


def _read_only(value: T, mask: np.ndarray) -> T:
    """``value`` with its arrays (it, or those of a tuple) read-only copies where shared."""
    if isinstance(value, tuple):
        return cast(T, tuple(_read_only(v, mask) for v in value))
    if isinstance(value, np.ndarray):
        array = value.copy() if value.base is not None or value is mask else value
        array.setflags(write=False)
        return cast(T, array)
    return value


def layout_memo(layout: FootLayout, name: str,
                function: Callable[[FootLayout, np.ndarray], T]) -> MaskMemo[T]:
    """The :class:`MaskMemo` of ``function(layout, mask)`` kept with ``layout`` under ``name``."""
    memo = layout.memos.get(name)
    if memo is None:
        memo = layout.memos[name] = MaskMemo(lambda mask: function(layout, mask))
    return memo


class LastInput:
    """``function(array, *rest)`` kept for the last read-only ``array`` (the same object).

    The per-frame evidence arrays (the smoothed sensed points, the foot pitches) are made
    read-only once computed, and several rules of one frame ask the same question of them (the
    release before the solve, the touch-down after it): the second asks pays an identity test.
    ``rest`` must be the same objects (read-only arrays among them) or equal numbers as in the
    kept call.
    """

    def __init__(self, function: Callable[..., np.ndarray]) -> None:
        self._function = function
        #: (array, rest, out) of the kept call, one attribute so that solvers in other threads
        #: sharing this function read and replace it whole
        self._kept: tuple[object, tuple[object, ...], np.ndarray] | None = None

    def __call__(self, array: np.ndarray | None, *rest: object) -> np.ndarray:
        """``function(array, *rest)``, kept when ``array`` is a read-only array."""
        kept = self._kept
        if kept is not None and array is kept[0] and _same(rest, kept[1]):
            return kept[2]
        out = np.asarray(self._function(array, *rest))
        if _read_only_arrays(array, rest):
            if out.base is not None or out is array:
                out = out.copy()
            out.setflags(write=False)
            self._kept = (array, rest, out)
        else:
            self._kept = None
        return out


def _read_only_arrays(array: object, rest: tuple[object, ...]) -> bool:
    """``array`` is a read-only array, and so is every array among ``rest``."""
    return (isinstance(array, np.ndarray) and not array.flags.writeable
            and not any(isinstance(x, np.ndarray) and x.flags.writeable for x in rest))


def _same(a: tuple[object, ...], b: tuple[object, ...]) -> bool:
    """The same objects, or equal numbers of one type (floats, ints)."""
    if len(a) != len(b):
        return False
    for x, y in zip(a, b):
        if x is not y and not (type(x) in _NUMBERS and type(y) is type(x) and x == y):
            return False
    return True


_NUMBERS = (int, float)
