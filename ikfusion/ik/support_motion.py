"""How the support's lag, lean and swing offsets (3,) [m] move in a frame, as floats.

The arithmetic of :meth:`.support.SupportFollower.follow` on :mod:`.vec3`'s tuples, bit for bit
NumPy's, with the usual frame's shortcuts: most frames nothing lags, the lean has reached what
it wants and no swing foot is led, and a vector of zeros (of either sign) clips to ``+0.0``
whatever its limit, with no norm to work out.
"""

from __future__ import annotations

import math

import numpy as np

from . import vec3
from .vec3 import ZERO, Vec3


def _is_zero(v: Vec3) -> bool:
    """Whether every component of ``v`` is zero (+0.0 or -0.0; NaN is not)."""
    return not (v[0] or v[1] or v[2])


def shrunk_lag(lag: Vec3, by: float, allowance: float, buffer: np.ndarray) -> Vec3:
    """``clip_norm(shrink(lag, by), allowance)`` [m] (a zero lag stays zero, +0.0)."""
    if _is_zero(lag):
        return ZERO
    return vec3.clip_norm(vec3.shrink(lag, by, buffer), allowance, buffer)


def moved_toward(v: Vec3, goal: Vec3, by: float, buffer: np.ndarray) -> Vec3:
    """``v + clip_norm(goal - v, by)`` [m]: ``v`` moved toward ``goal`` by at most ``by``."""
    d = (goal[0] - v[0], goal[1] - v[1], goal[2] - v[2])
    d = ZERO if _is_zero(d) else vec3.clip_norm(d, by, buffer)  # zeros clip to +0.0
    return (v[0] + d[0], v[1] + d[1], v[2] + d[2])


def leaned(lean: Vec3, step: Vec3, lag: Vec3, wanted: KeptClip, lean_max: float, by: float,
           buffer: np.ndarray) -> Vec3:
    """The lean [m] moved by at most ``by`` toward ``wanted(lean + step - pending, lean_max)``.

    ``pending`` (3,) [m] is what the ``lag`` will still move the pelvis, ``(-lag x, -lag y, 0)``.
    No lean, step nor lag (zeros of either sign: the usual frame) is no lean (+0.0s): the
    clipped goal is +0.0s whatever ``lean_max``, so is the move toward it and the lean moved.
    """
    if _is_zero(step) and _is_zero(lag):
        if _is_zero(lean):
            return ZERO
        if wanted.reached(lean, lean_max):  # the lean has reached what it wants: it stays
            return (lean[0] + 0.0, lean[1] + 0.0, lean[2] + 0.0)
    goal = wanted((lean[0] + step[0] - -lag[0], lean[1] + step[1] - -lag[1],
                   lean[2] + step[2] - 0.0), lean_max, buffer)
    return moved_toward(lean, goal, by, buffer)


def swing_toward(swing: Vec3, goal: Vec3, by: float, moved: Vec3, buffer: np.ndarray) -> Vec3:
    """A swing offset moved toward its ``goal`` by at most ``by``, less ``moved`` [m]."""
    if _is_zero(swing) and _is_zero(goal):  # the usual swing: +0.0s, less ``moved``
        return (0.0 - moved[0], 0.0 - moved[1], 0.0 - moved[2])
    return vec3.sub(moved_toward(swing, goal, by, buffer), moved)


class KeptClip:
    """``vec3.clip_norm(v, limit)``, kept for the last ``v`` and ``limit``.

    Equal floats clip alike (a zero's sign does not reach the result: its component of the
    clipped vector is ``+0.0`` either way), so an argument equal to the last one's gives the
    last result. NaN is never equal: it is clipped again.
    """

    def __init__(self) -> None:
        self._kept: tuple[Vec3, float, Vec3] | None = None

    def reached(self, v: Vec3, limit: float) -> bool:
        """Whether the last clip was of ``v`` (finite) at ``limit`` and gave ``v`` back.

        Then :func:`leaned` of a lean ``v`` with no step nor lag is ``v + 0.0``: its goal is
        ``v`` (the zeros added to it do not change its value), so is the move toward it.
        """
        kept = self._kept
        return (kept is not None and kept[0] == v and kept[1] == limit and kept[2] == v
                and math.isfinite(v[0] + v[1] + v[2]))

    def __call__(self, v: Vec3, limit: float, buffer: np.ndarray) -> Vec3:
        """``vec3.clip_norm(v, limit, buffer)``."""
        kept = self._kept
        if kept is not None and kept[0] == v and kept[1] == limit:
            return kept[2]
        out = vec3.clip_norm(v, limit, buffer)
        self._kept = (v, limit, out)
        return out
