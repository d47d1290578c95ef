"""A point sweeping over the floor does not take the body from a point that stands.

A helper of :mod:`.contacts` (``release_contacts``), on (k,) arrays of the contact points.

A body rising from the floor pushes off a toe while a palm sweeps along the floor beside it
(dm-getup-faceup: 0.7 m/s) and the other foot lands. The palm is the lowest point, so the toe,
lifted a couple of centimetres above it, lets go, and the lowest point takes the body; the
sweeping palm then drags the body with it. Accelerations cannot tell the palm from the landing
foot (the hand shakes less than the foot that lands). Velocities can: while the IMU of the point
that lets go says it does not move (:mod:`ikfusion.imu.point_speed`), the sensed pose's velocity
relative to it is each point's own, and a point faster than ``enter_speed`` horizontally would
not touch down (:func:`.contacts.touch_down`): it takes nothing, the standing point keeps the
body until a slow point takes it.
"""

from __future__ import annotations

import numpy as np

from .fast_math import row_norms
from .point_bits import PointBits, first
from .point_evidence import motion_bits


def sweeping_points(v_sensed: np.ndarray | None, kept: int, settled: np.ndarray,
                    limit: float) -> np.ndarray:
    """(k,) points moving faster than ``limit`` over the floor relative to point ``kept``.

    Args:
        v_sensed: (k, 3) velocities of the points in the sensed pose [m/s] (any translation:
            only differences count), None when unknown.
        kept: The planted point that lets go.
        settled: (k,) points whose IMU says they do not move; none are sweeping unless
            ``kept`` is one (a point leaving the floor moves: relative to it, all do).
        limit: Horizontal speed [m/s] above which a point takes nothing (``enter_speed``).
    """
    if v_sensed is None or not bool(settled[kept]):
        return np.zeros(len(settled), dtype=bool)
    return np.asarray(row_norms((v_sensed - v_sensed[kept])[:, :2]) > limit)


def sweeping_beside(bits: PointBits, v_sensed: np.ndarray | None, on: int,
                    points_moving: np.ndarray | None, limit: float) -> int:
    """Points (bits) sweeping relative to a planted point (in ``on``) its IMU says stands.

    The first such point is the reference (:func:`sweeping_points`); bits as in
    :mod:`.point_bits`.
    """
    settled = motion_bits(bits, points_moving)[1]
    if v_sensed is None or not on & settled:
        return 0
    return bits.of(sweeping_points(v_sensed, first(on & settled), bits.mask(settled), limit))
