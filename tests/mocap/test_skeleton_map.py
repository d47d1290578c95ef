"""BVH skeletons mapped onto the model segments: closed forms, Xsens MVN truth, real clips."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from ikfusion.errors import InputError
from ikfusion.io.bvh import BvhSkeleton, read_bvh, write_bvh
from ikfusion.mocap.skeleton_map import (
    MODEL_SEGMENTS,
    SEGMENT_PROXIMAL_JOINTS,
    build_skeleton_map,
    default_aliases,
    map_motion,
    normalize_joint_name,
)
from ikfusion.model.layout import HEEL_BEHIND_ANKLE
from ikfusion.rotations import (
    angle_between,
    axis_rotation,
    log_so3,
    matrix_to_quat_wxyz,
    quat_wxyz_to_matrix,
    slerp,
)

CLIPS = [
    "mocap/cmu_01_01_hop_turn.bvh",
    "mocap/cmu_02_01_walk.bvh",
    "mocap/cmu_131_01.bvh",
    "mocap/sfu_0005_Jogging001.bvh",
    "mocap/sfu_0005_Walking001.bvh",
    "mvnx/test_mocap.bvh",
]
WALKS = ["mocap/cmu_02_01_walk.bvh", "mocap/sfu_0005_Walking001.bvh",
         "mocap/sfu_0005_Jogging001.bvh"]
FIRST = slice(0, 240, 3)  # the first 2 s of a 120 Hz clip, every third frame
DEG = np.pi / 180.0


# --------------------------------------------------------------------------- synthetic
def _tpose_skeleton(prefix: str = "mixamorig:") -> BvhSkeleton:
    """A Mixamo-like skeleton in a T-pose, in our world axes (facing +X, left +Y, up +Z) [m]."""
    joints = [
        ("Hips", -1, (0, 0, 0.95)), ("Spine", 0, (0, 0, 0.1)), ("Spine1", 1, (0, 0, 0.12)),
        ("Spine2", 2, (0, 0, 0.12)), ("Neck", 3, (0, 0, 0.15)), ("Head", 4, (0, 0, 0.1)),
    ]
    for side, s in (("Left", 1.0), ("Right", -1.0)):
        base = len(joints)
        joints += [
            (f"{side}Shoulder", 3, (0, 0.03 * s, 0.1)), (f"{side}Arm", base, (0, 0.14 * s, 0)),
            (f"{side}ForeArm", base + 1, (0, 0.28 * s, 0)),
            (f"{side}Hand", base + 2, (0, 0.25 * s, 0)),
        ]
    for side, s in (("Left", 1.0), ("Right", -1.0)):
        base = len(joints)
        joints += [
            (f"{side}UpLeg", 0, (0, 0.09 * s, -0.05)), (f"{side}Leg", base, (0, 0, -0.42)),
            (f"{side}Foot", base + 1, (0, 0, -0.41)),
            (f"{side}ToeBase", base + 2, (0.14, 0, -0.06)),
        ]
    names = tuple(prefix + n for n, _, _ in joints)
    ends = [names.index(prefix + n) for n in ("Head", "LeftHand", "RightHand", "LeftToeBase",
                                              "RightToeBase")]
    end_offsets = [(0, 0, 0.18), (0, 0.18, 0), (0, -0.18, 0), (0.06, 0, 0), (0.06, 0, 0)]
    return BvhSkeleton(names, np.array([p for _, p, _ in joints]),
                       np.array([o for _, _, o in joints], dtype=float), np.array(ends),
                       np.array(end_offsets, dtype=float))


def _write_synthetic(tmp_path: Path, heading: float, knee: float, up: str = "y",
                     prefix: str = "mixamorig:") -> Path:
    """Frame 0: the T-pose turned by ``heading``; frame 1: N-pose with the left knee flexed."""
    skeleton = _tpose_skeleton(prefix)
    n = skeleton.num_joints
    R = np.broadcast_to(np.eye(3), (2, n, 3, 3)).copy()
    R[:, 0] = axis_rotation("z", heading)
    idx = {name.split(":")[-1]: k for k, name in enumerate(skeleton.joint_names)}
    R[1, idx["LeftArm"]] = axis_rotation("x", -np.pi / 2)  # left arm down to the side
    R[1, idx["RightArm"]] = axis_rotation("x", np.pi / 2)
    R[1, idx["LeftLeg"]] = axis_rotation("y", knee)  # shank swings backwards
    root = np.array([[1.0, 2.0, 0.95], [1.1, 2.0, 0.93]])
    return write_bvh(tmp_path / "synthetic.bvh", skeleton, root, R, 1 / 100,
                     up=up, scale=0.01, rotation_order="YXZ", decimals=None)  # type: ignore[arg-type]


@pytest.mark.parametrize("up", ["y", "z"])
def test_tpose_and_npose_closed_form(tmp_path: Path, up: str) -> None:
    heading, knee = 0.7, 50 * DEG
    motion = read_bvh(_write_synthetic(tmp_path, heading, knee, up))
    mapped = map_motion(motion)  # scale (cm) and up axis found automatically
    Rz = axis_rotation("z", heading)
    arms = ("UpperArm", "ForeArm", "Hand")
    for segment, R in mapped.R_world_segment.items():
        # Frame 0, T-pose: arms abducted 90 deg about the body's forward axis, the rest aligned.
        expected = Rz
        if segment.endswith(arms):
            expected = Rz @ axis_rotation("x", np.pi / 2 if segment.startswith("Left") else
                                          -np.pi / 2)
        np.testing.assert_allclose(R[0], expected, atol=1e-9, err_msg=segment)
        # Frame 1, N-pose: every segment parallel to the body frame, but the flexed left shank.
        expected = Rz
        if segment in ("LeftLowerLeg", "LeftFoot", "LeftToe"):
            expected = Rz @ axis_rotation("y", knee)
        np.testing.assert_allclose(R[1], expected, atol=1e-9, err_msg=segment)
    assert mapped.missing == ("L3",)  # Spine, Spine1, Spine2 -> L5, T12, T8
    np.testing.assert_allclose(mapped.root_position[0], [1.0, 2.0, 0.90], atol=1e-12)
    np.testing.assert_allclose(mapped.p_world_joint["jLeftHip"][0] - mapped.root_position[0],
                               Rz @ [0, 0.09, 0], atol=1e-12)
    np.testing.assert_allclose(mapped.time, [0.0, 0.01])
    dims = mapped.body_dims
    assert dims["upper_leg"] == pytest.approx(0.42)
    assert dims["lower_leg"] == pytest.approx(0.41)
    assert dims["upper_arm"] == pytest.approx(0.28)
    assert dims["forearm"] == pytest.approx(0.25)
    assert dims["hand"] == pytest.approx(0.18)
    assert dims["hip_width"] == pytest.approx(0.18)
    assert dims["shoulder_width"] == pytest.approx(2 * 0.17)
    assert dims["ankle_height"] == pytest.approx(0.06)
    assert dims["foot_length"] == pytest.approx(0.20 / (1.0 - HEEL_BEHIND_ANKLE))
    assert dims["hip_height"] == pytest.approx(0.06 + 0.41 + 0.42)
    # Hips 5 cm above the hip joints; head top 0.1+0.12+0.12+0.15+0.1+0.18 above the hips.
    assert dims["height"] == pytest.approx(0.89 + 0.05 + 0.77)
    assert dims["shoulder_height"] == pytest.approx(0.89 + 0.05 + 0.44)


def test_filled_segments_interpolate_the_trunk(tmp_path: Path) -> None:
    motion = read_bvh(_write_synthetic(tmp_path, 0.3, 0.2))
    smap = build_skeleton_map(motion)
    assert smap.describe()["L5"] == "mixamorig:Spine"
    assert smap.describe()["T12"] == "mixamorig:Spine1"
    # Bend the spine: L5 and T12 then differ and L3 is their geodesic midpoint.
    motion.channels[:, motion.channel_starts[2]:motion.channel_starts[2] + 3] = [20.0, -10.0, 30.0]
    mapped = map_motion(motion, skeleton_map=smap)
    q = slerp(matrix_to_quat_wxyz(mapped.R_world_segment["L5"]),
              matrix_to_quat_wxyz(mapped.R_world_segment["T12"]), 0.5)
    np.testing.assert_allclose(mapped.R_world_segment["L3"], quat_wxyz_to_matrix(q), atol=1e-12)
    assert angle_between(mapped.R_world_segment["L5"], mapped.R_world_segment["T12"])[0] > 0.3
    bare = map_motion(motion, skeleton_map=smap, fill=False)
    assert "L3" not in bare.R_world_segment and bare.missing == ("L3",)
    assert set(bare.R_world_segment) == set(MODEL_SEGMENTS) - {"L3"}


def test_lower_body_only_skeleton_fills_by_copy(tmp_path: Path) -> None:
    full = _tpose_skeleton(prefix="")
    keep = [k for k, n in enumerate(full.joint_names)
            if not n.endswith(("Shoulder", "Arm", "ForeArm", "Hand"))]
    remap = {old: new for new, old in enumerate(keep)}
    skeleton = BvhSkeleton(
        tuple(full.joint_names[k] for k in keep),
        np.array([remap.get(int(full.parents[k]), -1) for k in keep]),
        full.offsets[keep],
    )
    R = np.broadcast_to(np.eye(3), (1, len(keep), 3, 3))
    path = write_bvh(tmp_path / "legs.bvh", skeleton, [[0, 0, 0.95]], R, 0.01, up="y")
    mapped = map_motion(read_bvh(path), scale=1.0)
    # No arms: T8 comes from the neck's parent; clavicles and arms copy T8 (held neutral).
    assert mapped.segment_joint["T8"] == "Spine2"
    assert {"LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand"} <= set(mapped.missing)
    np.testing.assert_allclose(mapped.R_world_segment["LeftHand"], mapped.R_world_segment["T8"])
    assert "jLeftElbow" not in mapped.p_world_joint
    assert "shoulder_width" not in mapped.body_dims


def test_unknown_skeleton_lists_the_joint_names(tmp_path: Path) -> None:
    skeleton = BvhSkeleton(("Becken", "KnieL", "KnieR", "Kopf"), np.array([-1, 0, 0, 0]),
                           np.array([[0, 0, 1.0], [0, 0.1, -0.5], [0, -0.1, -0.5], [0, 0, 0.6]]))
    path = write_bvh(tmp_path / "odd.bvh", skeleton, [[0, 0, 1.0]],
                     np.broadcast_to(np.eye(3), (1, 4, 3, 3)), 0.01, up="y")
    motion = read_bvh(path)
    with pytest.raises(InputError, match="Becken, KnieL, KnieR, Kopf") as info:
        map_motion(motion)
    assert info.value.path == path
    assert "LeftLowerLeg" in str(info.value) and "T8 or Head" in str(info.value)


def test_user_aliases_extend_the_table(tmp_path: Path) -> None:
    names = {"Hips": "Becken", "LeftLeg": "KnieL", "RightLeg": "KnieR", "Head": "Kopf"}
    full = _tpose_skeleton(prefix="")
    renamed = tuple(names.get(n, n) for n in full.joint_names)
    skeleton = BvhSkeleton(renamed, full.parents, full.offsets, full.end_site_parents,
                           full.end_site_offsets)
    R = np.broadcast_to(np.eye(3), (1, skeleton.num_joints, 3, 3))
    path = write_bvh(tmp_path / "de.bvh", skeleton, [[0, 0, 0.95]], R, 0.01, up="y")
    aliases = default_aliases()
    aliases["LeftLowerLeg"] += ("KnieL",)
    aliases["RightLowerLeg"] += ("Knie_R",)  # normalised like the file's names
    aliases["Head"] += ("Kopf",)
    mapped = map_motion(read_bvh(path), aliases=aliases)
    assert mapped.segment_joint["LeftLowerLeg"] == "KnieL"
    assert mapped.segment_joint["Pelvis"] == "Becken"  # no alias: where the legs branch
    assert mapped.segment_joint["Head"] == "Kopf"


def test_name_normalisation() -> None:
    assert normalize_joint_name("mixamorig:Left_Up-Leg") == "leftupleg"
    assert normalize_joint_name("Bip01 L Thigh") == "bip01lthigh"
    assert normalize_joint_name("|root|Hips") == "hips"
    table = default_aliases()
    assert "leftupleg" in table["LeftUpperLeg"] and "rightupleg" in table["RightUpperLeg"]
    assert "bip01rcalf" in table["RightLowerLeg"]
    assert table is not default_aliases()  # a fresh table each call
    table["Head"] += ("Kopf",)
    assert "kopf" not in default_aliases()["Head"]  # extending a copy leaves the defaults


# --------------------------------------------------------------------------- real clips
@pytest.mark.parametrize("frames", [slice(None), np.arange(0, 270, 2), np.arange(1, 270, 5)])
def test_a_clip_is_posed_once_with_the_same_result(shared_data: Path, frames: object,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """The skeleton map's stance poses and the mapped frames come from one forward pass."""
    from ikfusion.io.bvh import BvhMotion

    motion = read_bvh(shared_data / "mocap/sfu_0005_Walking001.bvh")  # 120 Hz: stance at 30
    apart = map_motion(motion, frames=frames, skeleton_map=build_skeleton_map(motion))
    passes = []
    world_poses = BvhMotion.world_poses

    def counted(self: BvhMotion, *args: object, **kwargs: object) -> object:
        passes.append(args)
        return world_poses(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(BvhMotion, "world_poses", counted)
    mapped = map_motion(motion, frames=frames)
    assert len(passes) == 1
    for name, R in apart.R_world_segment.items():
        np.testing.assert_array_equal(mapped.R_world_segment[name], R)
    for name, p in apart.p_world_joint.items():
        np.testing.assert_array_equal(mapped.p_world_joint[name], p)
    np.testing.assert_array_equal(mapped.root_position, apart.root_position)
    np.testing.assert_array_equal(mapped.time, apart.time)


EXPECTED_JOINTS = {
    "mocap/cmu_02_01_walk.bvh": {
        "Pelvis": "Hips", "L5": "LowerBack", "T12": "Spine", "T8": "Spine1",
        "Neck": "Neck / Neck1", "LeftShoulder": "LeftShoulder", "LeftUpperArm": "LeftArm",
        "LeftHand": "LeftHand / LeftFingerBase", "LeftUpperLeg": "LeftUpLeg",
        "LeftToe": "LeftToeBase"},
    "mocap/cmu_131_01.bvh": {
        "L5": "lowerback", "T12": "Chest", "T8": "Chest2", "Neck": "lowerneck / Neck",
        "LeftShoulder": "LeftCollar", "LeftUpperArm": "LeftShoulder",
        "LeftForeArm": "LeftElbow", "LeftHand": "LeftWrist / lhand", "LeftUpperLeg": "LeftHip",
        "RightLowerLeg": "RightKnee", "RightFoot": "RightAnkle"},
    "mocap/sfu_0005_Walking001.bvh": {
        "L5": "Spine", "T8": "Spine1", "Neck": "Neck", "RightShoulder": "RightShoulder",
        "RightUpperArm": "RightArm", "RightHand": "RightHand"},
    "mvnx/test_mocap.bvh": {
        "L5": "Chest", "L3": "Chest2", "T12": "Chest3", "T8": "Chest4",
        "RightShoulder": "RightCollar", "RightUpperArm": "RightShoulder",
        "RightForeArm": "RightElbow", "RightHand": "RightWrist", "RightUpperLeg": "RightHip"},
}
EXPECTED_MISSING = {
    "mocap/cmu_02_01_walk.bvh": ("L3",), "mocap/cmu_131_01.bvh": ("L3",),
    "mocap/sfu_0005_Walking001.bvh": ("L3", "T12"), "mvnx/test_mocap.bvh": (),
}


@pytest.mark.parametrize("clip", sorted(EXPECTED_JOINTS))
def test_joint_identification_on_real_skeletons(shared_data: Path, clip: str) -> None:
    smap = build_skeleton_map(read_bvh(shared_data / clip))
    described = smap.describe()
    for segment, joint in EXPECTED_JOINTS[clip].items():
        assert described[segment] == joint, segment
    assert smap.missing == EXPECTED_MISSING[clip]
    assert smap.up == "y"


def _heading(R: np.ndarray) -> np.ndarray:
    """Heading [rad] of each frame's X axis projected on the ground."""
    return np.arctan2(R[:, 1, 0], R[:, 0, 0])


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


@pytest.mark.parametrize("clip", CLIPS)
def test_mapped_anatomy_is_plausible(shared_data: Path, clip: str) -> None:
    motion = read_bvh(shared_data / clip)
    frames = FIRST if motion.num_frames > 240 else slice(1, None)  # MVN: frame 0 is a T-pose
    mapped = map_motion(motion, frames=frames)
    R = mapped.R_world_segment
    p = mapped.p_world_joint
    assert set(R) == set(MODEL_SEGMENTS)
    for segment, R_seg in R.items():
        np.testing.assert_allclose(R_seg @ np.swapaxes(R_seg, 1, 2), np.broadcast_to(
            np.eye(3), R_seg.shape), atol=1e-12, err_msg=segment)
    for side in ("Left", "Right"):
        # Long axes (segment -Z) point from the proximal to the distal joint.
        for segment, a, b in ((f"{side}UpperLeg", "Hip", "Knee"),
                              (f"{side}LowerLeg", "Knee", "Ankle"),
                              (f"{side}UpperArm", "Shoulder", "Elbow"),
                              (f"{side}ForeArm", "Elbow", "Wrist")):
            d = p[f"j{side}{b}"] - p[f"j{side}{a}"]
            d /= np.linalg.norm(d, axis=1, keepdims=True)
            cos = np.einsum("fi,fi->f", -R[segment][:, :, 2], d)
            assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1.0, segment
        # The knee is a hinge about the segment Y axis and bends backwards (positive about +Y).
        knee = np.degrees(log_so3(np.swapaxes(R[f"{side}UpperLeg"], 1, 2) @ R[f"{side}LowerLeg"]))
        flexed = np.linalg.norm(knee, axis=1) > 20.0
        if motion.path is not None and "mvnx" not in str(motion.path):
            assert flexed.any()
        assert np.all(knee[flexed, 1] > 0.9 * np.linalg.norm(knee[flexed], axis=1)), side
        # Feet flat on the ground point where the foot points (ankle -> toe) and, in the
        # walking clips, forward like the pelvis (toe-out up to ~20 deg).
        foot = R[f"{side}Foot"]
        flat = foot[:, 2, 2] > np.cos(15 * DEG)
        if flat.any():
            d = p[f"j{side}BallFoot"][flat] - p[f"j{side}Ankle"][flat]
            along = np.degrees(np.abs(_wrap(_heading(foot[flat]) - np.arctan2(d[:, 1], d[:, 0]))))
            assert np.median(along) < 5.0, (side, np.median(along))
            diff = np.degrees(np.abs(_wrap(_heading(foot[flat]) - _heading(R["Pelvis"][flat]))))
            assert np.median(diff) < (25.0 if clip in WALKS else 40.0), (side, np.median(diff))
    # Hips to the left of / right of the pelvis origin along the pelvis Y axis.
    lateral = np.einsum("fi,fi->f", p["jLeftHip"] - p["jRightHip"], R["Pelvis"][:, :, 1])
    assert np.all(lateral > 0.1)
    # The head is above the pelvis and the thorax Z points up-ish.
    assert np.all(p["jC1Head"][:, 2] > mapped.root_position[:, 2] + 0.3)
    assert np.all(R["T8"][:, 2, 2] > np.cos(50 * DEG))


@pytest.mark.parametrize("clip", WALKS)
def test_walking_clips_face_the_way_they_walk(shared_data: Path, clip: str) -> None:
    motion = read_bvh(shared_data / clip)
    mapped = map_motion(motion, frames=slice(0, None, 4))
    pelvis = mapped.R_world_segment["Pelvis"]
    tilt = np.degrees(np.arccos(np.clip(pelvis[:, 2, 2], -1, 1)))
    assert np.median(tilt) < 10.0 and tilt.max() < 20.0
    # Walking direction (horizontal velocity, over 1/3 s) against the pelvis X axis.
    v = mapped.root_position[10:, :2] - mapped.root_position[:-10, :2]
    moving = np.linalg.norm(v, axis=1) > 0.2  # faster than 0.6 m/s
    assert moving.mean() > 0.5
    walk = np.arctan2(v[moving, 1], v[moving, 0])
    middle = _heading(pelvis[5:-5][moving])
    diff = np.degrees(np.abs(_wrap(walk - middle)))
    assert np.median(diff) < 15.0, np.median(diff)


@pytest.mark.parametrize("clip", WALKS)
def test_feet_are_level_in_stance(shared_data: Path, clip: str) -> None:
    motion = read_bvh(shared_data / clip)
    smap = build_skeleton_map(motion)
    mapped = map_motion(motion, skeleton_map=smap, frames=slice(0, None, 2))
    raw = map_motion(motion, skeleton_map=build_skeleton_map(motion, level_feet=False),
                     frames=slice(0, None, 2))
    for side in ("Left", "Right"):
        assert {f"{side}Foot", f"{side}Toe"} <= set(smap.foot_level)  # learnt from the steps
        ankle = mapped.p_world_joint[f"j{side}Ankle"]
        ball = mapped.p_world_joint[f"j{side}BallFoot"]
        stance = ((ankle[:, 2] < np.percentile(ankle[:, 2], 5) + 0.02)
                  & (ball[:, 2] < np.percentile(ball[:, 2], 5) + 0.02))
        assert stance.sum() >= 5
        for segment in (f"{side}Foot", f"{side}Toe"):
            R = mapped.R_world_segment[segment][stance]
            tilt = np.degrees(np.arccos(np.clip(R[:, 2, 2], -1, 1)))
            assert np.median(tilt) < 6.0, (segment, np.median(tilt))
            # Levelling tilts the frame, it does not turn it: X still follows ankle -> toe.
            d = ball[stance] - ankle[stance]
            turn = np.degrees(np.abs(_wrap(_heading(R) - np.arctan2(d[:, 1], d[:, 0]))))
            assert np.median(turn) < 3.0, (segment, np.median(turn))
        # The shank is untouched.
        np.testing.assert_array_equal(mapped.R_world_segment[f"{side}LowerLeg"],
                                      raw.R_world_segment[f"{side}LowerLeg"])
    if "cmu" in clip:
        # CMU's rest feet sit on splayed rest legs: unlevelled they stand tilted by ~30 deg.
        R = raw.R_world_segment["LeftFoot"][stance]
        assert np.median(np.degrees(np.arccos(np.clip(R[:, 2, 2], -1, 1)))) > 15.0


def test_cmu_walk_goes_along_pelvis_x(shared_data: Path) -> None:
    mapped = map_motion(read_bvh(shared_data / "mocap/cmu_02_01_walk.bvh"))
    travel = mapped.root_position[-1] - mapped.root_position[0]
    assert np.linalg.norm(travel[:2]) > 3.0  # about 3.5 m in 2.85 s
    mean_x = mapped.R_world_segment["Pelvis"][:, :, 0].mean(axis=0)
    angle = np.degrees(abs(_wrap(np.arctan2(travel[1], travel[0]) -
                                 np.arctan2(mean_x[1], mean_x[0]))))
    assert angle < 10.0


# --------------------------------------------------------------------------- Xsens MVN truth
def _read_mvnx(path: Path) -> tuple[list[str], np.ndarray, np.ndarray, dict]:
    """Segment labels, orientations (F, 23, 3, 3), positions (F, 23, 3) and segment points."""
    ns = "{http://www.xsens.com/mvn/mvnx}"
    root = ET.parse(path).getroot()
    segments = [s for s in root.iter(ns + "segment")]
    labels = [s.get("label", "") for s in segments]
    points = {(s.get("label"), p.get("label")): np.array(
        [float(v) for v in (p.findtext(ns + "pos_b") or "").split()])
        for s in segments for p in s.iter(ns + "point")}
    frames = [f for f in root.iter(ns + "frame") if f.get("type") == "normal"]
    quat = np.array([[float(v) for v in (f.findtext(ns + "orientation") or "").split()]
                     for f in frames]).reshape(len(frames), -1, 4)
    pos = np.array([[float(v) for v in (f.findtext(ns + "position") or "").split()]
                    for f in frames]).reshape(len(frames), -1, 3)
    return labels, quat_wxyz_to_matrix(quat), pos, points


def test_mvn_bvh_export_matches_the_mvnx_segments(shared_data: Path) -> None:
    """MVN's own BVH export mapped by us agrees with MVN's segment poses of the same take.

    MVN's BVH starts with its T-pose, so BVH frame k + 1 is MVNX frame k. MVN's own arm
    segment frames are world-parallel in the T-pose (its identity pose holds the arms out, and
    jLeftElbow lies on LeftUpperArm's +Y): ours (SPEC: parallel in the N-pose) differ from them
    by a quarter turn about X on the upper arms, forearms and hands.
    """
    labels, R_mvn, p_mvn, points = _read_mvnx(shared_data / "mvnx/test_mocap.mvnx")
    assert points[("LeftUpperArm", "jLeftElbow")][1] > 0.2  # MVN's arms: long axis +-Y
    motion = read_bvh(shared_data / "mvnx/test_mocap.bvh")
    smap = build_skeleton_map(motion)
    assert smap.foot_level == {}  # an upper-body take: the legs never step
    mapped = map_motion(motion, frames=slice(1, None), skeleton_map=smap)
    n = mapped.time.shape[0]
    assert n == len(R_mvn) - 1
    for segment in MODEL_SEGMENTS:
        truth = R_mvn[:n, labels.index(segment)]
        if segment.endswith(("UpperArm", "ForeArm", "Hand")):
            truth = truth @ axis_rotation("x", np.pi / 2 if "Left" in segment else -np.pi / 2)
        err = np.degrees(angle_between(mapped.R_world_segment[segment], truth))
        arm = segment.startswith(("Left", "Right")) and "Leg" not in segment and \
            "Foot" not in segment and "Toe" not in segment
        assert err.mean() < (2.5 if arm else 0.6), (segment, err.mean())
        assert err.max() < 6.0, (segment, err.max())
        if segment in SEGMENT_PROXIMAL_JOINTS:
            joint = mapped.p_world_joint[SEGMENT_PROXIMAL_JOINTS[segment]]
            d = np.linalg.norm(joint - p_mvn[:n, labels.index(segment)], axis=1)
            assert d.max() < 0.015, (segment, d.max())
    root = np.linalg.norm(mapped.root_position - p_mvn[:n, 0], axis=1)
    assert root.max() < 0.005
    # Body proportions against MVN's segment model.
    dims = mapped.body_dims

    def length(segment: str, point: str) -> float:
        return float(np.linalg.norm(points[(segment, point)]))

    assert dims["upper_leg"] == pytest.approx(length("LeftUpperLeg", "jLeftKnee"), abs=2e-3)
    assert dims["lower_leg"] == pytest.approx(length("LeftLowerLeg", "jLeftAnkle"), abs=2e-3)
    assert dims["upper_arm"] == pytest.approx(length("LeftUpperArm", "jLeftElbow"), abs=2e-3)
    assert dims["forearm"] == pytest.approx(length("LeftForeArm", "jLeftWrist"), abs=2e-3)
    assert dims["hand"] == pytest.approx(length("LeftHand", "pLeftTopOfHand"), abs=2e-3)
    hip_width = np.linalg.norm(points[("Pelvis", "jLeftHip")] - points[("Pelvis", "jRightHip")])
    assert dims["hip_width"] == pytest.approx(hip_width, abs=2e-3)
    assert 1.55 < dims["height"] < 1.75


@pytest.mark.parametrize("clip", CLIPS)
def test_body_dims_are_human(shared_data: Path, clip: str) -> None:
    dims = build_skeleton_map(read_bvh(shared_data / clip)).body_dims
    assert set(dims) == {"height", "shoulder_width", "hip_width", "upper_arm", "forearm", "hand",
                         "upper_leg", "lower_leg", "foot_length", "ankle_height",
                         "shoulder_height", "hip_height"}
    assert 1.3 < dims["height"] < 2.0
    assert 0.3 < dims["upper_leg"] < 0.55 and 0.3 < dims["lower_leg"] < 0.55
    assert 0.2 < dims["upper_arm"] < 0.4 and 0.15 < dims["forearm"] < 0.35
    assert 0.1 < dims["hip_width"] < 0.3 and 0.25 < dims["shoulder_width"] < 0.5
    assert 0.15 < dims["foot_length"] < 0.3
    assert dims["hip_height"] < dims["shoulder_height"] < dims["height"]
