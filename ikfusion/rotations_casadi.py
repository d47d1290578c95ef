"""CasADi twin of :mod:`ikfusion.rotations`: the same SO(3) formulas as symbolic expressions.

The compiled IK step (:mod:`ikfusion.ik.compiled`) builds its graph from these functions. Each
follows the NumPy function of the same name in :mod:`ikfusion.rotations` formula for formula,
with the same epsilon policy (:data:`~ikfusion.rotations.SMALL_ANGLE`,
:data:`~ikfusion.rotations.LARGE_ANGLE`); the tests check every pair equal on random samples,
near the identity and near pi. Quaternions here are Pinocchio's (x, y, z, w), the order of the
configuration vector ``q``.

CasADi's ``if_else`` evaluates both branches, so every division has a safe denominator in the
branch that is not taken.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import numpy.typing as npt

from .rotations import LARGE_ANGLE, SMALL_ANGLE

_AXES = {"x": 0, "y": 1, "z": 2}


def skew(w: ca.SX) -> ca.SX:
    """``[w]x`` (3, 3) of a 3-vector, ``[w]x @ u = w x u``."""
    return ca.vertcat(ca.horzcat(0, -w[2], w[1]), ca.horzcat(w[2], 0, -w[0]),
                      ca.horzcat(-w[1], w[0], 0))


def quat_xyzw_to_matrix(q: ca.SX) -> ca.SX:
    """Rotation matrix of a quaternion (x, y, z, w), normalised in the formula."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    s = 2.0 / (x * x + y * y + z * z + w * w)
    return ca.vertcat(
        ca.horzcat(1 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)),
        ca.horzcat(s * (x * y + w * z), 1 - s * (x * x + z * z), s * (y * z - w * x)),
        ca.horzcat(s * (x * z - w * y), s * (y * z + w * x), 1 - s * (x * x + y * y)),
    )


def matrix_to_quat_xyzw(R: ca.SX) -> ca.SX:
    """Unit quaternion (x, y, z, w) with ``w >= 0`` of a rotation matrix.

    Of the four algebraic forms, the one built on the largest of 4w^2, 4x^2, 4y^2, 4z^2 is
    taken (numerically stable for every rotation), as in
    :func:`ikfusion.rotations.matrix_to_quat_wxyz`.
    """
    t = [1 + R[0, 0] + R[1, 1] + R[2, 2], 1 + R[0, 0] - R[1, 1] - R[2, 2],
         1 - R[0, 0] + R[1, 1] - R[2, 2], 1 - R[0, 0] - R[1, 1] + R[2, 2]]
    a, b, c = R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]
    d, e, f = R[0, 1] + R[1, 0], R[0, 2] + R[2, 0], R[1, 2] + R[2, 1]
    forms = [ca.vertcat(a, b, c, t[0]), ca.vertcat(t[1], d, e, a), ca.vertcat(d, t[2], f, b),
             ca.vertcat(e, f, t[3], c)]  # each (x, y, z, w) times 4 * its largest component
    quat = ca.if_else(t[2] >= t[3], forms[2], forms[3])
    quat = ca.if_else(t[1] >= ca.fmax(t[2], t[3]), forms[1], quat)
    quat = ca.if_else(t[0] >= ca.fmax(t[1], ca.fmax(t[2], t[3])), forms[0], quat)
    quat = quat / ca.norm_2(quat)
    return ca.if_else(quat[3] < 0, -quat, quat)


def rotation_about(axis: npt.ArrayLike, angle: ca.SX) -> ca.SX:
    """``exp(angle [axis]x)`` for a constant unit ``axis`` and a symbolic ``angle`` [rad]."""
    u = np.asarray(axis, dtype=float)
    K = ca.DM(np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]]))
    return ca.DM.eye(3) + ca.sin(angle) * K + (1 - ca.cos(angle)) * (K @ K)


def log_so3(R: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Rotation vector (3,) [rad] of ``R`` and its angle in [0, pi].

    Same formula and branches as :func:`ikfusion.rotations.log_so3`: the skew part scaled by
    ``angle / sin(angle)`` (its series below ``SMALL_ANGLE``), the quaternion's vector part
    scaled to the angle above ``LARGE_ANGLE``.
    """
    vee = 0.5 * ca.vertcat(R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1])
    cos = ca.fmin(ca.fmax(0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0), -1.0), 1.0)
    sin = ca.norm_2(vee)
    theta = ca.atan2(sin, cos)
    small = theta < SMALL_ANGLE
    scale = ca.if_else(small, 1.0 + theta * theta / 6.0, theta / ca.if_else(small, 1.0, sin))
    quat = matrix_to_quat_xyzw(R)
    n = ca.norm_2(quat[0:3])
    half_turn = quat[0:3] * (2.0 * ca.atan2(n, quat[3]) / ca.if_else(n > 0, n, 1.0))
    return ca.if_else(theta > LARGE_ANGLE, half_turn, scale * vee), theta


def left_jacobian_inverse(e: ca.SX, theta: ca.SX) -> ca.SX:
    """``Jl^-1(e)`` (3, 3) at rotation vector ``e`` of angle ``theta = |e|`` [rad].

    Same formula as :func:`ikfusion.rotations.left_jacobian_inverse`.
    """
    small = theta < SMALL_ANGLE
    t = ca.if_else(small, 1.0, theta)
    coeff = ca.if_else(small, 1.0 / 12.0 + theta * theta / 720.0,
                       1.0 / (t * t) - ca.cos(0.5 * t) / (2.0 * t * ca.sin(0.5 * t)))
    K = skew(e)
    return ca.DM.eye(3) - 0.5 * K + coeff * (K @ K)


def right_jacobian_inverse(e: ca.SX, theta: ca.SX) -> ca.SX:
    """``Jr^-1(e) = Jl^-1(-e)`` (3, 3) at rotation vector ``e`` of angle ``theta`` [rad]."""
    return left_jacobian_inverse(-e, theta)


def matrix_to_euler(sequence: str, R: ca.SX) -> ca.SX:
    """Intrinsic Tait-Bryan angles (3,) [rad] of ``R``, as in ``rotations.matrix_to_euler``.

    Args:
        sequence: Three distinct axes, e.g. ``"YXZ"`` for ``R = Ry(a0) @ Rx(a1) @ Rz(a2)``.
        R: Rotation matrix (3, 3).
    """
    i, j, k = (_AXES[a] for a in sequence.lower())
    parity = 1.0 if (j - i) % 3 == 1 else -1.0
    middle = ca.asin(ca.fmin(ca.fmax(parity * R[i, k], -1.0), 1.0))
    first = ca.atan2(-parity * R[j, k], R[k, k])
    last = ca.atan2(-parity * R[i, j], R[i, i])
    return ca.vertcat(first, middle, last)
