"""The human model: sizes, N-pose geometry, exact ball-joint conversion, anatomical angles."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ikfusion.errors import NameNotFound
from ikfusion.model import (
    BODY_CONTACT_SITES,
    CONTACT_SITES,
    JOINTS,
    SEGMENTS,
    SENSOR_SEGMENTS,
    TAG_SITES,
    TRUNK_CONTACT_SITES,
    Body,
    HumanModel,
)
from ikfusion.model.human_model import _model_of_body


@pytest.fixture(scope="module")
def human() -> HumanModel:
    return HumanModel.default()


def test_default_model_sizes(human: HumanModel) -> None:
    m = human.model
    assert m.nv == 72
    assert m.nq == 7 + 4 * 22
    assert human.segment_names == list(SEGMENTS)
    assert human.joint_names == list(JOINTS)
    shortnames = [m.joints[j].shortname() for j in range(1, m.njoints)]
    assert shortnames.count("JointModelFreeFlyer") == 1
    assert shortnames.count("JointModelSpherical") == 22
    assert len(shortnames) == 23
    assert set(human.site_names) == (set(SENSOR_SEGMENTS) | set(TAG_SITES) | set(CONTACT_SITES)
                                     | set(BODY_CONTACT_SITES) | set(TRUNK_CONTACT_SITES))
    assert human.site("LeftKnee").segment == "LeftLowerLeg"
    assert human.site("RightPalm").segment == "RightHand"
    assert human.site("Sacrum").segment == "Pelvis" and human.site("Chest").segment == "T8"
    assert "LeftElbow" not in human.site_names  # elbows carry no body in the library
    assert human.site("LeftToe").segment == "LeftToe"
    assert human.site("LeftToe").kind == "contact"
    assert human.site("Pelvis").kind == "sensor"
    assert human.site("HeadTop").segment == "Head"


def test_unknown_names_list_the_valid_ones(human: HumanModel) -> None:
    with pytest.raises(NameNotFound, match="HeadTop"):
        human.site_position(human.neutral(), "Headtop")
    with pytest.raises(NameNotFound, match="Pelvis"):
        human.segment_frame_id("pelvis")
    with pytest.raises(NameNotFound, match="jLeftKnee") as err:
        human.ball_joint("jleftknee")
    assert (err.value.kind, err.value.name) == ("joint", "jleftknee")
    with pytest.raises(NameNotFound, match="unknown frame 'nowhere'") as err:
        human.frame_id("nowhere")
    assert "Pelvis" in err.value.valid


def _mirror(p: np.ndarray) -> np.ndarray:
    return p * np.array([1.0, -1.0, 1.0])


@pytest.mark.parametrize("height", [1.55, 1.75, 1.95])
def test_npose_stands_at_body_height_and_is_symmetric(height: float) -> None:
    model = HumanModel.from_body(Body.from_height(height))
    q = model.neutral()
    data = model.forward(q)
    head = data.oMf[model.site_frame_id("HeadTop")].translation
    assert abs(head[2] - height) <= 0.01
    feet = [data.oMf[model.site_frame_id(s)].translation[2] for s in CONTACT_SITES]
    np.testing.assert_allclose(feet, 0.0, atol=1e-12)
    for name in model.site_names:
        if name.startswith("Left"):
            left = data.oMf[model.site_frame_id(name)].translation
            right = data.oMf[model.site_frame_id("Right" + name[4:])].translation
            np.testing.assert_allclose(left, _mirror(right), atol=1e-9)
    for seg in SEGMENTS:
        R = data.oMf[model.segment_frame_id(seg)].rotation
        np.testing.assert_allclose(R, np.eye(3), atol=1e-12)
        if seg.startswith("Left"):
            left = data.oMf[model.segment_frame_id(seg)].translation
            right = data.oMf[model.segment_frame_id("Right" + seg[4:])].translation
            np.testing.assert_allclose(left, _mirror(right), atol=1e-9)


def test_mirror_symmetric_angles_give_mirror_poses(human: HumanModel, rng) -> None:
    """Equal angles on both sides produce mirror-image limbs (the sign conventions agree)."""
    angles = {}
    for joint in JOINTS:
        if joint.startswith("jRight"):
            for a in ("flex", "abd", "rot"):
                value = rng.uniform(-20, 20)
                angles[f"{joint}_{a}"] = value
                angles[f"jLeft{joint[6:]}_{a}"] = value
    q = human.configuration(angles)
    data = human.forward(q)
    for name in human.site_names:
        if name.startswith("Left"):
            left = data.oMf[human.site_frame_id(name)].translation
            right = data.oMf[human.site_frame_id("Right" + name[4:])].translation
            np.testing.assert_allclose(left, _mirror(right), atol=1e-9)


def test_spherical_model_equals_revolute_load(human: HumanModel, rng) -> None:
    rev = human.revolute_model
    rdata = rev.createData()
    names = [f.name for f in human.model.frames]
    checked = [n for n in names if n in SEGMENTS or n.endswith("_site")]
    for _ in range(200):
        qr = pin.neutral(rev)
        qr[:3] = rng.normal(size=3)
        qr[3:7] = pin.Quaternion(pin.SE3.Random().rotation).coeffs()
        for j in range(2, rev.njoints):
            iq = rev.idx_qs[j]
            qr[iq] = rng.uniform(rev.lowerPositionLimit[iq], rev.upperPositionLimit[iq])
        q = human.revolute_to_spherical(qr)
        pin.framesForwardKinematics(rev, rdata, qr)
        data = human.forward(q)
        for n in checked:
            a = data.oMf[human.frame_id(n)]
            b = rdata.oMf[rev.getFrameId(n)]
            np.testing.assert_allclose(a.translation, b.translation, atol=1e-9)
            np.testing.assert_allclose(a.rotation, b.rotation, atol=1e-9)


def test_revolute_positions_are_the_anatomical_angles(human: HumanModel, rng) -> None:
    rev = human.revolute_model
    for _ in range(20):
        qr = pin.neutral(rev)
        expected = {}
        for j in range(2, rev.njoints):
            iq = rev.idx_qs[j]
            qr[iq] = rng.uniform(rev.lowerPositionLimit[iq], rev.upperPositionLimit[iq])
            expected[rev.names[j]] = np.degrees(qr[iq])
        angles = human.joint_angles(human.revolute_to_spherical(qr))
        for key, value in expected.items():
            assert abs(angles[key] - value) < 1e-9


def test_angles_round_trip_inside_ranges(human: HumanModel, rng) -> None:
    for _ in range(200):
        q = human.random_configuration(rng)
        angles = human.joint_angles(q)
        back = human.joint_angles(human.configuration(angles, q[:3], human.segment_rotation(
            q, "Pelvis")))
        for key in angles:
            assert abs(back[key] - angles[key]) < 1e-9, key


@pytest.mark.parametrize(
    "angles",
    [
        {"jRightShoulder_flex": 90.0, "jRightShoulder_rot": 40.0},
        {"jLeftShoulder_abd": 90.0, "jLeftShoulder_rot": -60.0},
        {"jRightShoulder_flex": 90.0, "jRightShoulder_abd": 90.0, "jRightShoulder_rot": 30.0},
        {"jRightHip_flex": 90.0, "jRightHip_abd": 20.0, "jRightHip_rot": -30.0},
        {"jLeftHip_flex": 90.0, "jLeftKnee_flex": 90.0},
    ],
)
def test_angles_round_trip_at_elevations(human: HumanModel, angles: dict[str, float]) -> None:
    q = human.configuration(angles)
    back = human.joint_angles(q)
    for key, value in back.items():
        assert abs(value - angles.get(key, 0.0)) < 1e-9, key


def test_sign_conventions_in_the_world(human: HumanModel) -> None:
    """Positive flexions move limbs the way the anatomy says (facing +X, Z up)."""
    q0 = human.neutral()

    def moved(angles: dict[str, float], site: str) -> np.ndarray:
        return human.site_position(human.configuration(angles), site) - human.site_position(
            q0, site)

    assert moved({"jRightKnee_flex": 60}, "RightHeel")[0] < -0.1  # heel goes back
    assert moved({"jLeftHip_flex": 60}, "LeftHeel")[0] > 0.3  # leg goes forward
    assert moved({"jRightShoulder_flex": 90}, "RightHand")[0] > 0.3  # arm forward
    assert moved({"jRightShoulder_abd": 90}, "RightHand")[1] < -0.3  # right arm out to -Y
    assert moved({"jLeftShoulder_abd": 90}, "LeftHand")[1] > 0.3
    assert moved({"jRightElbow_flex": 90}, "RightHand")[0] > 0.1  # forearm forward
    assert moved({"jRightAnkle_flex": 20}, "RightToe")[2] > 0.02  # dorsiflexion lifts toes
    assert moved({"jL5S1_flex": 30}, "HeadTop")[0] > 0.2  # trunk bends forward


def test_joint_angle_matrix_matches_dict(human: HumanModel, rng) -> None:
    qs = np.stack([human.random_configuration(rng) for _ in range(5)])
    M = human.joint_angle_matrix(qs, continuous=False)  # unrelated poses, not a series
    for k, q in enumerate(qs):
        angles = human.joint_angles(q)
        np.testing.assert_allclose(M[k], [angles[c] for c in human.angle_columns], atol=1e-9)


def _same_model(a: pin.Model, b: pin.Model) -> bool:
    """Equal joints, placements, limits, inertias and frames (exactly)."""
    return (a.nq == b.nq and a.nv == b.nv and list(a.names) == list(b.names)
            and all(pa == pb for pa, pb in zip(a.jointPlacements, b.jointPlacements))
            and np.array_equal(a.lowerPositionLimit, b.lowerPositionLimit)
            and np.array_equal(a.upperPositionLimit, b.upperPositionLimit)
            and all(ia == ib for ia, ib in zip(a.inertias, b.inertias))
            and [f.name for f in a.frames] == [f.name for f in b.frames]
            and all(np.array_equal(fa.placement.homogeneous, fb.placement.homogeneous)
                    for fa, fb in zip(a.frames, b.frames)))


def test_a_body_is_parsed_once_and_equals_its_urdf_file(tmp_path) -> None:
    # Building a clip's body took ~20 ms of every BVH retarget (issue #20): an equal body
    # reuses the parsed model, which is exactly the model its URDF file loads to.
    body = Body.from_height(1.62)
    first, second = HumanModel.from_body(body), HumanModel.from_body(Body.from_height(1.62))
    assert second.model is first.model  # parsed once
    assert second.data is not first.data  # each its own kinematics buffer
    assert first.urdf_path is None
    from_file = HumanModel.from_body(body, tmp_path / "human.urdf")
    assert _same_model(first.model, from_file.model)
    assert _same_model(first.revolute_model, from_file.revolute_model)
    np.testing.assert_array_equal(first.neutral(), from_file.neutral())
    assert first.sites == from_file.sites and first.segment_names == from_file.segment_names
    other = HumanModel.from_body(Body.from_height(1.80))
    assert other.model is not first.model
    assert not _same_model(other.model, first.model)


def test_a_new_body_allocates_no_kinematics_buffer_and_stands_on_the_floor() -> None:
    # A pinocchio.Data of the human model took 5-8 ms of every BVH retarget (issue #20) only
    # to place the N-pose on the floor: the model is now built without one, and the N-pose
    # still has its lowest contact point exactly on z = 0 (checked with Pinocchio's own FK).
    body = Body.from_height(1.57)
    human = HumanModel.from_body(body)
    assert _model_of_body(body)._data is None  # the parsed model allocated none
    q = human.neutral()
    data = human.model.createData()
    pin.framesForwardKinematics(human.model, data, q)
    heights = [data.oMf[human.site_frame_id(s)].translation[2] for s in CONTACT_SITES]
    assert min(heights) == pytest.approx(0.0, abs=1e-12)
    assert np.array_equal(q[3:7], [0.0, 0.0, 0.0, 1.0]) and np.array_equal(q[:2], [0.0, 0.0])


def test_merged_ball_joints_carry_the_parent_and_child_of_configs_joints(human: HumanModel) -> None:
    # The triplet merge reads each frame's parent joint once (it scanned every frame of the
    # model per triplet: 4 ms of every body built, issue #20); the parent and child segment
    # of every joint are still those of configs/joints.yaml.
    from ikfusion.model.joints import load_joint_specs

    specs = load_joint_specs()
    for model in (human, HumanModel.from_body(Body.from_height(1.66))):
        assert list(model.ball_joints) == list(JOINTS)
        for name, joint in model.ball_joints.items():
            assert (joint.spec.parent, joint.spec.child) == (specs[name].parent,
                                                             specs[name].child), name


def test_angles_of_some_joints_are_theirs_in_the_whole_table(human: HumanModel, rng) -> None:
    qs = np.array([human.random_configuration(rng) for _ in range(40)])
    whole = human.joint_angle_matrix(qs)
    names = ["jLeftKnee", "jRightShoulder"]
    some = human.joint_angle_matrix(qs, joints=names)
    columns = [f"{n}_{a}" for n in names for a in ("flex", "abd", "rot")]
    index = [human.angle_columns.index(c) for c in columns]
    assert np.array_equal(some, whole[:, index])


def test_knees_flexing_backwards_are_reported(human: HumanModel) -> None:
    from ikfusion.app.pipeline import knee_warning
    from ikfusion.ik import Motion
    from ikfusion.rotations import matrix_to_quat_wxyz, wxyz_to_xyzw

    def motion(flex_deg: float) -> Motion:
        q = human.neutral()
        joint = human.ball_joints["jRightKnee"]
        angles = np.zeros(3)
        angles[[a.name for a in joint.spec.angles].index("flex")] = np.radians(flex_deg)
        q[joint.idx_q:joint.idx_q + 4] = wxyz_to_xyzw(matrix_to_quat_wxyz(
            joint.spec.rotation(angles)))
        n = 20
        return Motion(human, np.arange(n) / 60.0, np.tile(q, (n, 1)), [], np.zeros((n, 0), bool),
                      np.zeros(n), np.zeros(n, dtype=int), np.zeros(n, dtype=bool), [])

    backwards = motion(-30.0)
    assert human.joint_angle_matrix(backwards.q, joints=["jRightKnee"])[0, 0] < -8.0
    assert "right knee flexes the wrong way" in (knee_warning(backwards) or "")
    assert knee_warning(motion(30.0)) is None
