"""BVH reader, forward kinematics and writer: real clips, an independent parser, round trips."""

from __future__ import annotations

import itertools
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ikfusion.errors import InputError, NameNotFound
from ikfusion.io.bvh import (
    BVH_UNITS,
    BvhSkeleton,
    guess_bvh_scale,
    read_bvh,
    rotation_world_file,
    rotation_zup_yup,
    write_bvh,
)
from ikfusion.model.angle_continuity import equivalent_triple
from ikfusion.rotations import axis_rotation, euler_to_matrix, random_rotations

CLIPS = [
    "mocap/cmu_01_01_hop_turn.bvh",
    "mocap/cmu_02_01_walk.bvh",
    "mocap/cmu_131_01.bvh",
    "mocap/sfu_0005_Jogging001.bvh",
    "mocap/sfu_0005_Walking001.bvh",
    "mvnx/test_mocap.bvh",
]
ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]


def _header_facts(path: Path) -> dict:
    """What the file text says, read with plain string handling (no ikfusion code)."""
    lines = path.read_text().splitlines()
    words = [line.split() for line in lines]
    motion = next(i for i, w in enumerate(words) if w and w[0] == "MOTION")
    frames = int(words[motion + 1][1])
    frame_time = float(words[motion + 2][2])
    data = [w for w in words[motion + 3:] if w]
    return {
        "frames": frames,
        "frame_time": frame_time,
        "joints": sum(1 for w in words[:motion] if w and w[0] in ("ROOT", "JOINT")),
        "end_sites": sum(1 for w in words[:motion] if w[:2] == ["End", "Site"]),
        "channels": sum(int(w[1]) for w in words[:motion] if w and w[0] == "CHANNELS"),
        "first": [float(v) for v in data[0]],
        "last": [float(v) for v in data[-1]],
        "data_lines": len(data),
    }


def _spread(n_frames: int, count: int = 5) -> np.ndarray:
    return np.unique(np.linspace(0, n_frames - 1, count).round().astype(int))


@pytest.mark.parametrize("clip", CLIPS)
def test_reads_every_shared_clip_as_written(shared_data: Path, clip: str) -> None:
    path = shared_data / clip
    facts = _header_facts(path)
    motion = read_bvh(path)
    assert motion.num_frames == facts["frames"] == facts["data_lines"]
    assert motion.frame_time == facts["frame_time"]
    assert motion.frame_rate == pytest.approx(1.0 / facts["frame_time"])
    assert motion.duration == pytest.approx((facts["frames"] - 1) * facts["frame_time"])
    assert motion.num_joints == facts["joints"]
    assert len(motion.end_site_parents) == facts["end_sites"]
    assert motion.channels.shape == (facts["frames"], facts["channels"])
    assert len(motion.channel_names) == facts["channels"]
    # Values are the file's numbers exactly (bit for bit), first and last frame.
    assert motion.channels[0].tolist() == facts["first"]
    assert motion.channels[-1].tolist() == facts["last"]
    assert motion.parents[0] == -1
    assert np.all(motion.parents[1:] < np.arange(1, motion.num_joints))


def test_channel_layouts_of_the_real_files(shared_data: Path) -> None:
    cmu = read_bvh(shared_data / "mocap/cmu_131_01.bvh")
    assert cmu.joint_channels[0] == (
        "Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")
    # The 3ds Max conversion writes ZXY on the arms and ZYX elsewhere.
    assert cmu.rotation_order("LeftShoulder") == "ZXY"
    assert cmu.rotation_order("LeftHip") == "ZYX"
    sfu = read_bvh(shared_data / "mocap/sfu_0005_Walking001.bvh")
    assert sfu.rotation_order("Hips") == "XYZ"
    # SFU's wrist end joints are JOINTs without an End Site.
    assert "L_Wrist_End" in sfu.joint_names
    assert sfu.joint_index("L_Wrist_End") not in sfu.end_site_parents
    mvn = read_bvh(shared_data / "mvnx/test_mocap.bvh")
    assert mvn.rotation_order("LeftKnee") == "YXZ"
    with pytest.raises(NameNotFound, match="LeftKnee"):
        cmu.joint_index("NoSuchJoint")


@pytest.mark.parametrize("clip", CLIPS)
def test_forward_kinematics_matches_bvhio(shared_data: Path, clip: str, tmp_path: Path) -> None:
    bvhio = pytest.importorskip("bvhio", reason="bvhio (independent BVH parser) not installed")
    path = shared_data / clip
    motion = read_bvh(path)
    frames = _spread(motion.num_frames, 4)
    # Give bvhio a short copy holding only the chosen frames (keeps the test fast).
    lines = path.read_text().splitlines()
    words = [line.split() for line in lines]
    m = next(i for i, w in enumerate(words) if w and w[0] == "MOTION")
    data = [line for line in lines[m + 3:] if line.strip()]
    short = lines[:m] + ["MOTION", f"Frames: {len(frames)}", lines[m + 2]]
    short += [data[k] for k in frames]
    copy = tmp_path / "short.bvh"
    copy.write_text("\n".join(short) + "\n")

    root = bvhio.readAsHierarchy(str(copy))
    layout = [joint for joint, _, _ in root.layout()]
    assert [j.Name for j in layout] == list(motion.joint_names)
    # bvhio works in the file's axes and units: compare in those.
    p_file = motion.world_poses(1.0, "y", frames).p_world_joint @ rotation_zup_yup()
    for k in range(len(frames)):
        root.loadPose(k)
        theirs = np.array([list(j.PositionWorld) for j in layout], dtype=float)
        extent = np.ptp(theirs, axis=0).max()
        # bvhio computes in float32: relative agreement is ~3e-7 of the skeleton size.
        np.testing.assert_allclose(p_file[k], theirs, rtol=0, atol=1e-6 * extent)


def test_rotation_channels_compose_in_written_order(tmp_path: Path) -> None:
    text = """HIERARCHY
ROOT base
{
  OFFSET 1 2 3
  CHANNELS 6 Zrotation Xposition Xrotation Yposition Yrotation Zposition
  JOINT arm
  {
    OFFSET 0 5 0
    CHANNELS 6 Xposition Yrotation Xrotation Zrotation Yposition Zposition
    End Site
    {
      OFFSET 0 0 2
    }
  }
}
MOTION
Frames: 1
Frame Time: 0.01
30 10 -20 20 45 30   7 15 -40 60 5 0
"""
    path = tmp_path / "order.bvh"
    path.write_text(text)
    motion = read_bvh(path)
    assert motion.rotation_order("base") == "ZXY"
    assert motion.rotation_order("arm") == "YXZ"
    d = np.deg2rad
    R_base = axis_rotation("z", d(30)) @ axis_rotation("x", d(-20)) @ axis_rotation("y", d(45))
    R_arm = axis_rotation("y", d(15)) @ axis_rotation("x", d(-40)) @ axis_rotation("z", d(60))
    R_local = motion.local_rotations()
    np.testing.assert_allclose(R_local[0, 0], R_base, atol=1e-15)
    np.testing.assert_allclose(R_local[0, 1], R_arm, atol=1e-15)
    # Position channels replace the OFFSET; absent ones keep it.
    t = motion.local_translations()[0]
    np.testing.assert_array_equal(t[0], [10.0, 20.0, 30.0])
    np.testing.assert_array_equal(t[1], [7.0, 5.0, 0.0])
    # Forward kinematics by hand, in file axes (up="z" leaves the axes as they are).
    poses = motion.world_poses(scale=2.0, up="z")
    p_arm = 2.0 * (t[0] + R_base @ t[1])
    p_end = p_arm + R_base @ R_arm @ np.array([0.0, 0.0, 4.0])
    np.testing.assert_allclose(poses.p_world_joint[0, 1], p_arm, atol=1e-12)
    np.testing.assert_allclose(poses.p_world_end_site[0, 0], p_end, atol=1e-12)
    np.testing.assert_allclose(poses.R_world_joint[0, 1], R_base @ R_arm, atol=1e-15)
    # A Y-up file is turned into our Z-up world.
    turned = motion.world_poses(scale=2.0, up="y")
    np.testing.assert_allclose(turned.p_world_joint[0, 1], rotation_zup_yup() @ p_arm)


def test_zup_yup_rotation() -> None:
    R = rotation_zup_yup()
    np.testing.assert_allclose(R @ R.T, np.eye(3))
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_array_equal(R @ [0, 1, 0], [0, 0, 1])  # file up -> world up
    np.testing.assert_array_equal(R @ [0, 0, 1], [1, 0, 0])  # file +Z (facing) -> forward
    np.testing.assert_array_equal(R @ [1, 0, 0], [0, 1, 0])  # file +X -> left
    np.testing.assert_array_equal(rotation_world_file("z"), np.eye(3))
    with pytest.raises(ValueError, match="up"):
        rotation_world_file("x")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("clip", "unit"),
    [("mocap/cmu_02_01_walk.bvh", BVH_UNITS["cmu"]),
     ("mocap/cmu_131_01.bvh", BVH_UNITS["cmu"]),
     ("mocap/sfu_0005_Walking001.bvh", BVH_UNITS["inch"]),
     ("mvnx/test_mocap.bvh", BVH_UNITS["cm"])],
)
def test_guess_scale_finds_the_unit(shared_data: Path, clip: str, unit: float) -> None:
    motion = read_bvh(shared_data / clip)
    assert guess_bvh_scale(motion) == unit
    size = max(np.ptp(np.vstack(motion.rest_positions()), axis=0))
    assert guess_bvh_scale(motion, height=1.8) == pytest.approx(1.8 / size)


def test_guess_scale_on_metres_and_odd_units(tmp_path: Path) -> None:
    skeleton = _chain_skeleton(np.array([[0, 0, 0], [0, 0, -0.85], [0, 0, 1.7]]))
    path = write_bvh(tmp_path / "m.bvh", skeleton, np.zeros((1, 3)),
                     np.broadcast_to(np.eye(3), (1, 3, 3, 3)), 0.01)
    assert guess_bvh_scale(read_bvh(path)) == 1.0
    # 3 m per unit fits no common unit: the scale that makes the skeleton 1.7 m tall.
    path = write_bvh(tmp_path / "odd.bvh", skeleton, np.zeros((1, 3)),
                     np.broadcast_to(np.eye(3), (1, 3, 3, 3)), 0.01, scale=3.0)
    assert guess_bvh_scale(read_bvh(path)) == pytest.approx(3.0)


def _chain_skeleton(offsets: np.ndarray) -> BvhSkeleton:
    n = len(offsets)
    return BvhSkeleton(tuple(f"j{i}" for i in range(n)), np.arange(-1, n - 1), offsets,
                       np.array([n - 1]), np.array([[0.0, 0.1, 0.0]]))


@pytest.mark.parametrize("clip", CLIPS)
@pytest.mark.parametrize("up", ["y", "z"])
def test_round_trip_keeps_world_positions(
    shared_data: Path, clip: str, up: str, tmp_path: Path
) -> None:
    motion = read_bvh(shared_data / clip)
    scale = guess_bvh_scale(motion)
    frames = _spread(motion.num_frames, 40)
    skeleton = motion.skeleton(scale)
    before = motion.world_poses(scale, "y", frames)
    out = write_bvh(
        tmp_path / "rt.bvh", skeleton, motion.root_positions(scale, "y", frames),
        motion.local_rotations(frames, up="y"), motion.frame_time, up=up,  # type: ignore[arg-type]
        rotation_order="ZYX" if up == "y" else "ZXY",
    )
    again = read_bvh(out)
    assert again.joint_names == motion.joint_names
    assert again.num_frames == len(frames)
    assert again.frame_time == motion.frame_time
    after = again.world_poses(1.0, up, None)  # type: ignore[arg-type]
    np.testing.assert_allclose(after.p_world_joint, before.p_world_joint, rtol=0, atol=1e-6)
    np.testing.assert_allclose(after.p_world_end_site, before.p_world_end_site, rtol=0, atol=1e-6)
    # Joint axes are the written file's axes: they differ from the source's by a fixed turn.
    R_source_written = rotation_world_file(up).T @ rotation_zup_yup()  # type: ignore[arg-type]
    np.testing.assert_allclose(after.R_world_joint @ R_source_written, before.R_world_joint,
                               rtol=0, atol=1e-6)


@st.composite
def _random_motions(draw: st.DrawFn) -> tuple:
    n_joints = draw(st.integers(1, 6))
    parents = [-1] + [draw(st.integers(0, j - 1)) for j in range(1, n_joints)]
    orders = [draw(st.sampled_from(ORDERS)) for _ in range(n_joints)]
    n_frames = draw(st.integers(1, 4))
    outer = st.floats(-179.9, 179.9, allow_nan=False)
    middle = st.floats(-89.5, 89.5, allow_nan=False)
    angles = np.array([[[draw(outer), draw(middle), draw(outer)] for _ in range(n_joints)]
                       for _ in range(n_frames)])
    coord = st.floats(-2.0, 2.0, allow_nan=False)
    offsets = np.array([[draw(coord) for _ in range(3)] for _ in range(n_joints)])
    root = np.array([[draw(coord) for _ in range(3)] for _ in range(n_frames)])
    up = draw(st.sampled_from(["y", "z"]))
    return np.array(parents), orders, angles, offsets, root, up


def _turns_off(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per row, the largest difference [deg] of two triples up to whole turns."""
    return np.max(np.abs((a - b + 180.0) % 360.0 - 180.0), axis=-1)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=_random_motions())
def test_write_read_is_exact_for_any_euler_order(case: tuple, tmp_path: Path) -> None:
    parents, orders, angles_deg, offsets, root, up = case
    n_frames, n_joints = angles_deg.shape[:2]
    # Rotations in the written file's axes, built from the angles the file should hold.
    R_file = np.stack([euler_to_matrix(orders[j], np.deg2rad(angles_deg[:, j]))
                       for j in range(n_joints)], axis=1)
    A = rotation_world_file(up)
    skeleton = BvhSkeleton(tuple(f"joint{j}" for j in range(n_joints)), parents, offsets @ A.T)
    path = write_bvh(tmp_path / "p.bvh", skeleton, root @ A.T, A @ R_file @ A.T, 1 / 120,
                     rotation_order=orders, up=up, decimals=None)
    back = read_bvh(path)
    by_name = [back.joint_names.index(f"joint{j}") for j in range(n_joints)]
    for j in range(n_joints):
        assert back.rotation_order(by_name[j]) == orders[j]
        start = back.channel_starts[by_name[j]] + (3 if by_name[j] == 0 else 0)
        written = back.channels[:, start:start + 3]
        # continuous over frames: each frame holds the drawn triple or the other Euler triple of
        # the same rotation, each angle up to whole turns
        drawn = angles_deg[:, j]
        other = np.degrees(equivalent_triple(np.radians(drawn)))
        off = np.minimum(_turns_off(written, drawn), _turns_off(written, other))
        np.testing.assert_allclose(off, 0.0, rtol=0, atol=1e-9)
        assert np.all(np.abs(np.diff(written, axis=0)) <= 180.0 + 1e-9)  # no whole-turn jumps
    np.testing.assert_array_equal(back.channels[:, :3], root)
    np.testing.assert_allclose(back.local_rotations()[:, by_name], R_file, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.offsets[by_name], offsets)


def test_gimbal_lock_is_written_exactly(tmp_path: Path, rng: np.random.Generator) -> None:
    n = 8
    a, c = rng.uniform(-np.pi, np.pi, (2, n))
    for order in ORDERS:
        for middle in (np.pi / 2, -np.pi / 2):
            R = euler_to_matrix(order, np.stack([a, np.full(n, middle), c], axis=1))
            skeleton = BvhSkeleton(("root",), np.array([-1]), np.zeros((1, 3)))
            path = write_bvh(tmp_path / "g.bvh", skeleton, np.zeros((n, 3)), R[:, None], 0.01,
                             rotation_order=order, decimals=None)
            np.testing.assert_allclose(read_bvh(path).local_rotations()[:, 0], R, atol=1e-12)


def test_writer_orders_joints_depth_first_and_keeps_names(tmp_path: Path) -> None:
    # Joint 3 hangs under joint 1, joint 2 under the root: the file lists 0, 1, 3, 2.
    skeleton = BvhSkeleton(("hips", "spine", "leg", "head"), np.array([-1, 0, 0, 1]),
                           np.array([[0, 0, 1.0], [0, 0, 0.3], [0, 0.1, -0.4], [0, 0, 0.4]]),
                           np.array([3, 2]), np.array([[0, 0, 0.2], [0.1, 0, -0.4]]))
    rng = np.random.default_rng(3)
    R = random_rotations(2 * 4, rng).reshape(2, 4, 3, 3)
    root = rng.normal(size=(2, 3))
    path = write_bvh(tmp_path / "dfs.bvh", skeleton, root, R, 0.02, decimals=None)
    back = read_bvh(path)
    assert back.joint_names == ("hips", "spine", "head", "leg")
    order = [0, 1, 3, 2]
    np.testing.assert_allclose(back.local_rotations(up="z"), R[:, order], atol=1e-12)
    # World positions by hand for the head: root + R0 (offset1 + R1 offset3).
    p_head = root + np.einsum("fab,b->fa", R[:, 0], skeleton.offsets[1]) + np.einsum(
        "fab,fbc,c->fa", R[:, 0], R[:, 1], skeleton.offsets[3])
    np.testing.assert_allclose(back.world_poses(1.0, "z").p_world_joint[:, 2], p_head,
                               atol=1e-12)
    assert back.end_site_parents.tolist() == [2, 3]


def test_writer_defaults_and_text(tmp_path: Path) -> None:
    skeleton = BvhSkeleton(("Hips", "Knee"), np.array([-1, 0]),
                           np.array([[0.0, 0.0, 0.9], [0.0, 0.0, -0.45]]))
    R = np.stack([np.eye(3), axis_rotation("y", np.deg2rad(30.0))])[None]
    path = write_bvh(tmp_path / "t.bvh", skeleton, [[1.0, 2.0, 0.9]], R, 1 / 60, up="y",
                     scale=0.01)
    text = path.read_text()
    assert "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation" in text
    assert "CHANNELS 3 Zrotation Xrotation Yrotation" in text
    # Y-up file in centimetres: the knee hangs 45 cm below the hips along -Y.
    assert "OFFSET 0 -45 0" in text  # offsets: 4 more digits, trailing zeros dropped
    frame = text.strip().splitlines()[-1].split()
    # Root position (1, 2, 0.9) m in our world -> file (x, y, z) = (200, 90, 100) cm.
    assert [float(v) for v in frame[:3]] == [200.0, 90.0, 100.0]
    # A rotation about our Y (left) is about the file's X: Xrotation = 30 deg, the rest 0.
    assert [float(v) for v in frame[6:9]] == [0.0, 30.0, 0.0]
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_writer_is_atomic(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "motion.bvh"
    target.write_text("old content\n")
    skeleton = BvhSkeleton(("root",), np.array([-1]), np.zeros((1, 3)))
    good = np.broadcast_to(np.eye(3), (2, 1, 3, 3))

    def broken_replace(src: str, dst: str) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        write_bvh(target, skeleton, np.zeros((2, 3)), good, 0.01)
    monkeypatch.undo()
    assert target.read_text() == "old content\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["motion.bvh"]
    # Non-finite frames are refused before anything is written.
    bad = np.array(good)
    bad[1, 0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="frame 1"):
        write_bvh(target, skeleton, np.zeros((2, 3)), bad, 0.01)
    assert target.read_text() == "old content\n"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [({"rotation_order": "ZZY"}, "distinct axes"),
     ({"rotation_order": ["ZXY", "ZXY"]}, "needs 1 entries"),
     ({"rotation_order": {"nope": "ZXY"}}, "not in the skeleton"),
     ({"scale": 0.0}, "scale"),
     ({"decimals": -1}, "decimals")],
)
def test_writer_rejects_bad_options(tmp_path: Path, kwargs: dict, message: str) -> None:
    skeleton = BvhSkeleton(("root",), np.array([-1]), np.zeros((1, 3)))
    with pytest.raises(ValueError, match=message):
        write_bvh(tmp_path / "x.bvh", skeleton, np.zeros((1, 3)),
                  np.broadcast_to(np.eye(3), (1, 1, 3, 3)), 0.01, **kwargs)


def test_skeleton_validation() -> None:
    with pytest.raises(ValueError, match="parents"):
        BvhSkeleton(("a", "b"), np.array([-1, 1]), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="shape"):
        BvhSkeleton(("a", "b"), np.array([-1, 0]), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="spaces"):
        BvhSkeleton(("a b",), np.array([-1]), np.zeros((1, 3)))


# --------------------------------------------------------------------------- bad files
GOOD = """HIERARCHY
ROOT Hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT Left Up Leg
\t{
\t\tOFFSET 10 0 0
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 -40 0
\t\t}
\t}
}
MOTION
Frames: 2
Frame Time: 0.0333333
0 90 0 0 0 0 10 20 30
1 90 0 0 0 0 11 21 31
"""


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "clip.bvh"
    path.write_bytes(text.encode())
    return path


def test_small_good_file_with_spaces_in_names_bom_and_crlf(tmp_path: Path) -> None:
    path = _write(tmp_path, "\ufeff" + GOOD.replace("\n", "\r\n") + "\r\n  \r\n")
    motion = read_bvh(path)
    assert motion.joint_names == ("Hips", "Left Up Leg")
    assert motion.channels.tolist() == [[0, 90, 0, 0, 0, 0, 10, 20, 30],
                                        [1, 90, 0, 0, 0, 0, 11, 21, 31]]
    assert motion.frame_time == 0.0333333
    assert motion.channel_names[6] == "Left Up Leg.Zrotation"


@pytest.mark.parametrize(
    ("old", "new", "line", "field", "message"),
    [
        ("0 90 0 0 0 0 10 20 30\n", "0 90 0 0 0 0 10 20\n", 19, "Left Up Leg.Yrotation",
         "has 8 values, expected 9"),
        ("1 90 0 0 0 0 11 21 31\n", "1 90 0 0 0 0 11 21 31 5\n", 20, "(extra values)",
         "too many"),
        ("0 90 0 0 0 0 10 20 30\n", "0 90 0 zero 0 0 10 20 30\n", 19, "Hips.Zrotation",
         "'zero' is not a number"),
        ("MOTION\n", "", 19, "MOTION", "no MOTION"),
        ("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 3 Zrotation Xrot Yrotation",
         9, "CHANNELS", "unknown channel name 'Xrot'"),
        ("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 4 Zrotation Xrotation Yrotation",
         9, "CHANNELS", "declares 4 channels but names 3"),
        ("Frames: 2", "Frames: 3", 17, "Frames", "holds 2 frame lines"),
        ("Frames: 2", "Frames: 1", 20, "Frames", "more frame lines than the 1"),
        ("Frames: 2", "Frames: two", 17, "Frames", "not an integer"),
        ("Frame Time: 0.0333333", "Frame Time: 0", 18, "Frame Time", "positive"),
        ("Frame Time: 0.0333333", "Frame Tim 0.03", 18, "Frame Time", "expected 'Frame Time"),
        ("\t\tOFFSET 10 0 0\n", "\t\tOFFSET 10 0\n", 9, "OFFSET", "needs 3 numbers"),
        ("\t\tOFFSET 10 0 0\n", "", 6, "OFFSET", "has no OFFSET"),
        ("ROOT Hips", "JOINT Hips", 2, "ROOT", "expected ROOT"),
        ("HIERARCHY", "HIERARCH", 1, "HIERARCHY", "expected 'HIERARCHY'"),
        ("\t\tEnd Site", "\t\tEnd Sight", 10, "End Site", "expected 'End Site'"),
        ("}\nMOTION", "}\nROOT Other\n{\nOFFSET 0 0 0\n}\nMOTION", 16, "ROOT", "second ROOT"),
        ("\t\t}\n\t}\n}\n", "", 12, "}", "ends early"),
    ],
)
def test_malformed_files_name_line_and_field(
    tmp_path: Path, old: str, new: str, line: int, field: str, message: str
) -> None:
    assert old in GOOD
    path = _write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(InputError, match=message) as info:
        read_bvh(path)
    assert info.value.path == path
    assert info.value.line == line
    assert info.value.field == field
    assert str(path) in str(info.value)


def test_missing_and_empty_files(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="cannot read") as info:
        read_bvh(tmp_path / "absent.bvh")
    assert info.value.path == tmp_path / "absent.bvh"
    with pytest.raises(InputError, match="empty"):
        read_bvh(_write(tmp_path, "\n\n"))


def test_nan_values_are_kept_on_request(tmp_path: Path) -> None:
    """``bridge=False`` keeps bad values as written (tests/io/test_bad_samples.py: bridging)."""
    motion = read_bvh(_write(tmp_path, GOOD.replace("11 21 31", "nan 21 31")), bridge=False)
    assert np.isnan(motion.channels[1, 6])
    poses = motion.world_poses()
    assert np.all(np.isfinite(poses.p_world_joint[0]))
    assert np.all(np.isnan(poses.p_world_end_site[1]))


def test_gzip_compressed_file_reads_as_the_plain_one(tmp_path: Path) -> None:
    """A ``.bvh.gz`` (the benchmark's motion library) reads exactly like its plain text."""
    import gzip

    plain = _write(tmp_path, GOOD)
    packed = tmp_path / "clip.bvh.gz"
    packed.write_bytes(gzip.compress(GOOD.encode()))
    a, b = read_bvh(plain), read_bvh(packed)
    assert a.joint_names == b.joint_names
    np.testing.assert_array_equal(a.channels, b.channels)
    assert b.frame_time == a.frame_time and b.path == packed
    # a bad value inside the compressed text is reported with its line, as in a plain file
    broken = tmp_path / "broken.bvh.gz"
    broken.write_bytes(gzip.compress(GOOD.replace("11 21 31", "11 x 31").encode()))
    with pytest.raises(InputError, match="'x' is not a number") as info:
        read_bvh(broken)
    assert info.value.line == 20 and info.value.path == broken


def test_damaged_gzip_file_is_bad_input(tmp_path: Path) -> None:
    import gzip

    data = gzip.compress(GOOD.encode())
    for name, raw in (("cut.bvh.gz", data[: len(data) // 2]),
                      ("garbled.bvh.gz", data[:12] + bytes(40) + data[52:])):
        path = tmp_path / name
        path.write_bytes(raw)
        with pytest.raises(InputError, match="cannot read the BVH file") as info:
            read_bvh(path)
        assert info.value.path == path


@pytest.mark.parametrize("decimals", [0, 3, 6])
def test_frame_lines_fixed_decimals_never_write_negative_zero(decimals: int, rng) -> None:
    """Every value formats as on its own, except that ``-0.000`` is written ``0.000``."""
    from ikfusion.io.bvh import _frame_text

    unit = 10.0 ** -decimals
    awkward = [-0.0, 0.0, -0.49 * unit, -0.5 * unit, -0.51 * unit, -unit, -1e-300, 1e-300,
               0.5 * unit, -123.4567891, 1.5, -2.5]
    values = np.concatenate([np.array(awkward * 2).reshape(2, -1),
                             rng.normal(scale=unit, size=(5, len(awkward)))])
    number = f"%.{decimals}f"

    def one(v: float) -> str:
        text = number % v
        return text[1:] if text.lstrip("-0.") == "" and text.startswith("-") else text

    expected = [" ".join(one(v) for v in row) for row in values.tolist()]
    assert _frame_text(values, decimals) == "".join(line + "\n" for line in expected).encode()
    assert _frame_text(values[:0], decimals) == b""


@pytest.mark.parametrize("up", ["z", "y"])
def test_axes_change_of_rotations_is_the_matrix_product_to_the_bit(up: str, rng) -> None:
    """Signed zeros included: every 3x3 pattern of -0.0, 0.0 and two numbers of each sign."""
    from ikfusion.io.bvh import _conjugated, rotation_world_file

    A = rotation_world_file(up).T
    patterns = np.array(list(itertools.product([-0.0, 0.0, -1.5, 2.0], repeat=9)))
    for R in (patterns.reshape(-1, 3, 3), rng.normal(size=(50, 23, 3, 3))):
        assert (_conjugated(A, R).view(np.uint64) == (A @ R @ A.T).view(np.uint64)).all()


@pytest.mark.parametrize("p", list(itertools.permutations(range(3))))
def test_permuted_entries_equal_fancy_indexing_to_the_bit(p: tuple[int, ...], rng) -> None:
    """Every axis permutation, signed zeros and NaN included, on a (F, J, 3, 3) stack."""
    from ikfusion.io.bvh import _permuted_entries

    R = rng.normal(size=(40, 23, 3, 3))
    R[0, 0] = -0.0
    R[1, 2, 1, 0] = np.nan
    order = np.array(p)
    got = _permuted_entries(R, order)
    assert got.shape == R.shape and got.flags.c_contiguous
    assert got.tobytes() == (R[..., order, :][..., :, order] + 0.0).tobytes()
