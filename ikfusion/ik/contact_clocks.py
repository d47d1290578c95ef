"""A touch-down's contact clocks and settled anchors, in one native call.

Every :func:`.contacts.touch_down` moves the clocks of the contact state on by the frame's
step: how long each free point has been released, how long each planted point has been planted
(a free point's age is 0), and lets the anchors above the floor settle toward it
(:func:`.anchor_settling.settled_heights`): four or five NumPy operations on arrays of a dozen
numbers, each costing about a microsecond of call overhead. :class:`NativeClocks` makes them in
one call of a small C kernel (``contact_clocks.c``, compiled once like the step function,
:func:`ikfusion.native.kernel.loaded_kernel`), the same operations, so the same numbers, bit for
bit. :func:`python_clocks` is the reference and the path without a C compiler (or with
``IKFUSION_NO_COMPILE``).

Both return the state's own anchors array when no height changed (bit for bit): a state's arrays
are never written to (:class:`.contacts.ContactState`), and the caches keyed on the anchors'
identity downstream keep their rows.
"""

from __future__ import annotations

import ctypes
from typing import Protocol

import numpy as np

from ..model.topology import FootLayout
from ..native.kernel import kernel_source, loaded_kernel
from .anchor_settling import settled_anchors
from .kernel_arguments import ClockArguments
from .point_bits import point_bits

#: What is used when the kernel cannot be compiled (the end of the warning).
FALLBACK = "NumPy moves the contact clocks on instead"
_ROWS = 64  # outputs a block of memory holds

#: (released (k,) [s], age (k,) [s], anchors (k, 3) [m]) after a touch-down's step
Clocks = tuple[np.ndarray, np.ndarray, np.ndarray]


class ClockStep(Protocol):
    """:func:`python_clocks`'s signature (:class:`NativeClocks` is one too)."""

    def __call__(self, released: np.ndarray, age: np.ndarray, anchors: np.ndarray, was: int,
                 step: float, drop: float, floor_z: float, layout: FootLayout) -> Clocks:
        """The clocks and anchors ``step`` later (:func:`python_clocks`)."""


def python_clocks(released: np.ndarray, age: np.ndarray, anchors: np.ndarray, was: int,
                  step: float, drop: float, floor_z: float, layout: FootLayout) -> Clocks:
    """The contact clocks and anchors (k,) [s], (k,) [s], (k, 3) [m] ``step`` [s] later.

    Args:
        released: (k,) how long each point has been released [s].
        age: (k,) how long each point has been planted [s].
        anchors: (k, 3) the anchors [m] (world z up).
        was: The points planted (bits, :mod:`.point_bits`): their ages move on, the others'
            release times; a free point's age is 0.
        step: The time step [s] (>= 0).
        drop: How far an anchor settles at most [m] (:func:`.anchor_settling.settled_anchors`,
            the planted points ``was`` of one segment together).
        floor_z: The floor's height [m].
        layout: The points' :class:`FootLayout`.

    Returns:
        The new clocks (new arrays) and the settled anchors (``anchors`` itself when no height
        changed).
    """
    planted = point_bits(layout).mask(was)
    return (np.where(planted, released, released + step), np.where(planted, age + step, 0.0),
            settled_anchors(anchors, planted, drop, floor_z, layout))


class NativeClocks:
    """:func:`python_clocks` of k points in one kernel call (see the module docstring).

    The kernel reads the state's arrays where they are: the last call's outputs and anchors
    (the usual frame: held, so that their ids cannot pass to other arrays; one written in
    place is read as it is now) at the addresses it knows, other C-contiguous float arrays at
    their own addresses; any other array goes to :func:`python_clocks`. The outputs are new
    memory each call (rows of a block, each written once: a state's arrays are never written
    to again).

    Args:
        library: The loaded kernel.
        k: Number of contact points (at most 62: the bits are a C ``long long``).
    """

    def __init__(self, library: ctypes.CDLL, k: int) -> None:
        self.k = k
        self._args = ClockArguments(0, 0, 0, 0, 0, k, 0, 0.0, 0.0, 0.0, 0)
        self._at = ctypes.addressof(self._args)
        self._blocks, self._used, self._blocks_at = np.zeros((0, 5 * k)), 0, 0  # the outputs
        self._shares: tuple[FootLayout | None, int] = (None, 0)  # a layout's shares_segment
        #: the last call's released, age and anchors arrays, and their addresses
        self._last: tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None] = (
            None, None, None)
        self._last_at = (0, 0, 0)
        self._kernel = library.ik_contact_clocks
        self._kernel.restype = None
        self._kernel.argtypes = [ctypes.c_void_p]

    def __call__(self, released: np.ndarray, age: np.ndarray, anchors: np.ndarray, was: int,
                 step: float, drop: float, floor_z: float, layout: FootLayout) -> Clocks:
        """:func:`python_clocks` of the same arguments."""
        k, args, (last_released, last_age, last_anchors) = self.k, self._args, self._last
        at_released, at_age, at_anchors = self._last_at
        if released is not last_released:
            at_released = self._address(released, k)
        if age is not last_age:
            at_age = self._address(age, k)
        if anchors is not last_anchors:
            at_anchors = self._address(anchors, 3 * k)
        if self._shares[0] is not layout:
            self._shares = (layout, point_bits(layout).shares_segment)
        shared = was & self._shares[1]  # planted points settling together
        if not (at_released and at_age and at_anchors):  # (not C-contiguous float arrays)
            return python_clocks(released, age, anchors, was, step, drop, floor_z, layout)
        if self._used == len(self._blocks):
            self._blocks, self._used = np.zeros((_ROWS, 5 * k)), 0
            self._blocks_at = int(self._blocks.ctypes.data)
        row, at = self._blocks[self._used], self._blocks_at + 40 * k * self._used
        self._used += 1
        args.released, args.age, args.anchors, args.out = at_released, at_age, at_anchors, at
        args.was, args.settle, args.step, args.drop, args.floor_z = (was, not shared, step, drop,
                                                                     floor_z)
        self._kernel(self._at)
        if shared:  # (a lying body's shoulder blades: NumPy settles them together)
            anchors = settled_anchors(anchors, point_bits(layout).mask(was), drop, floor_z,
                                      layout)
            at_anchors = self._address(anchors, 3 * k)
        elif args.changed:
            anchors, at_anchors = row[2 * k:].reshape(k, 3), at + 16 * k
        self._last = (new_released, new_age, anchors) = (row[:k], row[k:2 * k], anchors)
        self._last_at = (at, at + 8 * k, at_anchors)
        return new_released, new_age, anchors

    def __deepcopy__(self, memo: dict[int, object]) -> NativeClocks:
        """Itself: a handle on the kernel (a copy of a tracker shares it, as the model).

        Its memory of the last call's arrays is by identity: a copy's arrays are read at their
        own addresses.
        """
        return self

    @staticmethod
    def _address(values: np.ndarray, size: int) -> int:
        """Where the kernel reads ``values`` of ``size`` numbers; 0 where it cannot."""
        if values.dtype != np.float64 or not values.flags.c_contiguous or values.size != size:
            return 0
        return int(values.ctypes.data)


def contact_clocks(k: int) -> NativeClocks | None:
    """The native :func:`python_clocks` of k points; None without the kernel."""
    if not 0 < k <= 62:
        return None
    library = loaded_kernel(kernel_source(__name__, "contact_clocks.c"), FALLBACK)
    return None if library is None else NativeClocks(library, k)
