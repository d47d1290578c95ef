"""3-vectors [m] as tuples of floats: NumPy's arithmetic on (3,) arrays without its call overhead.

Each function computes what the NumPy expression it names computes, the same operations in the
same order, so bit for bit the same numbers (a sum or product of two floats is one IEEE operation
either way; NumPy's ``np.add.reduce(rows, axis=0)`` adds the rows one by one to 0.0). The
squared norm is the exception: NumPy's ``v.dot(v)`` goes through BLAS, whose kernel fuses
multiply-adds (``x * x + y * y + z * z`` differs in the last bit), so it is still NumPy's, on a
(3,) ``buffer`` its caller owns (one per instance: no buffer shared between threads).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

Vec3 = tuple[float, float, float]
ZERO: Vec3 = (0.0, 0.0, 0.0)
#: A vector whose ``|x| + |y| + |z|`` (``a``) times this is at most a limit has a computed norm
#: at most that limit, however its squares are summed (each rounding is within ``1 + 2**-53``:
#: the norm is within ``a (1 + 7 * 2**-53)``), so :func:`clip_norm` and :func:`shrink` need not
#: work it out; ``a`` above :data:`_TINY` keeps the squares out of the subnormal range
_MARGIN = 1.0 + 1e-12
_TINY = 1e-140


def add(a: Vec3, b: Vec3) -> Vec3:
    """``a + b``."""
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a: Vec3, b: Vec3) -> Vec3:
    """``a - b``."""
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def norm(v: Vec3, buffer: np.ndarray) -> float:
    """``np.linalg.norm(v)``: ``sqrt(v.dot(v))`` by NumPy's dot on ``buffer`` (3,)."""
    if not (v[0] or v[1] or v[2]):  # zeros (signed or not: their squares are +0)
        return 0.0
    buffer[0], buffer[1], buffer[2] = v
    return math.sqrt(float(buffer.dot(buffer)))


def shrink(v: Vec3, by: float, buffer: np.ndarray) -> Vec3:
    """:func:`.fast_math.shrink`: ``v`` shortened by ``by`` (never past zero)."""
    a = abs(v[0]) + abs(v[1]) + abs(v[2])
    if _TINY < a and a * _MARGIN <= by:  # surely no longer than ``by`` (see :data:`_MARGIN`)
        return (v[0] * 0.0, v[1] * 0.0, v[2] * 0.0)
    return _shortened(v, by, norm(v, buffer))


def clip_norm(v: Vec3, limit: float, buffer: np.ndarray) -> Vec3:
    """:func:`.fast_math.clip_norm`: ``v`` shortened to at most ``limit`` long."""
    a = abs(v[0]) + abs(v[1]) + abs(v[2])
    if _TINY < a and a * _MARGIN <= limit:  # surely no longer than ``limit``: no norm needed
        return (v[0] + 0.0, v[1] + 0.0, v[2] + 0.0)
    n = norm(v, buffer)
    if n <= limit < math.inf:
        return (v[0] + 0.0, v[1] + 0.0, v[2] + 0.0)
    return sub(v, _shortened(v, limit, n))


def _shortened(v: Vec3, by: float, n: float) -> Vec3:
    """How much of ``v`` (``n`` long) is left shortened by ``by``: ``v * max(0, 1 - by / n)``."""
    if n > 0:
        s = max(0.0, 1.0 - by / n)
        return (v[0] * s, v[1] * s, v[2] * s)
    return (v[0] * 0.0, v[1] * 0.0, v[2] * 0.0)


def mean_rows(a: Sequence[Sequence[float]], rows: tuple[int, ...],
              b: Sequence[Sequence[float]] | None = None) -> Vec3:
    """``np.mean(a[rows], axis=0)`` of (k, 3) rows (``(a - b)[rows]`` with ``b``).

    ``a``, ``b``: the rows as lists of floats (``array.tolist()``: one call for every row).
    ``rows``: at least one index, in increasing order.
    """
    x = y = z = 0.0
    for i in rows:
        ax, ay, az = a[i]
        if b is not None:
            bx, by, bz = b[i]
            ax, ay, az = ax - bx, ay - by, az - bz
        x, y, z = x + ax, y + ay, z + az
    n = len(rows)
    return (x / n, y / n, z / n)


def floats(value: np.ndarray | Sequence[float]) -> Vec3:
    """A (3,) array's (or any three numbers') floats, as the tuple the vectors here are."""
    x, y, z = np.asarray(value, dtype=float).tolist()
    return (x, y, z)

