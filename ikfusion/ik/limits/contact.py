"""Contact points: no slip while in contact, never below the floor."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from ..configuration import Configuration
from ..fast_math import any_true, row_norms, true_indices
from .base import Equality, Inequality
from .shared_segment import shared_segment_rows


class ContactConstraint:
    """Contact points in contact stay at their anchors: ``p_i(q ⊕ dq) = anchor_i`` (3 rows each).

    A point may be held horizontally only (``free_z``): a heel rising as its foot rolls onto
    the toes does not slip, but it leaves the floor gradually instead of all at once.
    Planted points that share a rigid segment (the shoulder blades of a lying body) are held
    by independent rows only (:func:`~.shared_segment.shared_segment_rows`), so that the
    constraints stay feasible.

    Args:
        frame_ids: Frame indices of the contact points.
        names: Their names (``LeftHeel``, ...).
        segments: The segment carrying each point (None: each point on its own).
    """

    def __init__(self, frame_ids: Sequence[int], names: Sequence[str],
                 segments: Sequence[str] | None = None) -> None:
        self.frame_ids = list(frame_ids)
        self.names = list(names)
        self.segments = list(self.names if segments is None else segments)
        self.active = np.zeros(len(self.frame_ids), dtype=bool)
        self.anchors = np.zeros((len(self.frame_ids), 3))
        self.free_z = np.zeros(len(self.frame_ids), dtype=bool)
        self._held = np.zeros((len(self.frame_ids), 3), dtype=bool)
        self._held_rows = np.zeros(0, dtype=int)  # flat indices of ``_held`` (k * 3 + axis)
        # (k, 3, 3) the directions held of each point, when points share a segment
        self._basis: np.ndarray | None = None
        # (active, free_z) of the rows held now when they are along the world axes
        self._world_axes_key: tuple[bytes, bytes] | None = None
        # :meth:`slides`' planted points (index, anchor x, y, z, z held), made when first asked
        self._planted: list[tuple[int, float, float, float, bool]] | None = None
        # the bytes of what :meth:`set_anchors` was last given (free_z None: b"") and made
        self._given = (b"-", b"-", b"-", b"-")

    def set_anchors(self, active: npt.ArrayLike, anchors: npt.ArrayLike,
                    free_z: npt.ArrayLike | None = None) -> None:
        """Set the points in contact.

        Args:
            active: (k,) which points are in contact.
            anchors: (k, 3) where they are held [m].
            free_z: (k,) which of them are held horizontally only.
        """
        active = np.asarray(active, dtype=bool)
        anchors = np.asarray(anchors, dtype=float).reshape(-1, 3)
        rising = None if free_z is None else np.asarray(free_z, dtype=bool)
        self._planted = None
        if self._holds(active, anchors, rising):  # the usual frame: the same points and anchors
            return
        self.active, self.anchors = active.copy(), anchors.copy()
        self.free_z = np.zeros_like(self.active) if rising is None else rising & self.active
        self._given = (self.active.tobytes(), self.anchors.tobytes(),
                       b"" if rising is None else rising.tobytes(), self.free_z.tobytes())
        key = (self.active.tobytes(), self.free_z.tobytes())
        if key == self._world_axes_key:  # the same points held along the world axes as before
            return
        shared = shared_segment_rows(self.segments, self.active, self.anchors, self.free_z)
        if shared is None:  # the usual case: the world axes
            held = np.repeat(self.active[:, None], 3, axis=1)
            held[:, 2] &= ~self.free_z
            self._basis, self._held = None, held  # (k, 3) the coordinates held, one row each
            self._world_axes_key = key
        else:
            self._basis, self._held = shared
            self._world_axes_key = None
        self._held_rows = self._held.ravel().nonzero()[0]

    def _holds(self, active: np.ndarray, anchors: np.ndarray, rising: np.ndarray | None) -> bool:
        """Whether :meth:`set_anchors` of these arrays would set what the constraint holds now.

        Bit for bit the arrays it was last given, its own arrays unchanged since (so one
        written in place is never taken for what was set).
        """
        was_active, was_anchors, was_rising, was_free_z = self._given
        return (active.tobytes() == was_active == self.active.tobytes()
                and anchors.tobytes() == was_anchors == self.anchors.tobytes()
                and (b"" if rising is None else rising.tobytes()) == was_rising
                and self.free_z.tobytes() == was_free_z)

    def _along_held(self, vectors: np.ndarray, on: np.ndarray | slice) -> np.ndarray:
        """Per point ``on``, ``vectors`` (m, 3, ...) in its held directions' frame."""
        if self._basis is None:
            return vectors
        return np.einsum("kij,kj...->ki...", self._basis[on], vectors)

    def equality(self, configuration: Configuration,
                 p_world: np.ndarray | None = None) -> Equality:
        """Linearised rows ``J_i dq = anchor_i - p_i`` for the active points.

        ``p_world`` (k, 3) [m] are every point's positions at ``configuration`` when the
        caller has them (the projection does).
        """
        nv = configuration.model.nv
        on = self.active
        if not any_true(on):
            return Equality(np.zeros((0, nv)), np.zeros(0))
        planted = [self.frame_ids[i] for i in true_indices(on)]  # Jacobians of these only
        held = self._held[on]
        J = self._along_held(configuration.linear_jacobians(planted), on)
        p_planted = configuration.positions(planted) if p_world is None else p_world[on]
        if self._basis is None:  # the usual case: world axes, rows taken by index (faster)
            rows = held.ravel().nonzero()[0]
            return Equality(J.reshape(-1, nv).take(rows, axis=0),
                            (self.anchors[on] - p_planted).reshape(-1).take(rows))
        return Equality(J[held], self._along_held(self.anchors[on] - p_planted, on)[held])

    def count(self) -> int:
        """How many rows :meth:`rows` makes (the directions held)."""
        return len(self._held_rows)

    def world_rows(self) -> np.ndarray | None:
        """The rows held among every point's coordinates (k * 3): indices; None off world axes.

        The usual case (:meth:`rows` takes them by index) unless points share a segment.
        """
        return self._held_rows if self._basis is None else None

    def rows(self, p_world: np.ndarray, J_linear: np.ndarray,
             out: Equality | None = None) -> Equality:
        """Rows from every point's position (k, 3) [m] and linear Jacobian (k, 3, nv).

        ``out``: arrays of :meth:`count` rows to write them into (a QP's buffer), returned.
        """
        if self._basis is None:  # the usual case: world axes, rows taken by index (faster)
            rows = self._held_rows
            if out is None:
                return Equality(J_linear.reshape(-1, J_linear.shape[2]).take(rows, axis=0),
                                (self.anchors - p_world).reshape(-1).take(rows))
            # mode "clip" (the rows are in range): take's "raise" would write out through a copy
            J_linear.reshape(-1, J_linear.shape[2]).take(rows, axis=0, out=out.A, mode="clip")
            (self.anchors - p_world).reshape(-1).take(rows, out=out.b, mode="clip")
            return out
        held, every = self._held, slice(None)
        made = Equality(self._along_held(J_linear, every)[held],
                        self._along_held(self.anchors - p_world, every)[held])
        if out is None:
            return made
        out.A[:], out.b[:] = made
        return out

    def planted_slide_m(self, p_world: np.ndarray) -> np.ndarray:
        """Distance of each point in contact from its anchor (active,) [m].

        The same numbers as :meth:`slide_m` without the NaN rows, from the points' positions
        (k, 3) [m], counting only the directions held (all but a rising heel's height and,
        for points sharing a segment, what the segment's shape fixes).
        """
        on = self.active
        if self._basis is None:  # the usual case: every point at once, no row selected twice
            return row_norms(np.where(self._held, p_world - self.anchors, 0.0))[on]
        d = self._along_held(p_world[on] - self.anchors[on], on)
        return row_norms(np.where(self._held[on], d, 0.0))

    def slides(self, p_world: np.ndarray, tolerance: float) -> bool:
        """Whether a planted point is further than ``tolerance`` [m] from its anchor.

        ``any(planted_slide_m(p_world) > tolerance)`` for the points' positions (k, 3) [m]:
        with the rows along the world axes (the usual case), the same differences, squares,
        sums and square roots in the same order in Python floats, cheaper than NumPy's calls
        on a frame's few planted points.
        """
        if self._basis is not None:
            return any_true(self.planted_slide_m(p_world) > tolerance)
        planted = self._planted
        if planted is None:
            anchors, free_z = self.anchors.tolist(), self.free_z.tolist()
            planted = self._planted = [(i, *anchors[i], not free_z[i])
                                       for i in true_indices(self.active).tolist()]
        rows = p_world.tolist()
        for i, ax, ay, az, z_held in planted:
            x, y, z = rows[i]
            dx, dy = x - ax, y - ay
            dz = z - az if z_held else 0.0
            if math.sqrt(dx * dx + dy * dy + dz * dz) > tolerance:
                return True
        return False

    def slide_m(self, configuration: Configuration,
                p_world: np.ndarray | None = None) -> np.ndarray:
        """Distance of each point from its anchor (k,) [m]; NaN for points not in contact.

        ``p_world`` (k, 3) [m] are the points' positions when the caller has them.
        """
        p = configuration.positions(self.frame_ids) if p_world is None else p_world
        d = p - self.anchors
        d[self.free_z, 2] = 0.0
        return np.where(self.active, np.linalg.norm(d, axis=1), np.nan)


class FloorLimit:
    """Contact points stay above the floor: ``z_i(q ⊕ dq) >= floor_z``.

    Args:
        frame_ids: Frame indices of the points.
        floor_z: Floor height [m].
    """

    def __init__(self, frame_ids: Sequence[int], floor_z: float = 0.0) -> None:
        self.frame_ids = list(frame_ids)
        self.floor_z = float(floor_z)
        self.enabled = np.ones(len(self.frame_ids), dtype=bool)
        self._z_rows: dict[bytes, np.ndarray] = {}  # enabled's bytes -> :meth:`z_rows`

    def inequality(self, configuration: Configuration) -> Inequality:
        """Rows ``-J_z dq <= z - floor_z`` for the enabled points."""
        nv = configuration.model.nv
        if not any_true(self.enabled):
            return Inequality(np.zeros((0, nv)), np.zeros(0))
        on = [f for f, e in zip(self.frame_ids, self.enabled) if e]  # no kinematics for others
        return Inequality(-configuration.linear_jacobians(on)[:, 2, :],
                          configuration.positions(on)[:, 2] - self.floor_z)

    def z_rows(self) -> np.ndarray:
        """The z rows of the enabled points among every point's coordinates (k * 3): indices.

        Kept per mask of enabled points (a frame's few contact points: a few masks recur).
        """
        key = self.enabled.tobytes()
        rows = self._z_rows.get(key)
        if rows is None:
            rows = self._z_rows[key] = true_indices(self.enabled) * 3 + 2
        return rows

    def rows(self, p_world: np.ndarray, J_linear: np.ndarray,
             out: Inequality | None = None) -> Inequality:
        """Rows from every point's position (k, 3) [m] and linear Jacobian (k, 3, nv).

        ``out``: arrays of a row per enabled point (:meth:`z_rows`) to write them into (a
        QP's buffer), returned.
        """
        rows = self.z_rows()
        if out is None:
            return Inequality(-J_linear.reshape(-1, J_linear.shape[2]).take(rows, axis=0),
                              p_world.reshape(-1).take(rows) - self.floor_z)
        G, h = out
        # mode "clip" (the rows are in range): take's "raise" would write out through a copy
        J_linear.reshape(-1, J_linear.shape[2]).take(rows, axis=0, out=G, mode="clip")
        np.negative(G, out=G)
        np.subtract(p_world.reshape(-1).take(rows, out=h, mode="clip"), self.floor_z, out=h)
        return out
