"""Assumed orientations of unsensed hinge parents (ikfusion.ik.assumed)."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.errors import ConfigError
from ikfusion.ik.assumed import AssumedTargets, coverage_warning, hinge_angle, segment_coverage
from ikfusion.model import HumanModel
from ikfusion.rotations import axis_rotation, exp_so3


@pytest.fixture(scope="module")
def model() -> HumanModel:
    return HumanModel.default()


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    return exp_so3(rng.normal(size=3))


def test_hinge_angle_recovers_a_knee_under_a_straight_hip(rng: np.random.Generator) -> None:
    # thigh parallel to the pelvis: the whole pelvis-to-shank rotation is the knee's flexion
    for _ in range(50):
        R_pelvis = _random_rotation(rng)
        flex = rng.uniform(0.0, np.radians(150.0))
        R_shank = R_pelvis @ axis_rotation("y", flex)
        got = hinge_angle(R_pelvis, R_shank, "y", 1, 0.0, np.radians(155.0))
        assert got == pytest.approx(flex, abs=1e-9)
        # a mirrored sign convention (elbows: flexion is a negative turn about y)
        got = hinge_angle(R_pelvis, R_pelvis @ axis_rotation("y", -flex), "y", -1, 0.0,
                          np.radians(155.0))
        assert got == pytest.approx(flex, abs=1e-9)


def test_hinge_angle_stays_in_range() -> None:
    R = np.eye(3)
    # the shank ahead of the pelvis (hip flexion): the knee stays straight, never hyperextends
    assert hinge_angle(R, axis_rotation("y", -0.6), "y", 1, 0.0, 2.7) == 0.0
    assert hinge_angle(R, axis_rotation("y", 3.0), "y", 1, 0.0, 2.7) == pytest.approx(2.7)


def test_hinge_angle_is_the_best_hinge(rng: np.random.Generator) -> None:
    # against a brute-force search over the range: no other flexion turns the thigh less
    grid = np.radians(np.linspace(0.0, 155.0, 3101))
    for _ in range(20):
        R_pelvis, R_shank = _random_rotation(rng), _random_rotation(rng)
        got = hinge_angle(R_pelvis, R_shank, "y", 1, 0.0, grid[-1])
        traces = [np.trace(R_pelvis.T @ R_shank @ axis_rotation("y", k).T) for k in grid]
        assert np.trace(R_pelvis.T @ R_shank @ axis_rotation("y", got).T) >= max(traces) - 1e-9


def test_targets_fit_the_sensed_segments(model: HumanModel, rng: np.random.Generator) -> None:
    segments = model.segment_names
    index = {n: i for i, n in enumerate(segments)}
    assumed = AssumedTargets(segments, model.ball_joints, ["jRightKnee", "jLeftKnee"])
    R = np.tile(np.eye(3), (len(segments), 1, 1))
    sensed = np.zeros(len(segments), dtype=bool)
    for name in ("Pelvis", "RightLowerLeg", "LeftLowerLeg", "LeftUpperLeg"):
        R[index[name]] = _random_rotation(rng)
        sensed[index[name]] = True
    targets = dict(assumed.targets(R, sensed))
    assert list(targets) == [index["RightUpperLeg"]]  # the sensed left thigh needs none
    knee = targets[index["RightUpperLeg"]].T @ R[index["RightLowerLeg"]]
    # the knee is a pure hinge about the thigh's y axis, so the shank fits its sensor exactly
    assert knee[1] == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)
    sensed[index["Pelvis"]] = False  # no sensed segment above the thigh: nothing to assume
    assert assumed.targets(R, sensed) == []


def test_coverage_lists_and_warns(model: HumanModel) -> None:
    treadmill = ["Pelvis", "LeftFoot", "RightFoot", "LeftLowerLeg", "RightLowerLeg"]
    coverage = segment_coverage(model.segment_names, treadmill)
    assert sorted(coverage["measured"]) == sorted(treadmill)
    assert len(coverage["assumed"]) == len(model.segment_names) - 5
    warning = coverage_warning(model.ball_joints, treadmill)
    assert warning is not None
    assert "hip and knee angles are assumed" in warning and "RightUpperLeg" in warning
    assert "trunk and head are assumed" in warning
    full = ["Pelvis", "T8", "Head"] + [f"{s}{p}" for s in ("Right", "Left") for p in (
        "Shoulder", "UpperArm", "ForeArm", "Hand", "UpperLeg", "LowerLeg", "Foot")]
    assert coverage_warning(model.ball_joints, full) is None


def test_unknown_hinge_is_a_config_error(model: HumanModel) -> None:
    with pytest.raises(ConfigError, match="jRightKnees"):
        AssumedTargets(model.segment_names, model.ball_joints, ["jRightKnees"])
