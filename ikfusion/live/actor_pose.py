"""One actor's solved pose at one instant: what the live outputs send."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass(frozen=True)
class ActorPose:
    """One actor's pose at one instant, in the world frame (z up, metres).

    Attributes:
        actor: The actor's name (session file) .
        character_id: Small integer naming the actor in the streams (0, 1, ... in session
            order).
        time_s: Capture time of the frame [s] from the start of the capture.
        frame: Frame number from the start of the capture.
        segments: Segment names in the model's order (``Pelvis`` first).
        parents: Index in ``segments`` of each segment's parent (-1 for the root).
        p_world_segment: (S, 3) segment origins [m].
        R_world_segment: (S, 3, 3) segment orientations.
        joint_names: Joint-angle column names (``jRightKnee_flex``, ...), as ``joint_angles.csv``.
        joint_angles_deg: (J,) joint angles [deg].
    """

    actor: str
    character_id: int
    time_s: float
    frame: int
    segments: tuple[str, ...]
    parents: tuple[int, ...]
    p_world_segment: np.ndarray
    R_world_segment: np.ndarray
    joint_names: tuple[str, ...]
    joint_angles_deg: np.ndarray


class PoseSink(Protocol):
    """A live output: receives every solved frame of every actor."""

    def send(self, poses: Sequence[ActorPose]) -> None:
        """Send the poses of one instant (one per actor)."""

    def close(self) -> None:
        """Release sockets and files."""
