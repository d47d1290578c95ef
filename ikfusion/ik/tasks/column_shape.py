"""Column shape task: a site pulled toward a target only by how unsensed columns share a bend.

Between two sensed segments (Pelvis and T8, T8 and Head) the IMUs fix a column's whole bend,
not how its unsensed joints share it (:class:`.chain.EvenChainTask` wants it even). A tag on
the head says where the head is, and so how the trunk is really shaped: a crouched jumper
bends the spine at its base and straightens it above (an S), which put the chest and the head
4-9 cm behind an even arc. A plain position task on the head reaches its fix by whatever is
cheapest (the legs, the pelvis, a sensed segment turned against its IMU) and so must be weak
and bounded; this task can only change the share.

Its residual is a position task's, ``e = p_world_site - p_world_target`` [m], but its Jacobian
is the site's linear Jacobian projected onto the share directions of the columns,

    J_shape = J_site P,    P = blockdiag over columns and axes of (I_n - 1/n 1 1^T),

``n`` the column's joints, acting on their tangent steps about one axis at a time (all other
columns of ``P`` zero). A step along ``P`` keeps the sum of the column's rotation vectors, so
(to first order, for the small joint rotations of a spine) the column's end keeps its
orientation while the joints trade bend between them; the root, the limbs and the sensed
segments' orientations are left to their own tasks. The even-chain and chain-share tasks
oppose the pull, so the share moves as far as the fix's information outweighs them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ...errors import ConfigError
from ...model.ball_joints import BallJoint
from ..configuration import Configuration
from .position import PositionTask


def share_projection(joints: Mapping[str, BallJoint], chains: Sequence[Sequence[str]],
                     nv: int) -> np.ndarray:
    """The projection ``P`` (nv, nv) onto the columns' share directions (module docstring).

    Args:
        joints: ``HumanModel.ball_joints`` (name -> joint with ``idx_v``).
        chains: Columns of joints (e.g. the solver's ``even_chains``); a column of fewer than
            two joints has no share and adds nothing.
        nv: Tangent-space size.

    Raises:
        ConfigError: An unknown joint.
    """
    P = np.zeros((nv, nv))
    for chain in chains:
        for name in chain:
            if name not in joints:
                raise ConfigError(f"unknown joint {name!r} in even_chains; joints: "
                                  f"{', '.join(joints)}", field="even_chains")
        n = len(chain)
        if n < 2:
            continue
        centring = np.eye(n) - 1.0 / n
        for axis in range(3):
            idx = [joints[name].idx_v + axis for name in chain]
            P[np.ix_(idx, idx)] = centring
    return P


class ColumnShapeTask(PositionTask):
    """Sites pulled toward targets through the columns' share only (module docstring).

    Args:
        frame_ids: Pinocchio frame indices of the sites.
        names: Their names.
        joints: ``HumanModel.ball_joints``.
        chains: The unsensed columns, each from the root outward.
        nv: Tangent-space size.
        weight: Global scale of the information matrices.
    """

    def __init__(self, frame_ids: Sequence[int], names: Sequence[str],
                 joints: Mapping[str, BallJoint], chains: Sequence[Sequence[str]], nv: int,
                 weight: float = 1.0) -> None:
        super().__init__(frame_ids, names, weight)
        self.projection = share_projection(joints, chains, nv)
        self._columns = np.flatnonzero(self.projection.any(axis=0))

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:
        """The sites' linear Jacobians projected onto the share directions (3k, nv)."""
        return super().compute_jacobian(configuration) @ self.projection

    def add_rows(self, p_world: np.ndarray, J_linear: np.ndarray, H: np.ndarray,
                 c: np.ndarray) -> None:
        """Accumulate from the sites' positions (k, 3) [m] and linear Jacobians (k, 3, nv)."""
        # no site target (the usual frame): out before the row weights are worked out
        if not len(self._columns) or not self.has_targets() or not self.is_active():
            return
        J = np.zeros_like(J_linear)
        cols = self._columns
        J[..., cols] = J_linear[..., cols] @ self.projection[np.ix_(cols, cols)]
        super().add_rows(p_world, J, H, c)
