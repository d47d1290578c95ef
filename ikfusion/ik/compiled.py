"""Kinematics and task residuals of one Gauss-Newton step as a single CasADi function.

Building the QP from many small NumPy operations costs milliseconds per step in Python; here
the forward kinematics of the Pinocchio model and every residual with its Jacobian are written
once as a CasADi ``SX`` graph and evaluated in one call (CasADi's virtual machine), so a step
costs about a tenth of a millisecond. The graph follows the Pinocchio model exactly (same joint
placements and joint types); the tests compare it with Pinocchio's own kinematics.

Tangent steps follow Pinocchio: a free-flyer moves by ``M exp(v)`` in its local frame, a
spherical joint by ``R exp(w)``, a revolute joint by adding to its angle. Only first derivatives
at ``dq = 0`` are needed, so the graph uses the first-order forms ``R (I + [w]x)``, which have the
same value and Jacobian there.

Inputs besides ``q``, the targets and the geometry: per-row weights of the orientation
residuals ``w_orient`` (3k) and of the posture residuals ``w_posture`` (3j) [1/rad^2], and the
posture task's reference joint rotations ``R_reference`` (j, 3, 3). The SO(3) maps (log,
``Jl^-1``, quaternions, Euler angles) are those of :mod:`ikfusion.rotations_casadi`, the twin
of :mod:`ikfusion.rotations` that the NumPy tasks use, with one epsilon policy. Outputs
(``k`` tracked segments, ``j`` ball joints, ``m`` sites), all in the world frame:

* ``H`` (nv, nv) and ``c`` (nv): the Gauss-Newton objective ``1/2 dq^T H dq + c^T dq`` of the
  orientation and posture tasks, ``H = sum J^T W J`` and ``c = sum J^T W e``, with
  ``e_orient = log(R_world_segment R_world_target^T)``, ``J_orient = Jl^-1(e) J_angular``,
  ``e_posture = log(R_reference^T R_parent_child)`` and ``J_posture`` = ``Jr^-1(e)`` on each
  joint's columns (as :class:`ikfusion.ik.tasks.PostureTask`);
* ``e_orient`` (3k) [rad];
* ``angles`` (3j): anatomical angles [rad] in sequence order; ``E_inv`` (3j, 3): their rates
  per unit joint tangent step;
* ``p_sites`` (3m) [m] and ``J_sites`` (3m, nv);
* ``G_ranges`` (3j, nv), ``room_up`` and ``room_down`` (3j) [rad]: the ranges of motion (inputs
  ``lower``, ``upper``) linearised (:mod:`.compiled_ranges`).

The graph holds the model's *structure* only (:mod:`.casadi_kinematics`); joint and frame
placements are an input, so bodies of every size share one function. When a C compiler is on the
machine the function is compiled once (:mod:`.native`) and evaluates about ten times faster than
CasADi's virtual machine, which is the fallback. The first build says so on stderr; a failed
build too, and it becomes a warning of the solve.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np
import pinocchio as pin

from ..model.ball_joints import BallJoint
from ..rotations_casadi import (
    left_jacobian_inverse,
    log_so3,
    matrix_to_euler,
    matrix_to_quat_xyzw,
    quat_xyzw_to_matrix,
    right_jacobian_inverse,
    rotation_about,
    skew,
)
from .casadi_kinematics import forward, frame_pose, geometry_vector, jacobian, symbolic_placements
from .compiled_ranges import range_rows
from .native import BoundFunction, cached_functions, column_major, native_functions


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


class CompiledKinematics:
    """The residuals of one IK step for a fixed set of segments, ball joints and sites.

    Args:
        model: Pinocchio model (free-flyer, spherical and revolute joints).
        segment_frames: Frame ids whose orientations are tracked (targets are inputs).
        ball_joints: Ball joints for the posture prior and the ranges of motion.
        site_frames: Frame ids whose positions are needed (sites, contact points, the root).
        sensed: Also build :attr:`sensed_function` (the sensed configuration and positions of
            points there).
        loaded: The functions already built (:attr:`FUNCTION_NAMES`, loaded from a cached
            library): the graph is then not built again.

    Raises:
        NotImplementedError: For joint types the graph does not cover.
    """

    #: The names of the step function and of the sensed-pose function.
    FUNCTION_NAMES = ("ik_step_objective", "ik_sensed_pose")

    def __init__(self, model: pin.Model, segment_frames: Sequence[int],
                 ball_joints: Sequence[BallJoint], site_frames: Sequence[int],
                 sensed: SensedPoseSpec | None = None,
                 loaded: Sequence[ca.Function] | None = None) -> None:
        self.nv = model.nv
        self.warnings: list[str] = []  # e.g. a failed native compile (see compiled_kinematics)
        self.segment_frames = list(segment_frames)
        self.site_frames = list(site_frames)
        frames = sorted(set(self.segment_frames) | set(self.site_frames)
                        | set(sensed.points if sensed else ()))
        self._geometry_frames = frames
        if loaded is not None:
            self.function = loaded[0]
            self.sensed_function = loaded[1] if sensed is not None else None
            return
        q = ca.SX.sym("q", model.nq)
        targets = ca.SX.sym("R_world_target", 9 * len(segment_frames))
        geometry = ca.SX.sym("geometry", 12 * (model.njoints - 1 + len(frames)))
        placements = symbolic_placements(geometry, model.njoints - 1, frames)
        rotations, translations, axes = forward(model, q, placements)
        self.sensed_function = (None if sensed is None else
                                self._sensed(model, sensed, q, targets, geometry, placements))

        e_orient, J_orient = [], []
        for n, fid in enumerate(segment_frames):
            R, _ = frame_pose(model, fid, rotations, translations, placements)
            T = ca.reshape(targets[9 * n:9 * n + 9], 3, 3)
            e, theta = log_so3(R @ T.T)
            J_angular = jacobian(model, fid, axes, translations, None)[3:, :]
            e_orient.append(e)
            J_orient.append(left_jacobian_inverse(e, theta) @ J_angular)

        references = ca.SX.sym("R_reference", 9 * len(ball_joints))
        e_post, J_post, angles, E_inv = [], [], [], []
        for n, joint in enumerate(ball_joints):
            iq = joint.idx_q
            R_joint = quat_xyzw_to_matrix(q[iq:iq + 4])
            R_reference = ca.reshape(references[9 * n:9 * n + 9], 3, 3)
            e, theta = log_so3(R_reference.T @ R_joint)
            e_post.append(e)
            block = ca.SX(3, model.nv)
            block[:, joint.idx_v:joint.idx_v + 3] = right_jacobian_inverse(e, theta)
            J_post.append(block)
            w = ca.SX.sym("w", 3)
            signs = ca.DM(joint.spec.signs)
            a = matrix_to_euler(joint.spec.sequence, R_joint @ (ca.DM.eye(3) + skew(w))) * signs
            angles.append(ca.substitute(a, w, ca.DM.zeros(3)))
            E_inv.append(ca.substitute(ca.jacobian(a, w), w, ca.DM.zeros(3)))

        p_sites, J_sites = [], []
        for fid in site_frames:
            _, p = frame_pose(model, fid, rotations, translations, placements)
            p_sites.append(p)
            J_sites.append(jacobian(model, fid, axes, translations, p)[:3, :])

        def stack(parts: list[ca.SX], cols: int) -> ca.SX:
            return ca.vertcat(*parts) if parts else ca.SX(0, cols)
        lower = ca.SX.sym("lower", 3 * len(ball_joints))
        upper = ca.SX.sym("upper", 3 * len(ball_joints))
        G_ranges, room_up, room_down = range_rows(
            angles, E_inv, [j.idx_v for j in ball_joints],
            [j.spec.axis_coupling for j in ball_joints], lower, upper, model.nv)
        w_orient = ca.SX.sym("w_orient", 3 * len(segment_frames))
        w_posture = ca.SX.sym("w_posture", 3 * len(ball_joints))
        H = ca.SX(model.nv, model.nv)
        c = ca.SX(model.nv, 1)
        for e_all, J_all, weights in ((stack(e_orient, 1), stack(J_orient, model.nv), w_orient),
                                      (stack(e_post, 1), stack(J_post, model.nv), w_posture)):
            WJ = ca.diag(weights) @ J_all
            H += J_all.T @ WJ
            c += WJ.T @ e_all

        self.function = ca.Function(
            self.FUNCTION_NAMES[0],
            [q, targets, geometry, w_orient, w_posture, references, lower, upper],
            [H, c, stack(e_orient, 1), stack(angles, 1), stack(E_inv, 3), stack(p_sites, 1),
             stack(J_sites, model.nv), G_ranges, room_up, room_down],
            ["q", "R_world_target", "geometry", "w_orient", "w_posture", "R_reference",
             "lower", "upper"],
            ["H", "c", "e_orient", "angles", "E_inv", "p_sites", "J_sites", "G_ranges",
             "room_up", "room_down"],
        )

    def _sensed(self, model: pin.Model, spec: SensedPoseSpec, q: ca.SX, targets: ca.SX,
                geometry: ca.SX, placements: dict) -> ca.Function:
        """``sensed(q, R_world_target, geometry, tracked) -> (q_sensed, p_points (3n) [m])``.

        ``q_sensed`` keeps the toes of ``q``; the points are those of ``q_sensed`` with level toes.
        """
        tracked = ca.SX.sym("tracked", len(self.segment_frames))

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
        return ca.Function(self.FUNCTION_NAMES[1], [q, targets, geometry, tracked],
                           [q_sensed, ca.vertcat(*points) if points else ca.SX(0, 1)],
                           ["q", "R_world_target", "geometry", "tracked"],
                           ["q_sensed", "p_points"])

    def geometry(self, model: pin.Model) -> np.ndarray:
        """The geometry input of ``model`` (joint and frame placements; column-major R, then p).

        Bodies of another size share the compiled structure and only change this vector.
        """
        return geometry_vector(model, self._geometry_frames)

    def __call__(self, q: np.ndarray, R_world_target: np.ndarray, geometry: np.ndarray,
                 w_orient: np.ndarray, w_posture: np.ndarray, R_reference: np.ndarray,
                 limits: tuple[np.ndarray, np.ndarray] | None = None) -> list[np.ndarray]:
        """Evaluate the step function at ``q``.

        Args:
            q: Configuration (nq,).
            R_world_target: Segment targets (k, 3, 3).
            geometry: Joint and frame placements (:meth:`geometry`).
            w_orient: Per-row orientation weights (3k,) [1/rad^2].
            w_posture: Per-row posture weights (3j,) [1/rad^2].
            R_reference: The posture task's reference joint rotations (j, 3, 3).
            limits: The ranges of motion (lower, upper) (j, 3) [rad] for the outputs
                ``G_ranges``, ``room_up`` and ``room_down`` (:mod:`.compiled_ranges`; zero
                ranges when omitted).

        Returns:
            The outputs as dense arrays, overwritten by the next call (copy to keep them).
        """
        if not hasattr(self, "_step"):
            self._step = BoundFunction(self.function)
        none = np.zeros(len(w_posture))
        lower, upper = (none, none) if limits is None else (limits[0].ravel(), limits[1].ravel())
        return self._step(q, column_major(R_world_target), geometry, w_orient, w_posture,
                          column_major(R_reference), lower, upper)

    def sensed_pose(self, q: np.ndarray, R_world_target: np.ndarray, geometry: np.ndarray,
                    tracked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The sensed configuration and its points' world positions (points, 3) [m].

        See :class:`SensedPoseSpec`; ``tracked`` is 0/1 per target.

        Raises:
            ValueError: When built without a sensed-pose spec.
        """
        if self.sensed_function is None:
            raise ValueError("built without a SensedPoseSpec")
        if not hasattr(self, "_sensed_call"):
            self._sensed_call = BoundFunction(self.sensed_function)
        q_sensed, points = self._sensed_call(q, column_major(R_world_target), geometry, tracked)
        return q_sensed[:, 0].copy(), points.reshape(-1, 3).copy()


def structure_key(model: pin.Model, segment_frames: Sequence[int],
                  ball_joints: Sequence[BallJoint], site_frames: Sequence[int],
                  sensed: SensedPoseSpec | None = None) -> str:
    """A string identifying the compiled structure (not the geometry) of a step function."""
    parts = [
        "objective-v7",
        repr(sensed),
        ",".join(model.joints[j].shortname() for j in range(1, model.njoints)),
        ",".join(str(p) for p in model.parents),
        ",".join(str(model.frames[f].parentJoint) for f in (*segment_frames, *site_frames)),
        ",".join(str(f) for f in (*segment_frames, *site_frames)),
        ",".join(f"{j.idx_q}:{j.spec.sequence}:{j.spec.signs.tolist()}" for j in ball_joints),
    ]
    for j in range(1, model.njoints):
        if model.joints[j].shortname() == "JointModelRevoluteUnaligned":
            parts.append(str(np.round(model.joints[j].extract().axis, 12).tolist()))
    return hashlib.sha256("|".join(parts).encode()).hexdigest()[:20]


_BUILT: dict[str, CompiledKinematics] = {}


def compiled_kinematics(model: pin.Model, segment_frames: Sequence[int],
                        ball_joints: Sequence[BallJoint], site_frames: Sequence[int],
                        sensed: SensedPoseSpec | None = None) -> CompiledKinematics:
    """A (cached) :class:`CompiledKinematics`, natively compiled when a C compiler exists.

    A library already built and verified is loaded without building the CasADi graphs again
    (that takes longer than loading). A failed compile leaves CasADi's virtual machine in place
    and says so in :attr:`CompiledKinematics.warnings` (and on stderr).
    """
    key = structure_key(model, segment_frames, ball_joints, site_frames, sensed)
    built = _BUILT.get(key)
    if built is None:
        names = CompiledKinematics.FUNCTION_NAMES[:2 if sensed is not None else 1]
        cached = cached_functions(key, names)
        if cached is not None:
            built = _BUILT[key] = CompiledKinematics(model, segment_frames, ball_joints,
                                                     site_frames, sensed, cached)
            return built
        built = CompiledKinematics(model, segment_frames, ball_joints, site_frames, sensed)
        functions = [built.function]
        if built.sensed_function is not None:
            functions.append(built.sensed_function)
        native, problem = native_functions(functions, key)
        if native is not None:
            built.function = native[0]
            if built.sensed_function is not None:
                built.sensed_function = native[1]
        if problem is not None:
            built.warnings.append(problem)
        _BUILT[key] = built
    return built
