"""Retargeting a solved simulated walk onto the human model at other body sizes."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np
import pytest

from ikfusion.app.evaluate import phase_slides
from ikfusion.cli import main
from ikfusion.errors import InputError
from ikfusion.io.bvh import read_bvh
from ikfusion.mocap.model_motion import site_positions
from ikfusion.model import Body, HumanModel
from ikfusion.retarget import load_source, retarget
from ikfusion.retarget.human import source_joint_angles
from ikfusion.rotations import quat_wxyz_to_matrix


@pytest.fixture(scope="module")
def solved_walk(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``ikfusion demo`` on a short walk: its ``result`` folder is the source."""
    out = tmp_path_factory.mktemp("demo") / "demo"
    assert main(["demo", "--out", str(out), "--seconds", "6", "--quiet"]) == 0
    return out / "result"


@pytest.mark.parametrize("height", [1.55, 1.95])
def test_walk_onto_shorter_and_taller_bodies(solved_walk: Path, tmp_path: Path,
                                             height: float) -> None:
    out = tmp_path / "out"
    assert main(["retarget", str(solved_walk), "--robot", "human", "--height", str(height),
                 "--format", "gmr", "--out", str(out), "--quiet"]) == 0
    data = np.load(out / "robot_motion.npz")
    source = load_source(solved_walk)
    n = len(source)
    assert data["dof_pos"].shape == (n, 66) and data["root_pos"].shape == (n, 3)
    assert list(data["contact_frames"]) == source.contact_names
    summary = json.loads((out / "summary.json").read_text())
    assert summary["foot_slide_mm_max"] <= 1.0 and summary["floor_penetration_mm_max"] <= 1.0
    assert summary["joint_limit_violations"] == 0
    # Independently of the summary: rebuild the body from the written file, then check the
    # planted points over the source's contact phases and the angles against the source's.
    model = HumanModel.from_body(Body.from_height(height))
    angles = np.degrees(data["dof_pos"])
    names = list(data["dof_names"])
    assert names == model.angle_columns
    q = np.array([model.configuration(dict(zip(names, angles[k])), data["root_pos"][k],
                                      quat_wxyz_to_matrix(data["root_quat_wxyz"][k]))
                  for k in range(n)])
    points = site_positions(model, q, source.contact_names)
    assert max(phase_slides(points, source.contacts)) <= 1e-3
    assert points[..., 2].min() >= -1e-3
    reference = source_joint_angles(model, source)
    assert np.sqrt(np.mean((angles - reference) ** 2)) < 3.0
    # the walk is scaled: the pelvis travels in proportion to the legs
    path = np.linalg.norm(np.diff(data["root_pos"][:, :2], axis=0), axis=1).sum()
    source_path = np.linalg.norm(np.diff(source.p_world_segment[:, 0, :2], axis=0), axis=1).sum()
    assert path == pytest.approx(source_path * height / 1.75, rel=0.1)
    with (out / "robot_motion.pkl").open("rb") as f:
        gmr = pickle.load(f)
    assert set(gmr) == {"fps", "root_pos", "root_rot", "dof_pos"}
    np.testing.assert_allclose(gmr["root_rot"][:, 3], data["root_quat_wxyz"][:, 0])


def test_batch_retarget(solved_walk: Path, tmp_path: Path) -> None:
    """The batch command runs the retarget kind (one worker, local cluster)."""
    pytest.importorskip("distributed", reason="ikfusion batch needs dask[distributed]")
    out = tmp_path / "batch"
    assert main(["batch", "retarget", str(solved_walk), "--robot", "human", "--height", "1.6",
                 "--workers", "1", "--out", str(out)]) == 0
    report = (out / "batch_report.csv").read_text().splitlines()
    assert report[0] == "input,status,error,frames,seconds" and ",ok," in report[1]
    assert len(list(out.glob("*/robot_motion.npz"))) == 1


def test_bad_sources_and_options(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="result folder"):
        load_source(tmp_path)
    with pytest.raises(InputError, match="robot"):
        retarget(tmp_path, "g2", height=1.7)
    bad = tmp_path / "r"
    bad.mkdir()
    (bad / "segments.csv").write_text("time,segment,px,py,pz,qw,qx,qy,qz\n0,Pelvis,0,0,x,1,0,0,0\n")
    with pytest.raises(InputError, match="line 2") as err:
        load_source(bad)
    assert "pz" in str(err.value)


def test_human_retarget_csv_states_units_and_a_bvh_is_written(solved_walk: Path,
                                                               tmp_path: Path) -> None:
    """robot_motion.csv used joint_angles.csv's column names for radians; animators had no
    BVH. Now each column says its unit and motion.bvh holds the same motion."""
    out = tmp_path / "out"
    assert main(["retarget", str(solved_walk), "--robot", "human", "--height", "1.6",
                 "--out", str(out), "--quiet"]) == 0
    data = np.load(out / "robot_motion.npz")
    names = [str(n) for n in data["dof_names"]]
    with (out / "robot_motion.csv").open() as f:
        header = f.readline().strip().split(",")
    table = np.loadtxt(out / "robot_motion.csv", delimiter=",", skiprows=1)
    assert header[:9] == ["frame", "time_s", "root_x_m", "root_y_m", "root_z_m", "root_qw",
                          "root_qx", "root_qy", "root_qz"]
    assert "jRightKnee_flex_rad" in header
    assert header[9:9 + len(names)] == [f"{n}_rad" for n in names]
    assert header[9 + len(names):] == [f"{c}_planted" for c in data["contact_frames"]]
    np.testing.assert_allclose(table[:, 9:9 + len(names)], data["dof_pos"], atol=1e-6)
    np.testing.assert_allclose(table[:, 1], np.arange(len(table)) / float(data["fps"]),
                               atol=1e-6)
    # motion.bvh: the same frames, the pelvis path and the knees' rotations of the npz.
    bvh = read_bvh(out / "motion.bvh")
    assert bvh.num_frames == len(data["root_pos"])
    assert bvh.frame_time == pytest.approx(1.0 / float(data["fps"]))
    np.testing.assert_allclose(bvh.root_positions(up="z"), data["root_pos"], atol=1e-5)
    model = HumanModel.from_body(Body.from_height(1.6))
    local = bvh.local_rotations(up="z")
    knee = bvh.joint_index("RightLowerLeg")
    for k in range(0, bvh.num_frames, 25):
        q = model.configuration(dict(zip(names, np.degrees(data["dof_pos"][k]))))
        R = model.segment_rotation(q, "RightUpperLeg").T @ model.segment_rotation(
            q, "RightLowerLeg")
        np.testing.assert_allclose(local[k, knee], R, atol=1e-4)
