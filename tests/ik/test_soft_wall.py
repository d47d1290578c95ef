"""The soft wall at the ranges of motion: no pop where a joint runs into a limit (issue #19)."""

from __future__ import annotations

import numpy as np
import pytest
from motions import frames_from

from ikfusion.ik import Solver
from ikfusion.ik.limits import JointRangeLimit
from ikfusion.ik.limits.soft_wall import SoftWall
from ikfusion.model import HumanModel
from ikfusion.rotations import angle_between, exp_so3

LIMIT_DEG = 35.0  # jRightAnkle_rot's upper limit (configs/joints.yaml)


def ankle_running_into_its_limit(human: HumanModel) -> np.ndarray:
    """(N, nq) the right ankle turning from -3 to 34.3 deg in 14 frames at 60 Hz (4 deg a frame
    at most, as gen-backwards' ankles do), then resting 0.7 deg short of its 35 deg limit."""
    s = np.clip(np.arange(50) / 14.0, 0.0, 1.0)
    rot_deg = -3.0 + 37.3 * s * s * (3.0 - 2.0 * s)
    return np.array([human.configuration({"jRightAnkle_rot": r}) for r in rot_deg])


def ankle_rotations(human: HumanModel, qs: np.ndarray) -> np.ndarray:
    """(N, 3, 3) ``R_shank_foot`` of the right ankle."""
    return np.array([human.segment_rotation(q, "RightLowerLeg").T
                     @ human.segment_rotation(q, "RightFoot") for q in qs])


def solve(human: HumanModel, truth: np.ndarray, heading_error_deg: float,
          **settings: float) -> np.ndarray:
    """(N, nq) solved from the truth's orientations, the right foot's sensor turned about the
    vertical by ``heading_error_deg``."""
    frames = frames_from(human, truth)
    turn = exp_so3(np.radians([0.0, 0.0, heading_error_deg]))
    for frame in frames:
        frame.orientations["RightFoot"] = turn @ frame.orientations["RightFoot"]
    return Solver(human, contacts=False, **settings).solve(frames).q


def largest_error_change_deg(human: HumanModel, truth: np.ndarray, solved: np.ndarray) -> float:
    """The largest one-frame change of the ankle's error rotation against the truth [deg]
    (``evaluate``'s ``joint_angle_jump_max_deg`` for this joint)."""
    error = np.swapaxes(ankle_rotations(human, truth), -1, -2) @ ankle_rotations(human, solved)
    return float(np.max(np.degrees(angle_between(error[:-1], error[1:]))))


@pytest.mark.parametrize(("heading_error_deg", "pop_deg", "largest_deg"),
                         [(4.0, 1.0, 0.5), (10.0, 2.5, 1.0)])
def test_a_joint_degrees_ahead_of_the_truth_does_not_stop_dead_at_its_limit(
        human: HumanModel, heading_error_deg: float, pop_deg: float, largest_deg: float) -> None:
    """gen-backwards: a foot sensor's heading error puts the ankle's rotation degrees ahead of
    the truth (4 deg at 13.7 s of its first 15 s), which turns into its limit at up to 4 deg a
    frame. A hard limit stops the estimate dead while the true ankle still turns: the error
    changes by the truth's speed in one frame (1.5 deg with 4 deg ahead, 3.0 with 10). The soft
    wall lets the ankle sink past the limit and eases it back (0.2 and 0.5 deg)."""
    truth = ankle_running_into_its_limit(human)
    hard = solve(human, truth, heading_error_deg, joint_range_overshoot_deg=0.0)
    assert largest_error_change_deg(human, truth, hard) > pop_deg  # the pop
    soft = solve(human, truth, heading_error_deg)  # the shipped settings
    assert largest_error_change_deg(human, truth, soft) < largest_deg
    limits = JointRangeLimit(human.ball_joints, margin_deg=0.0)
    past = np.array([limits.violation_deg(q).max() for q in soft])
    assert past.max() <= 8.0 + 1e-6  # joint_range_overshoot_deg
    assert past[-1] < 0.01  # eased back into the range within the clip's 0.6 s at rest


def test_targets_inside_the_ranges_are_tracked_as_with_hard_limits(human: HumanModel) -> None:
    """The wall only widens a range: a joint driven fast into its limit by exact targets that
    stop short of it is solved exactly as with hard limits (no lag)."""
    truth = ankle_running_into_its_limit(human)
    np.testing.assert_array_equal(solve(human, truth, 0.0),
                                  solve(human, truth, 0.0, joint_range_overshoot_deg=0.0))


def test_the_wall_springs_back_like_a_critically_damped_spring() -> None:
    """One angle that came to rest 2 deg past its limit is pushed back as by the spring
    ``o'' = -o / tau^2 - 2 o' / tau``: its first step is the spring's exact one from rest, it
    then returns steadily, never faster than the spring's top speed ``o0 / (e tau)``, never
    past the limit, within 0.3 s; no other angle or limit gets any room."""
    lower, upper = np.full((1, 3), -0.5), np.full((1, 3), 0.5)  # [rad]
    tau, dt, o0 = 0.05, 1.0 / 60.0, np.radians(2.0)
    wall = SoftWall(lower, upper, np.radians(5.0), tau)
    a = np.zeros((1, 3))
    a[0, 2] = upper[0, 2] + o0
    wall.update(a.copy(), dt)  # at rest: the same angles twice
    past = [o0]
    for _ in range(18):  # 0.3 s
        wall.update(a.copy(), dt)
        room = wall.room(a)
        up, down = (np.zeros((1, 3)), np.zeros((1, 3))) if room is None else room
        assert np.all(down == 0.0) and np.all(up[0, :2] == 0.0)
        past.append(float(up[0, 2]))
        a[0, 2] = upper[0, 2] + up[0, 2]  # the angle follows the wall back
    np.testing.assert_allclose(past[1], o0 * (1.0 + dt / tau) * np.exp(-dt / tau))
    assert np.all(np.diff(past) <= 0.0) and min(past) >= 0.0 and past[-1] == 0.0
    assert -np.min(np.diff(past)) <= o0 / (np.e * tau) * dt


@pytest.mark.parametrize(("depth", "tau"), [(-1.0, 0.05), (5.0, 0.0)])
def test_a_bad_setting_names_its_field(human: HumanModel, depth: float, tau: float) -> None:
    from ikfusion.errors import ConfigError

    with pytest.raises(ConfigError, match="joint_range_(overshoot_deg|settle_s)"):
        JointRangeLimit(human.ball_joints, 5.0, depth, tau)
