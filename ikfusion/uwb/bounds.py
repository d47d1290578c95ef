"""Where a tag can be: the capture area of a constellation, the floor and the ceiling.

A fix that converged far outside the capture area, under the floor or far above the readers is
not a position (it is a wrong reader file, a reader clock that jumped, a reflection that
happened to fit); :func:`outside` finds such fixes so that they are not reported ``ok``.

- Horizontally, the area is the constellation's ``area`` polygon, else the convex hull of the
  readers (x, y) (readers may hang inside the space people walk in), widened by
  :data:`MARGIN_FRACTION` of its diameter or :data:`MIN_MARGIN_M`, whichever is larger: "far
  outside" scales with the hall (people do walk a little beyond a drawn area).
- Vertically, the floor is z = 0 or the lowest reader, whichever is lower, minus
  :data:`FLOOR_MARGIN_M`; the ceiling is the highest reader plus :data:`CEILING_MARGIN_M`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .constellation import Constellation

#: Tolerance around the area as a share of its diameter.
MARGIN_FRACTION = 0.25
#: Smallest tolerance around the area [m].
MIN_MARGIN_M = 2.0
#: Tolerance below the floor [m] (a foot tag is a few centimetres above it).
FLOOR_MARGIN_M = 0.5
#: Tolerance above the highest reader [m] (a raised hand or a jump).
CEILING_MARGIN_M = 2.0


@dataclass(frozen=True)
class CaptureBounds:
    """The space a tag can be in.

    Attributes:
        polygon: Corners (x, y) of the area, shape (K, 2) [m] (K may be 1 or 2 for readers in
            a point or a line).
        margin: Tolerance around the polygon [m].
        z_min: Lowest plausible tag height [m].
        z_max: Highest plausible tag height [m].
    """

    polygon: np.ndarray
    margin: float
    z_min: float
    z_max: float


def capture_bounds(constellation: Constellation) -> CaptureBounds:
    """The bounds of a constellation (see the module docstring)."""
    p = constellation.positions
    z_min = min(0.0, float(p[:, 2].min())) - FLOOR_MARGIN_M
    z_max = float(p[:, 2].max()) + CEILING_MARGIN_M
    if constellation.area is not None:
        polygon = np.asarray(constellation.area, dtype=float)
    else:
        polygon = convex_hull(p[:, :2])
    diameter = float(np.max(np.linalg.norm(polygon[:, None] - polygon[None], axis=2)))
    return CaptureBounds(polygon, max(MIN_MARGIN_M, MARGIN_FRACTION * diameter), z_min, z_max)


def outside(p_world_tag: np.ndarray, bounds: CaptureBounds) -> tuple[np.ndarray, np.ndarray]:
    """Which points lie outside the area and which at an impossible height.

    Args:
        p_world_tag: Points, shape (T, 3) [m]; NaN rows are neither.
        bounds: The bounds.

    Returns:
        ``(outside_area, bad_height)``, each shape (T,) bool.
    """
    p = np.asarray(p_world_tag, dtype=float)
    finite = np.isfinite(p).all(axis=1)
    xy = np.where(finite[:, None], p[:, :2], 0.0)
    near = _inside(xy, bounds.polygon) | (_distance(xy, bounds.polygon) <= bounds.margin)
    z = np.where(finite, p[:, 2], 0.0)
    return finite & ~near, finite & ((z < bounds.z_min) | (z > bounds.z_max))


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points, counter-clockwise, shape (K, 2) (monotone chain)."""
    pts = np.unique(np.asarray(points, dtype=float), axis=0)
    if pts.shape[0] < 3:
        return pts

    def half(seq: np.ndarray) -> list[np.ndarray]:
        chain: list[np.ndarray] = []
        for q in seq:
            while len(chain) >= 2 and _cross(chain[-2], chain[-1], q) <= 0:
                chain.pop()
            chain.append(q)
        return chain

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _inside(xy: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule; False for every point when the polygon has fewer than 3 corners."""
    inside = np.zeros(xy.shape[0], dtype=bool)
    if polygon.shape[0] < 3:
        return inside
    x, y = xy[:, 0], xy[:, 1]
    for (x1, y1), (x2, y2) in zip(polygon, np.roll(polygon, -1, axis=0)):
        crosses = (y1 > y) != (y2 > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
        inside ^= crosses & (x < x_at)
    return inside


def _distance(xy: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance of each point to the polygon's edges (or to its corner(s)) [m]."""
    if polygon.shape[0] == 1:
        return np.linalg.norm(xy - polygon[0], axis=1)
    best = np.full(xy.shape[0], np.inf)
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0)):
        ab = b - a
        length2 = float(ab @ ab)
        s = np.clip((xy - a) @ ab / length2, 0.0, 1.0) if length2 > 0 else np.zeros(len(xy))
        best = np.minimum(best, np.linalg.norm(xy - (a + s[:, None] * ab), axis=1))
    return best
