"""A foot that lands while the pelvis lags is anchored where the body without the lag puts it.

The support's *lag* (:mod:`.support`) is how far the pelvis is held from where the reference
foot's anchors and the sensed legs put it; it shrinks at ``lag_speed`` while the planted legs
take it up. IMU only, the lag grows at each push-off: the trailing toe's tip, carried along the
floor by its foot IMU (:mod:`.anchor_carry`), runs ahead of the pelvis, which follows at the
lag's speed. The swing leg hangs from that lagging pelvis, so the heel that lands then is
solved behind by the lag (8-13 mm at each step of cmu-02-02-walk) and anchored there: the new
foot agrees with the lagging body, the lag is handed over without a jump and shrinks to zero
without the body ever moving by it. Each step lost it (cmu-02-02-walk's sensed-links loss).

A heel that strikes while the body stands on the other foot's toes alone is therefore anchored
at its solved position less the lag (horizontally): the body catches up with it through the new
foot too. When those toes let go first (a lone toe pushing off, :mod:`.contacts`), the body flies
a few frames and the support forgets its lag: the contact tracker keeps the points the body took
off from and their lag, and passes them here at the landing in place of the planted points.
Only then, and only for a lag without height, which anchors carried along the floor
alone made: a foot that lands flat or on its toes (a skip, a crouch, a kick's return), or a heel
after a hand-over's disagreement (in height too: amp-dance-spins' whirls, 16-24 mm), lands after
lags of other origins, and moving its anchors made those clips worse (gen-skip's head 26.7 ->
44.6 cm, amp-dance-spins' 5.9 -> 6.9 cm IMU only). And only with the foot IMUs' point
velocities (IMU only, offline), where the lag is drift alone; with a correction the swing foot
is led to where the corrected body wants it (:mod:`.support`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..model.topology import FootLayout
from .contacts import ContactState
from .fast_math import any_true
from .frame import Frame


def unlagged_landings(before: np.ndarray, state: ContactState, layout: FootLayout,
                      lag: np.ndarray, frame: Frame) -> ContactState:
    """``state`` with a heel that struck while the body stood on toes alone moved by ``-lag``.

    Args:
        before: (k,) the points planted before this touch-down (after a flight: the points
            the body took off from).
        state: The contact state after it.
        layout: The points' feet (heels: on a foot proper; toes: below it).
        lag: (3,) the support's lag [m] (pelvis less where the reference foot puts it; after
            a flight, the one at its take-off); one with height is left alone.
        frame: The frame (with its points' velocities, IMU only; else ``state`` as it is).
    """
    if not frame.points_velocity or len(before) != len(state.active) or lag[2] != 0.0 \
            or not (lag[0] or lag[1]):
        return state
    landed = state.active & ~before
    heels = layout.stepping & ~layout.below_foot
    if not any_true(landed & heels) or any_true(landed & ~heels) \
            or not any_true(before) or any_true(before & ~layout.below_foot):
        return state
    landed &= ~(layout.same_foot & before[None, :]).any(axis=1)
    if not any_true(landed):
        return state
    anchors = state.anchors.copy()
    anchors[landed, :2] -= lag[:2]
    return replace(state, anchors=anchors)
