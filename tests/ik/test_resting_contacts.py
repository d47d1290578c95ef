"""Points where a lying or sitting body rests (``needs_rest``): planted only with their IMU's rest.

A forearm crawl's elbow brushes the floor, 0-3 cm up, while the upper arm swings on: the
kinematic touch-down alone held it (dm-crawl: elbows held 13 % of the clip against 8 % in the
truth, joint-angle jumps 7 -> 39 deg). A trunk point near the floor whose segment's IMU says it
moves does not touch down; at rest, or when nothing is known, the kinematics decide; a resting
trunk point is planted at once only as one of the lowest points.
"""

from __future__ import annotations

import numpy as np

from ikfusion.ik.contacts import ContactState, ContactThresholds, release_contacts, touch_down
from ikfusion.ik.settings import SolverSettings
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology, FootLayout

NAMES = ["LeftHeel", "LeftToe", "RightHeel", "RightToe", "Sacrum", "LeftElbow"]


def _setup() -> tuple[ContactThresholds, FootLayout, np.ndarray]:
    layout = BodyTopology.of(HumanModel.default()).foot_layout(NAMES)
    needs_rest = np.array([n in ("Sacrum", "LeftElbow") for n in NAMES])
    return ContactThresholds.from_settings(SolverSettings.load()), layout, needs_rest


def _planted_feet() -> ContactState:
    state = ContactState.empty(NAMES)
    state.active[:4] = True
    state.age[:4] = 1.0
    return state


def test_an_elbow_brushing_the_floor_while_its_arm_moves_does_not_touch_down() -> None:
    th, layout, needs_rest = _setup()
    p = np.array([[0.0, 0.1, 0.0], [0.2, 0.1, 0.0], [0.0, -0.1, 0.0], [0.2, -0.1, 0.0],
                  [-0.1, 0.0, 0.5], [0.4, 0.3, 0.01]])  # the elbow 1 cm up, slow
    outcome = {}
    for still in (0.0, 1.0, np.nan):  # upper arm moving, resting, unknown
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
