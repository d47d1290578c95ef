"""Where a point that takes the body over is anchored: where the solve carries it, not a jump.

Helper of :mod:`.contacts` (``release_contacts``) and :mod:`.contact_tracker`; positions in
metres, world z up.

When every planted point lets go and the lowest point of the sensed pose takes the body (a palm
after a buttock, a palm after a foot in a cartwheel), the new anchor used to be where the
*sensed* pose puts the point relative to the anchors let go. The solved pose is not the sensed
pose: the floor and the planted points bend it (a palm the truth has under the floor while the
body sits on a buttock: 3 deg at T8), so the sensed geometry put the anchor 1-2 cm beside where
the solved point was and the whole body jumped by that much in one frame. Horizontally the
anchor is now where this frame's solve would carry the point while the old points still held:
its last solved position, moved by its sensed motion over the frame relative to theirs. (The
height still comes from the sensed pose, on or above the floor: a foot swung overhead in a
cartwheel holds the solved body high, the palm taking over belongs on the floor.)
"""

from __future__ import annotations

import numpy as np

from ..model.topology import FootLayout
from .fast_math import any_true, mean_rows, true_indices
from .foot_pairs import landing_anchors


def sensed_offset(p_sensed: np.ndarray, anchors: np.ndarray, reference: np.ndarray
                  ) -> np.ndarray:
    """The shift (3,) [m] putting the sensed pose onto the ``reference`` anchors on average.

    Zero without a reference point.
    """
    if not any_true(reference):
        return np.zeros(3)
    return mean_rows(anchors[reference] - p_sensed[reference])


def carried_points(p_solved: np.ndarray, step_sensed: np.ndarray,
                   support: np.ndarray) -> np.ndarray:
    """(k, 3) where this frame's solve would put each contact point if ``support`` held [m].

    Args:
        p_solved: (k, 3) the points in the last solved pose [m].
        step_sensed: (k, 3) each point's motion in the sensed pose since that frame [m]
            (any translation: only the motion relative to the support counts).
        support: (k,) the points that held the body in the last solve.

    Returns:
        ``p_solved`` moved by each point's sensed motion minus the support's mean sensed
        motion (the support's points stay where they were); ``p_solved`` without support.
    """
    if not any_true(support):
        return p_solved.copy()
    return p_solved + step_sensed - mean_rows(step_sensed[support])


def takeover_anchors(p_sensed: np.ndarray, anchors: np.ndarray, support: np.ndarray,
                     plant: np.ndarray, p_solved: np.ndarray | None,
                     step_sensed: np.ndarray | None) -> np.ndarray:
    """Anchors (m, 3) [m] of the ``plant`` points taking the body over from ``support``.

    Args:
        p_sensed: (k, 3) the points in this frame's sensed pose [m] (any translation).
        anchors: (k, 3) the anchors of the points letting go [m].
        support: (k,) the points that held the body in the last solve and let go now.
        plant: (k,) the points taking over.
        p_solved: (k, 3) the points in the last solved pose [m] (None: unknown).
        step_sensed: (k, 3) their sensed motion since then [m] (None: unknown, taken as none).

    Returns:
        Where the sensed pose puts them aligned on the ``support`` anchors, horizontally moved
        to where the solve carries them (:func:`carried_points`) when the last solve is known.
    """
    out = p_sensed[plant] + sensed_offset(p_sensed, anchors, support)
    if p_solved is not None:
        carried = (p_solved if step_sensed is None
                   else carried_points(p_solved, step_sensed, support))
        out[:, :2] = carried[plant, :2]
    return out


def plant_anchors(anchors: np.ndarray, plant: np.ndarray, active: np.ndarray,
                   staying: np.ndarray, handover: bool, p_sensed: np.ndarray,
                   p_solved: np.ndarray | None, step_sensed: np.ndarray | None,
                   layout: FootLayout, floor_z: float) -> None:
    """Anchor the ``plant`` points (k,) of :func:`release_contacts` (``anchors`` in place).

    A point taking the body over where the solve carries it (``handover``), else where it
    lands beside the ``staying`` points (still planted) or, without a last solve, where the
    sensed pose puts it relative to them (or to ``active`` when none stays); on or above the
    floor ``floor_z`` [m].
    """
    if handover:
        anchors[plant] = takeover_anchors(p_sensed, anchors, active, plant, p_solved,
                                          step_sensed)
    elif p_solved is not None:
        anchors[plant] = landing_anchors(layout, staying, anchors, p_solved, plant)
    else:
        reference = staying if any_true(staying) else active
        same = layout.same_foot
        for j in true_indices(plant):
            # the point's own foot, when planted, keeps that foot's anchors in shape
            own = reference & same[j]
            ref = own if any_true(own) else reference & ~same[j]
            anchors[j] = p_sensed[j] + sensed_offset(p_sensed, anchors, ref)
    anchors[plant, 2] = np.maximum(anchors[plant, 2], floor_z)
