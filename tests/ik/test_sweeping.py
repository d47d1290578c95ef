"""A palm sweeping over the floor does not take the body from a toe that stands (issue #19).

dm-getup-faceup, perfect sensors, no UWB, rising at 7.17 s: the body pushes off its left toe
(its foot IMU says the toe does not move) while the right palm sweeps along the floor at
0.7 m/s, the lowest point of the sensed pose, and the right foot lands. The toe, 2.7 cm above
the palm, let go and the palm took the body and dragged it (RightHeel 60 mm, LeftToe 45 mm,
RightToe 21 mm beyond the truth); the palm also touched down beside the toe.
"""

from __future__ import annotations

import numpy as np

from ikfusion.ik.contacts import ContactState, ContactThresholds, release_contacts, touch_down
from ikfusion.ik.settings import SolverSettings
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology

NAMES = ["LeftHeel", "LeftToe", "RightHeel", "RightToe", "LeftPalm", "RightPalm"]
LAYOUT = BodyTopology.of(HumanModel.default()).foot_layout(NAMES)
TH = ContactThresholds.from_settings(SolverSettings.load())
TOE, PALM, HEEL = NAMES.index("LeftToe"), NAMES.index("RightPalm"), NAMES.index("RightHeel")


def _rising(toe_height: float) -> tuple[ContactState, np.ndarray, np.ndarray]:
    """The left toe held; the sensed pose lifts it ``toe_height`` [m] above the palm.

    Returns the state, the sensed points [m] and their sensed velocities [m/s]: the palm
    sweeps at 0.7 m/s, the landing right foot still moves at 0.6 m/s.
    """
    p = np.array([[0.3 * i, 0.1 * i, 0.4] for i in range(len(NAMES))])
    p[TOE, 2], p[PALM, 2], p[HEEL, 2] = toe_height, 0.0, 0.003
    state = ContactState.empty(NAMES)
    state.active[TOE], state.age[TOE] = True, 0.1
    state.anchors[:] = p
    v = np.zeros((len(NAMES), 3))
    v[PALM, :2] = [0.7, 0.0]
    v[HEEL, :2] = [0.0, 0.6]
    return state, p, v


def _held(state: ContactState) -> list[str]:
    return [n for n, a in zip(NAMES, state.active) if a]


def _standing_toe() -> np.ndarray:
    """The foot IMU says the left toe does not move; nothing known of the others."""
    moving = np.full(len(NAMES), np.nan)
    moving[TOE] = 0.0
    return moving


def test_a_sweeping_palm_does_not_take_the_body_from_a_standing_toe() -> None:
    state, p, v = _rising(0.027)
    out = release_contacts(state, p, TH, p_solved=p, layout=LAYOUT,
                           points_moving=_standing_toe(), v_sensed=v)
    assert _held(out) == ["LeftToe"]  # before: ["RightPalm"]
    # a palm at rest (the same pose, slow) takes it as before
    out = release_contacts(state, p, TH, p_solved=p, layout=LAYOUT,
                           points_moving=_standing_toe(), v_sensed=0.1 * v)
    assert _held(out) == ["RightPalm"]
    # the toe's IMU says nothing, or the toe is well up (beyond still_relative): as before
    for moving, height in ((None, 0.027), (_standing_toe(), TH.still_relative + 0.01)):
        state, p, v = _rising(height)
        out = release_contacts(state, p, TH, p_solved=p, layout=LAYOUT, points_moving=moving,
                               v_sensed=v)
        assert _held(out) == ["RightPalm"]


def test_a_sweeping_palm_does_not_touch_down_beside_a_standing_toe() -> None:
    state, p, v = _rising(0.0)
    p[PALM, 2] = 0.005

    def landed(v_sensed: np.ndarray, moving: np.ndarray | None) -> bool:
        out = touch_down(state, p, p, p, 1 / 60, TH, layout=LAYOUT, points_moving=moving,
                         v_sensed=v_sensed)
        return bool(out.active[PALM])

    assert not landed(v, _standing_toe())  # before: it touched down
    assert landed(0.1 * v, _standing_toe())  # a palm put down
    assert landed(v, None)  # nothing known of the toe: the kinematics decide
