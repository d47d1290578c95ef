"""Position task: frame origins (sites) follow target positions (UWB tags, markers)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from ..configuration import Configuration
from ..fast_math import any_true
from .base import Task

_IDENTITY = np.eye(3)
_IDENTITY.setflags(write=False)
_IDENTITY_1 = _IDENTITY[None]  # (1, 3, 3)


class PositionTask(Task):
    """Residual ``e_i = p_world_frame_i - p_world_target_i`` [m].

    Each frame has a 3x3 information matrix (inverse covariance [1/m^2]), so anisotropic UWB
    covariances weigh the axes correctly; :meth:`set_targets` also accepts scalar weights.
    With :attr:`reach` set, a target farther than ``reach`` pulls as if it were ``reach`` away
    (each error shortened to that length): a far target is approached at a bounded rate.

    Args:
        frame_ids: Pinocchio frame indices.
        names: Their names.
        weight: Global scale of the information matrices.
    """

    def __init__(self, frame_ids: Sequence[int], names: Sequence[str], weight: float = 1.0) -> None:
        self.frame_ids = list(frame_ids)
        self.names = list(names)
        self.weight = float(weight)
        k = len(self.frame_ids)
        self.targets = np.zeros((k, 3))
        self._scalar: np.ndarray | None = None  # the weights w when every matrix is w I
        self.information = np.zeros((k, 3, 3))  # also sets the rows' activity (setter)
        self.reach: float | None = None  # longest error one step acts on [m] (None: any)
        # :meth:`set_target`'s weight and its arrays (read-only), the same from frame to frame
        self._kept: tuple[float, np.ndarray, np.ndarray, np.ndarray] | None = None

    def set_targets(self, p_world_target: npt.ArrayLike, weights: npt.ArrayLike) -> None:
        """Targets (k, 3) [m] and weights: (k,) scalars or (k, 3, 3) information matrices."""
        p = np.asarray(p_world_target, dtype=float).reshape(-1, 3)
        w = np.asarray(weights, dtype=float)
        if w.ndim == 1 and np.isfinite(p.sum() + w.sum()):  # finite scalar weights: at once
            self.targets = p.copy()
            self._information = w[:, None, None] * _IDENTITY
            self._active = w != 0.0
            self._scalar = w.copy()
            return
        info = w[:, None, None] * np.eye(3) if w.ndim == 1 else w.reshape(-1, 3, 3)
        bad = ~np.isfinite(p).all(axis=1)
        self.targets = np.where(bad[:, None], 0.0, p)
        self.information = np.where(bad[:, None, None], 0.0, info)

    def set_target(self, p_world_target: tuple[float, float, float], weight: float) -> None:
        """The target (3,) [m] (floats) of a one-frame task, a scalar weight.

        ``set_targets([p_world_target], [weight])``, the same arrays without its conversions.
        """
        if not math.isfinite(sum(p_world_target, 0.0) + weight):
            self.set_targets([p_world_target], [weight])
            return
        self.targets = np.array([p_world_target])
        kept = self._kept
        if kept is None or kept[0] != weight or not weight:  # (a zero's sign is in the arrays)
            kept = self._kept = _weight_arrays(weight)
        _, self._information, self._active, self._scalar = kept

    @property
    def information(self) -> np.ndarray:
        """(k, 3, 3) information matrix of each frame [1/m^2] (zero: no target this frame)."""
        return self._information

    @information.setter
    def information(self, value: np.ndarray) -> None:
        info = np.asarray(value, dtype=float)
        self._information = info
        self._active = info.any(axis=(1, 2))
        # scalar weights (w I) weigh a Jacobian row by row: no 3x3 products needed
        scalar = info[:, 0, 0]
        self._scalar = scalar if np.array_equal(info, scalar[:, None, None] * np.eye(3)) \
            else None

    def scalar_weights(self) -> np.ndarray | None:
        """(k,) each frame's weight ``w`` when every information matrix is ``w I``; else None."""
        return self._scalar

    def has_targets(self) -> bool:
        """Whether any frame has a target this frame (a non-zero information matrix)."""
        return any_true(self._active)

    def row_weights(self) -> np.ndarray:
        """Diagonal of the information matrices (rows with zero are inactive)."""
        return self.weight * np.einsum("kii->ki", self.information).reshape(-1)

    def compute_error(self, configuration: Configuration) -> np.ndarray:
        """Stacked position errors (3k,) [m]."""
        return (configuration.positions(self.frame_ids) - self.targets).reshape(-1)

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:
        """Stacked linear Jacobians (3k, nv)."""
        return configuration.linear_jacobians(self.frame_ids).reshape(-1, configuration.model.nv)

    def add_objective(self, configuration: Configuration, H: np.ndarray, c: np.ndarray) -> None:
        """Accumulate ``J^T W J`` and ``J^T W e`` with the full information matrices."""
        if not self.is_active():
            return
        self.add_rows(configuration.positions(self.frame_ids),
                      configuration.linear_jacobians(self.frame_ids), H, c)

    def add_rows(self, p_world: np.ndarray, J_linear: np.ndarray, H: np.ndarray,
                 c: np.ndarray) -> None:
        """Accumulate from every frame's position (k, 3) [m] and linear Jacobian (k, 3, nv)."""
        active = self._active
        if not any_true(active):
            return
        if self._scalar is not None and self.reach is None and len(active) == 1:
            # one frame (the root), scalar weight: the same numbers without selecting rows
            WJ = (self.weight * self._scalar)[:, None, None] * J_linear
            add_products(J_linear.reshape(-1, H.shape[0]), WJ.reshape(-1, H.shape[0]),
                         (p_world - self.targets).reshape(-1), H, c)
            return
        J = J_linear[active]
        e = p_world[active] - self.targets[active]
        if self.reach is not None:  # the length over the axes the information weighs
            weighed = np.einsum("kii->ki", self.information[active]) > 0
            e = _shortened(e, weighed, self.reach)
        if self._scalar is not None:  # (weight w I) @ J to the bit: each row times weight w
            WJ = (self.weight * self._scalar[active])[:, None, None] * J
        else:
            WJ = self.weight * self.information[active] @ J
        add_products(J.reshape(-1, H.shape[0]), WJ.reshape(-1, H.shape[0]), e.reshape(-1), H, c)

    def errors_m(self, configuration: Configuration) -> dict[str, float]:
        """Distance of each active frame to its target [m]."""
        e = self.compute_error(configuration).reshape(-1, 3)
        return {n: float(np.linalg.norm(v)) for n, v, W in zip(self.names, e, self.information)
                if W.any()}


def _weight_arrays(weight: float) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """A one-frame task's ``weight`` and its arrays, read-only (shared by frames of that weight).

    Its information (1, 3, 3), activity (1,) and scalar weight (1,).
    """
    arrays = (weight * _IDENTITY_1, np.array([weight != 0.0]), np.array([weight], dtype=float))
    for a in arrays:
        a.setflags(write=False)
    return (weight, *arrays)


def _shortened(e: np.ndarray, weighed: np.ndarray, reach: float) -> np.ndarray:
    """Errors (k, 3) [m], each shortened to at most ``reach`` [m] long on its ``weighed`` axes."""
    length = np.linalg.norm(np.where(weighed, e, 0.0), axis=1)
    scale = np.minimum(1.0, reach / np.maximum(length, 1e-12))
    return np.asarray(e * scale[:, None])


def add_products(J: np.ndarray, WJ: np.ndarray, e: np.ndarray, H: np.ndarray,
                 c: np.ndarray) -> None:
    """``H += J^T WJ`` and ``c += WJ^T e`` for rows (m, nv), (m, nv) and (m,), in place.

    One dense matrix product: on the solver's few rows it is several times faster than picking
    the columns that move (index arrays cost more than the multiplications they save), and
    columns where ``J`` is zero receive exact zeros.
    """
    H += J.T @ WJ
    c += e @ WJ
