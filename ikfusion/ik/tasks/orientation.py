"""Orientation task: segment frames follow target orientations (IMU-derived)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from ...rotations import left_jacobian_inverse, log_so3
from ..configuration import Configuration
from ..fast_math import sum_of, true_indices
from .base import Task


class OrientationTask(Task):
    """Residual ``e_i = log(R_world_frame_i @ R_world_target_i^T)`` [rad], world frame.

    One task holds several frames so the error and Jacobian are computed in one batch. Targets
    and weights change every frame through :meth:`set_targets`; a weight of zero (or a NaN
    target) switches a frame off.

    Args:
        frame_ids: Pinocchio frame indices of the tracked frames.
        names: Their names (for residual reports).
        weight: Cost weight per unit rotation [1/rad^2].
    """

    def __init__(self, frame_ids: Sequence[int], names: Sequence[str], weight: float = 1.0) -> None:
        if len(frame_ids) != len(names):
            raise ValueError("frame_ids and names must have the same length")
        self.frame_ids = list(frame_ids)
        self.names = list(names)
        self.weight = float(weight)
        self.targets = np.tile(np.eye(3), (len(self.frame_ids), 1, 1))
        self.weights = np.zeros(len(self.frame_ids))

    def set_targets(self, R_world_target: npt.ArrayLike, weights: npt.ArrayLike,
                    owned: bool = False) -> None:
        """Set targets (k, 3, 3) and per-frame weights (k,) (0 = not tracked this frame).

        With ``owned`` the caller hands over float arrays it no longer changes (they are kept
        without a copy; ``weights`` may be read-only).
        """
        R = np.asarray(R_world_target, dtype=float).reshape(-1, 3, 3)
        w = np.asarray(weights, dtype=float).reshape(-1)
        if math.isfinite(sum_of(R)):  # every target finite (one sum: the usual frame, fast)
            self.targets, self.weights = (R, w) if owned else (R.copy(), w.copy())
            return
        bad = ~np.isfinite(R).all(axis=(1, 2))
        self.targets = np.where(bad[:, None, None], np.eye(3), R)
        self.weights = np.where(bad, 0.0, w)

    def row_weights(self) -> np.ndarray:
        """Per-row weights (3 rows per frame)."""
        return np.repeat(self.weight * self.weights, 3)

    def compute_error(self, configuration: Configuration) -> np.ndarray:
        """Stacked rotation-vector errors (3k,) [rad]."""
        R = configuration.rotations(self.frame_ids)
        return log_so3(R @ np.swapaxes(self.targets, 1, 2)).reshape(-1)

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:
        """``Jl^-1(e_i) @ J_angular_i`` stacked, shape (3k, nv)."""
        e = self.compute_error(configuration).reshape(-1, 3)
        Jw = configuration.angular_jacobians(self.frame_ids)
        return (left_jacobian_inverse(e) @ Jw).reshape(-1, configuration.model.nv)

    def add_objective(self, configuration: Configuration, H: np.ndarray, c: np.ndarray) -> None:
        """Accumulate ``J^T W J`` and ``J^T W e`` over the weighted frames, errors taken once."""
        on = true_indices(self.weights > 0.0)
        if not len(on):
            return
        ids = [self.frame_ids[i] for i in on]
        R = configuration.rotations(ids)
        e = log_so3(R @ np.swapaxes(self.targets[on], 1, 2))
        J = left_jacobian_inverse(e) @ configuration.angular_jacobians(ids)
        w = self.weight * self.weights[on]
        WJ = w[:, None, None] * J
        H += np.einsum("kin,kim->nm", J, WJ)
        c += np.einsum("kin,ki->n", WJ, e)

    def errors_deg(self, configuration: Configuration) -> dict[str, float]:
        """Angle of each tracked frame's error [deg] (for reports)."""
        e = self.compute_error(configuration).reshape(-1, 3)
        angles = np.degrees(np.linalg.norm(e, axis=1))
        return {n: float(a) for n, a, w in zip(self.names, angles, self.weights) if w > 0}
