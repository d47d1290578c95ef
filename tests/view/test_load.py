"""Loading result folders, truth files and BVH clips into the neutral viewer scene."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from view_motion import FRAMES, RATE, stepping_motion

from ikfusion.errors import InputError
from ikfusion.mocap.model_motion import TruthMotion
from ikfusion.model import HumanModel
from ikfusion.results import write_result_folder
from ikfusion.rotations import matrix_to_quat_wxyz
from ikfusion.sim.truth import write_truth
from ikfusion.view import load_scene
from ikfusion.view.draw import bone_strips, floor_lines
from ikfusion.view.load import MODEL_SEGMENT_PARENTS


def test_result_folder_poses_match_the_model(human: HumanModel, result_folder: Path) -> None:
    scene = load_scene(result_folder)
    actor = scene.main
    motion = stepping_motion(human)
    assert [a.name for a in scene.actors] == ["subject"]
    assert actor.frames == FRAMES
    assert actor.duration == pytest.approx((FRAMES - 1) / RATE)
    assert list(actor.segment_names) == human.segment_names
    k = 13
    for name in ("Pelvis", "RightLowerLeg", "Head"):
        s = actor.segment_names.index(name)
        np.testing.assert_allclose(actor.p_world_segment[k, s],
                                   human.segment_position(motion.q[k], name), atol=1e-5)
    R = human.segment_rotation(motion.q[k], "RightLowerLeg")
    w, x, y, z = actor.quat_wxyz_world_segment[k, actor.segment_names.index("RightLowerLeg")]
    q_ref = matrix_to_quat_wxyz(R)
    assert abs(float(np.dot(q_ref, [w, x, y, z]))) == pytest.approx(1.0, abs=1e-6)
    head_top = actor.site_index("HeadTop")
    assert head_top is not None
    np.testing.assert_allclose(actor.p_world_site[k, head_top],
                               human.site_position(motion.q[k], "HeadTop"), atol=1e-5)


def test_parents_contacts_angles_and_readers(result_folder: Path) -> None:
    scene = load_scene(result_folder)
    actor = scene.main
    for s, name in enumerate(actor.segment_names):
        parent = MODEL_SEGMENT_PARENTS[name]
        expected = -1 if parent is None else actor.segment_names.index(parent)
        assert actor.segment_parents[s] == expected
    assert actor.contact_names == ("LeftHeel", "LeftToe", "RightHeel", "RightToe")
    assert actor.contacts[0].tolist() == [True, True, False, False]
    assert actor.contacts[FRAMES // 2 - 5].tolist() == [False, False, True, True]
    knee = actor.angle_names.index("jRightKnee_flex")
    assert actor.joint_angles_deg[:, knee].max() == pytest.approx(40.0, abs=0.5)
    assert scene.readers is not None
    assert scene.readers.ids == ("R1", "R2")
    np.testing.assert_allclose(scene.readers.p_world_reader[1], [3.0, 2.0, 2.5])
    assert any("frames at 20.0 Hz" in n for n in scene.notes)
    assert actor.solve_time_ms is not None  # from solve_time.csv
    np.testing.assert_allclose(actor.solve_time_ms, 2.0)  # the stepping motion: 2 ms a frame


def test_bones_reach_children_and_tips(result_folder: Path) -> None:
    actor = load_scene(result_folder).main
    bones = bone_strips(actor)[0]
    # 22 parent-child bones, Head->HeadTop, two toes to their tips, two hand stubs
    assert len(bones) == 22 + 5
    lengths = [float(np.linalg.norm(b[1] - b[0])) for b in bones]
    assert max(lengths) < 0.6
    lines = floor_lines(load_scene(result_folder))
    assert all(abs(line[:, 2]).max() == 0.0 for line in lines)


def test_folder_of_results_gives_one_actor_each(result_folder: Path, tmp_path: Path) -> None:
    for name in ("alice", "bob"):
        shutil.copytree(result_folder, tmp_path / name)
    scene = load_scene(tmp_path)
    assert [a.name for a in scene.actors] == ["alice", "bob"]
    assert all(a.frames == FRAMES for a in scene.actors)


def test_truth_as_ghost_and_capture_folder(human: HumanModel, result_folder: Path,
                                           tmp_path: Path) -> None:
    motion = stepping_motion(human)
    truth = TruthMotion(human, motion.time, motion.q, motion.contact_names, motion.contacts)
    file = write_truth(tmp_path / "capture" / "truth.npz", truth)
    scene = load_scene(result_folder, truth=file)
    assert [(a.name, a.ghost) for a in scene.actors] == [("subject", False), ("truth", True)]
    assert scene.main.name == "subject"
    np.testing.assert_allclose(scene.actors[1].p_world_segment, scene.main.p_world_segment,
                               atol=1e-5)
    capture = load_scene(tmp_path / "capture")
    assert capture.main.frames == FRAMES and not capture.main.ghost


def test_bvh_clip(human: HumanModel, tmp_path: Path) -> None:
    motion = stepping_motion(human)
    out = write_result_folder(motion, tmp_path / "r")
    actor = load_scene(out / "motion.bvh").main
    assert actor.frames == FRAMES
    assert actor.duration == pytest.approx((FRAMES - 1) / RATE, rel=1e-3)
    assert (actor.segment_parents[1:] >= 0).all() and actor.segment_parents[0] == -1
    head = actor.p_world_site[:, :, 2].max()
    assert 1.5 < head < 2.0  # metres, Z up


def test_bad_inputs_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="segments.csv"):
        load_scene(tmp_path)
    (tmp_path / "segments.csv").write_text("time,segment,px,py,pz,qw,qx,qy,qz\n"
                                           "0.0,Pelvis,0,0,x,1,0,0,0\n")
    with pytest.raises(InputError) as err:
        load_scene(tmp_path)
    assert err.value.line == 2 and err.value.field == "pz"
