"""The sensed pose: what the sensors say before any constraint bends the body.

Every joint between two tracked segments is set from their orientation targets, and the root
from the root's target; joints with an unsensed side keep their angle from the given
configuration. It is the warm start of each frame (one Gauss-Newton step is then usually
enough), the evidence of contact release (a planted point cannot reveal lift-off by its own
motion), and the reference of the *persistence* task: a joint that the contacts, limits or
support tasks bent away from its sensors keeps that bend from frame to frame.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from ..model.human_model import HumanModel
from ..model.topology import BodyTopology
from ..rotations import log_so3, matrix_to_quat_wxyz, wxyz_to_xyzw
from .bound_function import BoundFunction
from .compiled import CompiledKinematics
from .compiled_inputs import memory_owner
from .compiled_sensed import SensedPoseSpec
from .fast_math import any_true
from .tasks import DampingTask


class SensedPose:
    """The sensed configuration and its contact points (see the module docstring).

    Args:
        model: The human model.
        topology: Its :class:`BodyTopology` (which joints are toe joints).
        segment_frames: Frame index of each segment, in :attr:`HumanModel.segment_names` order.
        contact_frames: Frame index of each contact point.
    """

    def __init__(self, model: HumanModel, topology: BodyTopology, segment_frames: Sequence[int],
                 contact_frames: Sequence[int]) -> None:
        self.model = model
        index = {n: i for i, n in enumerate(model.segment_names)}
        joints = list(model.ball_joints.values())
        self.joint_parent = np.array([index[j.spec.parent] for j in joints], dtype=int)
        self.joint_child = np.array([index[j.spec.child] for j in joints], dtype=int)
        self.joint_q_cols = np.array([j.idx_q for j in joints], dtype=int)[:, None] + np.arange(4)
        self.joint_v_cols = np.array([j.idx_v for j in joints], dtype=int)[:, None] + np.arange(3)
        # unsensed toes under a sensed foot: (joint, foot segment) and the flexion axis and range
        self.toe_joints = [(k, index[j.spec.parent]) for k, j in enumerate(joints)
                           if topology.is_toe_joint(j.spec.parent, j.spec.child)
                           and j.spec.angles[0].name == "flex"]
        self.toe_flexion = {}
        for k, _ in self.toe_joints:
            flex = joints[k].spec.angles[0]
            axis = np.eye(3)["xyz".index(flex.axis)] * flex.sign
            self.toe_flexion[k] = (axis, np.radians(flex.lower_deg), np.radians(flex.upper_deg))
        self.segment_frames = list(segment_frames)
        self.contact_frames = list(contact_frames)
        self._compiled: _CompiledPose | None = None

    def spec(self) -> SensedPoseSpec:
        """What :meth:`configuration` does, for the compiled sensed-pose function."""
        model = self.model.model
        root_joint = model.frames[self.segment_frames[0]].parentJoint
        joints = list(self.model.ball_joints.values())
        toes = []
        for k, foot in self.toe_joints:
            axis, lower, upper = self.toe_flexion[k]
            x, y, z = (float(a) for a in axis)
            toes.append((joints[k].joint_id, foot, int(self.joint_child[k]), (x, y, z),
                         float(lower), float(upper)))
        return SensedPoseSpec(
            root=(root_joint, 0),
            joints=tuple((j.joint_id, int(p), int(c)) for j, p, c in
                         zip(joints, self.joint_parent, self.joint_child)),
            toes=tuple(toes), points=tuple(self.contact_frames))

    def use_compiled(self, kinematics: CompiledKinematics, geometry: np.ndarray) -> None:
        """Evaluate :meth:`pose` with the compiled function of ``kinematics`` when it has one."""
        if kinematics.sensed_function is not None:
            self._compiled = _CompiledPose(BoundFunction(kinematics.sensed_function), geometry)

    def both_tracked(self, tracked: np.ndarray) -> np.ndarray:
        """(joints,) joints whose parent and child segments are both tracked."""
        return np.asarray(tracked[self.joint_parent] & tracked[self.joint_child])

    def pose(self, q: np.ndarray, R_world_target: np.ndarray,
             tracked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The sensed configuration at ``q`` and its contact points (c, 3) [m] (read-only).

        The configuration keeps the toes of ``q`` (the posture prior decides them); the points
        are those with level toes (see :meth:`configuration`). The points are kept for a frame
        (:meth:`.support.SupportFollower.keep_base`): never written to.

        Args:
            q: The configuration whose unsensed joints are kept.
            R_world_target: (n, 3, 3) the segments' sensed orientation targets.
            tracked: (n,) which segments are tracked.
        """
        if self._compiled is not None:
            q_sensed, p_sensed = self._compiled(q, R_world_target, tracked)
        else:
            q_sensed = self.configuration(q, R_world_target, tracked, level_toes=False)
            p_sensed = self.contact_positions(self.configuration(q, R_world_target, tracked))
        p_sensed.setflags(write=False)
        return q_sensed, p_sensed

    def configuration(self, q: np.ndarray, R_world_target: np.ndarray, tracked: np.ndarray,
                      level_toes: bool = True) -> np.ndarray:
        """``q`` with the root and every joint between two tracked segments set from targets.

        With ``level_toes``, unsensed toes under a sensed foot lie flat on heel-off.
        """
        qs = q.copy()
        T = R_world_target
        both = self.both_tracked(tracked)
        if tracked[0]:
            qs[3:7] = wxyz_to_xyzw(matrix_to_quat_wxyz(T[0]))
        if any_true(both):
            R = np.swapaxes(T[self.joint_parent[both]], 1, 2) @ T[self.joint_child[both]]
            qs[self.joint_q_cols[both]] = wxyz_to_xyzw(matrix_to_quat_wxyz(R))
        for joint, foot in self.toe_joints if level_toes else ():
            if tracked[foot] and not tracked[self.joint_child[joint]]:
                qs[self.joint_q_cols[joint]] = self._level_toe(T[foot], joint)
        # q and -q are one rotation: keep the hemisphere of q, so that q stays continuous
        blocks = np.vstack([np.arange(3, 7)[None], self.joint_q_cols])
        flip = np.einsum("ij,ij->i", qs[blocks], q[blocks]) < 0.0
        qs[blocks[flip]] *= -1.0
        return qs

    def _level_toe(self, R_world_foot: np.ndarray, joint: int) -> np.ndarray:
        """Toe joint quaternion (x, y, z, w) keeping an unsensed toe level on heel-off.

        While the foot pitches toe-down, the toes stay flat on the floor: the toe joint flexes
        by the foot's pitch (within its range), about the joint's flexion axis.
        """
        forward = R_world_foot[:, 0]
        pitch = np.arctan2(-forward[2], np.hypot(forward[0], forward[1]))
        axis, lower, upper = self.toe_flexion[joint]
        half = 0.5 * float(np.clip(max(pitch, 0.0), lower, upper))
        return np.concatenate([np.sin(half) * axis, [np.cos(half)]])

    def contact_positions(self, q: np.ndarray) -> np.ndarray:
        """The contact points (c, 3) [m] at ``q``."""
        data = self.model.data  # (the model's scratch Data: not one more, 13 MB to fault in)
        pin.forwardKinematics(self.model.model, data, q)
        return np.array([pin.updateFramePlacement(self.model.model, data, f).translation
                         for f in self.contact_frames]).reshape(-1, 3)

    def bend(self, q: np.ndarray, R_world_sensed: np.ndarray,
             segments: np.ndarray) -> np.ndarray:
        """How far ``q`` turns ``segments`` (m,) from their sensed orientations.

        ``Log(R_world_sensed^T R_world_solved)`` (m, 3) [rad], in the segment frames.
        """
        data = self.model.data
        pin.forwardKinematics(self.model.model, data, q)
        ids = [self.segment_frames[i] for i in segments]
        R_solved = np.array([pin.updateFramePlacement(self.model.model, data, f).rotation
                             for f in ids]).reshape(-1, 3, 3)
        return log_so3(np.swapaxes(R_world_sensed[segments], 1, 2) @ R_solved)


class _CompiledPose:
    """:meth:`SensedPose.pose` by the compiled function (:class:`.compiled_sensed.SensedPoseSpec`).

    Called every frame: the geometry is written once, the tracked set when it changes (kept
    while the same read-only array, its memory read-only: the frame targets', as
    :class:`.compiled_inputs.SlotInputs`), ``q`` and the targets every call,
    each straight into its input slot (the transposed targets flattened in C order are their
    column-major vector, as the function reads them).

    Args:
        call: The sensed-pose function bound to its buffers.
        geometry: Its geometry input (:meth:`.compiled.CompiledKinematics.geometry`).
    """

    def __init__(self, call: BoundFunction, geometry: np.ndarray) -> None:
        self.call = call
        call.input_slot(2)[:] = geometry
        self._q = call.input_slot(0)
        # a view: the slot's 3 x 3 blocks transposed (the targets copied in as they are: NumPy
        # copies into strided blocks faster than from them)
        self._R_T = call.input_slot(1).reshape(-1, 3, 3).transpose(0, 2, 1)
        self._tracked: np.ndarray | None = None  # the set in the slot ...
        self._owner: np.ndarray | None = None  # ... and the array owning its memory
        # the outputs as returned, views of their buffers (None: sparse, scattered per call)
        dense = call.is_dense(0) and call.is_dense(1)
        self._outputs = (call.output(0)[:, 0], call.output(1).reshape(-1, 3)) if dense \
            else None

    def __call__(self, q: np.ndarray, R_world_target: np.ndarray,
                 tracked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The sensed configuration (nq,) and the contact points (c, 3) [m] (new arrays)."""
        owner = self._owner  # (as SlotInputs: the same object, its memory read-only)
        if tracked is not self._tracked or owner is None or owner.flags.writeable:
            self.call.input_slot(3)[:] = tracked
            self._tracked, self._owner = tracked, memory_owner(tracked)
        self._q[:] = q
        self._R_T[...] = R_world_target
        self.call.run()
        if self._outputs is not None:
            q_out, p_out = self._outputs
            return q_out.copy(), p_out.copy()
        return self.call.output(0)[:, 0].copy(), self.call.output(1).reshape(-1, 3).copy()


class Persistence:
    """Joints between two sensed segments stay bent as they were in the last frame.

    Contacts, limits and the support tasks bend joints away from what the sensors say (the
    sensed pose); a soft task keeps that bend (tangent [rad]) from frame to frame, so it changes
    gradually when a constraint comes or goes. Joints with an unsensed side are left out: their
    warm start is the last solved angle, and keeping a change of it would keep a velocity.

    Args:
        model: The Pinocchio model.
        weight: The task's weight (0: off).
    """

    def __init__(self, model: pin.Model, weight: float) -> None:
        self.model = model
        self.weight = weight
        self.task = DampingTask(np.zeros(model.nv))
        # the last sensed columns given (read-only: the frame weighting's), their weights, mask
        # and the other columns (indices)
        self._columns: tuple[np.ndarray | None, np.ndarray, np.ndarray, np.ndarray] = (
            None, self.task.weights, np.zeros(model.nv, dtype=bool), np.arange(model.nv))

    def hold(self, q_warm: np.ndarray, sensed_joints: np.ndarray,
             bent: np.ndarray | None) -> None:
        """Keep the joints ``sensed_joints`` (tangent columns) bent by ``bent`` from ``q_warm``.

        Args:
            q_warm: The sensed pose this frame starts from.
            sensed_joints: Tangent columns of the joints between two sensed segments.
            bent: The last frame's bend (nv) [rad]; None: nothing kept (the first frame).
        """
        self.task.weights = self._on(sensed_joints)[0]
        self.task.set_reference(None if self.weight <= 0 or bent is None
                                else pin.integrate(self.model, q_warm, bent))

    def bend(self, q_warm: np.ndarray, q: np.ndarray, sensed_joints: np.ndarray) -> np.ndarray:
        """``q ⊖ q_warm`` (nv) on the ``sensed_joints`` columns, zero elsewhere."""
        bent = pin.difference(self.model, q_warm, q)  # (a new array)
        bent[self._on(sensed_joints)[2]] = 0.0
        return bent

    def _on(self, sensed_joints: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The task's weights (nv,), the mask (nv,) of the ``sensed_joints`` columns, the others.

        Kept while the columns are the same read-only array (a frame weighting's); read-only.
        """
        kept, weights, mask, others = self._columns
        if sensed_joints is not kept:
            weights = np.zeros(self.model.nv)
            weights[sensed_joints] = self.weight
            mask = np.zeros(self.model.nv, dtype=bool)
            mask[sensed_joints] = True
            others = np.flatnonzero(~mask)
            for array in (weights, mask, others):
                array.setflags(write=False)
            if not sensed_joints.flags.writeable:
                self._columns = (sensed_joints, weights, mask, others)
        return weights, mask, others

    def largest(self, bent: np.ndarray) -> float:
        """The largest turn of one joint in ``bent`` (nv, from :meth:`bend`) [rad].

        A ball joint's tangent step is its rotation vector, so its norm is how far the solve
        turned the joint from its sensed relative orientation (``bent`` is zero off the
        joints between two sensed segments, the root's columns included).
        """
        turns = [float(np.linalg.norm(bent[j.idx_v:j.idx_v + j.nv]))
                 for j in self.model.joints[1:]]
        return max(turns, default=0.0)
