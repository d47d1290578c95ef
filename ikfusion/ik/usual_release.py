"""The usual frame's release, told apart in a few bit operations: nothing lets go nor lands.

On most frames of a walk one foot stands planted, its IMU says it stands still, the other foot
swings and no point is lifted, tilted nor hinted: :func:`.contacts.release_contacts` then
returns its state unchanged, after some twenty calls (the evidence's bits, the points' motion,
the hints, the plant heights, the drift of two feet). :func:`keeps_every_point` reads that off
the frame's :class:`.point_evidence.FrameEvidence` bits alone (:mod:`.point_bits`), exactly:
where it says True the general rule returns the same state, and where it says False the
general rule decides. :func:`.contacts.release_contacts` asks it first and returns at once
where it may; the rest of that function is the reference (``tests/ik/test_usual_release.py``
checks the two on the real walk's frames and on random ones).
"""

from __future__ import annotations

from .point_bits import PointBits
from .point_evidence import FrameEvidence


def keeps_every_point(bits: PointBits, on: int, evidence: FrameEvidence,
                      leave_distance: float) -> bool:
    """Whether :func:`.contacts.release_contacts` keeps its state as it is (a sufficient test).

    Valid for the call without hints, toe-offs nor points' motion (``hints``, ``toe_off`` and
    ``points_moving`` None) and with the feet's stance (``foot_still`` given), whose evidence
    and planted points (bits) are ``evidence`` and ``on``. False where the points of two feet
    are planted (their drift decides: ``leave_distance`` [m], negative: always), where a still
    foot is free (it may be planted), where a planted point is lifted or tilted (it lets go)
    and where a planted trunk point may roll onto another point of its segment.
    """
    if leave_distance < 0 or on & bits.other_foot(on):
        return False
    still = evidence.still
    if still & ~on & ~evidence.tilted:
        return False
    # (one foot planted: no moving point is handed over to the other, none is pulled)
    if on & (evidence.high | evidence.tilted) & ~(still & bits.stepping):
        return False
    return not on & evidence.rest & bits.shares_segment
