"""Points where a lying or sitting body rests (``needs_rest``): planted only with their IMU's rest.

A body rolling or rising from the floor swings its trunk low through the air: the kinematic
touch-down alone held such points (an elbow point, since dropped, brushing the floor in a crawl
was held 13 % of the clip against 8 % in the truth, joint-angle jumps 7 -> 39 deg). A trunk point
near the floor whose segment's IMU says it moves does not touch down; at rest, or when nothing
is known, the kinematics decide; a resting trunk point is planted at once only as one of the
lowest points.
"""

from __future__ import annotations

import numpy as np

from ikfusion.ik.contacts import ContactState, ContactThresholds, release_contacts, touch_down
from ikfusion.ik.settings import SolverSettings
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology, FootLayout

NAMES = ["LeftHeel", "LeftToe", "RightHeel", "RightToe", "Sacrum", "Chest"]


def _setup() -> tuple[ContactThresholds, FootLayout, np.ndarray]:
    layout = BodyTopology.of(HumanModel.default()).foot_layout(NAMES)
    needs_rest = np.array([n in ("Sacrum", "Chest") for n in NAMES])
    return ContactThresholds.from_settings(SolverSettings.load()), layout, needs_rest


def _planted_feet() -> ContactState:
    state = ContactState.empty(NAMES)
    state.active[:4] = True
    state.age[:4] = 1.0
    return state


def test_a_chest_brushing_the_floor_while_the_trunk_moves_does_not_touch_down() -> None:
    th, layout, needs_rest = _setup()
    p = np.array([[0.0, 0.1, 0.0], [0.2, 0.1, 0.0], [0.0, -0.1, 0.0], [0.2, -0.1, 0.0],
                  [-0.1, 0.0, 0.5], [0.4, 0.3, 0.01]])  # the chest 1 cm up, slow
    outcome = {}
    for still in (0.0, 1.0, np.nan):  # upper trunk moving, resting, unknown
        foot_still = np.array([1.0, 1.0, 1.0, 1.0, np.nan, still])
        state = touch_down(_planted_feet(), p, p, p, 1 / 60, th, layout=layout,
                           foot_still=foot_still, needs_rest=needs_rest)
        outcome[str(still)] = bool(state.active[5])
    assert outcome == {"0.0": False, "1.0": True, "nan": True}
    # without the rule (a knee or palm) the kinematics alone plant it
    state = touch_down(_planted_feet(), p, p, p, 1 / 60, th, layout=layout)
    assert state.active[5]


def test_a_resting_trunk_point_is_planted_at_once_only_among_the_lowest() -> None:
    th, layout, needs_rest = _setup()
    for height, planted in ((0.5 * th.enter_relative, True),
                            (0.5 * (th.enter_relative + th.still_relative), False)):
        p = np.array([[0.0, 0.1, 0.0], [0.2, 0.1, 0.0], [0.0, -0.1, 0.0], [0.2, -0.1, 0.0],
                      [-0.1, 0.0, height], [0.4, 0.3, 0.5]])
        foot_still = np.array([1.0, 1.0, 1.0, 1.0, 1.0, np.nan])  # the pelvis rests
        state = release_contacts(_planted_feet(), p, th, foot_still=foot_still, p_solved=p,
                                 layout=layout, needs_rest=needs_rest)
        assert bool(state.active[4]) is planted, height
        # a knee or palm (no such rule) is planted within still_relative
        state = release_contacts(_planted_feet(), p, th, foot_still=foot_still, p_solved=p,
                                 layout=layout)
        assert state.active[4]


CRAWL = ["LeftKnee", "RightKnee", "LeftPalm", "Chest"]


def _crawl_setup() -> tuple[ContactThresholds, FootLayout, np.ndarray]:
    layout = BodyTopology.of(HumanModel.default()).foot_layout(CRAWL)
    return (ContactThresholds.from_settings(SolverSettings.load()), layout,
            np.array([n == "Chest" for n in CRAWL]))


def test_a_moving_chest_does_not_take_the_body_when_the_knees_let_go() -> None:
    # a body rising from the floor face down: the knees let go and the chest, swung lowest in
    # the sensed pose while the upper trunk moves, must not take the body (an elbow point,
    # since dropped, did so for a frame on dm-getup-facedown: contact slide 35 mm against 22)
    th, layout, needs_rest = _crawl_setup()
    state = ContactState.empty(CRAWL)
    state.active[:2] = True
    state.age[:2] = 1.0
    p = np.array([[0.0, 0.1, 0.10], [0.0, -0.1, 0.10],  # the knees lifted 10 cm
                  [0.5, 0.2, 0.01], [0.3, 0.2, 0.0]])  # the palm 1 cm up, the chest lowest
    foot_still = np.array([0.0, 0.0, np.nan, 0.0])  # the upper trunk moves
    new = release_contacts(state, p, th, foot_still=foot_still, layout=layout,
                           needs_rest=needs_rest)
    assert not new.active[:2].any()
    assert not new.active[3]  # without the rule the chest took the body
    assert new.active[2]  # the lowest point that may rest takes it
    # while the upper trunk rests, or when nothing is known, the chest may take the body
    for still in (1.0, np.nan):
        foot_still[3] = still
        new = release_contacts(state, p, th, foot_still=foot_still, layout=layout,
                               needs_rest=needs_rest)
        assert new.active[3] and not new.active[2]


def test_trunk_points_far_above_the_floor_get_no_floor_row() -> None:
    # issue #19/#22: the 6 points of a lying body must cost nothing while it stands
    from ikfusion.ik.contact_tracker import FAR_FROM_FLOOR, ContactTracker
    from ikfusion.ik.frame import Frame

    model = HumanModel.default()
    tracker = ContactTracker(model, BodyTopology.of(model), NAMES, SolverSettings.load())
    standing = np.array([[0.0, 0.1, 0.0], [0.2, 0.1, 0.0], [0.0, -0.1, 0.0], [0.2, -0.1, 0.0],
                         [-0.1, 0.0, 0.9], [0.0, 0.3, 1.0]])
    lying = standing.copy()
    lying[4:, 2] = [0.05, FAR_FROM_FLOOR - 0.05]  # on the back, the chest up
    for p, far in ((standing, [False] * 4 + [True, True]),
                   (lying, [False] * 6)):
        tracker.reset()
        tracker.start(p, np.zeros(len(NAMES)))
        tracker.touch_down(Frame(time=0.0), p, np.zeros(3))
        tracker.release(Frame(time=1 / 60), p, np.zeros(len(NAMES)))
        assert tracker.far_from_floor.tolist() == far
