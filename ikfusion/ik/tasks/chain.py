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
from ..fast_math import any_true, true_indices
from .base import Task
from .position import add_products


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
        self.pairs = pairs  # the compiled step sums them too (ikfusion.ik.compiled)
        self.pair_q = np.array([[a.idx_q, b.idx_q] for a, b in pairs], dtype=int).reshape(-1, 2)
        self.pair_v = np.array([[a.idx_v, b.idx_v] for a, b in pairs], dtype=int).reshape(-1, 2)
        self.shared = np.array([index[a.spec.child] for a, _ in pairs], dtype=int)
        self.active = np.ones(len(pairs), dtype=bool)
        self.reference = np.zeros((len(pairs), 3))  # each pair's wanted difference [rad]

    @property
    def active(self) -> np.ndarray:
        """(pairs,) the pairs in the objective this frame (set whole, not entry by entry)."""
        return self._active

    @active.setter
    def active(self, value: np.ndarray) -> None:
        self._active = value
        self._row_weights: tuple[float, np.ndarray] | None = None  # (weight, rows) of value

    def set_tracked(self, tracked: np.ndarray) -> None:
        """Pairs whose shared segment has an orientation target this frame are left out."""
        self.active = ~np.asarray(tracked, dtype=bool)[self.shared]

    def row_weights(self) -> np.ndarray:
        """Three rows per pair: ``weight`` where the pair is active, 0 elsewhere (read-only).

        Kept until :attr:`active` or :attr:`weight` changes: a step reads them every
        Gauss-Newton iteration, the tracked segments change rarely.
        """
        kept = self._row_weights
        if kept is None or kept[0] != self.weight:
            rows = np.repeat(np.where(self._active, self.weight, 0.0), 3)
            rows.setflags(write=False)
            self._row_weights = kept = (self.weight, rows)
        return kept[1]

    def _logs(self, q: np.ndarray, pairs: np.ndarray | slice = slice(None)) -> np.ndarray:
        """Rotation vectors (pairs, 2, 3) [rad] of both joints of each (selected) pair."""
        cols = self.pair_q[pairs, :, None] + np.arange(4, dtype=int)
        return log_so3(quat_wxyz_to_matrix(xyzw_to_wxyz(np.asarray(q)[cols])))

    def compute_error(self, configuration: Configuration) -> np.ndarray:
        """``log(R_i) - log(R_j)`` (minus :attr:`reference`) per pair, stacked (3 pairs,) [rad]."""
        e = self._logs(configuration.q)
        return (e[:, 0] - e[:, 1] - self.reference).reshape(-1)

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:
        """(3 pairs, nv): ``Jr^-1`` of the first joint, minus that of the second."""
        return self._jacobian(self._logs(configuration.q), self.pair_v,
                              configuration.model.nv).reshape(-1, configuration.model.nv)

    @staticmethod
    def _jacobian(logs: np.ndarray, pair_v: np.ndarray, nv: int) -> np.ndarray:
        """(pairs, 3, nv) rows of the pairs whose rotation vectors are ``logs`` (pairs, 2, 3)."""
        blocks = right_jacobian_inverse(logs)
        J = np.zeros((len(pair_v), 3, nv))
        pair, row = np.arange(len(pair_v))[:, None, None], np.arange(3)[:, None]
        columns = pair_v[:, :, None, None] + np.arange(3)  # (pairs, 2, 1, 3)
        J[pair, row, columns[:, 0]] = blocks[:, 0]
        J[pair, row, columns[:, 1]] = -blocks[:, 1]
        return J

    def add_objective(self, configuration: Configuration, H: np.ndarray, c: np.ndarray) -> None:
        """Accumulate the active pairs' objective (none when the weight is 0).

        The joint rotations are taken once, of the active pairs only, and their rows summed
        with :func:`.position.add_products`: the numbers of the base class's ``J^T W J``,
        whose inactive rows have weight 0.
        """
        if self.weight <= 0 or not any_true(self.active):
            return
        pairs = true_indices(self.active)
        logs = self._logs(configuration.q, pairs)
        nv = configuration.model.nv
        J = self._jacobian(logs, self.pair_v[pairs], nv).reshape(-1, nv)
        e = logs[:, 0] - logs[:, 1] - self.reference[pairs]
        add_products(J, self.weight * J, e.reshape(-1), H, c)


class ChainShareTask(EvenChainTask):
    """Each column keeps the last frame's share of its bend (see :class:`EvenChainTask`).

    The sensed segments at a column's ends fix its whole bend; how the unsensed joints share
    it is left to soft tasks: :class:`EvenChainTask` wants it even, a position task on a site
    beyond the column (the head's tag, :mod:`ikfusion.app.tag_tasks`) wants it uneven as the
    fix says. A change of the contact set (a toe letting go) changes what else can move that
    site, and the share that balances these tasks jumped in one frame (4 deg of the lower
    spine, issue #19). This task holds each pair's difference of rotation vectors where the
    last frame left it,

        e_ij = log(R_i) - log(R_j) - d_ij    [rad],    d_ij = the last frame's difference,

    so the share follows the other tasks over a few frames instead (a first-order lag whose
    length grows with ``weight``); the whole bend still follows the sensors at once.
    Arguments as :class:`EvenChainTask`'s; off until :meth:`set_previous` holds a frame.
    """

    def __init__(self, joints: Mapping[str, BallJoint], chains: Sequence[Sequence[str]],
                 weight: float, segments: Sequence[str]) -> None:
        super().__init__(joints, chains, weight, segments)
        #: The last solved frame whose differences are held; None: off.
        self.q_previous: np.ndarray | None = None
        self._stale = False  # reference not yet taken of q_previous

    def set_previous(self, q_previous: np.ndarray | None) -> None:
        """Hold the differences of ``q_previous`` (the last solved frame); None: off.

        The differences are taken when the NumPy objective needs them (the compiled step takes
        them of :attr:`q_previous` itself).
        """
        self.q_previous = None if q_previous is None or not len(self.pairs) \
            else np.array(q_previous, dtype=float)
        self._stale = self.q_previous is not None
        if self.q_previous is None:
            self.reference = np.zeros((len(self.pairs), 3))

    def _held(self) -> None:
        """Take :attr:`reference` of :attr:`q_previous` when it is not yet."""
        if self._stale and self.q_previous is not None:
            logs = self._logs(self.q_previous)
            self.reference = logs[:, 0] - logs[:, 1]
            self._stale = False

    def row_weights(self) -> np.ndarray:
        """Three rows per active pair: ``weight`` once a last frame is held, 0 before."""
        return super().row_weights() if self.q_previous is not None \
            else np.zeros(3 * len(self.pairs))

    def compute_error(self, configuration: Configuration) -> np.ndarray:
        """``log(R_i) - log(R_j) - d_ij`` per pair (3 pairs,) [rad]."""
        self._held()
        return super().compute_error(configuration)

    def add_objective(self, configuration: Configuration, H: np.ndarray, c: np.ndarray) -> None:
        """Accumulate the active pairs' objective (none before a last frame is held)."""
        if self.q_previous is not None:
            self._held()
            super().add_objective(configuration, H, c)
