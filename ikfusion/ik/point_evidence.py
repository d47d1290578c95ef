"""Per contact point, what a frame's evidence says: hints, IMU motion, the foot's pitch.

Helpers of :mod:`.contacts` (``release_contacts`` and ``touch_down``), on (k,) arrays of the
contact points.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..model.topology import FootLayout
from .fast_math import any_true


def hinted_points(names: Sequence[str],
                  hints: Mapping[str, bool] | None) -> list[tuple[int, bool]]:
    """(index, in contact) of the points ``hints`` names; none without hints (the usual case)."""
    if not hints:
        return []
    return [(i, bool(hints[n])) for i, n in enumerate(names) if n in hints]


def moving_rest_points(needs_rest: np.ndarray | None, foot_still: np.ndarray | None,
                       k: int) -> np.ndarray:
    """(k,) ``needs_rest`` points whose segment's IMU says it moves (``foot_still`` 0)."""
    if needs_rest is None or foot_still is None:
        return np.zeros(k, dtype=bool)
    return np.asarray(needs_rest, dtype=bool) & (np.asarray(foot_still, dtype=float) == 0.0)


def point_motion(points_moving: np.ndarray | None, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Per point (k,): its IMU says it moves; its IMU says it does not (both False: unknown)."""
    if points_moving is None:
        return np.zeros(k, dtype=bool), np.zeros(k, dtype=bool)
    value = np.asarray(points_moving, dtype=float)  # NaN compares False both ways
    return value == 1.0, value == 0.0


def all_planted_moving(active: np.ndarray, moving_point: np.ndarray) -> bool:
    """Some point is planted and the IMUs say every planted point moves."""
    return any_true(active) and not any_true(active & ~moving_point)


def tilted_points(layout: FootLayout, foot_pitch: np.ndarray | None, limit: float) -> np.ndarray:
    """Points whose foot pitch rules them out: heels when toe-down, toes when toe-up."""
    if foot_pitch is None:
        return np.zeros(len(layout.on_foot), dtype=bool)
    heel, toe = layout.on_foot, layout.below_foot
    pitch = foot_pitch if isinstance(foot_pitch, np.ndarray) \
        else np.asarray(foot_pitch, dtype=float)  # NaN (unknown) compares False: not tilted
    return (heel & (pitch > limit)) | (toe & (pitch < -limit))
