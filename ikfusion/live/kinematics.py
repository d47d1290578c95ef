"""What the live outputs need of a solved pose: segment and site poses, joint angles."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..ik.pose import Pose
from ..model.human_model import HumanModel
from ..rotations import matrix_to_euler, quat_wxyz_to_matrix
from .actor_pose import ActorPose


@dataclass(frozen=True)
class PoseValues:
    """One pose evaluated in the world frame (z up, metres).

    Attributes:
        p_world_segment: (S, 3) segment origins [m], ``model.segment_names`` order.
        R_world_segment: (S, 3, 3) segment orientations.
        p_world_site: (M, 3) site positions [m], ``model.site_names`` order.
        joint_angles_deg: (J,) joint angles [deg], ``model.angle_columns`` order.
    """

    p_world_segment: np.ndarray
    R_world_segment: np.ndarray
    p_world_site: np.ndarray
    joint_angles_deg: np.ndarray


class PoseKinematics:
    """Forward kinematics of one actor's model, for the live outputs and the recorder.

    Args:
        model: The actor's body model.
    """

    def __init__(self, model: HumanModel) -> None:
        self.model = model
        self._data = pin.Data(model.model)  # (createData(): the same, several times slower)
        self._segments = [model.segment_frame_id(n) for n in model.segment_names]
        self._sites = [model.site_frame_id(n) for n in model.site_names]
        parents = segment_parent_indices(model)
        self.segment_names = tuple(model.segment_names)
        self.parents = tuple(parents)
        self.joint_names = tuple(model.angle_columns)
        # joints grouped by Euler sequence: one conversion per group, not per joint
        groups: dict[str, list[tuple[int, list[int], np.ndarray]]] = {}
        for k, joint in enumerate(model.ball_joints.values()):
            spec = joint.spec
            columns = [3 * k + ("flex", "abd", "rot").index(a.name) for a in spec.angles]
            groups.setdefault(spec.sequence, []).append((joint.idx_q, columns, spec.signs))
        self._angle_groups = [
            (sequence,
             np.array([[i + 3, i, i + 1, i + 2] for i, _, _ in members]),  # xyzw -> wxyz
             np.array([c for _, c, _ in members]), np.array([s for _, _, s in members]))
            for sequence, members in groups.items()]

    def values(self, q: np.ndarray) -> PoseValues:
        """Segment and site poses and joint angles at configuration ``q``."""
        pin.framesForwardKinematics(self.model.model, self._data, q)
        oMf = self._data.oMf
        return PoseValues(
            np.array([oMf[f].translation for f in self._segments]),
            np.array([oMf[f].rotation for f in self._segments]),
            np.array([oMf[f].translation for f in self._sites]).reshape(-1, 3),
            self.joint_angles_deg(q))

    def joint_angles_deg(self, q: np.ndarray) -> np.ndarray:
        """(J,) joint angles [deg] at ``q``, as ``HumanModel.joint_angle_matrix`` (faster)."""
        out = np.empty(len(self.joint_names))
        for sequence, quat_index, columns, signs in self._angle_groups:
            R = quat_wxyz_to_matrix(q[quat_index])
            out[columns] = np.degrees(matrix_to_euler(sequence, R) * signs)
        return out

    def actor_pose(self, pose: Pose, values: PoseValues, actor: str, character_id: int,
                   frame: int) -> ActorPose:
        """The :class:`ActorPose` the live outputs send."""
        return ActorPose(actor, character_id, float(pose.time), frame, self.segment_names,
                         self.parents, values.p_world_segment, values.R_world_segment,
                         self.joint_names, values.joint_angles_deg)


def segment_parent_indices(model: HumanModel) -> list[int]:
    """Index in ``model.segment_names`` of each segment's parent (-1 for the root)."""
    names = model.segment_names
    index = {n: i for i, n in enumerate(names)}
    parents = {joint.spec.child: joint.spec.parent for joint in model.ball_joints.values()}
    return [index.get(parents.get(n, ""), -1) for n in names]
