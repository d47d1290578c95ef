"""Ranges of motion of ball joints as linearised limits on their anatomical angles.

No peer library limits spherical joints; without it arms bend backwards. Each joint's
anatomical angles ``a = (a1, a2, a3)`` (intrinsic Euler sequence with signs, see
``configs/joints.yaml``) relate to the joint's tangent step ``w`` (the child-frame rotation
vector Pinocchio uses for spherical joints) through ``w = E(a) da``, with

    E = [R3^T R2^T s1 e1,  R3^T s2 e2,  s3 e3],   Ri = R(ei, si ai),

so the linearised limits are ``lower - a <= E^-1 w <= upper - a``. ``E`` is singular where the
middle angle reaches +-90 deg (gimbal lock): the first and third angles of a joint exactly there
make no rows, their rates are not finite (only their sum or difference is defined). A middle
range reaching +-90 deg (a body file's ``rot: [-90, 90]`` for a shoulder) walls off no cone
around the lock.

A pose beyond its range (the warm start at the sensed pose of an athlete, or of noisy sensors
near a limit) is measured on the Euler triple that the smallest turn of the joint brings into
the range (:func:`~ikfusion.model.angle_continuity.nearest_to_ranges`), so it is pulled back to
the limit it crossed: not thrown to the opposite corner across the +-180 deg wrap of the
principal decomposition, nor through gimbal lock onto the other Euler branch.

The limits are hard unless ``overshoot_deg`` is set (solver settings
``joint_range_overshoot_deg``, ``joint_range_settle_s``): then a joint that arrives at a limit
at speed, its targets pulling past it, may sink past it a little and is eased back into the
range (:mod:`.soft_wall`) instead of stopping dead while the true joint still turns.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ...errors import ConfigError
from ...model.angle_continuity import nearest_to_ranges
from ...model.ball_joints import BallJoint
from ...rotations import exp_so3, quat_wxyz_to_matrix, xyzw_to_wxyz
from ..configuration import Configuration
from ..fast_math import any_true
from .base import Inequality
from .soft_wall import SoftWall

_UNIT = np.eye(3)
_STEEPEST = 1e8  # an angle's rate [rad/rad] beyond this (or not finite): a joint at the lock


class JointRangeLimit:
    """Anatomical range-of-motion limits of every ball joint.

    Args:
        joints: ``HumanModel.ball_joints``.
        margin_deg: Only angles within this distance of a limit produce rows (the others
            cannot reach it in one step); keeps the QP small.
        overshoot_deg: How far past a limit a joint that arrives at speed may sink [deg]
            (:mod:`.soft_wall`, fed by :meth:`next_frame`); 0: hard limits.
        settle_s: The time constant of that soft wall [s].

    Raises:
        ConfigError: A negative ``overshoot_deg`` or a ``settle_s`` not above 0.
    """

    def __init__(self, joints: Mapping[str, BallJoint], margin_deg: float,
                 overshoot_deg: float = 0.0, settle_s: float = 0.08) -> None:
        if overshoot_deg < 0.0:
            raise ConfigError(f"expected a depth >= 0 [deg], found {overshoot_deg!r}",
                              field="joint_range_overshoot_deg")
        if settle_s <= 0.0:
            raise ConfigError(f"expected a time constant > 0 [s], found {settle_s!r}",
                              field="joint_range_settle_s")
        specs = [j.spec for j in joints.values()]
        self.names = list(joints)
        self.idx_q = np.array([j.idx_q for j in joints.values()])
        self.idx_v = np.array([j.idx_v for j in joints.values()])
        axis_index = {"x": 0, "y": 1, "z": 2}
        self.axes = np.array([[axis_index[a.axis] for a in s.angles] for s in specs])
        self.signs = np.array([[a.sign for a in s.angles] for s in specs], dtype=float)
        self.lower = np.radians([[a.lower_deg for a in s.angles] for s in specs])
        self.upper = np.radians([[a.upper_deg for a in s.angles] for s in specs])
        self.lower.setflags(write=False)  # fixed (read-only: a compiled step keeps them)
        self.upper.setflags(write=False)
        i, j = self.axes[:, 0], self.axes[:, 1]
        self.parity = np.where((j - i) % 3 == 1, 1.0, -1.0)
        self.coupling = np.array([s.axis_coupling for s in specs])
        self.margin = np.radians(margin_deg)
        self.wall = SoftWall(self.lower, self.upper, float(np.radians(overshoot_deg)), settle_s)
        self._linearised: tuple[np.ndarray, np.ndarray] | None = None  # angles, G
        self._solved: np.ndarray | None = None  # (joints, 3) [rad] where this frame stands
        self._q_cols = self.idx_q[:, None] + np.arange(4)
        n = len(self.idx_v)  # where each E^-1 entry goes in the rows of all angles
        self._rows = np.repeat(np.arange(3 * n), 3)
        self._cols = (self.idx_v[:, None, None] + np.zeros((1, 3, 1), dtype=int)
                      + np.arange(3)).reshape(-1)

    def angles(self, q: np.ndarray) -> np.ndarray:
        """Anatomical angles (joints, 3) [rad] in sequence order (principal decomposition)."""
        R = quat_wxyz_to_matrix(xyzw_to_wxyz(np.asarray(q)[self._q_cols]))
        n = np.arange(len(R))
        i, j, k = self.axes[:, 0], self.axes[:, 1], self.axes[:, 2]
        p = self.parity
        middle = np.arcsin(np.clip(p * R[n, i, k], -1.0, 1.0))
        first = np.arctan2(-p * R[n, j, k], R[n, k, k])
        last = np.arctan2(-p * R[n, i, j], R[n, i, i])
        return np.stack([first, middle, last], axis=1) * self.signs

    def next_frame(self, dt: float | None) -> None:
        """A new frame, ``dt`` [s] after the last one solved (None: the first frame).

        The soft wall takes the angles the last frame was solved at (:meth:`took_step`) and
        gives each angle its room past its limits from them and the frame before (hard limits
        until two frames are known).
        """
        if dt is None:
            self.wall.reset()
        elif self._solved is not None:
            self.wall.update(self._solved, dt)
        self._solved = None

    def softened(self, ranges: LinearisedRanges,
                 still: np.ndarray | None = None) -> LinearisedRanges:
        """``ranges`` (hard) widened by the soft wall's room past each limit (:meth:`next_frame`).

        The angles they were linearised at are kept as where the frame stands until
        :meth:`took_step`. An angle measured on another triple than the previous frame's (the
        other Euler branch, a wrap) keeps its hard limits. ``still``: the mask of the rows of
        ``G`` that are all zeros when the caller has it
        (:meth:`LinearisedRanges.without_still_angles`).
        """
        room = self.wall_room(ranges.G, ranges.room_up)
        if room is not None:  # both limits' rooms at once
            ranges = LinearisedRanges(ranges.G, ranges.rooms + room.reshape(ranges.rooms.shape))
        return ranges.without_still_angles(still)

    def wall_room(self, G: np.ndarray, room_up: np.ndarray) -> np.ndarray | None:
        """The soft wall's room (2, joints, 3) [rad] of ranges ``G``, ``room_up`` (hard); None.

        What :meth:`softened` adds to the rooms; keeps the angles as where the frame stands.
        """
        a = self.upper - room_up.reshape(self.upper.shape)
        if self.wall.enabled:
            self._linearised = (a, G)
            self._solved = a
        return self.wall.room(a)

    def took_step(self, dq: np.ndarray) -> None:
        """Take the step ``dq`` (nv,) made from the last linearisation (:meth:`softened`).

        The frame's angles move by their rates, to first order (no kinematics per frame).
        """
        if self._linearised is not None:
            a, G = self._linearised
            self._solved = a + (G @ dq).reshape(a.shape)

    def rate_matrices(self, angles: np.ndarray) -> np.ndarray:
        """``E^-1`` per joint (joints, 3, 3): anatomical angle rates from the tangent step."""
        e = _UNIT[self.axes] * self.signs[:, :, None]  # (n, 3, 3): row m = s_m * e_m
        R2 = exp_so3(e[:, 1] * angles[:, 1:2])
        R3 = exp_so3(e[:, 2] * angles[:, 2:3])
        R3t = np.swapaxes(R3, 1, 2)
        col1 = R3t @ np.swapaxes(R2, 1, 2) @ e[:, 0, :, None]
        col2 = R3t @ e[:, 1, :, None]
        E = np.concatenate([col1, col2, e[:, 2, :, None]], axis=2)
        with np.errstate(all="ignore"):
            E_inv = np.linalg.inv(E)
        return finite_rates(E_inv)

    def violation_deg(self, q: np.ndarray) -> np.ndarray:
        """How far each angle lies outside its range (joints, 3) [deg], 0 inside."""
        a, _ = nearest_to_ranges(self.angles(q), self.lower, self.upper, self.coupling)
        return np.degrees(np.maximum(self.lower - a, 0.0) + np.maximum(a - self.upper, 0.0))

    def inequality(self, configuration: Configuration) -> Inequality:
        """Rows ``G dq <= h`` for the angles near or beyond a limit."""
        a = self.angles(configuration.q)
        linear = self.softened(self.linearise(a, None, configuration.model.nv))
        return linear.inequality(*linear.near(self.margin))

    def rows(self, angles: np.ndarray, rate_matrices: np.ndarray | None, nv: int) -> Inequality:
        """Rows ``G dq <= h`` for the angles (joints, 3) [rad] within the margin of a limit.

        ``rate_matrices`` (``E^-1``, joints x 3 x 3) are computed when not given.
        """
        linear = self.linearise(angles, rate_matrices, nv).without_still_angles()
        return linear.inequality(*linear.near(self.margin))

    def linearise(self, angles: np.ndarray, rate_matrices: np.ndarray | None,
                  nv: int) -> LinearisedRanges:
        """Every angle's rate per tangent step and its room to both limits.

        ``angles`` may be any Euler triple per joint (e.g. the principal one); each is measured
        on its triple closest to the range, whose middle rate row changes sign on the other
        branch.
        """
        a, flipped = nearest_to_ranges(angles, self.lower, self.upper, self.coupling)
        Einv = self.rate_matrices(angles) if rate_matrices is None else rate_matrices
        if any_true(flipped):
            Einv = Einv.copy()
            Einv[flipped, 1, :] *= -1.0
        G = np.zeros((a.size, nv))  # row 3j + m: angle m of joint j per unit tangent step
        G[self._rows, self._cols] = Einv.reshape(-1)
        rooms = np.stack((self.upper - a, a - self.lower)).reshape(2, -1)
        return LinearisedRanges(G, rooms)


def finite_rates(E_inv: np.ndarray) -> np.ndarray:
    """``E_inv`` (joints, 3, 3) with the rows of the angles of a joint at gimbal lock set to 0.

    Such a row holds a rate beyond any real one (or not finite): the angle is not defined there
    (only the sum or difference of the first and third is).
    """
    with np.errstate(invalid="ignore"):
        steep = ~np.all(np.abs(E_inv) < _STEEPEST, axis=2, keepdims=True)
    return np.where(steep, 0.0, E_inv)


class LinearisedRanges:
    """The ranges of motion linearised at one configuration.

    Attributes:
        G: (angles, nv) rate of each anatomical angle per unit tangent step.
        rooms: (2, angles) ``room_up`` then ``room_down``, one array (both limits' rows
            selected with one comparison and one ``compress``).
        room_up: (angles,) ``upper - a`` [rad] (negative beyond the limit), a view of ``rooms``.
        room_down: (angles,) ``a - lower`` [rad], a view of ``rooms``.
    """

    def __init__(self, G: np.ndarray, rooms: np.ndarray) -> None:
        """The ranges of ``G`` and the rooms (2, angles) [rad] (``rooms`` kept, not copied)."""
        self.G, self.rooms = G, rooms
        self.room_up, self.room_down = rooms[0], rooms[1]  # (indexed: faster than unpacked)

    def without_still_angles(self, still: np.ndarray | None = None) -> LinearisedRanges:
        """These ranges with endless room (no rows) for the angles whose rates are all 0.

        Those are the first and third angles of a joint at gimbal lock (:func:`finite_rates`),
        which no step could bring back (a row ``0 <= room`` past a limit is infeasible).
        ``still`` is the mask of those rows when the caller has it (else found here).
        """
        if still is None:
            still = ~np.any(self.G, axis=1)
        if not any_true(still):
            return self
        return LinearisedRanges(self.G, np.where(still, np.inf, self.rooms))

    def near(self, margin: float) -> np.ndarray:
        """Masks (2, angles) of the angles within ``margin`` [rad] of their limits.

        Row 0: the upper limits, row 1: the lower ones (views of one array).
        """
        return self.rooms < margin

    def inequality(self, up: np.ndarray, down: np.ndarray) -> Inequality:
        """Rows ``G dq <= h`` for the upper limits in ``up`` and the lower ones in ``down``."""
        return Inequality(np.concatenate([self.G[up], -self.G[down]]),
                          np.concatenate([self.room_up[up], self.room_down[down]]))

    def crossed(self, dq: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
        """Masks of the limits (upper, lower) that the step ``dq`` would cross."""
        rate = self.G.dot(dq)  # BLAS's gemv as G @ dq, without matmul's dispatch
        return rate > self.room_up + tolerance, -rate > self.room_down + tolerance
