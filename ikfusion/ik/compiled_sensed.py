"""The sensed pose as a CasADi function: the joint rotations the sensors give, straight away.

Built beside the step function of :mod:`.compiled` (the same symbols, compiled into the same
library): the configuration whose sensed joints take their rotations from the targets, and the
world positions [m] of some points there.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import pinocchio as pin

from ..rotations_casadi import matrix_to_quat_xyzw, rotation_about
from .casadi_kinematics import forward, frame_pose


@dataclass(frozen=True)
class SensedPoseSpec:
    """The pose the sensors say: which joint rotations come straight from the targets.

    Indices refer to the list of tracked segments (the targets). A joint takes its rotation from
    the targets only where the ``tracked`` input (0/1 per target) says both sides are sensed.

    Attributes:
        root: ``(free-flyer joint id, target index)``: the root's rotation is that target's.
        joints: ``(joint id, parent target, child target)``: ``R_parent^T R_child``.
        toes: ``(joint id, foot target, toe target, flexion axis, lower, upper [rad])``: for the
            points, an unsensed toe under a sensed foot flexes by the foot's toe-down pitch
            (clipped to its range), so the toes stay flat on heel-off. The sensed
            configuration itself keeps the toes of ``q`` (the posture prior decides them).
        points: Frame ids whose world positions [m] at the sensed pose are returned.

    Quaternions taken from the targets keep the sign of those in ``q`` (``q`` and ``-q`` are one
    rotation), so configurations stay continuous from frame to frame.
    """

    root: tuple[int, int] | None
    joints: tuple[tuple[int, int, int], ...]
    toes: tuple[tuple[int, int, int, tuple[float, float, float], float, float], ...]
    points: tuple[int, ...]


def sensed_pose_function(model: pin.Model, spec: SensedPoseSpec, name: str, q: ca.SX,
                         targets: ca.SX, geometry: ca.SX, placements: dict) -> ca.Function:
    """``name(q, R_world_target, geometry, tracked) -> (q_sensed, p_points (3n) [m])``.

    ``q_sensed`` keeps the toes of ``q``; the points are those of ``q_sensed`` with level toes.
    The symbols ``q``, ``targets`` (9 per target, column-major), ``geometry`` and the
    ``placements`` they make are those of the step function (:mod:`.compiled`).
    """
    tracked = ca.SX.sym("tracked", targets.numel() // 9)

    def target(n: int) -> ca.SX:
        return ca.reshape(targets[9 * n:9 * n + 9], 3, 3)

    def quaternion_start(j: int) -> int:
        return model.idx_qs[j] + (3 if model.joints[j].shortname() == "JointModelFreeFlyer"
                                  else 0)

    choices: dict[int, tuple[ca.SX, ca.SX]] = {}  # joint -> (use the targets, R_local)
    toes: dict[int, tuple[ca.SX, ca.SX]] = {}
    if spec.root is not None:
        j, n = spec.root
        choices[j] = (tracked[n] > 0.5, target(n))
    for j, parent, child in spec.joints:
        choices[j] = (tracked[parent] * tracked[child] > 0.5,
                      target(parent).T @ target(child))
    for j, foot, toe, axis, lower, upper in spec.toes:
        foot_x = target(foot)[:, 0]
        pitch = ca.atan2(-foot_x[2], ca.sqrt(foot_x[0] ** 2 + foot_x[1] ** 2))
        angle = ca.fmin(ca.fmax(ca.fmax(pitch, 0.0), lower), upper)
        level = rotation_about(axis, angle)
        use = tracked[foot] * (1.0 - tracked[toe]) > 0.5
        toes[j] = (use, level)

    def replace(q_in: ca.SX, rotations: dict[int, tuple[ca.SX, ca.SX]]) -> ca.SX:
        q_out = ca.SX(q_in)
        for j, (use, R) in rotations.items():
            iq = quaternion_start(j)
            quat, previous = matrix_to_quat_xyzw(R), q_in[iq:iq + 4]
            quat = ca.if_else(ca.dot(quat, previous) < 0, -quat, quat)  # keep q's hemisphere
            q_out[iq:iq + 4] = ca.if_else(use, quat, previous)
        return q_out

    q_sensed = replace(q, choices)
    rotations, translations, _ = forward(model, replace(q_sensed, toes), placements)
    points = [frame_pose(model, f, rotations, translations, placements)[1]
              for f in spec.points]
    return ca.Function(name, [q, targets, geometry, tracked],
                       [q_sensed, ca.vertcat(*points) if points else ca.SX(0, 1)],
                       ["q", "R_world_target", "geometry", "tracked"],
                       ["q_sensed", "p_points"])
