"""The result folder of a solve: files, columns, atomic writing, and a BVH other tools read."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from ikfusion.ik import Motion
from ikfusion.io.bvh import read_bvh
from ikfusion.model import CONTACT_SITES, HumanModel
from ikfusion.results import write_result_folder


@pytest.fixture(scope="module")
def human() -> HumanModel:
    return HumanModel.default()


def make_motion(model: HumanModel, rng: np.random.Generator, n: int = 12) -> Motion:
    qs = np.array([model.random_configuration(rng, p_world_pelvis=[0.1 * k, 0.0, 0.9])
                   for k in range(n)])
    contacts = rng.random((n, 4)) > 0.5
    return Motion(model, np.arange(n) / 60.0, qs, list(CONTACT_SITES), contacts,
                  np.full(n, 1e-3), np.full(n, 2), np.zeros(n, dtype=bool), ["a warning"])


def test_files_and_columns(human: HumanModel, rng, tmp_path: Path) -> None:
    motion = make_motion(human, rng)
    out = write_result_folder(motion, tmp_path / "result")
    names = sorted(p.name for p in out.iterdir())
    assert names == [".ikfusion.json", "contacts.csv", "joint_angles.csv", "motion.bvh",
                     "motion.mot", "segments.csv", "sites.csv", "solve_time.csv", "summary.json"]
    with (out / "joint_angles.csv").open() as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["time", *human.angle_columns]
    assert len(rows) == 1 + len(motion)
    knee = rows[0].index("jRightKnee_flex")
    assert float(rows[5][knee]) == pytest.approx(
        human.joint_angles(motion.q[4])["jRightKnee_flex"], abs=1e-5)
    with (out / "segments.csv").open() as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["time", "segment", "px", "py", "pz", "qw", "qx", "qy", "qz"]
    assert len(rows) == 1 + 23 * len(motion)
    head = next(r for r in rows[1:] if r[1] == "Head" and float(r[0]) == pytest.approx(3 / 60))
    np.testing.assert_allclose([float(v) for v in head[2:5]],
                               human.segment_position(motion.q[3], "Head"), atol=1e-6)
    with (out / "contacts.csv").open() as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["time", "LeftHeel", "LeftToe", "RightHeel", "RightToe"]
    assert [int(v) for v in rows[1][1:]] == motion.contacts[0].astype(int).tolist()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == len(motion)
    assert summary["rate"] == pytest.approx(60.0)
    assert summary["warnings"] == ["a warning"]


@pytest.mark.parametrize("up", ["z", "y"])
def test_bvh_positions_match_the_model(human: HumanModel, rng, tmp_path: Path, up: str) -> None:
    motion = make_motion(human, rng)
    out = write_result_folder(motion, tmp_path / "r", bvh_up=up)
    bvh = read_bvh(out / "motion.bvh")
    assert bvh.num_frames == len(motion)
    assert bvh.num_joints == 23
    poses = bvh.world_poses(scale=1.0, up=up)
    for k in (0, 5, len(motion) - 1):
        for j, name in enumerate(bvh.joint_names):
            np.testing.assert_allclose(poses.p_world_joint[k, j],
                                       human.segment_position(motion.q[k], name), atol=1e-3)


def test_independent_parser_reads_the_bvh(human: HumanModel, rng, tmp_path: Path) -> None:
    bvhio = pytest.importorskip("bvhio", reason="bvhio (dev extra) is the independent parser")
    motion = make_motion(human, rng)
    out = write_result_folder(motion, tmp_path / "r")
    root = bvhio.readAsHierarchy(str(out / "motion.bvh"))
    joints = [j for j, _, _ in root.layout()]
    assert len(joints) == 23
    root.loadRestPose()
    for k in (2, 7):
        root.loadPose(k)
        for joint in joints:
            if joint.Name in human.segment_names:
                np.testing.assert_allclose(np.array(joint.PositionWorld),
                                           human.segment_position(motion.q[k], joint.Name),
                                           atol=1e-3)


def test_interrupted_write_leaves_the_old_folder(human: HumanModel, rng, tmp_path: Path,
                                                 monkeypatch) -> None:
    motion = make_motion(human, rng)
    out = write_result_folder(motion, tmp_path / "r")
    before = (out / "summary.json").read_text()

    def boom(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("ikfusion.results.folder.write_motion_bvh", boom)
    with pytest.raises(KeyboardInterrupt):
        write_result_folder(make_motion(human, rng, 5), tmp_path / "r")
    assert (out / "summary.json").read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]
