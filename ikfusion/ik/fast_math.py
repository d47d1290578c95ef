"""NumPy reductions on the solver's small arrays, the same numbers without NumPy's overhead.

Each function computes exactly what the NumPy function it names computes (the same operations
in the same order, so bit for bit the same result), skipping the argument handling that
dominates on arrays of a few rows.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np


def _c_count_nonzero() -> Callable[[np.ndarray], Any]:
    """The C function behind ``np.count_nonzero(values)`` (its Python wrapper costs 3x the count).

    It returns a NumPy integer (hence ``Any``: compiled by mypyc, an ``int`` would refuse it);
    found by a function rather than a guarded import, which mypyc cannot compile.
    """
    try:
        from numpy._core.multiarray import count_nonzero
    except ImportError:  # NumPy 1
        return np.count_nonzero
    return count_nonzero  # type: ignore[no-any-return]


_count_nonzero = _c_count_nonzero()


def row_norms(v: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row of ``v`` (n, d): ``np.linalg.norm(v, axis=1)``."""
    return np.sqrt(np.add.reduce(v * v, axis=1))


def mean_rows(v: np.ndarray) -> np.ndarray:
    """The mean of the rows of ``v`` (n, d), n >= 1: ``np.mean(v, axis=0)``."""
    return np.add.reduce(v, axis=0) / len(v)


def min_of(values: np.ndarray) -> float:
    """The smallest entry of ``values`` (NaN if any; at least one entry): ``values.min()``."""
    return float(np.minimum.reduce(values, axis=None))


def sum_of(values: np.ndarray) -> float:
    """The sum of every entry of ``values`` (NaN or inf if any): ``values.sum()``."""
    return float(np.add.reduce(values, axis=None))


def add_to_diagonal(H: np.ndarray, values: np.ndarray | float) -> None:
    """``H[i, i] += values[i]`` (or a scalar) in place on a square ``H``.

    ``H.flat[::n + 1] += values``: the same sums, through a strided view when ``H`` is
    C-contiguous (without NumPy's flat iterator).
    """
    if H.flags.c_contiguous:
        H.reshape(-1)[::H.shape[0] + 1] += values
    else:
        H.flat[::H.shape[0] + 1] += values


def count_true(values: np.ndarray) -> int:
    """How many entries of ``values`` are non-zero: ``np.count_nonzero(values)``."""
    return int(_count_nonzero(values))


def any_true(values: np.ndarray) -> bool:
    """Whether any entry of ``values`` is non-zero (True, NaN): ``bool(np.any(values))``."""
    return bool(_count_nonzero(values))


def true_indices(mask: np.ndarray) -> np.ndarray:
    """The indices of the non-zero entries of a 1-D ``mask``: ``np.flatnonzero(mask)``."""
    return mask.nonzero()[0]


def shrink(v: np.ndarray, by: float) -> np.ndarray:
    """``v`` shortened by ``by`` (never past zero)."""
    n = math.sqrt(float(v.dot(v)))  # np.linalg.norm's own formula, without its overhead
    return v * max(0.0, 1.0 - by / n) if n > 0 else v * 0.0


def clip_norm(v: np.ndarray, limit: float) -> np.ndarray:
    """``v`` shortened to at most ``limit`` long (``v - v * 0.0``, i.e. ``v + 0.0``, when not)."""
    n = math.sqrt(float(v.dot(v)))
    return v + 0.0 if n <= limit < math.inf else v - shrink(v, limit)
