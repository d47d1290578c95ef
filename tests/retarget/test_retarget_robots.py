"""Retargeting real mocap (BVH, MVNX) onto humanoid robots: limits, feet, floor, capsules.

Every check recomputes from the written ``robot_motion.npz`` with Pinocchio and the URDF, not
from the summary the retargeter wrote.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ikfusion.app.evaluate import phase_slides
from ikfusion.cli import main
from ikfusion.errors import ConfigError
from ikfusion.ik.configuration import Configuration
from ikfusion.paths import robots_dir
from ikfusion.retarget import load_source, retarget
from ikfusion.retarget.capsules import CapsulePairs
from ikfusion.retarget.robot_config import (
    RetargetConfig,
    load_retarget_config,
    robots_installed,
)
from ikfusion.retarget.robot_model import RobotModel

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data"
CLIPS = sorted((SHARED / "mocap").glob("*.bvh")) + [SHARED / "mvnx" / "test_mocap.mvnx"]


needs_shared = pytest.mark.skipif(not (SHARED / "mocap").is_dir(),
                                  reason="../shared/data (the real mocap clips) is not beside "
                                  "the repository")
needs_robots = pytest.mark.skipif(not robots_installed(), reason="example-robot-data is not "
                                  "installed (pip install 'ikfusion[robots]')")


def check_output(out: Path, config: RetargetConfig) -> dict:
    """Assert the acceptance list on a written output folder; returns its summary."""
    data = np.load(out / "robot_motion.npz")
    summary = json.loads((out / "summary.json").read_text())
    robot = RobotModel(config)
    model = robot.model
    names = list(data["dof_names"])
    assert names == robot.dof_names
    lower, upper = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    dofs = data["dof_pos"]
    assert np.all(dofs >= lower - 1e-6) and np.all(dofs <= upper + 1e-6)
    speed = np.abs(np.diff(dofs, axis=0)) * float(data["fps"])
    limit = model.velocityLimit[6:]
    assert np.all((speed <= limit * (1 + 1e-6) + 1e-9) | (limit <= 0))
    q = np.column_stack([data["root_pos"], data["root_quat_wxyz"][:, 1:],
                         data["root_quat_wxyz"][:, :1], dofs])
    pin_data = model.createData()
    corners = []
    for qk in q:
        pin.framesForwardKinematics(model, pin_data, qk)
        row = []
        for side in ("left", "right"):
            foot = config.feet[side]
            T = pin_data.oMf[model.getFrameId(foot.link)]
            row.append(foot.corners @ T.rotation.T + T.translation)
        corners.append(np.concatenate(row))
    corners = np.array(corners)
    planted = np.repeat(data["contacts"], 4, axis=1)
    assert planted.any(), "no foot was ever planted"
    assert max(phase_slides(corners, planted)) <= 1e-3
    assert corners[..., 2].min() >= -1e-3
    pairs = CapsulePairs(config.capsules, config.collision_pairs, robot.frame_ids,
                         activation=np.inf)
    conf = Configuration(model, q[0])
    gaps = []
    for qk in q:
        conf.update(qk)
        gaps.append(pairs.distances(conf).min())
    assert min(gaps) >= 0.0
    assert summary["joint_limit_violations"] == 0 and summary["velocity_limit_violations"] == 0
    return summary


@needs_shared
def test_a_walk_onto_any_urdf_given_with_a_config(tmp_path: Path, human_as_robot: Path) -> None:
    """Our human URDF as a robot: the path route needs no extra package."""
    config_file = human_as_robot
    out = tmp_path / "out"
    clip = SHARED / "mocap" / "sfu_0005_Walking001.bvh"
    assert main(["retarget", str(clip), "--robot", str(robots_dir() / "human.urdf"),
                 "--config", str(config_file), "--out", str(out), "--quiet"]) == 0
    summary = check_output(out, load_retarget_config(robots_dir() / "human.urdf", config_file))
    # a body like the clip's tracks it closely (feet planted flat cost a few degrees)
    assert summary["tracking_orientation_rms_deg"]["LeftLowerLeg->LeftLowerLeg"] < 8.0


@needs_shared
@needs_robots
@pytest.mark.parametrize("robot", ["g1", "talos", "icub", "romeo"])
def test_every_clip_onto_the_shipped_robots(tmp_path: Path, robot: str) -> None:
    config = load_retarget_config(robot)
    for clip in CLIPS:
        out = tmp_path / clip.stem
        _, metrics = retarget(load_source(clip), robot, out=out, gmr=True)
        summary = check_output(out, config)
        assert summary["self_collision_min_distance_m"] >= 0.0, clip.name
        assert summary["relaxed_frames"] == metrics["relaxed_frames"]
        assert (out / "robot_motion.pkl").is_file() and (out / "robot_motion.csv").is_file()


@needs_robots
def test_unknown_robots_and_urdfs_without_config_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="g1, talos, icub, romeo"):
        load_retarget_config("asimo")
    with pytest.raises(ConfigError, match="--config"):
        load_retarget_config(robots_dir() / "human.urdf")


def test_robot_motion_csv_is_what_savetxt_writes(tmp_path: Path) -> None:
    # robot_motion.csv is formatted in one pass (issue #20: the row-by-row writer was ~1 ms
    # of a short clip's command); its text must stay exactly the six-decimal CSV it was.
    from ikfusion.retarget.output import RobotMotion, write_robot_motion

    rng = np.random.default_rng(3)
    n = 57
    quat = rng.normal(size=(n, 4))
    motion = RobotMotion(30.0, rng.normal(size=(n, 3)),
                         quat / np.linalg.norm(quat, axis=1, keepdims=True),
                         rng.normal(scale=2.0, size=(n, 5)) * [1, 1e-7, -1e-7, 1e6, 0],
                         ["a", "b", "c", "d", "e"], rng.random((n, 2)) < 0.5,
                         ["left_foot", "right_foot"], dof_units=["rad", "rad", "m", "rad", "rad"])
    out = write_robot_motion(tmp_path / "out", motion, {"frames": n})
    table = np.column_stack([np.arange(n), np.arange(n) / motion.fps, motion.root_pos,
                             motion.root_quat_wxyz, motion.dof_pos, motion.contacts])
    expected = tmp_path / "expected.csv"
    np.savetxt(expected, table, delimiter=",", fmt="%.6f",
               header=",".join(motion.csv_header()), comments="")
    assert (out / "robot_motion.csv").read_text() == expected.read_text()
