"""How far a joint that arrives at a limit at speed may sink past it: a damped, springy wall.

An estimate a few degrees off (a foot sensor's heading error) reaches a limit frames before
the true joint does, at the true joint's full speed. A hard wall stops it dead there while the
true joint still turns: the error changes by the truth's speed in one frame (a pop). Here the
wall gives like a critically damped spring of time constant ``tau``: an angle at ``o`` past its
limit [rad] (negative inside the range) moving toward it at ``v`` [rad/s] may be, one time step
``dt`` later, at most

    o' = (o + (v + o / tau) dt) exp(-dt / tau)     (clipped to [0, depth]),

past it: the exact step of ``o'' = -o / tau^2 - 2 o' / tau``. A joint that arrives at speed
sinks in by about ``v tau / e`` and is pushed back out over a few ``tau``, smoothly, while the
true joint slows into its own limit; a joint at rest, or one whose targets stay inside the range,
never leaves it. The wall only ever widens a range, so targets inside the ranges are tracked
exactly as with hard limits (no lag); it gives only where the targets pull past a limit.
"""

from __future__ import annotations

import math

import numpy as np

from ..wall_sink import wall_sink

_SAME_TRIPLE = np.radians(60.0)  # [rad] an angle further from its previous one changed triple
_GIMBAL_FREE = np.radians(60.0)  # [rad] a joint whose middle angle is further is near gimbal lock
_GIMBAL_KEEP = np.radians(80.0)  # [rad] a middle angle never sinks beyond this


class SoftWall:
    """The room past each limit that each anatomical angle may use in the next frame.

    Args:
        lower: (joints, 3) lower limits [rad].
        upper: (joints, 3) upper limits [rad].
        depth: The deepest an angle may sink past a limit [rad]; 0: hard limits.
        tau: The spring's time constant [s] (> 0).
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray, depth: float, tau: float) -> None:
        self.tau = float(tau)
        self.enabled = depth > 0.0
        # both limits at once, as "how far past it": sign * angle - limit, upper then lower
        self._sign = np.array([1.0, -1.0])[:, None, None]
        self._limit = np.stack([upper, -lower])
        self._depth = np.full(self._limit.shape, float(depth))
        # a middle angle sinking to +-90 deg would meet gimbal lock (the rates blow up)
        self._depth[:, :, 1] = np.clip(_GIMBAL_KEEP - np.abs(self._limit[:, :, 1]), 0.0, depth)
        # the sink in one native call (the same numbers as NumPy's below); None: NumPy's
        self._sink = wall_sink(self._limit) if self.enabled else None
        self._factors = (0.0, 0.0, 0.0, 0.0)  # dt, dt before, the sink's and the drift's factor
        self.reset()

    def reset(self) -> None:
        """Forget the previous frames: hard limits until two frames are known."""
        self._before: tuple[np.ndarray, float] | None = None  # angles, time step after them
        self._previous: np.ndarray | None = None
        self._room: np.ndarray | None = None  # (2, joints, 3) past the upper, the lower limits

    def update(self, angles: np.ndarray, dt: float) -> None:
        """Take the previous frame's angles; the room for the next frame follows.

        Args:
            angles: (joints, 3) [rad], each on its triple nearest the range.
            dt: The time step from that frame to the one about to be solved [s].
        """
        before, self._before = self._before, (angles, float(dt))
        self._previous, self._room = angles, None
        if not self.enabled or before is None or before[1] <= 0.0 or dt <= 0.0:
            if self._sink is not None:
                self._sink.first(angles)
            return
        a_before, dt_before = before
        grow, drift = self._factors_of(dt, dt_before)
        if self._sink is not None:  # the same numbers as the NumPy below
            if not self._sink.reaches(angles, grow, drift):
                return
            sunk = self._sink.sunk
            moved = angles - a_before
        else:
            # the module's formula with v = moved / dt_before, its constants folded; computed
            # in place, the upper limits' rows (sign +1) then the lower ones' (sign -1)
            moved = angles - a_before
            sunk = np.multiply(self._sign, angles)
            sunk -= self._limit
            sunk *= grow
            change = moved * drift
            sunk[0] += change
            sunk[1] -= change
            if not sunk.max() > 0.0:  # no angle reaches a limit (most frames): hard limits
                return
        # no rate across a change of triple, nor near gimbal lock (the first and third angles
        # of a joint there turn by tens of degrees for a small turn of the joint)
        steady = np.abs(moved) < _SAME_TRIPLE
        steady &= np.abs(angles[:, 1:2]) < _GIMBAL_FREE
        sunk *= steady
        if sunk.max() > 0.0:  # else no angle reaches a limit: hard limits
            self._room = np.minimum(np.maximum(sunk, 0.0), self._depth)

    def _factors_of(self, dt: float, dt_before: float) -> tuple[float, float]:
        """The module's formula's factors of ``o`` and of the angles' change.

        Over ``dt`` [s] after a step of ``dt_before`` [s]; kept while the time steps stay.
        """
        kept = self._factors
        if kept[0] != dt or kept[1] != dt_before:
            decay = math.exp(-dt / self.tau)
            kept = self._factors = (dt, dt_before, (1.0 + dt / self.tau) * decay,
                                    dt * decay / dt_before)
        return kept[2], kept[3]

    def room(self, angles: np.ndarray) -> np.ndarray | None:
        """The room past the upper and the lower limits (2, joints, 3) [rad]; None: hard limits.

        ``angles`` (joints, 3) [rad] are where the step is linearised, each on its triple
        nearest the range. An angle on another triple than the previous frame's (the other
        Euler branch, a wrap) gets none.
        """
        if self._room is None or self._previous is None:
            return None
        return self._room * (np.abs(angles - self._previous) < _SAME_TRIPLE)
