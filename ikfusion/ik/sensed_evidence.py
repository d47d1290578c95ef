"""A frame's smoothed sensed contact points and their evidence, in one native call.

:meth:`.contact_tracker.ContactTracker.release` starts every frame by smoothing the sensed
contact points and foot pitches (sensor noise is white), and reads off them which points are
low, high, far from the floor and ruled out by their foot's pitch (:mod:`.point_evidence`):
about twenty NumPy and Python operations on arrays of a dozen numbers. :class:`NativeSensing`
makes them in one call of a small C kernel (``sensed_evidence.c``, compiled once like the step
function, :func:`ikfusion.native.kernel.loaded_kernel`), the same operations in the same order,
so the numbers and bits are the same, bit for bit. :func:`python_evidence` is the reference and
the path without a C compiler (or with ``IKFUSION_NO_COMPILE``).
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ..native.kernel import kernel_source, loaded_kernel
from .fast_math import min_of
from .kernel_arguments import SensedArguments
from .point_bits import above, below_above
from .point_evidence import tilted_of

#: What is used when the kernel cannot be compiled (the end of the warning).
FALLBACK = "NumPy smooths the sensed contact points instead"
#: :class:`NativeSensing`'s frames a block of output memory (a block of 14 points: 77 kB)
FRAMES_A_BLOCK = 64


class Sensed(NamedTuple):
    """One frame's smoothed sensed points and what they say (bits: :mod:`.point_bits`).

    Attributes:
        p: (k, 3) the smoothed sensed contact points [m] (read-only).
        pitch: (k,) the smoothed foot pitches [rad] (read-only).
        step: (k, 3) ``p`` less the last frame's [m].
        velocity: (k, 3) ``step`` over the time since the last frame [m/s], None without time.
        height_rel: (k,) how far each point is above the lowest of ``p`` [m] (world z).
        far: The rest points higher than ``far`` above the lowest.
        low: Points less than ``enter`` above the lowest; ``high``: more than ``leave``.
        tilted: Heels pitched more than ``tilt`` toe-down, toes more than ``tilt`` toe-up.
    """

    p: np.ndarray
    pitch: np.ndarray
    step: np.ndarray
    velocity: np.ndarray | None
    height_rel: np.ndarray
    far: int
    low: int
    high: int
    tilted: int


class Rules(NamedTuple):
    """The constants of :func:`python_evidence` for one tracker.

    Attributes:
        a: The smoothing factor (the last frame's share).
        far: ``Sensed.far``'s height above the lowest point [m].
        enter: ``Sensed.low``'s height [m]; ``leave``: ``Sensed.high``'s [m].
        tilt: The pitch [rad] past which a heel or toe is ruled out.
        rest: The rest points' indices; ``heels``, ``toes``: the heels' and toes'.
    """

    a: float
    far: float
    enter: float
    leave: float
    tilt: float
    rest: Sequence[int]
    heels: Sequence[int]
    toes: Sequence[int]


def python_evidence(rules: Rules, p_old: np.ndarray, pitch_old: np.ndarray, p_new: np.ndarray,
                    pitch_new: np.ndarray, dt: float) -> Sensed:
    """:class:`Sensed` of the last frame's smoothed points and pitches and this frame's."""
    a = rules.a
    p = a * p_old + (1.0 - a) * p_new
    step = p - p_old  # [m]
    pitch = a * pitch_old + (1.0 - a) * pitch_new
    # read-only: every rule of this frame reads them (FrameEvidence), none may write them
    p.setflags(write=False)
    pitch.setflags(write=False)
    z = p[:, 2]
    lowest = min_of(z)
    far = above(z.tolist(), lowest + rules.far, rules.rest)
    height_rel = z - lowest
    low, high = below_above(height_rel.tolist(), rules.enter, rules.leave)
    tilted = tilted_of(pitch.tolist(), rules.tilt, rules.heels, rules.toes)
    return Sensed(p, pitch, step, step / dt if dt > 0 else None, height_rel, far, low, high,
                  tilted)


class NativeSensing:
    """:func:`python_evidence` of k points in one kernel call (see the module docstring).

    This frame's points and pitches are copied into buffers of their own; the outputs are new
    memory each frame (a frame's arrays are never written to again), whose address the next
    frame reads its last smoothed points from. The frames' outputs are the rows of blocks of
    :data:`FRAMES_A_BLOCK` frames, each block's arrays viewed once (a frame indexes them).

    Args:
        library: The loaded kernel.
        rules: The tracker's constants.
        k: Number of contact points (at most 62: the bits are a C ``long long``).
    """

    def __init__(self, library: ctypes.CDLL, rules: Rules, k: int) -> None:
        self.rules, self.k = rules, k
        self._p_new, self._pitch_new = np.zeros((k, 3)), np.zeros(k)
        self._p_old, self._pitch_old = np.zeros((k, 3)), np.zeros(k)  # an outside start
        self._rows = [np.array(r, dtype=np.intc) for r in (rules.rest, rules.heels, rules.toes)]
        rows = [int(r.ctypes.data) for r in self._rows]
        self._args = SensedArguments(
            int(self._p_new.ctypes.data), int(self._pitch_new.ctypes.data), 0, 0, 0, *rows,
            *(len(r) for r in self._rows), k, rules.a, 1.0 - rules.a, 0.0, rules.far,
            rules.enter, rules.leave, rules.tilt, 0, 0, 0, 0)
        self._old_at = (int(self._p_old.ctypes.data), int(self._pitch_old.ctypes.data))
        self._at = ctypes.addressof(self._args)
        #: the last call's smoothed points and pitches, and their block's address
        self._last: tuple[np.ndarray | None, np.ndarray | None, int] = (None, None, 0)
        self._next = FRAMES_A_BLOCK  # the next frame's row of the block (none yet)
        self._block_at = 0  # the block's address
        self._views: tuple[np.ndarray, ...] = ()  # its p, pitch, step, velocity, height rows
        self._kernel = library.ik_sensed_evidence
        self._kernel.restype = None
        self._kernel.argtypes = [ctypes.c_void_p]

    def __call__(self, p_old: np.ndarray, pitch_old: np.ndarray, p_new: np.ndarray,
                 pitch_new: np.ndarray, dt: float) -> Sensed:
        """:func:`python_evidence` of the same arguments (this tracker's rules)."""
        k, args = self.k, self._args
        self._p_new[...] = p_new
        self._pitch_new[...] = pitch_new
        last_p, last_pitch, at = self._last
        if p_old is last_p and pitch_old is last_pitch:  # the last call's (the usual frame)
            args.p_old, args.pitch_old = at, at + 24 * k  # (8 bytes a number)
        else:  # a start or reset: copied
            self._p_old[...] = p_old
            self._pitch_old[...] = pitch_old
            args.p_old, args.pitch_old = self._old_at
        if (row := self._next) == FRAMES_A_BLOCK:
            row = self._new_block()
        self._next = row + 1
        at = self._block_at + 88 * k * row  # (11 k numbers a frame)
        args.out, args.dt = at, dt
        self._kernel(self._at)
        p_rows, pitch_rows, step_rows, velocity_rows, height_rows = self._views
        p, pitch = p_rows[row], pitch_rows[row]
        self._last = (p, pitch, at)
        return Sensed(p, pitch, step_rows[row], velocity_rows[row] if dt > 0 else None,
                      height_rows[row], args.far_bits, args.low, args.high, args.tilted)

    def _new_block(self) -> int:
        """Fresh memory for the next :data:`FRAMES_A_BLOCK` frames; the first row (0).

        A frame's row holds 11 k numbers: ``p`` (k, 3), ``pitch`` (k), ``step`` (k, 3),
        ``velocity`` (k, 3), ``height_rel`` (k) (``sensed_evidence.c``'s ``out``); ``p`` and
        ``pitch`` are viewed read-only, the others writable, as :func:`python_evidence`'s.
        """
        k = self.k
        block = np.empty((FRAMES_A_BLOCK, 11 * k))
        self._block_at = int(block.ctypes.data)
        read_only = block.view()
        read_only.setflags(write=False)
        self._views = (read_only[:, :3 * k].reshape(-1, k, 3), read_only[:, 3 * k:4 * k],
                       block[:, 4 * k:7 * k].reshape(-1, k, 3),
                       block[:, 7 * k:10 * k].reshape(-1, k, 3), block[:, 10 * k:])
        return 0

def sensing(rules: Rules, k: int) -> NativeSensing | None:
    """The native :func:`python_evidence` (:class:`NativeSensing`); None without the kernel."""
    if not 0 < k <= 62:
        return None
    library = loaded_kernel(kernel_source(__name__, "sensed_evidence.c"), FALLBACK)
    return None if library is None else NativeSensing(library, rules, k)
