"""Contact detection from the kinematics, heel and toe separately, with hysteresis.

A contact point enters contact when it is near the floor, nearly still horizontally and among
the lowest points of the body. It leaves when the *sensed* pose (every joint between two tracked
segments set from the targets, before the no-slip constraints bend anything) lifts it above the
lowest point or pulls it away from its anchor: a planted point cannot reveal lift-off by its own
motion, since the constraint holds it. Hints given with a frame override the detection.

When the feet carry IMUs, their stance (:mod:`ikfusion.imu.stance`) is stronger evidence than the
kinematics: a still foot keeps its planted points, a still foot near the floor is planted at once
where the sensed pose puts it relative to the points planted so far, and a moving foot lets go as
soon as the other foot stands still (the body is handed over to the still foot, so a kinematic
threshold missed by a few centimetres cannot hold a swinging foot on the floor), except its points
that the foot IMU says do not move (:mod:`ikfusion.imu.point_speed`). Knees and palms may carry the
same evidence from their accelerometers (:mod:`ikfusion.imu.resting`), weaker than a foot's: it
plants and hands over, but does not stop the sensed pose from lifting them. So may the points where
a lying or sitting body rests (sacrum, buttocks, shoulder blades, chest: ``needs_rest``), with a
stricter rule, as their segments are also calm when the body stands still: they are planted only
among the lowest points and never while their segment's IMU says it moves (a body rolling on its
back: :mod:`.trunk_roll`). When every planted point lets go, the lowest point of the sensed pose
takes the body (a palm in a cartwheel), not a foot swung overhead nor one sweeping over the floor
(:mod:`.sweeping`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..model.topology import FootLayout
from .anchor_settling import settled_anchors
from .contact_clocks import ClockStep, python_clocks
from .contact_thresholds import ContactThresholds
from .foot_pairs import drifting_points, landing_anchors, other_foot_age
from .handover import plant_anchors
from .landing_rules import may_land
from .point_bits import PointBits, below, has, indices, point_bits
from .point_evidence import (
    FrameEvidence,
    by_rest,
    frame_evidence,
    heights_above_lowest,
    hinted_points,
    motion_bits,
    stance_bits,
)
from .sweeping import sweeping_beside, sweeping_points
from .trunk_roll import body_takers, pulled_points, roll_on_segment
from .usual_release import keeps_every_point


@dataclass
class ContactState:
    """Contact state of every contact point.

    Attributes:
        names: Contact point names.
        active: (k,) in contact.
        anchors: (k, 3) [m] where each point is held while in contact.
        age: (k,) [s] how long each point has been in contact.
        released: (k,) [s] how long ago each point left contact (inf: never in contact).

    A state is replaced, never written to: successive states share the arrays that did not
    change.
    """

    names: list[str]
    active: np.ndarray
    anchors: np.ndarray
    age: np.ndarray
    released: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        if len(self.released) != len(self.names):
            self.released = np.full(len(self.names), np.inf)

    @classmethod
    def empty(cls, names: Sequence[str]) -> ContactState:
        """No point in contact."""
        k = len(names)
        return cls(list(names), np.zeros(k, dtype=bool), np.zeros((k, 3)), np.zeros(k))

    def as_dict(self) -> dict[str, bool]:
        """Name -> in contact."""
        return {n: bool(a) for n, a in zip(self.names, self.active)}


def release_contacts(state: ContactState, p_sensed: np.ndarray, thresholds: ContactThresholds,
                     hints: Mapping[str, bool] | None = None,
                     foot_pitch: np.ndarray | None = None,
                     foot_still: np.ndarray | None = None,
                     p_solved: np.ndarray | None = None, placed: np.ndarray | None = None, *,
                     layout: FootLayout, points_moving: np.ndarray | None = None,
                     needs_rest: np.ndarray | None = None,
                     v_sensed: np.ndarray | None = None,
                     step_sensed: np.ndarray | None = None,
                     toe_off: np.ndarray | None = None,
                     evidence: FrameEvidence | None = None,
                     on: int | None = None) -> ContactState:
    """Let go of planted points the current frame's sensed pose lifts (run before solving).

    With ``foot_still``, also plant the points of still feet and hand the body over to them.

    Args:
        state: Current state.
        p_sensed: (k, 3) the contact points in this frame's sensed pose [m] (any translation).
        thresholds: Hysteresis thresholds.
        hints: Name -> in contact, overriding the detection for those points.
        foot_pitch: (k,) pitch [rad] of each point's foot (toe down positive), NaN when unknown.
            A foot pitched toe-down cannot stand on its heel, one pitched toe-up not on its toes.
        foot_still: (k,) 1 where each point's foot stands still by its IMU, 0 where it moves,
            NaN when unknown. Sensor noise in the pose cannot lift a still foot.
        p_solved: (k, 3) contact point positions of the last solved pose [m]: where points
            planted by stance are anchored (on or above the floor; anchors settle down).
        placed: (k, 3) offsets [m] by which anchors were placed on purpose away from where the
            sensed legs put them (a swing foot led by the drift correction): not drift.
        layout: Which points share a foot (:meth:`BodyTopology.foot_layout`).
        points_moving: (k,) 1 where a point's foot IMU says the point itself moves (a heel that
            rises, a toe that pushes off while its foot turns), 0 where it says the point does
            not, NaN unknown (booleans: True and False). A moving point lets go while a point of
            the other foot that does not move stays planted (when every point moves, as on a
            skating mocap clip, the kinematic rules decide alone). A point known not to move
            is not handed over with its foot when that foot stops standing still: the foot of a
            two-footed take-off accelerates flat on the floor before it turns or slides, and
            one foot crossing the stance thresholds a sample before the other must not lift it
            (the ball of a foot that rolls over it stays too, until it moves itself).
        needs_rest: (k,) points where the body rests only lying or sitting (the trunk): one
            whose segment's IMU says it moves is never planted, nor takes the body when the
            planted points let go (a body rising) unless a trunk point held it (rolling on its
            back: :mod:`.trunk_roll`); it counts as the lowest point; a resting one is planted
            only among the lowest points (``enter_relative``), not within ``still_relative``
            as a foot, knee or palm (None: no such point).
        v_sensed: (k, 3) the points' sensed-pose velocities [m/s] (:mod:`.sweeping`).
        step_sensed: (k, 3) the points' sensed-pose motion since ``p_solved``'s frame [m]
            (a point taking the body over: :mod:`.handover`).
        toe_off: (k,) lone toes sliding by their foot IMU (:class:`.anchor_carry.AnchorCarry`):
            they let go even holding the body alone (it flies; held, it fell back 3-5 mm).
        evidence: The :func:`.point_evidence.frame_evidence` of these arguments, when the
            caller worked it out already (None: worked out here).
        on: ``state.active`` as bits (:mod:`.point_bits`), when the caller has them.

    Returns:
        A new state: the same anchors for the points that stay, fewer active points, and
        anchors for the points planted by stance.
    """
    th = thresholds
    active = state.active  # read only: the new state's is built at the end
    # masks as the bits of ints (:mod:`.point_bits`): bit i is point i
    bits = point_bits(layout)
    on = bits.of(active) if on is None else on  # planted
    ev = evidence or _evidence(bits, p_sensed, foot_pitch, foot_still, needs_rest, th)
    if not hints and toe_off is None and points_moving is None and foot_still is not None \
            and keeps_every_point(bits, on, ev, th.leave_distance):
        return state  # the usual frame: nothing lets go nor lands (:mod:`.usual_release`)
    height_rel, tilted, still, rest = ev.height_rel, ev.tilted, ev.still, ev.rest
    moving_point, settled = motion_bits(bits, points_moving)
    pushing_off = bits.of_optional(toe_off)  # lone toes pushing off: they let go
    handed_over = plant = 0
    if foot_still is not None:
        # A moving foot lets go once the other foot stands planted and still; a still foot
        # low in the sensed pose is planted while the other foot holds the body (after a
        # flight the usual touch-down, near the floor and slow, plants the landing feet).
        plant = still & ~on & ~tilted
        if plant:
            plant &= bits.of(height_rel < _plant_height(th, needs_rest)) & bits.other_foot(on)
        moving = on & ev.foot_moves
        if moving:  # ... handed over to the other foot, planted still or planted now
            handed_over = moving & bits.other_foot((on & still) | plant) & ~settled
    staying = on & ~handed_over
    # Two planted feet that disagree: the foot planted earlier lets go (toe-off), even a
    # still one (its anchor is out of date); a still foot ignores the sensed height and pitch.
    pulled = 0  # one foot planted: no drift from another (nothing pulled, as leave_distance >= 0)
    if staying & bits.other_foot(staying) or th.leave_distance < 0:
        held = state.anchors if placed is None else state.anchors - placed
        planted = bits.mask(staying)
        # only a planted point that disagrees may be pulled (the ages of the rare frame)
        if disagrees := drifting_points(layout, planted, held, p_sensed, th.leave_distance,
                                        indices(staying)):
            older = bits.of(state.age >= other_foot_age(layout, planted, state.age))
            pulled = pulled_points(bits, disagrees, older, staying, rest)
    # a resting knee or palm (calm accelerometer) is weaker evidence than a still foot: the
    # sensed pose may still lift it
    lifted = (ev.high | tilted) & ~(still & bits.stepping)
    leave = staying & (lifted | pulled | pushing_off) | handed_over
    if points_moving is not None:  # while a still point of the other foot holds the body
        leave |= staying & moving_point & bits.other_foot(staying & ~moving_point)
    for i, hinted in hinted_points(state.names, hints):
        point = 1 << i
        leave = leave | point if on & point and not hinted else leave & ~point
        plant = plant if not on & point and hinted else plant & ~point
    handover = False
    if on and not on & ~leave and not plant and not hints:
        # Without a flight hint the lowest point of the sensed pose keeps the body down: the
        # lowest planted one, unless the body rests on another point (hands in a cartwheel)
        # or the planted points are all well above the lowest (a foot swung overhead).
        # (a trunk point whose segment's IMU says it moves takes nothing, a body rising swings
        # it low through the air, unless the body rolls on its back: :mod:`.trunk_roll`)
        kept = int(np.argmin(np.where(active, p_sensed[:, 2], np.inf)))
        takers = body_takers(needs_rest, foot_still, kept, len(active)) & ~sweeping_points(
            v_sensed, kept, bits.mask(settled) & (height_rel <= th.still_relative),
            th.enter_speed)
        lowest = int(np.argmin(np.where(takers, p_sensed[:, 2], np.inf)))
        handover = bool(takers[lowest] and not has(on | tilted, lowest)
                        and (not has(bits.stepping, lowest)
                             or height_rel[kept] > th.still_relative))
        if handover:
            plant |= 1 << lowest
        elif not has(pushing_off, kept):  # a toe pushing off flies
            leave &= ~(1 << kept)
    anchors, age, released = state.anchors, state.age, state.released
    if plant:
        anchors, age = anchors.copy(), age.copy()
        plant_anchors(anchors, bits.mask(plant), active, bits.mask(on & ~leave), handover,
                       p_sensed, p_solved, step_sensed, layout, th.floor_z)
        age[bits.mask(plant)] = 0.0
    if leave:
        released = released.copy()
        released[bits.mask(leave)] = 0.0
    now = on & ~leave | plant
    held_now = active if now == on else bits.array(now)
    if not hints and now & rest & bits.shares_segment:
        # a planted trunk point rolls onto a lower point of its segment (in place: copies)
        held_now, anchors, age, released = (held_now.copy(), anchors.copy(), age.copy(),
                                            released.copy())
        roll_on_segment(held_now, anchors, age, released, p_sensed, needs_rest, layout, th.floor_z)
    elif held_now is active and anchors is state.anchors and not leave:
        return state  # nothing let go nor planted (the usual frame): the same state
    return ContactState(state.names, held_now, anchors, age, released)


def _evidence(bits: PointBits, p_sensed: np.ndarray, foot_pitch: np.ndarray | None,
              foot_still: np.ndarray | None, needs_rest: np.ndarray | None,
              th: ContactThresholds) -> FrameEvidence:
    """The :func:`.point_evidence.frame_evidence` of a frame under thresholds ``th``."""
    return frame_evidence(bits, heights_above_lowest(p_sensed), foot_pitch,
                          stance_bits(bits, foot_still), bits.of_optional(needs_rest),
                          math.radians(th.tilt_deg), th.leave_relative, th.enter_relative)


def _plant_height(th: ContactThresholds, needs_rest: np.ndarray | None) -> np.ndarray | float:
    """How far above the lowest point [m] a still point is planted at once, per point."""
    if needs_rest is None:
        return th.still_relative
    return by_rest(needs_rest, th.enter_relative, th.still_relative)


def touch_down(state: ContactState, p_solved: np.ndarray, p_solved_previous: np.ndarray,
               p_sensed: np.ndarray, dt: float, thresholds: ContactThresholds,
               hints: Mapping[str, bool] | None = None,
               foot_pitch: np.ndarray | None = None, *, layout: FootLayout,
               points_moving: np.ndarray | None = None,
               foot_still: np.ndarray | None = None,
               needs_rest: np.ndarray | None = None,
               v_sensed: np.ndarray | None = None,
               evidence: FrameEvidence | None = None,
               on: int | None = None, clocks: ClockStep | None = None) -> ContactState:
    """Plant the points that reached the floor this frame (run after solving).

    A point enters contact when it is near the floor, slow, among the lowest points of the
    sensed pose and not ruled out by its foot's pitch; its anchor is where it was solved.

    Args:
        state: State after :func:`release_contacts`.
        p_solved: (k, 3) contact point positions of the solved pose [m].
        p_solved_previous: (k, 3) the same some frames earlier [m].
        p_sensed: (k, 3) positions in the sensed pose (any translation) [m].
        dt: Time between ``p_solved_previous`` and ``p_solved`` [s].
        thresholds: Hysteresis thresholds.
        hints: Name -> in contact, overriding the detection for those points.
        foot_pitch: See :func:`release_contacts`.
        layout: See :func:`release_contacts`.
        points_moving: See :func:`release_contacts`: a moving point does not touch down
            while a point of the other foot that does not move is planted; while every planted
            point moves, a point as low as they are in the sensed pose touches down whatever
            its solved speed.
        foot_still: See :func:`release_contacts`.
        needs_rest: See :func:`release_contacts`: such a point does not touch down while its
            segment's IMU says it moves (``foot_still`` 0; unknown: the kinematics decide).
        v_sensed: See :func:`release_contacts`: a point sweeping beside a planted point whose
            IMU says it does not move does not touch down.
        evidence: See :func:`release_contacts` (the same frame's).
        on: See :func:`release_contacts`.
        clocks: The native :func:`.contact_clocks.python_clocks`, when the caller has it.

    Returns:
        A new state; anchors above the floor settle toward it at ``settle_speed``
        (:func:`.anchor_settling.settled_heights`: the planted points of one segment together).
    """
    th = thresholds
    was = state.active
    bits = point_bits(layout)
    on = bits.of(was) if on is None else on  # planted (bits: :mod:`.point_bits`)
    step = max(dt, 0.0)
    ev = evidence or _evidence(bits, p_sensed, foot_pitch, foot_still, needs_rest, th)
    # the clocks move on and the anchors settle as if no point landed (the usual frame): the
    # points that land were free (age 0 either way) and their anchors settle anew below
    released, age, anchors = (clocks or python_clocks)(
        state.released, state.age, state.anchors, on, step, th.settle_speed * step, th.floor_z,
        layout)
    # near the floor and among the lowest points: the candidates (few frames have any)
    if enter := ev.low & ~on:
        enter = below(p_solved[:, 2].tolist(), th.floor_z + th.enter_height, indices(enter))
    if enter:
        enter &= may_land(bits, on, enter, p_solved, p_solved_previous, dt, ev, released, th,
                            points_moving)
        enter &= ~sweeping_beside(bits, v_sensed, on, points_moving, th.enter_speed)
    for i, hinted in hinted_points(state.names, hints):
        enter = enter | 1 << i if not on & 1 << i and hinted else enter & ~(1 << i)
    if not on and not enter and not hints:
        enter = 1 << int(np.argmin(p_sensed[:, 2]))
    if not enter:  # (shared while unchanged, as release_contacts's)
        return ContactState(state.names, was, anchors, age, released)
    entering = bits.mask(enter)
    anchors = state.anchors.copy()
    anchors[entering] = landing_anchors(layout, was, anchors, p_solved, entering)
    active = bits.array(on | enter)
    anchors[entering, 2] = np.maximum(anchors[entering, 2], th.floor_z)
    anchors = settled_anchors(anchors, active, th.settle_speed * step, th.floor_z, layout)
    return ContactState(state.names, active, anchors, age, released)
