"""The per-frame contact glue's shortcuts (issue #20) give what the full computation gives."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ikfusion.ik.anchor_settling import settled_heights
from ikfusion.ik.configuration import Configuration
from ikfusion.ik.limits import ContactConstraint, FloorLimit
from ikfusion.ik.limits.base import Equality, Inequality
from ikfusion.ik.release import ReleaseEasing
from ikfusion.ik.support import SupportFollower
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology

MODEL = HumanModel.default()
POINTS = MODEL.sites_of_kind("contact")
LAYOUT = BodyTopology.of(MODEL).foot_layout(POINTS)
FEET = ["LeftHeel", "LeftToe", "RightHeel", "RightToe"]
DT = 0.01


def test_the_layout_knows_which_points_share_their_segment() -> None:
    shares = dict(zip(POINTS, LAYOUT.shares_segment.tolist()))
    # the sacrum and buttocks on the pelvis, shoulder blades and chest on the upper trunk
    assert {n for n, s in shares.items() if s} == {
        "Sacrum", "LeftButtock", "RightButtock", "LeftShoulderBlade", "RightShoulderBlade",
        "Chest"}


@pytest.mark.parametrize("seed", range(40))
def test_anchors_settle_alone_as_the_segment_pass_says(seed: int) -> None:
    rng = np.random.default_rng(seed)
    k = len(POINTS)
    z = rng.uniform(-0.01, 0.05, k)
    active = rng.random(k) < 0.5
    if seed % 2:  # half the cases: feet, knees and palms only (the shortcut's case)
        active &= ~LAYOUT.shares_segment
    drop = 0.002
    full = settled_heights(z, active, LAYOUT.same_segment, drop, 0.0)
    fast = settled_heights(z, active, LAYOUT.same_segment, drop, 0.0, LAYOUT.shares_segment)
    assert fast.tobytes() == full.tobytes()  # the same numbers, bit for bit
    if not (active & LAYOUT.shares_segment).any():
        # each anchor settles by itself: down by at most ``drop``, never under the floor
        np.testing.assert_allclose(fast, np.maximum(z - np.clip(z, 0.0, drop), 0.0))


def test_contact_and_floor_rows_are_the_held_coordinates() -> None:
    rng = np.random.default_rng(3)
    k, nv = len(POINTS), MODEL.model.nv
    contact = ContactConstraint(list(range(k)), POINTS)
    active = np.zeros(k, dtype=bool)
    active[[0, 1, 3, 5]] = True  # a left foot, a right toe, a knee
    free_z = np.zeros(k, dtype=bool)
    free_z[0] = True  # a rising heel: held horizontally only
    anchors = rng.normal(size=(k, 3))
    contact.set_anchors(active, anchors, free_z)
    p, J = rng.normal(size=(k, 3)), rng.normal(size=(k, 3, nv))
    rows = [(i, a) for i in range(k) for a in range(3) if active[i] and not (a == 2 and free_z[i])]
    eq = contact.rows(p, J)
    np.testing.assert_array_equal(eq.A, np.array([J[i, a] for i, a in rows]))
    np.testing.assert_array_equal(eq.b, np.array([anchors[i, a] - p[i, a] for i, a in rows]))
    floor = FloorLimit(list(range(k)), floor_z=0.01)
    floor.enabled = ~active
    ineq = floor.rows(p, J)
    below = [i for i in range(k) if not active[i]]
    np.testing.assert_array_equal(ineq.G, np.array([-J[i, 2] for i in below]))
    np.testing.assert_array_equal(ineq.h, np.array([p[i, 2] - 0.01 for i in below]))
    # the same rows written into given arrays (a QP's buffer), bit for bit
    into = Equality(np.full((contact.count(), nv), np.nan), np.full(contact.count(), np.nan))
    assert contact.rows(p, J, into) is into
    np.testing.assert_array_equal(into.A, eq.A)
    np.testing.assert_array_equal(into.b, eq.b)
    floor_into = Inequality(np.full((len(below), nv), np.nan), np.full(len(below), np.nan))
    floor.rows(p, J, floor_into)
    np.testing.assert_array_equal(floor_into.G, ineq.G)
    np.testing.assert_array_equal(floor_into.h, ineq.h)
    floor.enabled[below[0]] = False  # changed in place: its rows follow
    np.testing.assert_array_equal(floor.z_rows(), np.array([3 * i + 2 for i in below[1:]]))


def test_contact_equality_rows_are_the_held_coordinates() -> None:
    conf_model = MODEL.model
    ids = [MODEL.site_frame_id(n) for n in FEET]
    conf = Configuration(conf_model, pin.neutral(conf_model))
    contact = ContactConstraint(ids, FEET)
    anchors = conf.positions(ids) + 0.01
    contact.set_anchors(np.array([True, True, False, True]), anchors,
                        np.array([False, True, False, False]))
    eq = contact.equality(conf)
    J = conf.linear_jacobians(ids)
    held = [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (3, 0), (3, 1), (3, 2)]
    np.testing.assert_array_equal(eq.A, np.array([J[i, a] for i, a in held]))
    np.testing.assert_allclose(eq.b, np.full(len(held), 0.01), atol=1e-12)


def _follower() -> SupportFollower:
    layout = BodyTopology.of(MODEL).foot_layout(FEET)
    return SupportFollower(layout, lag_speed=0.3, lag_max=0.05, swing_speed=0.6,
                           lean_max=0.0, lean_speed=0.0, confirm=0.2)


def _feet(x_left: float, x_right: float) -> np.ndarray:
    return np.array([[x_left, 0.1, 0.0], [x_left + 0.2, 0.1, 0.0],
                     [x_right, -0.1, 0.0], [x_right + 0.2, -0.1, 0.0]])


LEFT = np.array([True, True, False, False])


def test_only_a_led_swing_foot_asks_for_swing_targets() -> None:
    sensed = _feet(0.0, 0.5)
    plain = _follower()  # no correction: a swinging foot is not led
    plain.follow(LEFT | ~LEFT, sensed, sensed, DT)
    plain.follow(LEFT, sensed, sensed, DT)
    assert not plain.leads()
    assert not plain.swing_targets(sensed)[1].any()  # what the shortcut skips: no information
    led = _follower()
    led.set_step(np.array([0.3, 0.0, 0.0]), max_step=0.1)
    led.follow(LEFT | ~LEFT, sensed, sensed, DT)
    led.follow(LEFT, sensed, sensed, DT)  # the right foot lifts off toward the correction
    assert led.leads()
    assert led.swing_targets(sensed)[1][2].any()


def test_one_planted_foot_has_no_placed_offsets() -> None:
    f = _follower()
    sensed = _feet(0.0, 0.5)
    f.follow(LEFT, sensed, sensed, DT)
    assert f.placed_offsets(LEFT) is None  # nothing to tell apart from drift
    offsets = f.placed_offsets(LEFT | ~LEFT)
    assert offsets is not None and offsets.shape == (4, 3)


def test_a_leg_that_let_go_eases_back_then_stops_easing() -> None:
    easing = ReleaseEasing([np.array([1, 2])], n_segments=4, speed=1.0)
    R = np.tile(np.eye(3), (4, 1, 1))
    assert easing.apply(R, DT) is None  # nothing released
    easing.release(np.array([True]), lambda legs: np.tile([0.0, 0.0, 0.05], (len(legs), 1)))
    eased = easing.apply(R, DT)
    assert eased is not None
    np.testing.assert_allclose(pin.log3(eased[1]), [0.0, 0.0, 0.05 - DT], atol=1e-12)
    for _ in range(5):  # 0.04 rad left at 1 rad/s: gone within 0.05 s
        easing.apply(R, DT)
    assert easing.apply(R, DT) is None
    easing.release(np.array([True]), lambda legs: np.tile([0.02, 0.0, 0.0], (len(legs), 1)))
    again = easing.apply(R, DT)
    assert again is not None  # a second release eases again
    np.testing.assert_allclose(pin.log3(again[2]), [0.02 - DT, 0.0, 0.0], atol=1e-12)
