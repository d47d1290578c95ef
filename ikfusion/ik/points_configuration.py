"""A :class:`Configuration` whose contact points come from one compiled call per configuration.

The projection onto the contacts, the touch-down and the floor ask for the contact points'
positions and linear Jacobians several times per frame. Pinocchio answers one point per Python
call (about 1 us each, 14 points); the compiled points function (:mod:`.compiled_points`)
answers all of them at once, and its answer is kept until the next :meth:`update`. The numbers
are Pinocchio's to rounding (the tests compare them).
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .configuration import Configuration
from .native import BoundFunction


class PointsConfiguration(Configuration):
    """:class:`Configuration` with the points of ``points_function`` from one call per ``q``.

    Args:
        model: The Pinocchio model.
        q: Configuration, size ``model.nq``.
        frame_ids: The frames of ``points_function`` (its output rows, in order).
        points_function: ``(q, geometry) -> (p_points (3n) [m], J_points (3n, nv))``
            (:func:`.compiled_points.points_function`).
        geometry: Its geometry input (:meth:`.compiled.CompiledKinematics.geometry`).
    """

    def __init__(self, model: pin.Model, q: npt.ArrayLike, frame_ids: Sequence[int],
                 points_function: ca.Function, geometry: np.ndarray) -> None:
        self._row = {f: i for i, f in enumerate(frame_ids)}
        self._all = tuple(frame_ids)
        #: The points function and its buffers (:mod:`.contact_projection` evaluates it too)
        self.points_function = points_function
        self._call = BoundFunction(points_function)
        self._call.set_input(1, geometry)  # kept: each call writes q only
        self._q_input = self._call.input_slot(0)
        # the positions' output buffer as (n, 3) when dense (None: scattered per read)
        self._P_buffer = self._call.output(0).reshape(-1, 3) if self._call.is_dense(0) else None
        self._P: np.ndarray | None = None
        self._J: np.ndarray | None = None
        super().__init__(model, q)

    def _hold(self, qq: np.ndarray) -> None:
        """A new configuration (:meth:`update`, :meth:`step_by`): points computed when asked."""
        super()._hold(qq)
        self._P = self._J = None

    @property
    def point_frames(self) -> tuple[int, ...]:
        """The frames of the points function (its output rows, in order)."""
        return self._all

    @property
    def points_call(self) -> BoundFunction:
        """The points function's buffers: input 0 ``q``, 1 the geometry; outputs P, J."""
        return self._call

    def set_evaluated(self, q: np.ndarray) -> None:
        """Set ``q`` where the points function's output buffers were just evaluated.

        For a caller that ran the function itself (:mod:`.contact_projection`): the points
        are read from the buffers instead of evaluated again.
        """
        super().update(q)
        self.points_evaluated()

    def points_evaluated(self) -> None:
        """The points function's output buffers were just evaluated at this very ``q``.

        The points are read from them (a caller's evaluation, :mod:`.contact_projection`, that
        did not move ``q``: every other cached answer stays valid).
        """
        self._P, self._J = self._read_positions(), None

    def _read_positions(self) -> np.ndarray:
        """The points' positions (n, 3) [m] in the output buffer: a read-only copy."""
        buffer = self._P_buffer
        P = (self._call.output(0).reshape(-1, 3) if buffer is None else buffer).copy()
        P.setflags(write=False)
        return P

    def _point_positions(self) -> np.ndarray:
        """Every point's ``p_world_point`` (n, 3) [m], read-only."""
        if self._P is None:
            self._q_input[:] = self._q
            self._call.run()
            self._J = None  # scattered from this evaluation when asked for
            self._P = self._read_positions()
        return self._P

    def _point_jacobians(self) -> np.ndarray:
        """Every point's world linear-velocity Jacobian (n, 3, nv), a view of the output buffer.

        Only :meth:`_point_positions` evaluates, once per :meth:`update`: the buffer holds this
        configuration's Jacobians until the next one (callers get copies by row selection).
        """
        if self._J is None:
            self._point_positions()
            self._J = self._call.output(1).reshape(-1, 3, self.model.nv)
        return self._J

    def _rows(self, frame_ids: Sequence[int]) -> list[int] | None:
        """The rows of ``frame_ids`` among the points, None when one is not a point."""
        rows = [self._row.get(f) for f in frame_ids]
        return None if None in rows else rows  # type: ignore[return-value]

    def positions(self, frame_ids: Sequence[int]) -> np.ndarray:
        """``p_world_frame`` [m] of several frames, shape (k, 3), read-only."""
        if tuple(frame_ids) == self._all:
            return self._point_positions()
        rows = self._rows(frame_ids)
        if rows is None:
            return super().positions(frame_ids)
        P = self._point_positions()[rows]
        P.setflags(write=False)
        return P

    def linear_jacobians(self, frame_ids: Sequence[int]) -> np.ndarray:
        """World linear-velocity Jacobians of frame origins, shape (k, 3, nv).

        Those of every point, in order, are a read-only view of the output buffer, valid until
        the next :meth:`update` (the projection takes its rows at once); others a copy.
        """
        if tuple(frame_ids) == self._all:
            J = self._point_jacobians()[:]
            J.setflags(write=False)
            return J
        rows = self._rows(frame_ids)
        if rows is None:
            return super().linear_jacobians(frame_ids)
        return self._point_jacobians()[rows]
