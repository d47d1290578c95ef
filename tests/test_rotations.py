"""Rotation helpers: conventions, round trips, and the hard cases near identity and pi."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from so3_samples import rotation_vectors, rotation_vectors_below_pi

from ikfusion import rotations as rot

SEQUENCES = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]
unit = st.floats(-1.0, 1.0, allow_nan=False)


@given(st.tuples(unit, unit, unit, unit).filter(lambda q: np.linalg.norm(q) > 1e-3))
def test_quaternion_matrix_round_trip(q: tuple[float, float, float, float]) -> None:
    quat = np.array(q) / np.linalg.norm(q)
    R = rot.quat_wxyz_to_matrix(quat)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    back = rot.matrix_to_quat_wxyz(R)
    assert back[0] >= 0.0
    assert min(np.abs(back - quat).max(), np.abs(back + quat).max()) < 1e-9


def test_quaternion_convention_is_scalar_first() -> None:
    # 90 deg about z: (cos 45, 0, 0, sin 45)
    R = rot.quat_wxyz_to_matrix([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-12)


@pytest.mark.parametrize("sequence", SEQUENCES)
@given(a=st.floats(-3.1, 3.1), b=st.floats(-1.55, 1.55), c=st.floats(-3.1, 3.1))
@settings(max_examples=60)
def test_euler_round_trip(sequence: str, a: float, b: float, c: float) -> None:
    R = rot.euler_to_matrix(sequence, [a, b, c])
    back = rot.matrix_to_euler(sequence, R)
    np.testing.assert_allclose(rot.euler_to_matrix(sequence, back), R, atol=1e-12)
    np.testing.assert_allclose(back, [a, b, c], atol=1e-7)


def test_euler_is_intrinsic_product() -> None:
    a = np.array([0.3, -0.4, 1.1])
    R = rot.euler_to_matrix("YXZ", a)
    expected = rot.axis_rotation("y", a[0]) @ rot.axis_rotation("x", a[1]) @ rot.axis_rotation(
        "z", a[2])
    np.testing.assert_allclose(R, expected, atol=1e-15)


def test_xsens_euler_convention() -> None:
    roll, pitch, yaw = 10.0, -20.0, 130.0
    R = rot.xsens_euler_to_matrix(roll, pitch, yaw)
    expected = (rot.axis_rotation("z", np.radians(yaw)) @ rot.axis_rotation(
        "y", np.radians(pitch)) @ rot.axis_rotation("x", np.radians(roll)))
    np.testing.assert_allclose(R, expected, atol=1e-15)
    np.testing.assert_allclose(rot.matrix_to_xsens_euler(R), [roll, pitch, yaw], atol=1e-9)


@given(st.tuples(unit, unit, unit), st.floats(0.0, np.pi - 1e-6))
def test_exp_log_round_trip(axis: tuple[float, float, float], angle: float) -> None:
    v = np.array(axis)
    if np.linalg.norm(v) < 1e-3:
        v = np.array([0.0, 0.0, 1.0])
    w = v / np.linalg.norm(v) * angle
    R = rot.exp_so3(w)
    np.testing.assert_allclose(rot.log_so3(R), w, atol=1e-7)


def test_exp_log_near_identity_and_half_turn() -> None:
    for w in ([1e-10, 0, 0], [0, 1e-14, 2e-14], [np.pi - 1e-9, 0, 0]):
        np.testing.assert_allclose(rot.log_so3(rot.exp_so3(w)), w, atol=1e-8)
    angle = rot.angle_between(np.eye(3), rot.exp_so3([0, 0, np.pi]))
    assert angle == pytest.approx(np.pi)


def test_exp_matches_pinocchio() -> None:
    import pinocchio as pin

    rng = np.random.default_rng(3)
    for w in rng.normal(size=(20, 3)):
        np.testing.assert_allclose(rot.exp_so3(w), pin.exp3(w), atol=1e-12)


def test_slerp_midpoint_and_ends() -> None:
    q0 = np.array([1.0, 0, 0, 0])
    q1 = rot.matrix_to_quat_wxyz(rot.axis_rotation("z", 1.0))
    mid = rot.slerp(q0, q1, 0.5)
    np.testing.assert_allclose(rot.quat_wxyz_to_matrix(mid), rot.axis_rotation("z", 0.5),
                               atol=1e-12)
    np.testing.assert_allclose(rot.slerp(q0, q1, 0.0), q0, atol=1e-12)
    np.testing.assert_allclose(rot.slerp(q0, -q1, 1.0), q1, atol=1e-12)  # short arc


def test_enu_conversions() -> None:
    north_in_ned = np.array([1.0, 0, 0])
    np.testing.assert_allclose(rot.R_ENU_NED @ north_in_ned, [0, 1, 0])
    np.testing.assert_allclose(rot.R_ENU_NED @ [0, 0, 1.0], [0, 0, -1])  # down
    np.testing.assert_allclose(rot.R_ENU_NWU @ [0, 1.0, 0], [-1, 0, 0])  # west
    for M in (rot.R_ENU_NED, rot.R_ENU_NWU):
        assert np.linalg.det(M) == pytest.approx(1.0)


# --------------------------------------------------------------------------- SO(3) maps
@given(rotation_vectors)
def test_log_inverts_exp_near_identity_anywhere_and_near_pi(w: np.ndarray) -> None:
    R = rot.exp_so3(w)
    v = rot.log_so3(R)
    assert np.linalg.norm(v) == pytest.approx(np.linalg.norm(w), abs=1e-12)
    np.testing.assert_allclose(rot.exp_so3(v), R, atol=1e-12)
    if np.linalg.norm(w) < np.pi - 1e-9:  # at pi, -w is the same rotation
        np.testing.assert_allclose(v, w, atol=1e-9)


def test_log_is_right_a_hair_below_pi() -> None:
    axis = np.array([2.0, -1.0, 0.5]) / np.linalg.norm([2.0, -1.0, 0.5])
    for angle in (np.pi - 1e-8, np.pi - 1e-12):
        v = rot.log_so3(rot.exp_so3(axis * angle))
        assert np.linalg.norm(v) == pytest.approx(angle, abs=1e-13)
        np.testing.assert_allclose(v / np.linalg.norm(v), axis, atol=1e-12)


@given(rotation_vectors)
def test_one_item_and_batch_paths_agree(w: np.ndarray) -> None:
    R = rot.exp_so3(w)
    np.testing.assert_allclose(rot.log_so3(R), rot.log_so3(R[None])[0], atol=1e-14)
    np.testing.assert_allclose(rot.rotvec_to_quat_wxyz(w), rot.rotvec_to_quat_wxyz(w[None])[0],
                               atol=1e-15)
    np.testing.assert_array_equal(rot.skew(w), rot.skew(w[None])[0])


@given(rotation_vectors)
def test_rotvec_quaternion_is_the_exponential(w: np.ndarray) -> None:
    q = rot.rotvec_to_quat_wxyz(w)
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(rot.quat_wxyz_to_matrix(q), rot.exp_so3(w), atol=1e-14)


@pytest.mark.parametrize("side", ["left", "right"])
@given(e=rotation_vectors_below_pi)
@settings(max_examples=60)
def test_inverse_jacobians_match_finite_differences_on_the_manifold(
        side: str, e: np.ndarray) -> None:
    """``log(exp(h u) exp(e))`` (left) or ``log(exp(e) exp(h u))`` (right) moves by ``J^-1 u h``."""
    h = 1e-6
    R = rot.exp_so3(e)

    def moved(step: np.ndarray) -> np.ndarray:
        X = rot.exp_so3(step) @ R if side == "left" else R @ rot.exp_so3(step)
        return rot.log_so3(X)

    numeric = np.column_stack([(moved(h * u) - moved(-h * u)) / (2 * h) for u in np.eye(3)])
    analytic = (rot.left_jacobian_inverse(e) if side == "left"
                else rot.right_jacobian_inverse(e))
    np.testing.assert_allclose(analytic, numeric, atol=1e-7)


def test_inverse_jacobian_is_finite_at_pi() -> None:
    J = rot.left_jacobian_inverse([np.pi, 0.0, 0.0])
    # Along the axis a step changes the angle one to one; across it Jl^-1 = [[0, pi/2], ...].
    np.testing.assert_allclose(J, [[1, 0, 0], [0, 0, np.pi / 2], [0, -np.pi / 2, 0]],
                               atol=1e-12)


def test_many_batches_convert_as_each_alone_to_the_bit() -> None:
    rng = np.random.default_rng(7)
    near_pi = rot.exp_so3(rng.normal(size=(40, 3)) * 1e-9 + np.array([np.pi, 0.0, 0.0]))
    with_nan = rot.exp_so3(rng.normal(size=(5, 3)))
    with_nan[2, 0, 0] = np.nan
    batches = [rot.exp_so3(rng.normal(size=(135, 3))),  # converted together ...
               rot.exp_so3(rng.normal(size=3)),  # ... not these: one matrix, a few, NaN
               rot.exp_so3(rng.normal(size=(7, 3))), near_pi, with_nan,
               rot.exp_so3(rng.normal(size=(4, 30, 3))), np.eye(3)[None].repeat(25, axis=0)]
    together = rot.matrices_to_quats_wxyz(batches)
    assert len(together) == len(batches)
    for R, q in zip(batches, together, strict=True):
        np.testing.assert_array_equal(q, rot.matrix_to_quat_wxyz(R))
    assert rot.matrices_to_quats_wxyz([]) == []


def _skew_reference(a: np.ndarray) -> np.ndarray:
    """skew's batch as it was written before its single take (#20): the reference."""
    S = np.zeros(a.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -a[..., 2], a[..., 1]
    S[..., 1, 0], S[..., 1, 2] = a[..., 2], -a[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -a[..., 1], a[..., 0]
    return S


def _exp_so3_reference(w: np.ndarray) -> np.ndarray:
    """exp_so3 as it was before (np.linalg.norm, np.eye, the zeros-filled skew): the reference."""
    theta = np.linalg.norm(w, axis=-1)[..., None, None]
    K = _skew_reference(w) if w.shape != (3,) else rot.skew(w)
    small = theta < rot.SMALL_ANGLE
    if not small.any():
        return np.eye(3) + np.sin(theta) / theta * K + (1.0 - np.cos(theta)) / theta**2 * (K @ K)
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    return np.eye(3) + a * K + b * (K @ K)


@pytest.mark.parametrize("shape", [(3,), (1, 3), (2, 3), (7, 3), (4, 5, 3), (0, 3)])
def test_exp_so3_and_skew_are_their_references_bytes(shape: tuple[int, ...]) -> None:
    """The norm's own sum and root, the kept identity and skew's take: the same bits.

    Angles near zero (the series), near pi and far beyond, signed zeros, NaN and inf.
    """
    rng = np.random.default_rng(len(shape) * 10 + shape[0])
    for case in range(300):
        w = rng.normal(size=shape) * rng.choice([1e-7, 1e-4, 0.5, 3.0, 40.0], size=shape)
        if case % 5 == 0:
            w.reshape(-1)[:: 3 + case % 4] *= [0.0, -0.0, np.nan, np.inf][case % 4]
        with np.errstate(all="ignore"):
            got, want = rot.exp_so3(w), _exp_so3_reference(w)
            assert got.shape == want.shape and got.tobytes() == want.tobytes()
            if w.shape != (3,):
                assert rot.skew(w).tobytes() == _skew_reference(w).tobytes()
