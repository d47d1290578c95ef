"""A toe pushing off lets go even when it holds the body alone (issue #19).

At the end of a walk's push-off the toe is the body's only support until the other heel lands;
its tip, by the foot IMU, slides or lifts faster than a point touches down. Held, the solver
bent the unsensed toe and the planted leg against the truth and the body fell back.
"""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.ik.contact_tracker import ContactTracker
from ikfusion.ik.contacts import ContactState, ContactThresholds, release_contacts
from ikfusion.ik.frame import Frame
from ikfusion.ik.settings import SolverSettings
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology

NAMES = ["LeftHeel", "LeftToe", "RightHeel", "RightToe"]
LAYOUT = BodyTopology.of(HumanModel.default()).foot_layout(NAMES)
TH = ContactThresholds(floor_z=0.0, enter_height=0.03, enter_speed=0.5, enter_relative=0.05,
                       leave_relative=0.05, leave_distance=0.08, settle_speed=0.02, tilt_deg=30.0,
                       still_relative=0.06, reenter_delay=0.1)
# the right toe on the floor, the right heel risen, the left foot swinging 2 cm above the floor
P = np.array([[0.5, 0.1, 0.02], [0.7, 0.1, 0.04], [-0.1, -0.1, 0.08], [0.1, -0.1, 0.0]])


def _release(active: list[bool], toe_off: np.ndarray | None) -> np.ndarray:
    state = ContactState(NAMES, np.array(active), P.copy(), np.full(4, 0.3))
    return release_contacts(state, P, TH, foot_pitch=np.zeros(4), p_solved=P, layout=LAYOUT,
                            toe_off=toe_off).active


def test_a_lone_toe_pushing_off_lets_go_of_the_body() -> None:
    off = np.array([False, False, False, True])
    np.testing.assert_array_equal(_release([False, False, False, True], off), [False] * 4)


def test_a_lone_toe_not_pushing_off_keeps_the_body() -> None:
    """Without the cue (or with it for another point) the lowest point keeps the body down."""
    for off in (None, np.zeros(4, dtype=bool), np.array([True, False, False, False])):
        np.testing.assert_array_equal(_release([False, False, False, True], off),
                                      [False, False, False, True])


def test_a_toe_pushing_off_lets_go_while_the_other_foot_holds() -> None:
    off = np.array([False, False, False, True])
    np.testing.assert_array_equal(_release([True, False, False, True], off),
                                  [True, False, False, False])


def test_a_toe_held_alone_lets_go_once_its_foot_imu_says_its_tip_slides_fast() -> None:
    """Through the tracker: the right toe alone holds the body (the left foot in the air). Its
    ball moving along the toe at 0.8 m/s drags the tip on the floor faster than a point touches
    down (``enter_speed``): it lets go; at 0.2 m/s (a slide the carry follows) it is held."""
    model = HumanModel.default()
    q = model.neutral()
    q[2] -= min(model.site_position(q, n)[2] for n in NAMES)
    along = model.site_position(q, "RightToe") - model.segment_position(q, "RightToe")
    along[2] = 0.0
    along /= np.linalg.norm(along)
    settings = SolverSettings.load()
    tracker = ContactTracker(model, BodyTopology.of(model), NAMES, settings)
    p = np.array([model.site_position(q, n) for n in NAMES])
    p[:2, 2] += 0.05  # the left foot swings above the floor
    pitch = np.zeros(4)
    for speed, held in ((0.8, False), (0.2, True)):
        tracker.reset()
        tracker.start(p, pitch)
        tracker.touch_down(Frame(time=0.0), p, q[:3])
        tracker.state = ContactState(NAMES, np.array([False, False, False, True]), p.copy(),
                                     np.array([0.0, 0.0, 0.0, 0.4]))
        velocity = dict.fromkeys(NAMES, speed * along)
        frame = Frame(time=1 / 60, points_velocity=velocity)
        tracker.carry(frame, 1 / 60, None, speed * along, q)
        assert tracker.carrier.tip_speed[3] == pytest.approx(speed)
        tracker.release(frame, p, pitch)
        assert bool(tracker.state.active[3]) == held
