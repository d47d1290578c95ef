"""Hand-overs between the feet and swing feet led by the no-slide correction, in closed form."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.ik.contacts import ContactState, ContactThresholds, release_contacts, touch_down
from ikfusion.ik.settings import SolverSettings
from ikfusion.ik.support import SupportFollower
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology

NAMES = ["LeftHeel", "LeftToe", "RightHeel", "RightToe"]
LAYOUT = BodyTopology.of(HumanModel.default()).foot_layout(NAMES)
DT = 1.0 / 60.0
LEFT = np.array([True, True, False, False])
RIGHT = ~LEFT
BOTH = LEFT | RIGHT


def _follower(**kw) -> SupportFollower:
    args = {"lag_speed": 0.3, "lag_max": 0.05, "swing_speed": 0.6, "lean_max": 0.0,
            "lean_speed": 0.0, "confirm": 0.2} | kw
    return SupportFollower(LAYOUT, **args)


def _points(x_left: float, x_right: float) -> np.ndarray:
    """Contact points of a sensed pose: left foot at x_left, right foot at x_right [m]."""
    return np.array([[x_left, 0.1, 0.0], [x_left + 0.2, 0.1, 0.0],
                     [x_right, -0.1, 0.0], [x_right + 0.2, -0.1, 0.0]])


def test_the_pelvis_lags_a_hand_over_jump_and_catches_up_at_its_speed() -> None:
    f = _follower()
    anchors = _points(0.0, 0.5)
    sensed = _points(0.0, 0.5)
    assert np.allclose(f.follow(LEFT, anchors, sensed, DT), 0.0)  # standing on the left foot
    # the right foot lands where the sensed pose disagrees by 3 cm: the body stays on the left
    anchors = _points(0.0, 0.53)
    assert np.allclose(f.follow(BOTH, anchors, sensed, DT), 0.0)
    assert np.allclose(f.lag, 0.0)
    # the left toe and heel let go: the support says +3 cm at once; the pelvis lags it
    offset = f.follow(RIGHT, anchors, sensed, DT)
    assert offset[0] == pytest.approx(0.03)
    assert f.lag[0] == pytest.approx(-0.03 + 0.3 * DT)  # continuous, then shrinking
    assert f.pending[0] == pytest.approx(0.03 - 0.3 * DT)
    for _ in range(5):
        f.follow(RIGHT, anchors, sensed, DT)
    assert f.lag[0] == pytest.approx(-0.03 + 6 * 0.3 * DT)
    # a larger disagreement than lag_max is jumped over beyond it
    g = _follower()
    g.follow(LEFT, _points(0.0, 0.5), sensed, DT)
    g.follow(BOTH, _points(0.0, 0.7), sensed, DT)
    g.follow(RIGHT, _points(0.0, 0.7), sensed, DT)
    assert np.linalg.norm(g.lag) == pytest.approx(0.05)


def test_intended_moves_of_the_anchors_are_followed_at_once() -> None:
    f = _follower()
    sensed = _points(0.0, 0.5)
    f.follow(LEFT, _points(0.0, 0.5), sensed, DT)
    f.shift(np.array([0.02, 0.0, 0.0]))  # the slide correction moved the planted points
    offset = f.follow(LEFT, _points(0.02, 0.5), sensed, DT)
    assert offset[0] == pytest.approx(0.02) and np.allclose(f.lag, 0.0)


def test_a_swing_foot_is_led_to_the_correction_at_its_speed() -> None:
    f = _follower()
    sensed = _points(0.0, 0.5)
    f.set_step(np.array([0.3, 0.0, 0.0]), max_step=0.1)
    f.follow(BOTH, _points(0.0, 0.5), sensed, DT)
    f.follow(LEFT, _points(0.0, 0.5), sensed, DT)  # the right foot lifts off
    assert f.swing[1][0] == pytest.approx(0.6 * DT)  # toward the step, at most max_step
    targets, weights = f.swing_targets(sensed)
    # its heel only, on all three axes (above the floor its height is that of the sensed leg)
    assert np.array_equal(weights[2], np.eye(3))
    assert not np.delete(weights, 2, axis=0).any()
    assert targets[2, 0] == pytest.approx(0.5 + 0.6 * DT)
    for _ in range(30):
        f.follow(LEFT, _points(0.0, 0.5), sensed, DT)
    assert f.swing[1][0] == pytest.approx(0.1)  # reached, not beyond
    f.follow(BOTH, _points(0.0, 0.6), sensed, DT)  # it lands there
    assert f.landed[0] == pytest.approx(0.1)
    # ... and the body stays on the left foot until that lets go, then follows without a jump
    assert np.allclose(f.lag, 0.0)
    f.follow(RIGHT, _points(0.0, 0.6), sensed, DT)
    # a foot placed by the correction is caught up with, even beyond lag_max: no jump
    assert f.lag[0] == pytest.approx(-0.1 + 0.3 * DT) and f.placed


def test_a_swing_heel_is_held_at_its_sensed_height_unless_its_foot_sinks_under_the_floor(
        ) -> None:
    """Free in height, a led heel rose with the pelvis and landed high, lifting the body at each
    heel strike (head 1.4 mm higher on average on the demo walk). Held at the sensed leg's
    height, it lets that go as the sensed foot sinks under the floor: the floor lifts the foot
    then, and a heel held down while the floor lifts the toe pitches the foot (a pop)."""
    f = _follower()
    f.set_step(np.array([0.3, 0.0, 0.0]), max_step=0.1)
    f.follow(BOTH, _points(0.0, 0.5), _points(0.0, 0.5), DT)
    f.follow(LEFT, _points(0.0, 0.5), _points(0.0, 0.5), DT)  # the right foot lifts off
    heights = []
    for toe_z in (0.05, 0.0, -0.005, -0.01, -0.04):  # the sensed right toe sinks
        sensed = _points(0.0, 0.5)
        sensed[2:, 2] = 0.03
        sensed[3, 2] = toe_z
        f.follow(LEFT, _points(0.0, 0.5), sensed, DT)
        _, info = f.swing_targets(sensed)
        assert np.array_equal(info[2][:2], np.eye(3)[:2])  # always led sideways
        heights.append(info[2][2, 2])
    assert heights[:2] == [1.0, 1.0] and 0.0 < heights[2] < 1.0 and heights[3:] == [0.0, 0.0]


def test_a_heel_that_left_the_floor_away_from_its_sensed_height_is_led_sideways_only(
        ) -> None:
    """A run's sensed legs put a planted heel 4 cm under the floor: the heel left the floor
    4 cm above the sensed leg's height. Held at that height, it pulled the body up after
    lift-off and down before landing (run head 3.2 -> 4.0 cm); its height is left free."""
    sensed = _points(0.0, 0.5)
    for deviation_z, held in ((0.0, 1.0), (0.005, 0.5), (0.04, 0.0)):
        f = _follower()
        f.set_step(np.array([0.3, 0.0, 0.0]), max_step=0.1)
        f.follow(BOTH, _points(0.0, 0.5), sensed, DT)
        f.swing_targets(sensed)
        solved = sensed.copy()
        solved[2:, 2] += deviation_z  # the right foot held that far above its sensed height
        f.record(solved, np.zeros(3))
        f.follow(LEFT, _points(0.0, 0.5), sensed + [0.0, 0.0, 0.05], DT)  # it lifts off
        _, info = f.swing_targets(sensed + [0.0, 0.0, 0.05])
        assert info[2][2, 2] == pytest.approx(held)
        assert np.array_equal(info[2][:2], np.eye(3)[:2])


def test_a_touch_down_let_go_at_once_resumes_its_swing_from_where_the_heel_is() -> None:
    """A heel strike the gyroscope did not confirm: the landing is not counted and the swing
    goes on toward the same goal, from where the heel is. Held on the floor while the body
    moved on (here 2 cm), the heel is no longer where it was led; resumed there, its target
    jumped by that much in one frame (issue #19: the jumps' heels moved 2.6 cm at once)."""
    f = _follower()
    sensed = _points(0.0, 0.5)
    f.set_step(np.array([0.1, 0.0, 0.0]), max_step=0.1)
    f.follow(BOTH, _points(0.0, 0.5), sensed, DT)
    for _ in range(5):
        f.follow(LEFT, _points(0.0, 0.5), sensed, DT)
        targets, _ = f.swing_targets(sensed)
        f.record(targets, np.zeros(3))  # the heel reached its target
    led = f.swing[1].copy()
    held = _points(0.0, 0.5 + led[0])
    f.follow(BOTH, held, sensed, DT)  # a heel strike ...
    assert f.landed[0] == pytest.approx(led[0])
    moved_on = sensed + [0.02, 0.0, 0.0]  # the body moves on while the heel is held
    f.swing_targets(moved_on)
    f.record(held, np.zeros(3))
    f.set_step(np.zeros(3), max_step=0.1)  # (the correction would now see less to do)
    f.follow(LEFT, _points(0.0, 0.5), sensed, DT)  # ... the gyroscope did not confirm
    assert f.landed[0] == pytest.approx(-led[0])  # not counted
    # the goal kept (not restarted from the smaller step), from where the heel is
    assert f.swing[1][0] == pytest.approx(led[0] - 0.02 + 0.6 * DT)
    targets, _ = f.swing_targets(moved_on)
    assert targets[2, 0] - held[2, 0] == pytest.approx(0.6 * DT)  # no jump of the target


def test_a_point_that_let_go_does_not_come_back_down_at_once() -> None:
    th = ContactThresholds.from_settings(SolverSettings.load())
    low = _points(0.0, 0.5)
    # the right toe just let go (toe-off), still low and slow: it stays off for reenter_delay
    state = ContactState(NAMES, LEFT.copy(), low.copy(), np.zeros(4), np.array(
        [np.inf, np.inf, np.inf, 0.0]))
    frames = 0
    while not state.active[3]:
        state = touch_down(state, low, low, low, DT, th, layout=LAYOUT)
        frames += 1
        assert frames < 60
    assert frames * DT == pytest.approx(th.reenter_delay, abs=DT)
    # a point never in contact lands at once
    fresh = touch_down(ContactState(NAMES, LEFT.copy(), low.copy(), np.zeros(4)), low, low,
                       low, DT, th, layout=LAYOUT)
    assert fresh.active.all()


def test_a_led_foot_that_lands_does_not_pull_the_other_foot_off() -> None:
    """A swing foot led by the correction lands where the pelvis (leaning toward the
    correction) and its swing put it: the feet disagree by that much on purpose, from the
    first frame after the touch-down on (issue #19: the gap-closing walk's heel landed 13.8 cm
    from where the sensed legs put it, the frame after read that as drift, the left toe let go
    at once with its foot pitched 23 deg and the ankle popped 1.5 deg)."""
    f = _follower(lean_max=0.04, lean_speed=1.0)
    sensed = _points(0.0, 0.5)
    f.set_step(np.array([0.3, 0.0, 0.0]), max_step=0.1)
    f.follow(BOTH, _points(0.0, 0.5), sensed, DT)
    for _ in range(30):  # the right foot swings, led; the pelvis leans
        f.follow(LEFT, _points(0.0, 0.5), sensed, DT)
    lead = f.lean + f.swing[1]
    assert lead[0] == pytest.approx(0.14)
    anchors = _points(0.0, 0.5 + lead[0])  # its points land where they were led
    th = ContactThresholds.from_settings(SolverSettings.load())
    state = ContactState(NAMES, BOTH.copy(), anchors, np.zeros(4))
    for _ in range(3):  # the touch-down frame is not settled yet, then it is
        placed = f.placed_offsets(BOTH)
        assert np.allclose(placed[RIGHT], lead) and np.allclose(placed[LEFT], 0.0)
        state = release_contacts(state, sensed, th, placed=placed, layout=LAYOUT)
        assert state.active.all()  # no toe-off forced by the placement
        f.follow(BOTH, anchors, sensed, DT)


def test_the_swinging_groups_bits_are_kept_with_their_flags() -> None:
    """The swinging and led groups' bits (the usual frame's shortcuts) are their flags."""
    follower, anchors = _follower(lean_max=0.02, lean_speed=0.1), _points(0.0, 0.5)
    follower.set_step(np.array([0.1, 0.0, 0.0]), 0.2)
    for i, on in enumerate([BOTH, LEFT, LEFT, BOTH, RIGHT, RIGHT, BOTH, LEFT, BOTH] * 3):
        offset = follower.follow(on, anchors, _points(0.01 * i, 0.5 + 0.01 * i), DT)
        follower.swing_targets(_points(0.0, 0.5) + offset)
        follower.record(_points(0.0, 0.5), np.zeros(3))
        swinging = sum(1 << f for f, s in enumerate(follower._swinging) if s)
        assert follower._swinging_bits == swinging
        assert follower._goal_bits == sum(1 << f for f, g in enumerate(follower._has_goal) if g)
        assert follower.leads() == any(map(bool.__and__, follower._swinging, follower._has_goal))
    assert follower._goal_bits  # (the swings were led)
