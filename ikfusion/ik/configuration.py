"""A robot configuration ``q`` with its forward kinematics and frame Jacobians computed once.

Frames are addressed by Pinocchio frame index. Jacobians are ``LOCAL_WORLD_ALIGNED``: rows 0-2
map ``dq`` to the world-frame velocity of the frame origin [m], rows 3-5 to the world-frame
angular velocity [rad] (per unit tangent step).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pinocchio as pin


class Configuration:
    """Model, data and a read-only configuration; kinematics are cached per :meth:`update`.

    Args:
        model: The Pinocchio model.
        q: Configuration, size ``model.nq``.
    """

    def __init__(self, model: pin.Model, q: npt.ArrayLike) -> None:
        self.model = model
        self.data = pin.Data(model)  # (createData() builds the same, several times slower)
        self._placements: dict[int, pin.SE3] = {}
        self._jacobians: dict[int, np.ndarray] = {}
        self._points: dict[tuple[int, ...], np.ndarray] = {}
        self.update(q)

    @property
    def q(self) -> np.ndarray:
        """The configuration (a read-only view)."""
        return self._q

    def update(self, q: npt.ArrayLike) -> None:
        """Set ``q``; forward kinematics and joint Jacobians run once, when first needed."""
        self._hold(np.array(q, dtype=float))

    def step_by(self, dq: np.ndarray) -> None:
        """Move to ``q ⊕ dq`` (``dq`` (nv,) float): :meth:`update` of :meth:`integrate`.

        The same configuration bit for bit, its new array held without copying it.
        """
        self._hold(pin.integrate(self.model, self._q, dq))

    def _hold(self, qq: np.ndarray) -> None:
        """Make ``qq`` (nq,), an array no one else holds, the read-only configuration."""
        qq.setflags(write=False)
        self._q = qq
        self._kinematics_done = False
        self._placements.clear()
        self._jacobians.clear()
        self._points.clear()

    def _kinematics(self) -> None:
        if not self._kinematics_done:
            pin.computeJointJacobians(self.model, self.data, self._q)
            self._kinematics_done = True

    def placement(self, frame_id: int) -> pin.SE3:
        """``T_world_frame`` of one frame."""
        T = self._placements.get(frame_id)
        if T is None:
            self._kinematics()
            T = pin.updateFramePlacement(self.model, self.data, frame_id)
            self._placements[frame_id] = T
        return T

    def jacobian(self, frame_id: int) -> np.ndarray:
        """Frame Jacobian (6, nv), LOCAL_WORLD_ALIGNED (linear rows first)."""
        J = self._jacobians.get(frame_id)
        if J is None:
            self._kinematics()
            J = pin.getFrameJacobian(self.model, self.data, frame_id, pin.LOCAL_WORLD_ALIGNED)
            self._jacobians[frame_id] = J
        return J

    def rotations(self, frame_ids: Sequence[int]) -> np.ndarray:
        """``R_world_frame`` of several frames, shape (k, 3, 3)."""
        return np.array([self.placement(f).rotation for f in frame_ids]).reshape(-1, 3, 3)

    def positions(self, frame_ids: Sequence[int]) -> np.ndarray:
        """``p_world_frame`` [m] of several frames, shape (k, 3), read-only.

        Kept until the next :meth:`update`: the contact points are asked for several times
        per configuration (the projection, then the touch-down).
        """
        key = tuple(frame_ids)
        P = self._points.get(key)
        if P is None:
            self._kinematics()
            model, data, placements = self.model, self.data, self._placements
            rows = []
            for f in key:  # placement() inlined: called for every contact point, every frame
                T = placements.get(f)
                if T is None:
                    T = placements[f] = pin.updateFramePlacement(model, data, f)
                rows.append(T.translation)
            P = np.array(rows).reshape(-1, 3)
            P.setflags(write=False)
            self._points[key] = P
        return P

    def angular_jacobians(self, frame_ids: Sequence[int]) -> np.ndarray:
        """World angular-velocity Jacobians, shape (k, 3, nv)."""
        return np.array([self.jacobian(f)[3:] for f in frame_ids]).reshape(-1, 3, self.model.nv)

    def linear_jacobians(self, frame_ids: Sequence[int]) -> np.ndarray:
        """World linear-velocity Jacobians of frame origins, shape (k, 3, nv)."""
        return np.array([self.jacobian(f)[:3] for f in frame_ids]).reshape(-1, 3, self.model.nv)

    def integrate(self, dq: npt.ArrayLike) -> np.ndarray:
        """``q ⊕ dq`` on the configuration manifold (a new array)."""
        return pin.integrate(self.model, self._q, np.asarray(dq, dtype=float))

    def difference(self, q_from: npt.ArrayLike) -> np.ndarray:
        """Tangent vector ``q ⊖ q_from`` (from ``q_from`` to the current ``q``), size nv."""
        return pin.difference(self.model, np.asarray(q_from, dtype=float), self._q)
