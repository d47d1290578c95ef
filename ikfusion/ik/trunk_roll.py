"""A body rolling on its back: the contact passes along the trunk instead of sliding with it.

Helpers of :mod:`.contacts` (``release_contacts``), on (k,) arrays of the contact points or
their bits (:mod:`.point_bits`); positions in metres, world z up.

A body sitting up from lying on its back rolls over its back: the contact leaves the shoulder
blades for the sacrum, then the sacrum for a buttock. The trunk points are fixed points of
their segments (the pelvis: sacrum and buttocks; T8: shoulder blades and chest), while the true
contact moves over the body's surface as it rolls. Two rules follow:

* when the planted trunk point lets go, the trunk may carry on: a trunk point takes the body
  even while its segment's IMU says it moves (:func:`body_takers`); otherwise a moving trunk
  point takes nothing (a body rising swings it low through the air) and a palm a few
  centimetres higher, sweeping over the floor, took the body and dragged it along;
* a planted trunk point hands its hold over to a lower point of its own rigid segment as soon
  as the sensed pose puts that one lower (:func:`roll_on_segment`): held until it is lifted
  ``leave_relative`` above the lowest point, the old point would hold the rolling segment still
  where the true contact has moved on, and the body slid by as much.
"""

from __future__ import annotations

import numpy as np

from ..model.topology import FootLayout
from .fast_math import any_true, true_indices
from .point_bits import PointBits
from .point_evidence import moving_rest_points

#: A point of a planted trunk point's segment this much [m] lower in the sensed pose takes
#: the hold over (a margin against flip-flops between two points at one height, far below the
#: ``leave_relative`` at which the held point would let go).
ROLL_MARGIN = 0.002


def body_takers(needs_rest: np.ndarray | None, foot_still: np.ndarray | None,
                kept: int, k: int) -> np.ndarray:
    """(k,) the points that may take the body when every planted point lets go.

    Args:
        needs_rest: (k,) trunk points (None: none).
        foot_still: (k,) 1 where each point's segment rests by its IMU, 0 where it moves,
            NaN unknown (None: nothing known).
        kept: The planted point that held the body longest (the lowest planted one).
        k: Number of contact points.

    Returns:
        Every point but the trunk points whose segment moves; those too when ``kept`` is a
        trunk point (the body rolls along its back).
    """
    if needs_rest is not None and bool(needs_rest[kept]):
        return np.ones(k, dtype=bool)
    return ~moving_rest_points(needs_rest, foot_still, k)


def roll_on_segment(active: np.ndarray, anchors: np.ndarray, age: np.ndarray,
                    released: np.ndarray, p_sensed: np.ndarray, needs_rest: np.ndarray | None,
                    layout: FootLayout, floor_z: float) -> None:
    """Hand each planted trunk point's hold to a lower point of its segment (in place).

    The point ``j`` taking over from ``i`` is the lowest free trunk point of ``i``'s rigid
    segment, when it is ``ROLL_MARGIN`` lower than ``i`` in the sensed pose; it is anchored
    where the sensed segment puts it relative to ``i``'s anchor (no jump: the solved segment
    already has it there), on or above the floor, and keeps ``i``'s contact age.

    Args:
        active: (k,) planted points (updated).
        anchors: (k, 3) anchors [m] (updated).
        age: (k,) contact ages [s] (updated).
        released: (k,) time since each point let go [s] (updated: 0 for a point that hands
            over).
        p_sensed: (k, 3) the sensed pose's contact points [m] (any translation).
        needs_rest: (k,) trunk points (None: none, nothing rolls).
        layout: Which points share a rigid segment (``same_segment``, ``shares_segment``).
        floor_z: Floor height [m].
    """
    if needs_rest is None:
        return
    trunk = np.asarray(needs_rest, dtype=bool)
    held = active & trunk & layout.shares_segment
    if not any_true(held):  # the usual frame: no trunk point planted
        return
    z = p_sensed[:, 2]
    for i in true_indices(held):
        free = trunk & layout.same_segment[i] & ~active
        if not any_true(free):
            continue
        j = int(np.argmin(np.where(free, z, np.inf)))
        if z[j] > z[i] - ROLL_MARGIN:
            continue
        anchors[j] = anchors[i] + (p_sensed[j] - p_sensed[i])
        anchors[j, 2] = max(float(anchors[j, 2]), floor_z)
        active[i], active[j] = False, True
        age[j], released[i] = age[i], 0.0


def pulled_points(bits: PointBits, disagrees: int, older: int, staying: int,
                  trunk: int) -> int:
    """Planted points (bits) that let go as the other planted points pull them off their anchor.

    Of two feet that disagree the one planted earlier lets go (toe-off). A body resting on its
    trunk keeps it: a planted trunk point's drift is its roll, and a point that disagrees
    with a planted trunk point (a palm or a foot brushing the floor beside a seat) lets go
    whatever its age.

    Args:
        bits: The contact points' groups (:mod:`.point_bits`); the masks below are bits.
        disagrees: Points pulled farther than ``leave_distance`` from their anchor.
        older: Points planted no later than the other foot's planted points.
        staying: Planted points.
        trunk: Trunk points (``needs_rest``; 0: none).
    """
    if not staying & trunk:
        return disagrees & older
    return disagrees & ~trunk & (older | bits.other_foot(staying & trunk))
