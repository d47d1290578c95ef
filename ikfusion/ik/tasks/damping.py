"""Smoothness: stay close to a reference configuration (the previous frame)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..configuration import Configuration
from ..fast_math import add_to_diagonal
from .base import Task


class DampingTask(Task):
    """Residual ``e = q ⊖ q_ref`` (tangent vector, nv) with a weight per tangent coordinate.

    The Jacobian is taken as the identity (exact at ``q = q_ref``; the task is a regulariser).

    Args:
        weights: Weight per tangent coordinate (nv,) [1/m^2 or 1/rad^2].
    """

    def __init__(self, weights: npt.ArrayLike) -> None:
        self.weights = np.asarray(weights, dtype=float).reshape(-1)
        self.q_reference: np.ndarray | None = None

    def set_reference(self, q_reference: npt.ArrayLike | None) -> None:
        """The configuration to stay close to (None switches the task off)."""
        self.q_reference = None if q_reference is None else np.asarray(q_reference, dtype=float)

    def row_weights(self) -> np.ndarray:
        """The per-coordinate weights (zero when there is no reference)."""
        return self.weights if self.q_reference is not None else np.zeros_like(self.weights)

    def compute_error(self, configuration: Configuration) -> np.ndarray:
        """``q ⊖ q_ref`` (nv,)."""
        if self.q_reference is None:
            return np.zeros(configuration.model.nv)
        return configuration.difference(self.q_reference)

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:
        """Identity (nv, nv)."""
        return np.eye(configuration.model.nv)

    def add_objective(self, configuration: Configuration, H: np.ndarray, c: np.ndarray,
                      error: np.ndarray | None = None) -> None:
        """Diagonal assembly; ``error`` is ``q ⊖ q_ref`` when the caller has it already."""
        if self.q_reference is None:
            return
        add_to_diagonal(H, self.weights)
        c += self.weights * (self.compute_error(configuration) if error is None else error)
