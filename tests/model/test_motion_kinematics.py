"""Forward kinematics of a whole motion at once, against Pinocchio frame by frame."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ikfusion.model import HumanModel
from ikfusion.model.motion_kinematics import frame_placements, quat_xyzw_matrix


@pytest.fixture(scope="module")
def human() -> HumanModel:
    return HumanModel.default()


def pinocchio_frames(model: pin.Model, q: np.ndarray, ids: list[int]) -> tuple[np.ndarray,
                                                                                np.ndarray]:
    data = model.createData()
    p = np.empty((len(q), len(ids), 3))
    R = np.empty((len(q), len(ids), 3, 3))
    for k, qk in enumerate(q):
        pin.framesForwardKinematics(model, data, qk)
        for i, f in enumerate(ids):
            p[k, i], R[k, i] = data.oMf[f].translation, data.oMf[f].rotation
    return p, R


def test_every_frame_equals_pinocchio(human: HumanModel, rng) -> None:
    q = np.array([human.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
                  for _ in range(40)])
    ids = list(range(human.model.nframes))
    p, R = frame_placements(human.model, q, ids)
    p_ref, R_ref = pinocchio_frames(human.model, q, ids)
    np.testing.assert_allclose(p, p_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(R, R_ref, rtol=0, atol=1e-12)


def test_a_chosen_subset_in_the_given_order(human: HumanModel, rng) -> None:
    q = np.array([human.random_configuration(rng) for _ in range(5)])
    ids = [human.site_frame_id("RightToe"), human.segment_frame_id("Head"),
           human.segment_frame_id("Pelvis")]
    p, R = frame_placements(human.model, q, ids)
    p_ref, R_ref = pinocchio_frames(human.model, q, ids)
    np.testing.assert_allclose(p, p_ref, atol=1e-12)
    np.testing.assert_allclose(R, R_ref, atol=1e-12)


def test_revolute_joints_about_each_axis(rng) -> None:
    model = pin.buildSampleModelManipulator()  # revolute joints about x, y and z
    q = np.array([pin.randomConfiguration(model) for _ in range(4)])
    ids = list(range(model.nframes))
    p, R = frame_placements(model, q, ids)
    p_ref, R_ref = pinocchio_frames(model, q, ids)
    np.testing.assert_allclose(p, p_ref, atol=1e-12)
    np.testing.assert_allclose(R, R_ref, atol=1e-12)


def test_other_joint_types_fall_back_to_pinocchio() -> None:
    model = pin.Model()
    slide = model.addJoint(0, pin.JointModelPX(), pin.SE3.Random(), "slide")
    hinge = model.addJoint(slide, pin.JointModelRevoluteUnaligned(np.array([0.6, 0.0, 0.8])),
                           pin.SE3.Random(), "hinge")
    model.addFrame(pin.Frame("tip", hinge, 0, pin.SE3.Random(), pin.FrameType.OP_FRAME))
    q = np.array([[0.3, -1.1], [-0.2, 2.0]])
    ids = list(range(model.nframes))
    p, R = frame_placements(model, q, ids)
    p_ref, R_ref = pinocchio_frames(model, q, ids)
    np.testing.assert_array_equal(p, p_ref)
    np.testing.assert_array_equal(R, R_ref)


def test_quaternion_matrix_as_eigen(rng) -> None:
    quat = rng.normal(size=(20, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    expected = [pin.Quaternion(w, x, y, z).matrix() for x, y, z, w in quat]
    np.testing.assert_array_equal(quat_xyzw_matrix(quat), expected)


def test_identity_placements_cost_no_rotation_product(human: HumanModel, rng,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    # Every joint and site placement of the human model is a pure translation: its rotation
    # product was half of a BVH clip's kinematics (run three times per retarget, issue #20).
    # Only the parent-child products remain (one per joint below the root), and the result
    # is still Pinocchio's.
    import ikfusion.model.motion_kinematics as kinematics

    products = []
    rot_rot = kinematics._rot_rot

    def counted(A: np.ndarray, B: np.ndarray) -> np.ndarray:
        products.append(1)
        return rot_rot(A, B)

    monkeypatch.setattr(kinematics, "_rot_rot", counted)
    monkeypatch.setattr(kinematics, "kernel_placements", lambda *args: None)  # NumPy's path
    q = np.array([human.random_configuration(rng) for _ in range(5)])
    ids = list(range(human.model.nframes))
    p, R = frame_placements(human.model, q, ids)
    assert len(products) == human.model.njoints - 2  # neither the universe nor the root
    p_ref, R_ref = pinocchio_frames(human.model, q, ids)
    np.testing.assert_allclose(p, p_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(R, R_ref, rtol=0, atol=1e-12)


def test_rotations_kept_while_only_the_root_moves(human: HumanModel, rng,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    # A BVH source is levelled, locked and lifted (only q[:, :3] changes) between three
    # queries of its kinematics (issue #20): the joints' rotations are computed once, and every
    # result is bit for bit the one computed without them.
    import ikfusion.model.motion_kinematics as kinematics
    from ikfusion.model.motion_kinematics import JointRotations

    q = np.array([human.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
                  for _ in range(30)])
    ids = list(range(human.model.nframes))
    kept = JointRotations()
    first = frame_placements(human.model, q, ids, kept)
    shifted = q.copy()
    shifted[:, :3] += rng.normal(size=(30, 3))
    expected = frame_placements(human.model, shifted, ids)
    calls = []
    rotation = kinematics._joint_rotation
    monkeypatch.setattr(kinematics, "_joint_rotation",
                        lambda *a: calls.append(1) or rotation(*a))
    again = frame_placements(human.model, shifted, ids, kept)
    assert not calls  # no joint rotation computed again
    for a, b in zip(again, expected):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(again[1], first[1])
    turned = shifted.copy()  # another motion: its own rotations, the kept ones dropped
    turned[:, 3:7] = turned[::-1, 3:7]
    other = frame_placements(human.model, turned, ids, kept)
    assert calls
    for a, b in zip(other, frame_placements(human.model, turned, ids)):
        np.testing.assert_array_equal(a, b)


def rotated_placements_model(rng) -> pin.Model:
    """A free flyer and spherical joints whose placements turn, frames on the universe too."""
    def turned() -> pin.SE3:
        return pin.SE3(pin.Quaternion(rng.normal(size=4)).normalized().matrix(),
                       rng.normal(size=3))

    model = pin.Model()
    root = model.addJoint(0, pin.JointModelFreeFlyer(), turned(), "root")
    parent = root
    for i in range(4):
        placement = turned() if i % 2 else pin.SE3(np.eye(3), rng.normal(size=3))
        parent = model.addJoint(parent, pin.JointModelSpherical(), placement, f"ball{i}")
        model.addFrame(pin.Frame(f"tip{i}", parent, 0, turned(), pin.FrameType.OP_FRAME))
    model.addFrame(pin.Frame("fixed", 0, 0, turned(), pin.FrameType.OP_FRAME))
    return model


def test_the_c_kernel_gives_the_numpy_paths_numbers_to_the_bit(human: HumanModel, rng,
                                                               monkeypatch) -> None:
    # The human model (identity placements) and a model with turned placements, quaternions
    # not normalised (used as given, as Pinocchio does), frames of the universe.
    import ikfusion.model.motion_kinematics as kinematics
    from ikfusion.model.placements_kernel import kernel_placements

    other = rotated_placements_model(rng)
    cases = [(human.model, np.array([human.random_configuration(
        rng, p_world_pelvis=rng.normal(size=3)) for _ in range(50)]))]
    q = rng.normal(size=(60, other.nq))
    q[:30, 3:] /= np.linalg.norm(q[:30, 3:].reshape(30, -1, 4), axis=2).repeat(4, axis=1)
    cases.append((other, q))
    results = []
    for model, q in cases:
        ids = list(range(model.nframes))
        joints = list(range(1, model.njoints))
        if kernel_placements(model, q[:1], ids[:1], joints,
                             kinematics._is_identity) is None:
            pytest.skip("no C kernel (no compiler or IKFUSION_NO_COMPILE): NumPy runs")
        results.append(frame_placements(model, q, ids))
    monkeypatch.setattr(kinematics, "kernel_placements", lambda *args: None)
    for (model, q), got in zip(cases, results):
        expected = frame_placements(model, q, list(range(model.nframes)))
        for a, b in zip(got, expected):
            assert np.array_equal(a.view(np.uint64), b.view(np.uint64))
