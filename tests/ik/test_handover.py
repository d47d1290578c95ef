"""A foot that stops standing still hands the body over to the other foot, unless its points
are known not to move (issue #19: gen-jumps, one foot of a two-footed take-off crossing the
stance thresholds a sample before the other let go of both its points ~80 ms early)."""

from __future__ import annotations

import numpy as np

from ikfusion.ik.contacts import ContactState, ContactThresholds, release_contacts, touch_down
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology

NAMES = ["LeftHeel", "LeftToe", "RightHeel", "RightToe"]
LAYOUT = BodyTopology.of(HumanModel.default()).foot_layout(NAMES)
TH = ContactThresholds(floor_z=0.0, enter_height=0.03, enter_speed=0.5, enter_relative=0.05,
                       leave_relative=0.05, leave_distance=0.08, settle_speed=0.02, tilt_deg=30.0,
                       still_relative=0.06, reenter_delay=0.1)
# both feet flat on the floor, side by side; the sensed pose puts them on their anchors
P = np.array([[0.0, 0.1, 0.0], [0.2, 0.1, 0.0], [0.0, -0.1, 0.0], [0.2, -0.1, 0.0]])
# the left foot's IMU no longer says still (its push-off acceleration), the right one's does
FEET = np.array([0.0, 0.0, 1.0, 1.0])


def _release(points_moving: np.ndarray | None) -> np.ndarray:
    """Active points after one release step with both feet planted."""
    state = ContactState(NAMES, np.ones(4, dtype=bool), P.copy(), np.full(4, 0.3))
    out = release_contacts(state, P, TH, foot_pitch=np.zeros(4), foot_still=FEET,
                           p_solved=P, layout=LAYOUT, points_moving=points_moving)
    return out.active


def test_points_known_not_to_move_are_not_handed_over() -> None:
    np.testing.assert_array_equal(_release(np.zeros(4, dtype=bool)), [True, True, True, True])
    np.testing.assert_array_equal(_release(np.zeros(4)), [True, True, True, True])


def test_unknown_or_moving_points_are_still_handed_over() -> None:
    """Without point speeds the foot's stance decides as before; a moving point lets go."""
    np.testing.assert_array_equal(_release(None), [False, False, True, True])
    np.testing.assert_array_equal(_release(np.full(4, np.nan)), [False, False, True, True])
    np.testing.assert_array_equal(_release(np.array([1.0, np.nan, 0.0, 0.0])),
                                  [False, False, True, True])
    # the ball a foot rolls over stays while its heel, which moves, lets go
    np.testing.assert_array_equal(_release(np.array([1.0, 0.0, 0.0, 0.0])),
                                  [False, True, True, True])


def test_a_moving_point_does_not_touch_down_while_the_other_foot_holds() -> None:
    """Unknown speeds (NaN) neither block nor force a touch-down."""
    state = ContactState(NAMES, np.array([False, False, True, True]), P.copy(), np.zeros(4))
    state.released[:] = 1.0
    for moving, planted in ((np.array([1.0, 1.0, 0.0, 0.0]), False),
                            (np.array([np.nan, np.nan, 0.0, 0.0]), True)):
        out = touch_down(state, P, P, P, 0.1, TH, foot_pitch=np.zeros(4), layout=LAYOUT,
                         points_moving=moving)
        assert out.active[:2].tolist() == [planted, planted]


def test_a_heel_let_go_while_it_skidded_lands_again_once_it_stops() -> None:
    """A landing heel that skids lets go (its IMU says it moves while the other toe holds);
    the moment its IMU says it stopped, it lands again, without waiting ``reenter_delay`` as a
    toe that pushed off does (issue #19: cmu-02-01-walk's heel waited 0.2 s while the rear toe
    held the body; the heel slid 70 mm in the truth's contact phase)."""
    state = ContactState(NAMES, np.array([False, False, False, True]), P.copy(), np.zeros(4))
    state.released[:] = [0.0, np.inf, np.inf, np.inf]  # the left heel let go just now
    for moving, planted in ((np.array([0.0, 1.0, 1.0, 1.0]), True),  # stopped
                            (np.array([np.nan, 1.0, 1.0, 1.0]), False)):  # unknown: it waits
        out = touch_down(state, P, P, P, 1.0 / 60.0, TH, foot_pitch=np.zeros(4), layout=LAYOUT,
                         points_moving=moving)
        assert bool(out.active[0]) is planted


def test_a_landing_heel_its_imu_says_is_still_touches_down_though_the_body_slides() -> None:
    """The heel lands while the rear toe, still held, truly drags forward (a mocap walk's
    push-off): the body solved on that toe carries the landing heel along at over 1 m/s, but
    its foot IMU says the heel does not move, so it touches down (issue #19: cmu-02-02-walk
    planted its heel 100 ms late, and the toe held meanwhile slid 15 cm in the truth)."""
    state = ContactState(NAMES, np.array([False, False, False, True]), P.copy(), np.full(4, 0.5))
    state.released[:] = [1.0, 1.0, np.inf, np.inf]
    dt = 1.0 / 60.0
    previous = P - np.array([1.5 * dt, 0.0, 0.0])  # solved 1.5 m/s forward in one frame
    for moving, planted in ((np.array([0.0, 1.0, np.nan, np.nan]), True),  # the heel still
                            (np.array([np.nan, np.nan, np.nan, np.nan]), False),  # unknown
                            (np.array([1.0, 1.0, np.nan, np.nan]), False)):  # it moves
        out = touch_down(state, P, previous, P, dt, TH, foot_pitch=np.zeros(4), layout=LAYOUT,
                         points_moving=moving)
        assert bool(out.active[0]) is planted
        assert not out.active[1]


def test_a_toe_lands_while_the_toe_holding_the_body_lifts() -> None:
    """The body held on a left toe its IMU says lifts (getting down onto the knees): the right
    toe, solved relative to that toe, moves at 0.7 m/s while it truly lands, so its solved
    speed says nothing; it touches down once it is as low as the planted toe in the sensed
    pose (issue #19: dm-getup-facedown's right toe waited 0.2 s unheld and slid 15 cm)."""
    state = ContactState(NAMES, np.array([False, True, False, False]), P.copy(), np.full(4, 1.0))
    state.released[:] = 1.0
    dt = 1.0 / 60.0
    previous = P - np.array([0.7 * dt, 0.0, 0.0])  # solved 0.7 m/s forward in one frame
    above = P + np.array([0.0, 0.0, 0.02])  # the right toe still 2 cm above the left one
    above[1, 2] = 0.0
    for moving, sensed, planted in (
            (np.array([np.nan, 1.0, np.nan, 1.0]), P, True),  # the held toe lifts
            (np.array([np.nan, 0.0, np.nan, 1.0]), P, False),  # it stands: the speed rules
            (np.array([np.nan, np.nan, np.nan, 1.0]), P, False),  # unknown: the speed rules
            (np.array([np.nan, 1.0, np.nan, 1.0]), above, False)):  # not down yet
        out = touch_down(state, P, previous, sensed, dt, TH, foot_pitch=np.zeros(4),
                         layout=LAYOUT, points_moving=moving)
        assert bool(out.active[3]) is planted
        assert out.active[1]


def _take_over(p_solved: np.ndarray, step_sensed: np.ndarray | None) -> np.ndarray:
    """The right heel's anchor when the left foot, lifted 8 cm in the sensed pose, lets go."""
    sensed = P.copy()
    sensed[:2, 2] = 0.08
    state = ContactState(NAMES, np.array([True, True, False, False]), P.copy(), np.full(4, 1.0))
    state.released[:] = 1.0
    out = release_contacts(state, sensed, TH, foot_pitch=np.zeros(4), p_solved=p_solved,
                           layout=LAYOUT, step_sensed=step_sensed)
    assert out.active.tolist() == [False, False, True, False]
    return out.anchors[2]


def test_the_point_taking_the_body_over_is_anchored_where_the_solve_has_it() -> None:
    """The solved pose is bent 2 cm away from the sensed one (the floor held a point the sensed
    pose puts under it): the point taking the body over is anchored where it was solved, moved
    on by its sensed motion relative to the points that held, not where the sensed geometry
    puts it relative to them (issue #19: dm-getup-faceup, the hold passing from a buttock to a
    palm moved the whole body 22 mm in one frame)."""
    bent = P.copy()
    bent[2] += [0.02, -0.01, 0.003]  # where the last solve had the right heel
    step = np.zeros((4, 3))
    step[:, 0] = 0.004  # the whole sensed pose moved 4 mm: nothing relative to the support
    step[2, 1] = 0.003  # the right heel 3 mm to the left of it
    anchor = _take_over(bent, step)
    np.testing.assert_allclose(anchor[:2], bent[2, :2] + [0.0, 0.003], atol=1e-12)
    assert anchor[2] == 0.0  # the height from the sensed pose, on the floor
    # without the sensed step (callers that do not give it): where the last solve had it
    np.testing.assert_allclose(_take_over(bent, None)[:2], bent[2, :2], atol=1e-12)
