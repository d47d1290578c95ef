"""Plane geometry of capture areas: polygons, their borders and regular grids over them."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.spatial import ConvexHull, QhullError


def polygon_contains(
    polygon: npt.ArrayLike, points: npt.ArrayLike, tol: float = 1e-9
) -> np.ndarray:
    """Whether points lie inside a polygon or on its border (even-odd rule).

    Args:
        polygon: Corners in order, shape (K, 2) [m].
        points: Query points, shape (N, 2) [m].
        tol: Distance to an edge counted as on the border [m].

    Returns:
        Shape (N,) bool.
    """
    poly = np.asarray(polygon, dtype=float)
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    x, y = pts[:, 0], pts[:, 1]
    inside = np.zeros(pts.shape[0], dtype=bool)
    on_edge = np.zeros(pts.shape[0], dtype=bool)
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        crosses = (a[1] > y) != (b[1] > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_cross = a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
        inside ^= crosses & (x < x_cross)
        on_edge |= _segment_distance(pts, a, b) <= tol
    return inside | on_edge


def _segment_distance(pts: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    length2 = float(ab @ ab)
    t = np.zeros(pts.shape[0]) if length2 == 0 else np.clip((pts - a) @ ab / length2, 0, 1)
    return np.linalg.norm(pts - (a + t[:, None] * ab), axis=1)


def polygon_area(polygon: npt.ArrayLike) -> float:
    """Unsigned area of a simple polygon [m^2] (shoelace formula)."""
    p = np.asarray(polygon, dtype=float)
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))


def convex_hull_polygon(points: npt.ArrayLike) -> np.ndarray:
    """Counter-clockwise convex hull of plane points, shape (K, 2); the bounding box if flat."""
    p = np.asarray(points, dtype=float)[:, :2]
    try:
        hull = ConvexHull(p)
        return p[hull.vertices]
    except (QhullError, ValueError):
        lo, hi = p.min(axis=0), p.max(axis=0)
        hi = np.where(hi - lo < 1e-6, lo + 1.0, hi)
        return np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])


def perimeter_points(polygon: npt.ArrayLike, spacing: float) -> np.ndarray:
    """Points along a closed polygon border, every corner included, about ``spacing`` apart.

    Each edge is divided into ``ceil(length / spacing)`` equal parts.

    Returns:
        Shape (N, 2) [m], in border order starting at the first corner.
    """
    poly = np.asarray(polygon, dtype=float)
    out = []
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        length = float(np.linalg.norm(b - a))
        parts = max(int(np.ceil(length / spacing - 1e-9)), 1)
        t = np.arange(parts) / parts
        out.append(a + t[:, None] * (b - a))
    return np.concatenate(out)


def evenly_spaced_on_border(polygon: npt.ArrayLike, n: int) -> np.ndarray:
    """``n`` points at equal arc length along a closed polygon border, from the first corner.

    Returns:
        Shape (n, 2) [m].
    """
    poly = np.asarray(polygon, dtype=float)
    closed = np.vstack([poly, poly[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.arange(n) * cum[-1] / n
    x = np.interp(s, cum, closed[:, 0])
    y = np.interp(s, cum, closed[:, 1])
    return np.column_stack([x, y])


def grid_over(
    polygon: npt.ArrayLike, step: float, margin: float, extra_points: npt.ArrayLike | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Regular grid covering a polygon (and optional extra points) with a margin.

    The grid is anchored at the polygon's bounding-box corner, so the area's corners and
    axis-aligned borders fall on grid points.

    Args:
        polygon: Shape (K, 2) [m].
        step: Grid spacing [m].
        margin: Extra extent on every side [m].
        extra_points: Points that must also lie inside the grid, shape (N, 2+) [m].

    Returns:
        ``(x, y)`` axes [m].
    """
    poly = np.asarray(polygon, dtype=float)
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    lo_all, hi_all = lo.copy(), hi.copy()
    if extra_points is not None:
        extra = np.asarray(extra_points, dtype=float)[:, :2]
        lo_all = np.minimum(lo_all, extra.min(axis=0))
        hi_all = np.maximum(hi_all, extra.max(axis=0))
    axes = []
    for i in range(2):
        below = int(np.ceil((lo[i] - lo_all[i] + margin) / step - 1e-9))
        above = int(np.ceil((hi_all[i] - lo[i] + margin) / step - 1e-9))
        axes.append(lo[i] + step * np.arange(-below, above + 1))
    return axes[0], axes[1]
