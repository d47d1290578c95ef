"""Per-joint and per-segment pieces of the step function as CasADi subfunctions, called by it.

The step function of :mod:`.compiled` repeats the same expressions for every tracked segment
(the orientation residual's log, ``Jl^-1`` and weighted products) and for every ball joint (the
posture log and ``Jr^-1``, the anatomical angles and their rates, the linearised range). Written
inline, each repetition is its own straight-line machine code: the compiled step was ~0.7 MB,
fetched from the L3 cache on every call (the solver's Python loop evicts it between calls).
Here each kind of piece is one CasADi function marked ``never_inline``: the step's SX graph
holds call nodes, and the generated C holds one body per kind, called once per segment or joint.
The operations inside are those written inline before (the same numbers).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

import casadi as ca

from ..model.ball_joints import BallJoint
from ..rotations_casadi import (
    left_jacobian_inverse,
    log_so3,
    matrix_to_euler,
    quat_xyzw_to_matrix,
    right_jacobian_inverse,
    skew,
)
from .compiled_ranges import range_block

#: The options of every piece: kept a call in the caller's graph (one body in the C code).
_CALLED = {"never_inline": True, "cse": True}


@cache
def spherical_joint_function() -> ca.Function:
    """The forward kinematics' step of one spherical joint (a function).

    ``(R_world_parent (3, 3), p_world_parent (3), R_M (3, 3), p_M (3), quaternion xyzw (4)) ->
    (R_world_joint (3, 3), p_world_joint (3))``: through the joint placement ``M`` (``R_M``,
    ``p_M`` [m]) and the joint's rotation, as :func:`.casadi_kinematics.forward` writes it
    inline for the other joint types.
    """
    R_world_parent, p_world_parent = ca.SX.sym("R_world_parent", 3, 3), ca.SX.sym("p", 3)
    R_M, p_M, quaternion = ca.SX.sym("R_M", 3, 3), ca.SX.sym("p_M", 3), ca.SX.sym("quat", 4)
    R_parent = R_world_parent @ R_M
    p_parent = p_world_parent + R_world_parent @ p_M
    return ca.Function("ik_spherical_joint",
                       [R_world_parent, p_world_parent, R_M, p_M, quaternion],
                       [R_parent @ quat_xyzw_to_matrix(quaternion),
                        p_parent + R_parent @ ca.SX.zeros(3)],
                       ["R_world_parent", "p_world_parent", "R_M", "p_M", "quaternion"],
                       ["R_world_joint", "p_world_joint"], _CALLED)


@cache
def dot_block_function() -> ca.Function:
    """``(X (3, 3), Y (3, 3)) -> Z (3, 3)`` with ``Z[v, u] = dot(X[:, v], Y[:, u])``.

    A 3x3 block of the tree-summed orientation objective
    (:func:`.casadi_kinematics.angular_objective`), the products of two joints' columns.
    """
    X, Y = ca.SX.sym("X", 3, 3), ca.SX.sym("Y", 3, 3)
    Z = ca.SX(3, 3)
    for v in range(3):
        for u in range(3):
            Z[v, u] = ca.dot(X[:, v], Y[:, u])
    return ca.Function("ik_dot_block", [X, Y], [Z], ["X", "Y"], ["Z"], _CALLED)


@cache
def segment_function() -> ca.Function:
    """``(R_world_joint (3, 3), R_M (3, 3), R_world_target (3, 3), w (3)) -> (e, K, g)``.

    Of one segment, the frame ``M`` (rotation ``R_M``) on the joint: ``R = R_world_joint R_M``
    (the segment's world rotation, as :func:`.casadi_kinematics.frame_pose` writes it),
    ``e = log(R R_world_target^T)`` [rad], ``M = Jl^-1(e)``, ``K = M^T W M`` and
    ``g = M^T W e`` with ``W = diag(w)`` [1/rad^2] (see
    :func:`.casadi_kinematics.orientation_terms`). ``R_M`` is read from the geometry input.
    """
    R_joint, R_M = ca.SX.sym("R_joint", 3, 3), ca.SX.sym("R_M", 3, 3)
    T, w = ca.SX.sym("T", 3, 3), ca.SX.sym("w", 3)
    e, theta = log_so3(R_joint @ R_M @ T.T)
    M = left_jacobian_inverse(e, theta)
    return ca.Function("ik_segment", [R_joint, R_M, T, w],
                       [e, M.T @ ca.diag(w) @ M, M.T @ (w * e)],
                       ["R_joint", "R_M", "T", "w"], ["e", "K", "g"], _CALLED)


def ball_joint_function(sequence: str, name: str = "ik_ball_joint") -> ca.Function:
    """The pieces of one ball joint whose anatomical angles follow the Euler ``sequence``.

    ``(quaternion xyzw (4), R_reference (3, 3), lower (3), upper (3), signs (3), coupling) ->
    (e_posture (3), Jr^-1 (3, 3), angles (3), E_inv (3, 3), G (3, 3), room_up (3), room_down
    (3))``: the posture residual ``log(R_reference^T R_joint)`` [rad] and its ``Jr^-1``, the
    anatomical angles [rad] (the joint's ``signs`` times those of the sequence) with their
    rates per unit joint tangent step, and the linearised range
    (:func:`.compiled_ranges.range_block`, ``coupling`` the joint's ``axis_coupling``) on the
    joint's three columns. The signs and the coupling are +-1: products with them are exact, so
    joints of one sequence share the body with the numbers of constants written inline.
    """
    quaternion, R_reference = ca.SX.sym("quaternion", 4), ca.SX.sym("R_reference", 3, 3)
    lower, upper = ca.SX.sym("lower", 3), ca.SX.sym("upper", 3)
    signs, coupling = ca.SX.sym("signs", 3), ca.SX.sym("coupling")
    R_joint = quat_xyzw_to_matrix(quaternion)
    e, theta = log_so3(R_reference.T @ R_joint)
    w = ca.SX.sym("w", 3)
    a = matrix_to_euler(sequence, R_joint @ (ca.DM.eye(3) + skew(w))) * signs
    angles = ca.substitute(a, w, ca.DM.zeros(3))
    E_inv = ca.substitute(ca.jacobian(a, w), w, ca.DM.zeros(3))
    G, up, down = range_block(angles, E_inv, lower, upper, coupling)
    return ca.Function(name, [quaternion, R_reference, lower, upper, signs, coupling],
                       [e, right_jacobian_inverse(e, theta), angles, E_inv, G, up, down],
                       ["quaternion", "R_reference", "lower", "upper", "signs", "coupling"],
                       ["e", "Jr_inv", "angles", "E_inv", "G", "room_up", "room_down"], _CALLED)


def ball_joint_pieces() -> Callable[..., list[ca.SX]]:
    """Calls of :func:`ball_joint_function`, one function per Euler sequence (shared).

    The returned callable takes a :class:`~ikfusion.model.ball_joints.BallJoint` and the
    function's first four arguments.
    """
    made: dict[str, ca.Function] = {}

    def of(joint: BallJoint, *arguments: ca.SX) -> list[ca.SX]:
        sequence = joint.spec.sequence
        if sequence not in made:
            made[sequence] = ball_joint_function(sequence, f"ik_ball_joint_{len(made)}")
        return made[sequence].call([*arguments, ca.SX(ca.DM(joint.spec.signs)),
                                    ca.SX(joint.spec.axis_coupling)])
    return of
