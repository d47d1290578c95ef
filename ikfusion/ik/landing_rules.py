"""Which candidate points may land in a frame, the touch-down's rules other than height.

A helper of :func:`.contacts.touch_down`: a point near the floor and among the lowest of the
sensed pose lands when it is slow, not ruled out by its foot's pitch, not let go just now, and
its IMUs do not say otherwise. The rules run on the few candidates of a frame only (bits of ints,
:mod:`.point_bits`; their speeds with floats, the sums of ``row_norms``).
"""

from __future__ import annotations

import math

import numpy as np

from .contact_thresholds import ContactThresholds
from .point_bits import PointBits, indices
from .point_evidence import FrameEvidence, motion_bits


def may_land(bits: PointBits, on: int, enter: int, p_solved: np.ndarray,
             p_solved_previous: np.ndarray, dt: float, ev: FrameEvidence, released: np.ndarray,
             th: ContactThresholds, points_moving: np.ndarray | None) -> int:
    """Of the points ``enter`` (bits), those :func:`.contacts.touch_down` lets land.

    Its rules other than height, for the candidates near the floor and among the lowest
    (``p_solved`` and ``p_solved_previous`` (k, 3) [m] ``dt`` [s] apart; ``released`` (k,) [s]
    since each point let go).

    Slow (or known not to move, or as low as a support that moves), not ruled out by the foot
    pitch, not let go just now (toe-off), not a moving point while a point of the other foot
    that does not move holds the body, not a trunk point whose segment moves. ``on``: the
    planted points; ``ev``: the frame's evidence.
    """
    moving_point, settled = motion_bits(bits, points_moving)
    since = released.tolist()
    # the rules without speeds first: most candidates fail them (a toe let go just now, a foot
    # pitched), and the rest is a conjunction of rules of each point alone
    enter &= (~ev.tilted & ~(ev.rest & ev.foot_moves)
              & (sum(1 << i for i in indices(enter) if since[i] >= th.reenter_delay) | settled))
    if points_moving is not None:  # see :func:`.contacts.release_contacts`
        enter &= ~(moving_point & bits.other_foot(on & ~moving_point))
    if not enter:
        return 0
    # a point that just let go (toe-off) does not come back down at once while it is low,
    # unless its foot IMU says it no longer moves (a landing heel let go while it skidded).
    # A point its foot IMU says does not move is slow whatever its solved speed: that speed
    # is relative to the planted points, and a planted point that truly slides (a toe dragged
    # at push-off) moves the whole solved body, the landing foot with it. For the same reason
    # the solved speed says nothing while the IMUs say every planted point moves (a body held
    # on a toe that lifts): the sensed pose decides then, a point taking the body once it is
    # as low as the planted points.
    height_rel = ev.height_rel
    support_moving = (bits.of(height_rel <= np.min(height_rel[bits.mask(on)], initial=np.inf))
                      if on and not on & ~moving_point else 0)
    return enter & (_slow(indices(enter), p_solved, p_solved_previous, dt, th.enter_speed)
                    | settled | support_moving)


def _slow(rows: tuple[int, ...], p: np.ndarray, p_before: np.ndarray, dt: float,
          limit: float) -> int:
    """The points of ``rows`` (bits) slower than ``limit`` [m/s] from ``p_before`` to ``p``.

    Their speed ``|p - p_before| / dt`` (rows of (k, 3) [m]; 0 for ``dt`` <= 0 [s]), by the
    sums of ``row_norms``, for the few candidate points of a frame.
    """
    if dt <= 0:
        return sum(1 << i for i in rows) if 0.0 < limit else 0
    out = 0
    for i in rows:
        (x, y, z), (u, v, w) = p[i].tolist(), p_before[i].tolist()
        dx, dy, dz = x - u, y - v, z - w
        if math.sqrt(dx * dx + dy * dy + dz * dz) / dt < limit:
            out |= 1 << i
    return out

