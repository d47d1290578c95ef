"""Legs that let go of the floor return to their sensed orientations gradually.

While a foot is planted, its leg is bent away from what its sensors say whenever the body is
moved: the pelvis kept continuous across a hand-over, leaning toward a drift correction, or
inertial drift between the feet. The moment the foot lets go (its heel, then its toes), nothing
holds that strain any more, and a leg that jumped back to its sensed orientations would pop by
the whole strain in one frame.

:class:`ReleaseEasing` keeps, for every segment of a leg that let go, its deviation from the
sensed orientation at that moment as an *offset* of its orientation target,
``R_world_target = R_world_sensed @ Exp(offset)`` (offset in the segment frame [rad]), and
shrinks it at a bounded rate, so the leg returns to its sensors within a few frames.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from ..rotations import exp_so3
from .fast_math import any_true, true_indices

#: How many segments of a leg, from its foot up, ease back to their sensors when its heel rises
#: (:meth:`.contact_tracker.ContactTracker.ease`): the foot and the shank, the ankle's two. Freed
#: in height, the ankle the floor bent away from its sensors sprang back in one frame (dm-kick
#: causal: a heel held three frames under a foot that still pivots, the foot 10 deg off its
#: sensor, the ankle's error jumped 4.4 deg; gen-jumps take-offs 0.9 deg). The thigh gets no
#: offset: through the toe its leg still carries the body, and an offset there moved a standing
#: body's pelvis by 5 mm in the frame its heel rose (dm-getup-facedown).
ANKLE = 2


class ReleaseEasing:
    """Orientation-target offsets of the legs that let go (see the module docstring).

    Args:
        legs: For each contact point, the indices of the segments its release lets go of
            (its foot and the segments up to the pelvis, the pelvis excluded).
        n_segments: Number of segments (rows of the orientation targets).
        speed: The offsets shrink at this rate [rad/s].
    """

    def __init__(self, legs: Sequence[np.ndarray], n_segments: int, speed: float) -> None:
        self.speed = speed
        self._legs = [np.asarray(leg, dtype=int) for leg in legs]
        self._n = n_segments
        self._segments: dict[tuple[str, bytes, int | None], np.ndarray] = {}  # :meth:`release`'s
        self.reset()

    def reset(self) -> None:
        """No offsets."""
        self.offsets = np.zeros((self._n, 3))
        self._easing = False  # whether an offset may be non-zero (False: all are zero)
        self._rows: tuple[int, ...] = ()  # the rows that may be non-zero (the others are zeros)

    def release(self, released: np.ndarray, bend: Callable[[np.ndarray], np.ndarray],
                reach: int | None = None) -> None:
        """Points that let go (k,) bool: the segments of their legs keep their bend as offsets.

        Args:
            released: Which contact points let go this frame.
            bend: Given segment indices (m,), their last solved orientations' deviation from
                their sensed ones, ``Log(R_world_sensed^T R_world_solved)`` (m, 3) [rad].
            reach: Only this many segments of each leg, from the point's own segment up
                (None: the whole leg).
        """
        if self.speed <= 0 or not any_true(released):
            return
        key = (released.dtype.char, released.tobytes(), reach)
        legs = self._segments.get(key)
        if legs is None:  # (a few patterns: a heel, a toe, a foot, each foot)
            legs = np.unique(np.concatenate([self._legs[k][:reach]
                                             for k in true_indices(released)]))
            legs.setflags(write=False)
            if len(self._segments) < 64:
                self._segments[key] = legs
        if len(legs):
            self.offsets[legs] = bend(legs)
            self._easing = True
            self._rows = tuple(sorted(set(self._rows).union(legs.tolist())))

    def apply(self, R_world_sensed: np.ndarray, dt: float) -> np.ndarray | None:
        """Shrink the offsets by ``speed * dt``; the offset targets (n, 3, 3), None if none."""
        if not self._easing:  # the usual case: no leg eases
            return None
        # the rows that may be non-zero, as floats: NumPy's numbers (``row_norms`` sums the
        # squares from the first; ``np.maximum(0.0, k)`` keeps a NaN); rows of zeros keep theirs
        # (rows as index arrays: NumPy's fancy indexing converts a list at each use)
        by, rows, out = self.speed * dt, np.array(self._rows, dtype=np.intp), []
        for x, y, z in self.offsets.take(rows, axis=0).tolist():
            n = math.sqrt(x * x + y * y + z * z)
            keep = 1.0 - by / n if n > 0 else 0.0
            keep = 0.0 if 0.0 >= keep else keep
            out.append((x * keep, y * keep, z * keep))
        self.offsets[rows] = out
        moving = [i for i, v in zip(self._rows, out, strict=True) if any(v)]  # (a list: rows)
        self._rows = tuple(moving)
        if not moving:
            self._easing = False
            return None
        R, at = R_world_sensed.copy(), np.array(moving, dtype=np.intp)
        R[at] = R.take(at, axis=0) @ exp_so3(self.offsets.take(at, axis=0))
        return R

