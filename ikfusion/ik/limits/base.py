"""Linear constraints on a Gauss-Newton step ``dq`` (tangent space)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Inequality(NamedTuple):
    """``G dq <= h`` with G (m, nv), h (m,)."""

    G: np.ndarray
    h: np.ndarray


class Equality(NamedTuple):
    """``A dq = b`` with A (m, nv), b (m,)."""

    A: np.ndarray
    b: np.ndarray


def empty_inequality(nv: int) -> Inequality:
    """No rows."""
    return Inequality(np.zeros((0, nv)), np.zeros(0))


def empty_equality(nv: int) -> Equality:
    """No rows."""
    return Equality(np.zeros((0, nv)), np.zeros(0))
