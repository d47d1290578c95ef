"""The CasADi twin equals the NumPy SO(3) maps, near the identity, anywhere and near pi."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from so3_samples import rotation_vectors, unit_axes

from ikfusion import rotations as rot
from ikfusion import rotations_casadi as twin

SEQUENCES = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]


def _evaluate(function: ca.Function, *args: np.ndarray) -> list[np.ndarray]:
    """A CasADi function's outputs as dense arrays (matrices row-major as in NumPy)."""
    out = function(*[ca.DM(np.asarray(a, dtype=float)) for a in args])
    return [np.array(o) for o in (out if isinstance(out, tuple) else [out])]


def _log_function() -> ca.Function:
    R = ca.SX.sym("R", 3, 3)
    e, theta = twin.log_so3(R)
    return ca.Function("log", [R], [e, theta])


def _jacobian_functions() -> tuple[ca.Function, ca.Function]:
    e = ca.SX.sym("e", 3)
    theta = ca.norm_2(e)
    return (ca.Function("Jl_inv", [e], [twin.left_jacobian_inverse(e, theta)]),
            ca.Function("Jr_inv", [e], [twin.right_jacobian_inverse(e, theta)]))


def _quaternion_functions() -> tuple[ca.Function, ca.Function]:
    R = ca.SX.sym("R", 3, 3)
    q = ca.SX.sym("q", 4)
    return (ca.Function("to_quat", [R], [twin.matrix_to_quat_xyzw(R)]),
            ca.Function("to_matrix", [q], [twin.quat_xyzw_to_matrix(q)]))


LOG = _log_function()
JL_INV, JR_INV = _jacobian_functions()
TO_QUAT, TO_MATRIX = _quaternion_functions()


@given(rotation_vectors)
def test_log_equals_numpy(w: np.ndarray) -> None:
    R = rot.exp_so3(w)
    e, theta = _evaluate(LOG, R)
    expected = rot.log_so3(R)
    assert float(theta[0, 0]) == pytest.approx(np.linalg.norm(expected), abs=1e-12)
    if np.linalg.norm(w) < np.pi - 1e-9:
        np.testing.assert_allclose(e[:, 0], expected, atol=1e-9)
    else:  # a half turn: w and -w are the same rotation
        assert min(np.abs(e[:, 0] - expected).max(), np.abs(e[:, 0] + expected).max()) < 1e-8


def test_log_is_right_a_hair_below_pi() -> None:
    """At pi - 1e-8 the skew part has norm 1e-8: the log must still be a near half turn."""
    axis = np.array([0.3, -0.9, 0.2]) / np.linalg.norm([0.3, -0.9, 0.2])
    for angle in (np.pi - 1e-8, np.pi - 1e-6):
        e, theta = _evaluate(LOG, rot.exp_so3(axis * angle))
        assert float(theta[0, 0]) == pytest.approx(angle, abs=1e-13)
        assert np.linalg.norm(e) == pytest.approx(angle, abs=1e-13)
        np.testing.assert_allclose(e[:, 0] / np.linalg.norm(e), axis, atol=1e-12)


@given(rotation_vectors)
def test_inverse_jacobians_equal_numpy(e: np.ndarray) -> None:
    np.testing.assert_allclose(_evaluate(JL_INV, e)[0], rot.left_jacobian_inverse(e),
                               atol=1e-12)
    np.testing.assert_allclose(_evaluate(JR_INV, e)[0], rot.right_jacobian_inverse(e),
                               atol=1e-12)


@given(rotation_vectors)
def test_quaternions_equal_numpy(w: np.ndarray) -> None:
    R = rot.exp_so3(w)
    q_xyzw = _evaluate(TO_QUAT, R)[0][:, 0]
    expected = rot.wxyz_to_xyzw(rot.matrix_to_quat_wxyz(R))
    assert q_xyzw[3] >= 0.0
    # At a half turn w = 0 and q, -q are both "w >= 0".
    assert min(np.abs(q_xyzw - expected).max(), np.abs(q_xyzw + expected).max()) < 1e-12
    np.testing.assert_allclose(_evaluate(TO_MATRIX, 3.0 * q_xyzw)[0], R, atol=1e-14)


@given(unit_axes, st.floats(-np.pi, np.pi))
@settings(max_examples=30)
def test_rotation_about_an_axis_is_the_exponential(axis: np.ndarray, angle: float) -> None:
    a = ca.SX.sym("a")
    function = ca.Function("about", [a], [twin.rotation_about(axis, a)])
    np.testing.assert_allclose(_evaluate(function, angle)[0], rot.exp_so3(axis * angle),
                               atol=1e-14)


@pytest.mark.parametrize("sequence", SEQUENCES)
@given(w=rotation_vectors)
@settings(max_examples=30)
def test_euler_angles_equal_numpy(sequence: str, w: np.ndarray) -> None:
    R_sym = ca.SX.sym("R", 3, 3)
    function = ca.Function("euler", [R_sym], [twin.matrix_to_euler(sequence, R_sym)])
    R = rot.exp_so3(w)
    np.testing.assert_allclose(_evaluate(function, R)[0][:, 0], rot.matrix_to_euler(sequence, R),
                               atol=1e-12)


def test_skew_is_the_cross_product() -> None:
    v, u = np.array([0.3, -1.2, 2.0]), np.array([-0.5, 0.7, 0.1])
    x = ca.SX.sym("x", 3)
    function = ca.Function("skew", [x], [twin.skew(x)])
    K = _evaluate(function, v)[0]
    np.testing.assert_allclose(K, rot.skew(v), atol=0.0)
    np.testing.assert_allclose(K @ u, np.cross(v, u), atol=1e-15)
