"""Batched inverse Jacobians of SO(3) used to linearise rotation-vector errors.

For ``e = log(X)`` and a left perturbation ``log(exp(w) X) ~ e + Jl^-1(e) w``; for a right
perturbation ``log(X exp(w)) ~ e + Jr^-1(e) w``, with ``Jr^-1(e) = Jl^-1(-e)``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..rotations import skew


def left_jacobian_inverse(e: npt.ArrayLike) -> np.ndarray:
    """``Jl^-1(e)`` for rotation vectors ``e`` [rad], shape ``S + (3, 3)``."""
    v = np.asarray(e, dtype=float)
    theta = np.linalg.norm(v, axis=-1)[..., None, None]
    small = theta < 1e-6
    t = np.where(small, 1.0, theta)
    coeff = np.where(small, 1.0 / 12.0 + theta**2 / 720.0,
                     1.0 / t**2 - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t)))
    K = skew(v)
    return np.eye(3) - 0.5 * K + coeff * (K @ K)


def right_jacobian_inverse(e: npt.ArrayLike) -> np.ndarray:
    """``Jr^-1(e)`` for rotation vectors ``e`` [rad], shape ``S + (3, 3)``."""
    return left_jacobian_inverse(-np.asarray(e, dtype=float))
