"""Fit a simulated motion into the readers' capture area (``ikfusion simulate --readers``).

A BVH clip keeps the coordinates its studio gave it, and a procedural walk starts at the
origin; neither knows where the readers are. Before sensors are simulated, the whole motion is
moved rigidly, ``p_world = R_z(yaw) p_clip + t``, so that its ground track (the pelvis' x, y
over time) lies inside the capture area with a margin. Everything simulated afterwards (IMUs,
UWB times of arrival, ``truth.npz``) comes from the moved motion, so it all agrees.

The search keeps a motion that already fits where it is. Otherwise it tries headings in order
of their size (0, +-10, +-20, ... deg) and, for each, positions of the track's centre on a grid
over the area; the first heading that fits wins, centred where its clearance to the border is
largest. A motion that fits nowhere is placed where most of its track is covered, and the
result says so (:attr:`AreaFit.fits`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from ..mocap.model_motion import TruthMotion, moved_configurations
from ..rotations import axis_rotation
from ..uwb.geometry import polygon_contains

#: Default clearance between the ground track and the area border [m] (a body's half width
#: and a step's reach beyond the pelvis).
DEFAULT_MARGIN = 0.5
#: Headings tried, in degrees, smallest turn first.
_YAWS_DEG = [0.0] + [s * a for a in range(10, 181, 10) for s in (1, -1) if s * a != -180]
#: Track samples scored per layout.
_TRACK_POINTS = 64
#: Grid cells across each side of the area's bounding box for the centre positions tried.
_GRID_CELLS = 24


@dataclass(frozen=True)
class AreaFit:
    """Where a motion was put in the capture area.

    Attributes:
        yaw_deg: Turn about the world z axis applied to the whole motion [deg].
        t_world_clip: Translation applied after the turn, shape (3,) [m] (z = 0).
        margin: Clearance asked between ground track and area border [m].
        inside_before: Share of the ground track inside the area before placement.
        inside_after: The same after placement.
        clearance: Smallest distance of the placed track to the border [m] (negative: outside).
        fits: Whether the placed track keeps ``margin`` from the border everywhere.
        moved: Whether the motion was moved at all.
    """

    yaw_deg: float
    t_world_clip: np.ndarray
    margin: float
    inside_before: float
    inside_after: float
    clearance: float
    fits: bool
    moved: bool

    @property
    def R_world_clip(self) -> np.ndarray:
        """The turn applied, shape (3, 3)."""
        return axis_rotation("z", np.radians(self.yaw_deg))

    def as_dict(self) -> dict[str, Any]:
        """Plain mapping for metadata (JSON)."""
        return {
            "yaw_deg": round(self.yaw_deg, 3),
            "t_world_clip_m": [round(float(v), 4) for v in self.t_world_clip],
            "margin_m": self.margin,
            "inside_before": round(self.inside_before, 4),
            "inside_after": round(self.inside_after, 4),
            "clearance_m": round(self.clearance, 4),
            "fits": self.fits,
            "moved": self.moved,
        }

    def describe(self) -> str:
        """One line for the terminal."""
        share = (
            f"{100 * self.inside_before:.0f} % -> {100 * self.inside_after:.0f} % of its "
            "ground track inside the capture area"
        )
        if not self.moved:
            return f"motion kept where it is ({share})"
        t = self.t_world_clip
        return (
            f"motion placed in the capture area: turned {self.yaw_deg:+.0f} deg, moved by "
            f"[{t[0]:.2f}, {t[1]:.2f}] m ({share})"
        )


def signed_clearance(area: npt.ArrayLike, points: npt.ArrayLike) -> np.ndarray:
    """Distance of points to the polygon's border, positive inside, negative outside [m].

    Args:
        area: Polygon corners in order, shape (K, 2) [m].
        points: Shape (..., 2) [m].

    Returns:
        Shape (...).
    """
    poly = np.asarray(area, dtype=float)
    pts = np.asarray(points, dtype=float)
    flat = pts.reshape(-1, 2)
    dist = np.full(len(flat), np.inf)
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        ab = b - a
        length2 = float(ab @ ab)
        t = np.zeros(len(flat)) if length2 == 0 else np.clip((flat - a) @ ab / length2, 0, 1)
        dist = np.minimum(dist, np.linalg.norm(flat - (a + t[:, None] * ab), axis=1))
    inside = polygon_contains(poly, flat, tol=0.0)
    return np.where(inside, dist, -dist).reshape(pts.shape[:-1])


def fit_track(
    track_xy: npt.ArrayLike, area: npt.ArrayLike, margin: float = DEFAULT_MARGIN
) -> tuple[float, np.ndarray]:
    """The turn and shift that put a ground track inside an area with a margin.

    Args:
        track_xy: Ground track, shape (N, 2) [m].
        area: Capture-area polygon, shape (K, 2) [m].
        margin: Clearance wanted to the border [m].

    Returns:
        ``(yaw, t)``: the turn about z [rad] and the shift (2,) [m] of ``p -> R(yaw) p + t``.
        A track already inside with the margin gets ``(0, 0)``.
    """
    track = np.asarray(track_xy, dtype=float)
    poly = np.asarray(area, dtype=float)
    if np.min(signed_clearance(poly, track)) >= margin:
        return 0.0, np.zeros(2)
    pick = np.unique(np.linspace(0, len(track) - 1, min(len(track), _TRACK_POINTS)).astype(int))
    centre = 0.5 * (track.min(axis=0) + track.max(axis=0))
    local = track[pick] - centre
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    # The same number of cells on both sides, so a narrow area is searched across too.
    gx = np.linspace(lo[0], hi[0], _GRID_CELLS + 1)
    gy = np.linspace(lo[1], hi[1], _GRID_CELLS + 1)
    step = max(float(np.min(hi - lo)) / _GRID_CELLS, 0.01)
    spots = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 2)
    middle = 0.5 * (lo + hi)
    best: tuple[tuple[float, float, float], float, np.ndarray] | None = None
    for yaw_deg in _YAWS_DEG:
        yaw = np.radians(yaw_deg)
        c, s = np.cos(yaw), np.sin(yaw)
        turned = local @ np.array([[c, -s], [s, c]]).T
        clear = signed_clearance(poly, spots[:, None, :] + turned[None])
        # Most track inside with the margin, then inside at all, then the largest clearance
        # (to the step of the grid), then the spot nearest the area's middle.
        keys = (
            -np.linalg.norm(spots - middle, axis=1),
            np.floor(clear.min(axis=1) / step),
            np.mean(clear >= 0, axis=1),
            np.mean(clear >= margin, axis=1),
        )
        i = int(np.lexsort(keys)[-1])
        key = (float(keys[3][i]), float(keys[2][i]), float(clear[i].min()))
        if best is None or key > best[0]:
            best = (key, yaw, spots[i])
        if key[0] == 1.0:
            break
    assert best is not None
    _, yaw, spot = best
    c, s = np.cos(yaw), np.sin(yaw)
    return yaw, spot - np.array([[c, -s], [s, c]]) @ centre


def place_in_area(
    truth: TruthMotion, area: npt.ArrayLike, margin: float = DEFAULT_MARGIN
) -> tuple[TruthMotion, AreaFit]:
    """Move a motion rigidly (turn about z, shift in x, y) into a capture area.

    Args:
        truth: The motion; its root (pelvis) x, y over time is the ground track.
        area: Capture-area polygon, shape (K, 2) [m] (world frame, metres).
        margin: Clearance wanted between the ground track and the border [m].

    Returns:
        The moved motion (``info["area_fit"]`` holds :meth:`AreaFit.as_dict`) and the fit.
    """
    poly = np.asarray(area, dtype=float)
    track = truth.q[:, :2]
    yaw, t = fit_track(track, poly, margin)
    R = axis_rotation("z", yaw)
    t3 = np.array([t[0], t[1], 0.0])
    moved = bool(yaw != 0.0 or np.any(t != 0.0))
    q = moved_configurations(truth.q, R, t3) if moved else truth.q
    before = signed_clearance(poly, track)
    after = signed_clearance(poly, q[:, :2])
    fit = AreaFit(
        yaw_deg=float(np.degrees(yaw)),
        t_world_clip=t3,
        margin=float(margin),
        inside_before=float(np.mean(before >= 0)),
        inside_after=float(np.mean(after >= 0)),
        clearance=float(after.min()),
        fits=bool(after.min() >= margin),
        moved=moved,
    )
    placed = replace(truth, q=q, info={**truth.info, "area_fit": fit.as_dict()})
    return placed, fit
