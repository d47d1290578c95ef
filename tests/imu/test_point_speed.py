"""Heel and toe speeds from a foot IMU, against the simulator's true site velocities."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikfusion.imu.flight import world_acceleration
from ikfusion.imu.point_speed import (
    floor_tip_slide,
    foot_point_offsets,
    point_speeds,
    points_moving,
    sensor_velocity,
)
from ikfusion.imu.point_speed_stream import FootPointsStream
from ikfusion.imu.stance import foot_still, velocity_anchors
from ikfusion.mocap.model_motion import site_positions
from ikfusion.model import HumanModel
from ikfusion.sim.capture import truth_motion
from ikfusion.sim.imu import ImuNoise, simulate_imus
from ikfusion.sim.uwb_capture import smooth_truth

RATE = 60.0
BRISK_WALK = (Path(__file__).resolve().parents[2] / "benchmarks" / "motions"
              / "cmu_07_01_or_08_02_walk_amp.bvh.gz")


def test_zero_velocity_updates_remove_a_constant_accelerometer_error() -> None:
    """A step of 0.4 s between two stances: v = 0.8 sin(pi t / T), plus a 0.3 m/s^2 bias."""
    t = np.arange(0, 1.0, 1 / RATE)
    T0, T = 0.3, 0.4
    inside = (t > T0) & (t < T0 + T)
    v_true = np.zeros((len(t), 3))
    v_true[inside, 0] = 0.8 * np.sin(np.pi * (t[inside] - T0) / T)
    a = np.gradient(v_true, 1 / RATE, axis=0) + np.array([0.3, -0.2, 0.1])
    still = ~inside
    v = sensor_velocity(a, still, RATE)
    assert np.all(v[still] == 0.0)
    np.testing.assert_allclose(v, v_true, atol=0.03)  # [m/s]; 0.3 m/s^2 * 0.4 s = 0.12 unaided


def test_velocity_is_unknown_far_from_every_stance() -> None:
    """1.5 s moving, 0.5 s still, 2 s moving at 1 m/s^2: known within 0.5 s of the stance."""
    still = np.r_[np.zeros(90, bool), np.ones(30, bool), np.zeros(120, bool)]
    a = np.zeros((240, 3))
    a[:90, 0] = -1.0  # braking to the stance (backward from it: v = 1 m/s^2 * time to go)
    a[120:, 0] = 1.0
    v = sensor_velocity(a, still, RATE, horizon=0.5)
    known = np.isfinite(v).all(axis=1)
    np.testing.assert_array_equal(np.flatnonzero(known), np.arange(60, 150))
    t_to_go = (90 - np.arange(60, 90)) / RATE
    np.testing.assert_allclose(v[60:90, 0], t_to_go, atol=0.02)
    np.testing.assert_allclose(v[120:150, 0], (np.arange(120, 150) - 119) / RATE, atol=0.02)


def test_pivot_point_does_not_move_while_the_heel_does() -> None:
    """A foot turning on its ball (about the vertical) at 3 rad/s: the ball still, the heel,
    0.2 m behind it, at 3 * 0.2 m/s."""
    omega = np.array([[0.0, 0.0, 3.0]])
    r = np.array([[[0.05, 0.0, -0.03], [-0.15, 0.0, -0.03]]])  # ball, heel from the sensor
    v_sensor = -np.cross(omega[0], r[0, 0])[None]  # the sensor turns about the ball
    speeds = point_speeds(v_sensor, omega, r)[0]
    assert speeds[0] == pytest.approx(0.0, abs=1e-12)
    assert speeds[1] == pytest.approx(3.0 * 0.2, rel=1e-6)


def _toe_pose(pitch: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A toe 7 cm long pitched ``pitch`` [rad] nose down: ball (3,), tip (3,) [m], and the
    rotation axis (3,) about which it pitches (the toe's y)."""
    ball = np.array([0.3, 0.1, 0.02 + 0.07 * np.sin(pitch)])
    tip = ball + 0.07 * np.array([np.cos(pitch), 0.0, -np.sin(pitch)])
    return ball, tip, np.array([0.0, 1.0, 0.0])


@pytest.mark.parametrize("pitch", [0.0, 0.4, 1.2])
def test_a_toe_turning_about_its_tip_does_not_slide(pitch: float) -> None:
    """Toes bent under a foot that pivots on them (kneeling down: the ball swings about the
    planted tip, in pitch or about the vertical) slide by nothing, however fast the ball."""
    ball, tip, y = _toe_pose(pitch)
    for omega in (3.0 * y, np.array([0.0, 0.0, 2.0]), np.array([1.0, -2.0, 0.5])):
        v_ball = np.cross(omega, ball - tip)  # a rigid turn about the tip
        np.testing.assert_allclose(floor_tip_slide(v_ball, ball, tip), 0.0, atol=1e-12)


@pytest.mark.parametrize("pitch", [0.0, 0.3, 0.6, 0.8])
def test_a_tip_on_the_floor_slides_at_its_true_speed(pitch: float) -> None:
    """Issue #19: a toe pitched nose down (push-off, the heel rising) whose tip stays on the
    floor while the foot turns it further down and pushes it forward: the tip's velocity is
    horizontal, and its part along the toe is the ball's. :func:`floor_tip_slide` gives that
    velocity exactly; the horizontal part of the ball's velocity along the toe gives
    ``cos(pitch)^2`` of it (58 % at 40 deg), which held the push-off toes of the CMU walks back
    at every step."""
    ball, tip, y = _toe_pose(pitch)
    for slide, pitch_rate in ((0.3, 0.0), (0.8, 2.0), (0.1, 5.0)):
        v_tip = np.array([slide, 0.0, 0.0])
        v_ball = v_tip + np.cross(pitch_rate * y, ball - tip)  # turning nose down about y
        np.testing.assert_allclose(floor_tip_slide(v_ball, ball, tip), v_tip, atol=1e-12)
        u = (tip - ball) / np.linalg.norm(tip - ball)
        least = float(v_ball @ u) * u[0]
        assert least == pytest.approx(slide * np.cos(pitch) ** 2, abs=1e-12)


def test_a_tip_slides_no_faster_than_its_ball_nor_from_a_turn_across_the_toe() -> None:
    """A toe pitched near the vertical (a solved toe standing on its tip: ``cos(pitch)``
    vanishes) slides at most at its ball's speed along the toe; a ball moving more across the
    toe than along it (a foot spinning on its forefoot, as in the dance's whirls) gives no
    slide: the tip's motion is the unknown turn's, and carrying it drifted the body."""
    ball, tip, _ = _toe_pose(1.5)
    v_ball = np.array([0.2, 0.0, -0.2])
    np.testing.assert_allclose(floor_tip_slide(v_ball, ball, tip), [0.2, 0.0, 0.0], atol=1e-12)
    ball, tip, _ = _toe_pose(0.4)
    for across in (np.array([0.1, 0.17, 0.0]), np.array([-0.05, -0.3, 0.1])):
        np.testing.assert_allclose(floor_tip_slide(across, ball, tip), 0.0, atol=1e-12)
    np.testing.assert_allclose(floor_tip_slide(np.array([0.3, 0.2, 0.0]), ball, tip),
                               [0.3, 0.0, 0.0], atol=1e-12)  # along the toe's direction only


@pytest.fixture(scope="module")
def walk():
    """A simulated walk (perfect sensors) with its foot IMU and true contact site speeds."""
    human = HumanModel.default()
    truth = truth_motion("gait:circle", 7.0, RATE)
    imus = simulate_imus(truth.model, truth.time, truth.q, ["LeftFoot"],
                         np.random.default_rng(1), ImuNoise.none())
    names = ["LeftHeel", "LeftToe"]
    P = site_positions(truth.model, truth.q, names)
    v_true = np.linalg.norm(np.gradient(P[..., :2], 1 / RATE, axis=0), axis=-1)
    return human, truth, imus, names, v_true


def test_heel_and_toe_speeds_follow_the_truth(walk) -> None:
    """The IMU's heel and toe speeds match the true sites' within 5 cm/s in a walk.

    (The true toe point is on the toes, which bend: at push-off it moves like the ball of the
    foot, where the speeds are taken, within a few cm/s.)
    """
    human, truth, imus, names, v_true = walk
    R, acc, gyr = imus.R_world_sensor[0], imus.acc[0], imus.gyr[0]
    still = foot_still(R, RATE, gyr, acc=acc) == 1.0
    R_sensor_segment = imus.R_segment_sensor[0].T  # the mounting (known: perfect calibration)
    offsets = foot_point_offsets(human)["LeftFoot"]
    assert list(offsets) == names
    v = sensor_velocity(world_acceleration(R, acc), still, RATE)
    r_world = np.einsum("nij,kj->nki", R @ R_sensor_segment, np.stack(list(offsets.values())))
    speeds = point_speeds(v, np.einsum("nij,nj->ni", R, gyr), r_world)
    known = np.isfinite(speeds).all(axis=1)
    assert known.mean() > 0.9
    slow = v_true[known] < 1.0  # the stance and push-off, where the timing is decided
    error = np.abs(speeds[known] - v_true[known])[slow]
    assert np.percentile(error, 95) <= 0.05


def test_causal_stream_agrees_with_offline_after_a_stance(walk) -> None:
    """Within its horizon the causal speeds say the same as the offline ones almost always."""
    human, _, imus, names, _ = walk
    R, acc, gyr = imus.R_world_sensor[0], imus.acc[0], imus.gyr[0]
    still = foot_still(R, RATE, gyr, acc=acc) == 1.0
    offsets = foot_point_offsets(human)["LeftFoot"]
    R_sensor_segment = imus.R_segment_sensor[0].T
    offline = points_moving(R, acc, gyr, still, RATE, R_sensor_segment, offsets, 0.1)
    stream = FootPointsStream(R_sensor_segment, offsets, 0.1, horizon=0.3)
    same, count = 0, 0
    for k in range(len(R)):
        out = stream.update(k / RATE, R[k], acc[k], gyr[k], bool(still[k]))
        for name, moving in out.items():
            count += 1
            same += moving == (offline[name][k] == 1.0)
    assert count > 200
    assert same / count >= 0.97


def test_a_foot_rolling_through_its_stances_still_gets_point_speeds() -> None:
    """A brisk mocap walk (AMP's CMU walk): the feet roll from heel to ball all through each
    stance (never slower than ~0.5 rad/s), so they are never *still* and the point speeds were
    unknown over 86-92 % of the walk, the toes dragged at push-off held as planted (issue #19:
    amp-walk drifted 10 %). Anchored at each stance's slowest sample, the speeds are known over
    most of the walk and say moving/not as the true sites do."""
    truth = smooth_truth(truth_motion(str(BRISK_WALK), 30.0, RATE))
    feet = ["LeftFoot", "RightFoot"]
    imus = simulate_imus(truth.model, truth.time, truth.q, feet, np.random.default_rng(1),
                         ImuNoise())
    offsets = foot_point_offsets(truth.model)
    walking = truth.time > 3.6  # after the N-pose and the step into the walk
    for i, foot in enumerate(feet):
        R, acc, gyr = imus.R_world_sensor[i], imus.acc[i], imus.gyr[i]
        still = foot_still(R, RATE, gyr, acc=acc) == 1.0
        assert still[walking].mean() < 0.05  # the premise: hardly ever still
        anchors = velocity_anchors(R, still, RATE, gyr, acc=acc)
        moving = points_moving(R, acc, gyr, anchors, RATE, imus.R_segment_sensor[i].T,
                               offsets[foot], 0.1)
        names = list(offsets[foot])
        P = site_positions(truth.model, truth.q, names)
        v_true = np.linalg.norm(np.gradient(P[..., :2], 1 / RATE, axis=0), axis=-1)[walking]
        for j, name in enumerate(names):
            said = moving[name][walking]
            known = np.isfinite(said)
            assert known.mean() >= 0.8, (name, known.mean())
            clear = known & ((v_true[:, j] > 0.3) | (v_true[:, j] < 0.05))
            assert clear.sum() > 60
            agree = (said[clear] == 1.0) == (v_true[clear, j] > 0.3)
            assert agree.mean() >= 0.95, (name, agree.mean())
