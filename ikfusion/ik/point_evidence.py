"""Per contact point, what a frame's evidence says: hints, IMU motion, the foot's pitch.

Helpers of :mod:`.contacts` (``release_contacts`` and ``touch_down``), on (k,) arrays of the
contact points; the masks they combine as the bits of ints (:mod:`.point_bits`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numpy as np

from .fast_math import min_of
from .point_bits import PointBits, above, below, below_above, indices
from .point_masks import LastInput


def hinted_points(names: Sequence[str],
                  hints: Mapping[str, object] | None) -> list[tuple[int, bool]]:
    """(index, in contact) of the points ``hints`` names; none without hints (the usual case).

    A hint is anything ``bool`` takes (NumPy's booleans too: compiled, :mod:`ikfusion.native.
    typed_modules`, a ``bool`` annotation would refuse them).
    """
    if not hints:
        return []
    return [(i, bool(hints[n])) for i, n in enumerate(names) if n in hints]


def heights_above_lowest(p_sensed: np.ndarray, lowest: float | None = None) -> np.ndarray:
    """(k,) how far each point is above the lowest of ``p_sensed`` (k, 3) [m] (world z).

    Worked out once per frame (:func:`frame_evidence`), for the release and the touch-down.
    ``lowest``: that lowest height [m] when the caller has it (``min_of`` of the heights).
    """
    z = p_sensed[:, 2]
    return z - (min_of(z) if lowest is None else lowest)


def _by_rest(needs_rest: np.ndarray, rest: float, other: float) -> np.ndarray:
    """(k,) ``rest`` for the points that need rest (the trunk), ``other`` for the others."""
    return np.where(np.asarray(needs_rest, dtype=bool), rest, other)


by_rest = LastInput(_by_rest)  # :func:`_by_rest`, kept for a read-only ``needs_rest``


def moving_rest_points(needs_rest: np.ndarray | None, foot_still: np.ndarray | None,
                       k: int) -> np.ndarray:
    """(k,) ``needs_rest`` points whose segment's IMU says it moves (``foot_still`` 0)."""
    if needs_rest is None or foot_still is None:
        return np.zeros(k, dtype=bool)
    return np.asarray(needs_rest, dtype=bool) & (np.asarray(foot_still, dtype=float) == 0.0)


def tilted_bits(bits: PointBits, foot_pitch: np.ndarray | None, limit: float) -> int:
    """Points (bits) whose foot pitch [rad] rules them out past ``limit`` [rad].

    Heels when toe-down, toes when toe-up; none without a pitch.
    """
    if foot_pitch is None:
        return 0
    pitch = np.asarray(foot_pitch, dtype=float).tolist()
    return tilted_of(pitch, limit, indices(bits.heels), indices(bits.toes))


def tilted_of(pitch: list[float], limit: float, heels: Sequence[int], toes: Sequence[int]) -> int:
    """The ``heels`` pitched more than ``limit`` [rad] toe-down, ``toes`` more than it toe-up.

    ``pitch``: each point's foot pitch [rad] (toe down positive; NaN, unknown, compares False).
    """
    return above(pitch, limit, heels) | below(pitch, -limit, toes)


def motion_bits(bits: PointBits, points_moving: np.ndarray | None) -> tuple[int, int]:
    """Per point (bits), its IMU says it moves (``points_moving`` 1); ... does not (0).

    Neither where unknown (NaN); nothing known without ``points_moving``.
    """
    return _known_bits(bits, "motion", points_moving)


def stance_bits(bits: PointBits, foot_still: np.ndarray | None) -> tuple[int, int]:
    """Per point, its foot's IMU says it stands still (``foot_still`` 1); ... it moves (0)."""
    return _known_bits(bits, "stance", foot_still)


def _known_bits(bits: PointBits, name: str, evidence: np.ndarray | None) -> tuple[int, int]:
    """The points where ``evidence`` (k,) is 1, and where it is 0 (NaN: neither), per pattern."""
    if evidence is None:
        return 0, 0
    value = np.asarray(evidence, dtype=float)
    return bits.memo(name, value.tobytes(),
                     lambda: (bits.of(value == 1.0), bits.of(value == 0.0)))


class FrameEvidence(NamedTuple):
    """What one frame's sensed pose and IMUs say of each contact point, worked out once.

    The release before the solve (:func:`.contacts.release_contacts`) and the touch-down after
    it (:func:`.contacts.touch_down`) read the same smoothed sensed points, foot pitches and
    feet stance (:class:`.contact_tracker.ContactTracker` keeps them for the frame), so their
    masks are computed here once per frame; none depends on the solve of the frame. (A named
    tuple: made every frame, it costs a tenth of a frozen dataclass.)

    Attributes:
        height_rel: (k,) [m] how far each point is above the lowest of the sensed pose.
        tilted: Points (bits) their foot's pitch rules out (:func:`tilted_bits`).
        still: Points whose foot's IMU says it stands still; ``foot_moves``: ... it moves.
        rest: The ``needs_rest`` points (the trunk; bits).
        high: Points more than ``leave_relative`` above the lowest.
        low: Points less than ``enter_relative`` above the lowest.
    """

    height_rel: np.ndarray
    tilted: int
    still: int
    foot_moves: int
    rest: int
    high: int
    low: int


def frame_evidence(bits: PointBits, height_rel: np.ndarray, foot_pitch: np.ndarray | None,
                   stance: tuple[int, int], rest: int, tilt: float, leave_relative: float,
                   enter_relative: float) -> FrameEvidence:
    """The :class:`FrameEvidence` of one frame's sensed points.

    Args:
        bits: The points' :class:`PointBits`.
        height_rel: (k,) how far each point is above the lowest (:func:`heights_above_lowest`
            of the smoothed sensed pose) [m].
        foot_pitch: (k,) each point's foot pitch [rad] (toe down positive, NaN unknown).
        stance: The points whose foot stands still by its IMU and those whose foot moves
            (:func:`stance_bits`).
        rest: The points where the body rests only lying or sitting (bits).
        tilt: The pitch [rad] past which a heel or toe is ruled out.
        leave_relative: ``high``'s height above the lowest point [m].
        enter_relative: ``low``'s height above the lowest point [m].
    """
    low, high = below_above(height_rel.tolist(), enter_relative, leave_relative)
    return FrameEvidence(height_rel, tilted_bits(bits, foot_pitch, tilt), stance[0], stance[1],
                         rest, high, low)
