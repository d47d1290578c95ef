"""Even bending of a column of joints: the spine or the neck bends as one arc, never in an S.

Between two sensed segments (Pelvis and T8, T8 and Head) lie joints whose segments carry no
sensor (L5, L3, T12; Neck). The sensors fix only their product; the posture prior spreads it
evenly, but with the small weight a prior must have. Any constraint that wants the upper body
moved a few centimetres relative to the pelvis (a planted palm or foot the sensed pose
disagrees with, the floor) finds the cheapest way in an S-shaped column: opposite flexions of
tens of degrees that keep both sensed orientations and shear the column. The moment that
constraint lets go, the column snaps back in one frame, a pop of tens of degrees (issue #19).

This task makes the shape itself costly: for each pair of neighbouring joints of a column
whose shared segment is unsensed this frame, the residual is the difference of their rotation
vectors,

    e_ij = log(R_i) - log(R_j)    [rad],   de_ij/dw = [Jr^-1(log R_i), -Jr^-1(log R_j)],

with ``R_i`` the joint rotation ``R_parent_child`` and ``w`` the joints' tangent steps (child
frame). It is zero for every evenly bent column, so it never biases what the sensors say; it
only leaves the constraints the sensed joints (bent at the cost of their orientation errors,
and eased back when a contact lets go) instead of a free shear of the column.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ...errors import ConfigError
from ...model.ball_joints import BallJoint
from ...rotations import log_so3, quat_wxyz_to_matrix, right_jacobian_inverse, xyzw_to_wxyz
from ..configuration import Configuration
from .base import Task


class EvenChainTask(Task):
    """Neighbouring joints of each column bend alike (see the module docstring).

    Args:
        joints: ``HumanModel.ball_joints`` (name -> joint with ``idx_q``, ``idx_v``, ``spec``).
        chains: Columns of joints, each listed from the root outward (e.g. ``[jL5S1, jL4L3,
            jL1T12, jT9T8]``); each joint's child segment must be the next joint's parent.
        weight: Weight of each pair's residual [1/rad^2] (0: off).
        segments: Segment names, in the order of the ``tracked`` masks of :meth:`set_tracked`.

    Raises:
        ConfigError: An unknown joint, or a chain whose joints do not follow each other.
    """

    def __init__(self, joints: Mapping[str, BallJoint], chains: Sequence[Sequence[str]],
                 weight: float, segments: Sequence[str]) -> None:
        index = {n: i for i, n in enumerate(segments)}
        pairs: list[tuple[BallJoint, BallJoint]] = []
        for chain in chains:
            for name in chain:
                if name not in joints:
                    raise ConfigError(f"unknown joint {name!r} in even_chains; joints: "
                                      f"{', '.join(joints)}", field="even_chains")
            for first, second in zip(chain[:-1], chain[1:]):
                a, b = joints[first], joints[second]
                if a.spec.child != b.spec.parent:
                    raise ConfigError(f"even_chains: {second!r} does not follow {first!r} "
                                      "(its parent segment is not the other's child)",
                                      field="even_chains")
                pairs.append((a, b))
        self.weight = float(weight)
        self.pair_q = np.array([[a.idx_q, b.idx_q] for a, b in pairs], dtype=int).reshape(-1, 2)
        self.pair_v = np.array([[a.idx_v, b.idx_v] for a, b in pairs], dtype=int).reshape(-1, 2)
        self.shared = np.array([index[a.spec.child] for a, _ in pairs], dtype=int)
        self.active = np.ones(len(pairs), dtype=bool)

    def set_tracked(self, tracked: np.ndarray) -> None:
        """Pairs whose shared segment has an orientation target this frame are left out."""
        self.active = ~np.asarray(tracked, dtype=bool)[self.shared]

    def row_weights(self) -> np.ndarray:
        """Three rows per pair: ``weight`` where the pair is active, 0 elsewhere."""
        return np.repeat(np.where(self.active, self.weight, 0.0), 3)

    def _logs(self, q: np.ndarray) -> np.ndarray:
        """Rotation vectors (pairs, 2, 3) [rad] of both joints of each pair."""
        cols = self.pair_q[..., None] + np.arange(4, dtype=int)
        return log_so3(quat_wxyz_to_matrix(xyzw_to_wxyz(np.asarray(q)[cols])))

    def compute_error(self, configuration: Configuration) -> np.ndarray:
        """``log(R_i) - log(R_j)`` per pair, stacked (3 pairs,) [rad]."""
        e = self._logs(configuration.q)
        return (e[:, 0] - e[:, 1]).reshape(-1)

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:
        """(3 pairs, nv): ``Jr^-1`` of the first joint, minus that of the second."""
        blocks = right_jacobian_inverse(self._logs(configuration.q))
        J = np.zeros((3 * len(self.pair_v), configuration.model.nv))
        for k, (vi, vj) in enumerate(self.pair_v):
            J[3 * k:3 * k + 3, vi:vi + 3] = blocks[k, 0]
            J[3 * k:3 * k + 3, vj:vj + 3] -= blocks[k, 1]
        return J

    def add_objective(self, configuration: Configuration, H: np.ndarray, c: np.ndarray) -> None:
        """Accumulate the active pairs' objective (none when the weight is 0)."""
        if self.weight <= 0 or not self.active.any():
            return
        super().add_objective(configuration, H, c)
