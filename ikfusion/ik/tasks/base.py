"""Base class of IK tasks: an error and its Jacobian, turned into a quadratic objective."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import NamedTuple

import numpy as np

from ..configuration import Configuration
from ..fast_math import any_true


class Objective(NamedTuple):
    """Quadratic objective ``1/2 dq^T H dq + c^T dq`` in the tangent space.

    Attributes:
        H: Hessian (nv, nv).
        c: Linear term (nv,).
    """

    H: np.ndarray
    c: np.ndarray


class Task(ABC):
    """A residual ``e(q)`` (k,) to drive to zero, with Jacobian ``J = de/ddq`` (k, nv).

    The objective of one Gauss-Newton step is ``1/2 ||e + J dq||^2_W`` with a diagonal weight
    ``W`` from :meth:`row_weights`. Subclasses implement :meth:`compute_error` and
    :meth:`compute_jacobian`; they may override :meth:`add_objective` with a faster assembly.
    """

    @abstractmethod
    def compute_error(self, configuration: Configuration) -> np.ndarray:
        """Residual ``e`` at the configuration, shape (k,)."""

    @abstractmethod
    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:
        """Jacobian of the residual with respect to a tangent step, shape (k, nv)."""

    @abstractmethod
    def row_weights(self) -> np.ndarray:
        """Weight of each residual row, shape (k,) (zero rows are inactive)."""

    def is_active(self) -> bool:
        """False when the task has no rows with weight this frame."""
        return any_true(self.row_weights() > 0.0)

    def add_objective(self, configuration: Configuration, H: np.ndarray, c: np.ndarray) -> None:
        """Accumulate ``J^T W J`` into ``H`` and ``J^T W e`` into ``c`` (in place)."""
        if not self.is_active():
            return
        e = self.compute_error(configuration)
        J = self.compute_jacobian(configuration)
        WJ = self.row_weights()[:, None] * J
        H += J.T @ WJ
        c += WJ.T @ e

    def objective(self, configuration: Configuration) -> Objective:
        """The task's objective alone (for inspection and tests)."""
        nv = configuration.model.nv
        H, c = np.zeros((nv, nv)), np.zeros(nv)
        self.add_objective(configuration, H, c)
        return Objective(H, c)
