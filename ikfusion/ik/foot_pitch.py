"""The pitch of each contact point's foot in a frame, from its sensed orientation target.

:meth:`.contact_tracker.ContactTracker.foot_pitch` asks it every frame (the release's rules:
a heel pitched toe-down, a toe pitched toe-up, is ruled out). :class:`FootPitch` reads the
forward axes of the feet off the frame's (n, 3, 3) targets with one flat ``take`` (the x, y, z
rows of every point with a foot at once), and writes the pitches of consecutive points through a
slice: the same NumPy operations on the same numbers as :meth:`FootPitch.reference` (the
strided columns it takes), a few microseconds less a frame.
"""

from __future__ import annotations

import numpy as np

from ..model.human_model import HumanModel
from .fast_math import true_indices

_PATTERNS = 64  # at most this many patterns of tracked targets are kept (a few in practice)


class FootPitch:
    """Pitch [rad] (toe down positive) of the foot of each contact point, NaN without a foot.

    Args:
        model: The human model (the feet without sensor: their rotation at ``q``).
        feet: (c,) the segment index of each point's foot, -1 without a foot.
    """

    def __init__(self, model: HumanModel, feet: np.ndarray) -> None:
        self.model = model
        has_foot = feet >= 0
        self._foot_rows = feet[has_foot]  # the segment of each point with a foot
        self._foot_points = true_indices(has_foot)  # ... and the point
        self._no_pitch = np.full(len(feet), np.nan)  # the start: no foot
        # the flat indices into the (n, 3, 3) targets of the feet's forward axes (column 0):
        # rows x, y, z; the points with a foot as a slice when they are consecutive
        self._forward_at = self._foot_rows[None, :] * 9 + np.array([[0], [3], [6]])
        self._pitch_at = _as_slice(self._foot_points)
        self._untracked: dict[bytes, tuple[int, ...]] = {}  # _untracked_feet's, per pattern

    def __call__(self, q: np.ndarray, R_world_sensed: np.ndarray,
                 tracked: np.ndarray) -> np.ndarray:
        """(c,) the pitches [rad], a new array.

        From the foot's target in ``R_world_sensed`` (n, 3, 3) where ``tracked`` (n,), else
        from ``q``.
        """
        if not len(self._no_pitch):  # no contact points
            return np.zeros(0)
        # (3, points with a foot) the x, y, z of their forward axes, by index (a copy)
        forward = R_world_sensed.reshape(-1).take(self._forward_at)
        for row in self._untracked_feet(tracked):  # a foot without sensor
            forward[:, row] = self._forward_at_q(q, row)
        pitch = self._no_pitch.copy()
        pitch[self._pitch_at] = np.arctan2(-forward[2], np.hypot(forward[0], forward[1]))
        return pitch

    def reference(self, q: np.ndarray, R_world_sensed: np.ndarray,
                  tracked: np.ndarray) -> np.ndarray:
        """:meth:`__call__` on the targets' strided columns (its reference, for the tests)."""
        if not len(self._no_pitch):
            return np.zeros(0)
        forward = R_world_sensed[:, :, 0].take(self._foot_rows, axis=0)  # (points with a foot, 3)
        for row in self._untracked_feet(tracked):
            forward[row] = self._forward_at_q(q, row)
        pitch = self._no_pitch.copy()
        pitch[self._foot_points] = np.arctan2(-forward[:, 2],
                                              np.hypot(forward[:, 0], forward[:, 1]))
        return pitch

    def _forward_at_q(self, q: np.ndarray, row: int) -> np.ndarray:
        """(3,) the forward axis of the foot of ``_foot_rows[row]`` at ``q`` (world)."""
        name = self.model.segment_names[self._foot_rows[row]]
        return self.model.segment_rotation(q, name)[:, 0]

    def _untracked_feet(self, tracked: np.ndarray) -> tuple[int, ...]:
        """Rows of ``_foot_rows`` whose foot has no target in ``tracked`` (n,) bool.

        Kept per pattern of ``tracked`` (the targets' weighting is the same from frame to frame
        until a sensor drops out or comes back).
        """
        key = tracked.tobytes()
        rows = self._untracked.get(key)
        if rows is None:
            rows = tuple(true_indices(~np.asarray(tracked, dtype=bool)[self._foot_rows]).tolist())
            if len(self._untracked) < _PATTERNS:  # (sensors dropping out, coming back)
                self._untracked[key] = rows
        return rows


def _as_slice(rows: np.ndarray) -> slice | np.ndarray:
    """``rows`` (increasing indices) as the slice they make when consecutive (a cheaper index)."""
    if len(rows) and rows[-1] - rows[0] == len(rows) - 1:
        return slice(int(rows[0]), int(rows[-1]) + 1)
    return rows
