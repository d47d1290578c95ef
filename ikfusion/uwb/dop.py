"""Dilution of precision (DOP) of a reader constellation, at points and as maps.

For a tag at ``p`` and the readers that hear it, the linearised TOA model has one row per
reader, ``h_m = [u_m, 1]`` with ``u_m = (p - p_world_reader_m) / ||p - p_world_reader_m||``
(the unit line of sight; only its x, y part in 2-D mode, where the tag height is known) and a
1 for the unknown transmit time (dropped when the clock is known, e.g. two-way ranges). With
``Q = (H^T H)^-1``::

    PDOP = sqrt(Q_xx + Q_yy + Q_zz),  HDOP = sqrt(Q_xx + Q_yy),  VDOP = sqrt(Q_zz),
    TDOP = sqrt(Q_tt),

and, for independent range noise sigma, the position error has RMS ``sigma * DOP`` (PDOP in
3-D, HDOP in 2-D). Readers farther than the coverage radius do not count; with fewer readers
than unknowns (4 in 3-D with clock, 3 in 2-D with clock) there is no value (NaN).

Reader positions known only to within a covariance ``C_m`` (from calibration) add, to first
order, ``u_m^T C_m u_m`` to the variance of range m; the expected position sigma is then
``sqrt(trace_pos((H^T W H)^-1))`` with ``W = diag(1 / (sigma^2 + u_m^T C_m u_m))``. A joint
covariance of all readers, shape (3M, 3M) (a calibration's posterior, whose readers' errors are
correlated), gives the full range-error covariance ``Sigma = sigma^2 I + U C U^T`` (``U`` holds
the ``u_m^T`` block-diagonally) and ``W = Sigma^-1``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from .constellation import Constellation
from .geometry import convex_hull_polygon, grid_over, polygon_area, polygon_contains
from .linalg import inverse_batched

Mode = Literal["3d", "2d"]

#: Expected sigma under which a point counts as well covered in summaries [m].
GOOD_SIGMA = 0.05


@dataclass(frozen=True)
class Dop:
    """DOP values at G points (NaN where the point has no fix).

    Attributes:
        position: The DOP of the solved position: PDOP in 3-D, HDOP in 2-D, shape (G,).
        hdop: Horizontal DOP, shape (G,).
        vdop: Vertical DOP, shape (G,) (NaN in 2-D).
        tdop: Transmit-time DOP, shape (G,) (NaN without clock).
        n_readers: Readers in coverage, shape (G,).
        expected_sigma: Expected RMS position error, shape (G,) [m]: ``sigma * position``,
            plus reader-position uncertainty when given.
    """

    position: np.ndarray
    hdop: np.ndarray
    vdop: np.ndarray
    tdop: np.ndarray
    n_readers: np.ndarray
    expected_sigma: np.ndarray


def min_readers(mode: Mode, clock: bool = True) -> int:
    """Readers needed for a fix: unknowns of the mode (3 or 2 coordinates, plus the clock)."""
    return (3 if mode == "3d" else 2) + int(clock)


def information_rows(
    p_world_points: np.ndarray,
    p_world_readers: np.ndarray,
    *,
    mode: Mode,
    clock: bool,
    coverage: float | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows ``h_m`` of the geometry matrix per point and reader, with the coverage mask.

    Returns:
        ``(h, in_range, u)``: shape (G, M, k), (G, M) bool and the unit lines of sight
        (G, M, 3).
    """
    diff = p_world_points[:, None, :] - p_world_readers[None, :, :]
    dist = np.linalg.norm(diff, axis=2)
    u = diff / np.maximum(dist, 1e-12)[..., None]
    in_range = dist > 1e-9
    if coverage is not None:
        in_range &= dist <= coverage
    dims = 3 if mode == "3d" else 2
    k = dims + int(clock)
    h = np.empty(dist.shape + (k,))
    h[..., :dims] = u[..., :dims]
    if clock:
        h[..., dims] = 1.0
    return h, in_range, u


def compute_dop(
    p_world_points: npt.ArrayLike,
    p_world_readers: npt.ArrayLike,
    *,
    mode: Mode = "3d",
    clock: bool = True,
    coverage: float | None = None,
    sigma: float = 0.03,
    reader_covariances: npt.ArrayLike | None = None,
) -> Dop:
    """DOP and expected position sigma at points.

    Args:
        p_world_points: Tag positions, shape (G, 3) [m] (in 2-D mode their z is the known
            tag height).
        p_world_readers: Reader positions, shape (M, 3) [m].
        mode: ``"3d"`` (x, y, z unknown) or ``"2d"`` (height known).
        clock: Whether the transmit time is unknown (TOA) or known (two-way ranges).
        coverage: Coverage radius [m]; readers farther away do not count. None: unlimited.
        sigma: Range noise [m].
        reader_covariances: Reader position covariances [m^2]: one per reader, shape
            (M, 3, 3), or the joint covariance of all readers, shape (3M, 3M) (order x1, y1,
            z1, x2, ...), or None.

    Returns:
        The DOP values.

    Raises:
        InputError: On a wrong mode or shapes.
    """
    if mode not in ("3d", "2d"):
        raise InputError(f"mode must be '3d' or '2d', got {mode!r}")
    pts = np.atleast_2d(np.asarray(p_world_points, dtype=float))
    readers = np.atleast_2d(np.asarray(p_world_readers, dtype=float))
    if pts.shape[-1] != 3 or readers.shape[-1] != 3:
        raise InputError("points and readers must have shape (N, 3)")
    h, in_range, u = information_rows(pts, readers, mode=mode, clock=clock, coverage=coverage)
    w = in_range.astype(float)
    q, ok = _covariance(h, w)
    n = in_range.sum(axis=1)
    ok &= n >= min_readers(mode, clock)
    dims = 3 if mode == "3d" else 2
    diag = np.where(ok[:, None], np.diagonal(q, axis1=1, axis2=2), np.nan)
    hdop = np.sqrt(diag[:, 0] + diag[:, 1])
    vdop = np.sqrt(diag[:, 2]) if dims == 3 else np.full(len(pts), np.nan)
    tdop = np.sqrt(diag[:, dims]) if clock else np.full(len(pts), np.nan)
    position = np.sqrt(np.sum(diag[:, :dims], axis=1))
    if reader_covariances is None:
        expected = sigma * position
    else:
        cov = np.asarray(reader_covariances, dtype=float)
        m = readers.shape[0]
        if cov.shape == (3 * m, 3 * m):
            qw, okw = _correlated_covariance(h, in_range, u, cov, sigma)
        elif cov.shape == (m, 3, 3):
            extra = np.einsum("gmi,mij,gmj->gm", u, cov, u)
            qw, okw = _covariance(h, in_range / (sigma**2 + extra))
        else:
            raise InputError(
                f"reader covariances must have shape ({m}, 3, 3) or ({3 * m}, {3 * m})"
            )
        okw &= ok
        expected = np.where(
            okw, np.sqrt(np.sum(np.diagonal(qw, axis1=1, axis2=2)[:, :dims], axis=1)), np.nan
        )
    return Dop(
        position=position,
        hdop=hdop,
        vdop=vdop,
        tdop=tdop,
        n_readers=n,
        expected_sigma=expected,
    )


def constellation_dop(
    constellation: Constellation,
    p_world_points: npt.ArrayLike,
    *,
    mode: Mode = "3d",
    clock: bool = True,
    use_reader_covariance: bool = True,
    reader_covariances: npt.ArrayLike | None = None,
) -> Dop:
    """:func:`compute_dop` with the constellation's readers, coverage, sigma and covariances.

    ``reader_covariances`` (shape (M, 3, 3) or (3M, 3M) [m^2], e.g. a calibration's joint
    posterior) replaces the constellation's per-reader covariances when given.
    """
    if reader_covariances is None and use_reader_covariance:
        reader_covariances = constellation.position_covariances
    return compute_dop(
        p_world_points,
        constellation.positions,
        mode=mode,
        clock=clock,
        coverage=constellation.range,
        sigma=constellation.sigma,
        reader_covariances=reader_covariances if use_reader_covariance else None,
    )


def _correlated_covariance(
    h: np.ndarray, in_range: np.ndarray, u: np.ndarray, joint: np.ndarray, sigma: float
) -> tuple[np.ndarray, np.ndarray]:
    """``(H^T Sigma^-1 H)^-1`` per point, shape (G, k, k), and whether it exists.

    ``Sigma = sigma^2 I + U C U^T`` over the readers in range (see the module docstring).
    """
    m = u.shape[1]
    blocks = joint.reshape(m, 3, m, 3)
    ranges = sigma**2 * np.eye(m) + np.einsum("gmi,minj,gnj->gmn", u, blocks, u)
    pair = in_range[:, :, None] & in_range[:, None, :]
    ranges = np.where(pair, ranges, 0.0) + np.where(in_range, 0.0, 1.0)[:, :, None] * np.eye(m)
    h_in = np.where(in_range[..., None], h, 0.0)
    weighted = np.linalg.solve(ranges, h_in)
    return inverse_batched(np.einsum("gmi,gmj->gij", h_in, weighted))


def _covariance(h: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(H^T W H)^-1`` per point, shape (G, k, k), and whether it exists."""
    normal = np.einsum("gmi,gm,gmj->gij", h, w, h)
    return inverse_batched(normal)


@dataclass(frozen=True)
class PlanSummary:
    """Expected position sigma over the points of a capture area.

    Uncovered points (no fix possible) count as infinitely bad, so a percentile that reaches
    them is infinite.

    Attributes:
        median: Median expected sigma [m].
        p95: 95th percentile [m].
        max: Maximum [m].
        fraction_under_5cm: Fraction of area points with expected sigma under 5 cm.
        covered_fraction: Fraction of area points with a fix at all.
        points: Number of grid points inside the area.
    """

    median: float
    p95: float
    max: float
    fraction_under_5cm: float
    covered_fraction: float
    points: int

    def as_dict(self, unit: Literal["m", "cm"] = "cm") -> dict[str, float | int | None]:
        """Plain mapping for JSON (non-finite values become None)."""
        scale = 100.0 if unit == "cm" else 1.0

        def num(v: float) -> float | None:
            return round(v * scale, 4) if np.isfinite(v) else None

        return {
            f"median_{unit}": num(self.median),
            f"p95_{unit}": num(self.p95),
            f"max_{unit}": num(self.max),
            "fraction_under_5cm": round(self.fraction_under_5cm, 4),
            "covered_fraction": round(self.covered_fraction, 4),
            "points": self.points,
        }


def summarize(expected_sigma: np.ndarray) -> PlanSummary:
    """Summary statistics of expected sigmas at area points (NaN = no fix)."""
    s = np.where(np.isfinite(expected_sigma), expected_sigma, np.inf).ravel()
    if s.size == 0:
        raise InputError("the capture area contains no grid point; use a smaller --step")
    return PlanSummary(
        median=float(np.percentile(s, 50, method="higher")),
        p95=float(np.percentile(s, 95, method="higher")),
        max=float(np.max(s)),
        fraction_under_5cm=float(np.mean(s < GOOD_SIGMA)),
        covered_fraction=float(np.mean(np.isfinite(s))),
        points=int(s.size),
    )


@dataclass(frozen=True)
class DopMap:
    """DOP over a horizontal grid at one tag height.

    Attributes:
        x: Grid x coordinates, shape (nx,) [m].
        y: Grid y coordinates, shape (ny,) [m].
        height: Tag height of the plane [m].
        mode: ``"3d"`` or ``"2d"``.
        clock: Whether the transmit time was unknown.
        dop: Values at the grid points, each array of shape (ny, nx).
        inside: Grid points inside the capture area, shape (ny, nx).
        area: The capture-area polygon used, shape (K, 2) [m].
    """

    x: np.ndarray
    y: np.ndarray
    height: float
    mode: Mode
    clock: bool
    dop: Dop
    inside: np.ndarray
    area: np.ndarray

    @property
    def expected_sigma(self) -> np.ndarray:
        """Expected position sigma, shape (ny, nx) [m]."""
        return self.dop.expected_sigma

    def summary(self) -> PlanSummary:
        """Statistics of the expected sigma inside the capture area."""
        return summarize(self.expected_sigma[self.inside])


def capture_area(constellation: Constellation) -> np.ndarray:
    """The constellation's area polygon, or the convex hull of its readers when it has none."""
    if constellation.area is not None:
        return constellation.area
    return convex_hull_polygon(constellation.positions[:, :2])


def map_step(area: npt.ArrayLike, step: float | None = None) -> float:
    """Grid spacing of a DOP map over ``area``: ``step``, or about 10 000 points (>= 5 cm) [m].

    Raises:
        InputError: When ``step`` is not positive.
    """
    poly = np.asarray(area, dtype=float)
    value = max(np.sqrt(polygon_area(poly) / 1e4), 0.05) if step is None else float(step)
    if not value > 0:
        raise InputError(f"grid step must be positive, got {value}")
    return value


def area_points(area: npt.ArrayLike, height: float, step: float | None = None) -> np.ndarray:
    """The grid points inside ``area`` at which :func:`dop_map` summarises, shape (G, 3) [m].

    The grid is anchored at the area's bounding-box corner with spacing :func:`map_step`, so
    these are exactly the map's inside points whatever the readers' positions.
    """
    poly = np.asarray(area, dtype=float)
    step = map_step(poly, step)
    size = float(np.max(poly.max(axis=0) - poly.min(axis=0)))
    gx, gy = grid_over(poly, step, 0.0)
    mx, my = np.meshgrid(gx, gy)
    xy = np.column_stack([mx.ravel(), my.ravel()])
    xy = xy[polygon_contains(poly, xy, tol=1e-6 * max(size, 1.0))]
    return np.column_stack([xy, np.full(len(xy), float(height))])


def dop_map(
    constellation: Constellation,
    *,
    height: float = 1.5,
    mode: Mode = "3d",
    clock: bool = True,
    step: float | None = None,
    margin: float | None = None,
    use_reader_covariance: bool = True,
    reader_covariances: npt.ArrayLike | None = None,
) -> DopMap:
    """DOP over a grid covering the capture area and the readers, at one tag height.

    Args:
        constellation: Readers, coverage, sigma, area (the readers' convex hull if absent).
        height: Tag height [m].
        mode: ``"3d"`` or ``"2d"`` (height known).
        clock: Whether the transmit time is unknown.
        step: Grid spacing [m]; by default about 10 000 points over the area (at least 5 cm).
        margin: Extent around area and readers [m]; by default 5 % of the larger side.
        use_reader_covariance: Propagate the readers' position covariances when present.
        reader_covariances: Reader covariances replacing the constellation's, shape (M, 3, 3)
            or the joint (3M, 3M) [m^2] (see :func:`compute_dop`).

    Returns:
        The map.
    """
    area = capture_area(constellation)
    size = float(np.max(area.max(axis=0) - area.min(axis=0)))
    step = map_step(area, step)
    margin = 0.05 * size if margin is None else float(margin)
    x, y = grid_over(area, step, margin, constellation.positions)
    if x.size * y.size > 4_000_000:
        raise InputError(f"grid of {x.size} x {y.size} points is too fine; use a larger --step")
    gx, gy = np.meshgrid(x, y)
    pts = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, height)])
    dop = constellation_dop(
        constellation,
        pts,
        mode=mode,
        clock=clock,
        use_reader_covariance=use_reader_covariance,
        reader_covariances=reader_covariances,
    )
    shape = gx.shape
    shaped = Dop(**{name: getattr(dop, name).reshape(shape) for name in dop.__dataclass_fields__})
    inside = polygon_contains(area, pts[:, :2], tol=1e-6 * max(size, 1.0)).reshape(shape)
    return DopMap(
        x=x, y=y, height=height, mode=mode, clock=clock, dop=shaped, inside=inside, area=area
    )
