"""Batched linear algebra for many small symmetric systems (k <= 5 unknowns).

LAPACK through ``numpy.linalg`` pays a per-matrix overhead that dominates for 4x4 systems; a
Cholesky factorisation written column by column over the batch axis is several times faster and
reports, per matrix, whether it was safely positive definite, so one singular system never sinks
a batch.
"""

from __future__ import annotations

import numpy as np

#: Smallest accepted ratio of a Cholesky pivot to the largest diagonal entry.
RCOND = 1e-12


def cholesky_batched(a: np.ndarray, rcond: float = RCOND) -> tuple[np.ndarray, np.ndarray]:
    """Lower Cholesky factors of a batch of symmetric matrices.

    Args:
        a: Symmetric matrices, shape (T, k, k).
        rcond: A pivot below ``rcond`` times the largest diagonal entry marks the matrix as
            singular or ill-conditioned.

    Returns:
        ``(L, ok)``: factors with ``L L^T = a`` where ``ok``, shape (T, k, k); ``ok`` shape (T,).
    """
    t_count, k, _ = a.shape
    low = np.zeros_like(a, dtype=float)
    scale = np.max(np.abs(np.diagonal(a, axis1=1, axis2=2)), axis=1) if k else np.zeros(t_count)
    ok = np.isfinite(scale) & (scale > 0)
    tiny = np.where(ok, rcond * scale, 1.0)
    for j in range(k):
        d = a[:, j, j] - np.sum(low[:, j, :j] ** 2, axis=1)
        ok &= d > tiny
        pivot = np.sqrt(np.where(d > tiny, d, tiny))
        low[:, j, j] = pivot
        if j + 1 < k:
            rest = a[:, j + 1 :, j] - np.einsum("tip,tp->ti", low[:, j + 1 :, :j], low[:, j, :j])
            low[:, j + 1 :, j] = rest / pivot[:, None]
    return low, ok


def _substitute(low: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``L L^T x = b`` given the factor, b shape (T, k, r)."""
    k = low.shape[1]
    z = np.empty_like(b)
    for i in range(k):
        z[:, i] = (b[:, i] - np.einsum("tp,tpr->tr", low[:, i, :i], z[:, :i])) / low[:, i, i, None]
    x = np.empty_like(b)
    for i in range(k - 1, -1, -1):
        acc = np.einsum("tp,tpr->tr", low[:, i + 1 :, i], x[:, i + 1 :])
        x[:, i] = (z[:, i] - acc) / low[:, i, i, None]
    return x


def well_conditioned(a: np.ndarray, rcond: float = RCOND) -> np.ndarray:
    """Whether each symmetric positive semi-definite matrix is safely invertible, shape (T,)."""
    return cholesky_batched(a, rcond)[1]


def solve_batched(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve ``a x = b`` for a batch of symmetric positive definite systems.

    Args:
        a: Matrices, shape (T, k, k).
        b: Right-hand sides, shape (T, k) or (T, k, r).

    Returns:
        ``(x, ok)`` with x shaped like b; where ``ok`` is False (not positive definite, or
        ill-conditioned) x is 0.
    """
    vector = b.ndim == 2
    rhs = b[..., None] if vector else b
    low, ok = cholesky_batched(a)
    with np.errstate(all="ignore"):
        x = _substitute(low, np.where(ok[:, None, None], rhs, 0.0))
    ok &= np.all(np.isfinite(x), axis=(1, 2))
    x = np.where(ok[:, None, None], x, 0.0)
    return (x[..., 0] if vector else x), ok


def inverse_batched(a: np.ndarray, rcond: float = RCOND) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of a batch of symmetric positive definite matrices.

    Returns:
        ``(inv, ok)``: inverses, shape (T, k, k), NaN where ``ok`` is False.
    """
    t_count, k, _ = a.shape
    low, ok = cholesky_batched(a, rcond)
    eye = np.broadcast_to(np.eye(k), (t_count, k, k))
    with np.errstate(all="ignore"):
        inv = _substitute(low, np.array(eye))
    ok &= np.all(np.isfinite(inv), axis=(1, 2))
    return np.where(ok[:, None, None], inv, np.nan), ok
