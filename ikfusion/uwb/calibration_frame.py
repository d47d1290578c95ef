"""Reference frames of a calibration: the gauge, rigid 2-D alignments and covariance gauges.

Times of arrival do not change when the whole scene (readers and wand) moves rigidly, nor when
every clock offset grows by a constant the transmit times give back. With the reader heights
known the free motions are a horizontal translation, a rotation about the vertical and a mirror
image (``y -> -y``, which no time of arrival can tell apart). The calibration fixes them by its
*gauge*: the origin reader at ``x = y = 0``, the axis reader on the +x axis, the origin reader's
clock offset 0, and the mirror chosen so that the reader farthest from the x axis has ``y > 0``.

Covariances depend on the gauge. The one in the gauge frame says nothing about the origin
reader (it is exact by definition); what a user needs is the error left after aligning the
result to the true (or surveyed) frame with a rigid least-squares fit on some readers. To first
order that error is ``S e`` with the *S-transformation*
``S = I - G (G_Q^T G_Q)^-1 G_Q^T E_Q``: ``G`` spans the rigid motions of all readers and the
subscript ``Q`` keeps the readers the alignment uses (all of them: the minimum-trace, "inner"
gauge). :func:`alignment_projector` builds ``S``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..errors import InputError


@dataclass(frozen=True)
class Rigid2D:
    """A horizontal rigid transform ``p' = R p + t`` (``z`` unchanged).

    Attributes:
        rotation: ``R``, shape (2, 2); a mirror has determinant -1.
        translation: ``t``, shape (2,) [m].
    """

    rotation: np.ndarray
    translation: np.ndarray

    @staticmethod
    def identity() -> Rigid2D:
        """The transform that changes nothing."""
        return Rigid2D(np.eye(2), np.zeros(2))

    @property
    def mirrored(self) -> bool:
        """Whether the transform flips handedness."""
        return bool(np.linalg.det(self.rotation) < 0)

    def apply(self, points: npt.ArrayLike) -> np.ndarray:
        """Transform points, shape (N, 2) or (N, 3) [m] (``z`` is kept)."""
        p = np.array(points, dtype=float)
        p[..., :2] = p[..., :2] @ self.rotation.T + self.translation
        return p


def fit_rigid_2d(
    source: npt.ArrayLike,
    target: npt.ArrayLike,
    *,
    weights: npt.ArrayLike | None = None,
    allow_mirror: bool = False,
) -> Rigid2D:
    """Least-squares rigid transform taking ``source`` onto ``target`` (Kabsch in the plane).

    Args:
        source: Points, shape (N, 2+) [m] (only x, y are used).
        target: Points, shape (N, 2+) [m].
        weights: Weights per point, shape (N,); equal by default.
        allow_mirror: Also consider transforms that flip handedness, and keep the better fit.

    Returns:
        The transform (exact for N = 2 up to the distance mismatch).

    Raises:
        ValueError: With fewer than 2 points or mismatched shapes.
    """
    a = np.asarray(source, dtype=float)[:, :2]
    b = np.asarray(target, dtype=float)[:, :2]
    if a.shape != b.shape or a.shape[0] < 2:
        raise ValueError("a rigid 2-D fit needs at least 2 matching points")
    w = np.ones(a.shape[0]) if weights is None else np.asarray(weights, dtype=float)
    w = w / w.sum()
    ca, cb = w @ a, w @ b
    cov = (b - cb).T @ ((a - ca) * w[:, None])
    u, _, vt = np.linalg.svd(cov)
    sign = 1.0 if np.linalg.det(u @ vt) >= 0 else -1.0
    candidates = []
    for det in (1.0, -1.0) if allow_mirror else (1.0,):
        r = u @ np.diag([1.0, det * sign]) @ vt  # det(r) = det
        candidates.append(Rigid2D(r, cb - r @ ca))
    errors = [float(w @ np.sum((t.apply(a) - b) ** 2, axis=1)) for t in candidates]
    return candidates[int(np.argmin(errors))]


def gauge_transform(p_xy: npt.ArrayLike, origin: int, axis: int) -> Rigid2D:
    """The transform into the gauge frame (see the module docstring).

    Args:
        p_xy: Horizontal reader positions, shape (M, 2) [m].
        origin: Index of the reader put at the origin.
        axis: Index of the reader put on the +x axis.

    Raises:
        ValueError: When the two readers coincide horizontally.
    """
    p = np.asarray(p_xy, dtype=float)[:, :2]
    direction = p[axis] - p[origin]
    length = float(np.hypot(*direction))
    if length < 1e-6:
        raise ValueError("origin and axis readers coincide horizontally")
    c, s = direction / length
    rot = np.array([[c, s], [-s, c]])
    moved = (p - p[origin]) @ rot.T
    far = int(np.nanargmax(np.abs(moved[:, 1])))
    if moved[far, 1] < 0:
        rot = np.diag([1.0, -1.0]) @ rot
    return Rigid2D(rot, -rot @ p[origin])


def rigid_motions(p_xy: npt.ArrayLike) -> np.ndarray:
    """Basis of the horizontal rigid motions of M points, shape (2 M, 3).

    Columns: translation in x, translation in y, rotation about the centroid (per point
    ``(-y, x)``), in the interleaved order ``x_1, y_1, x_2, ...``.
    """
    p = np.asarray(p_xy, dtype=float)[:, :2]
    q = p - p.mean(axis=0)
    m = p.shape[0]
    g = np.zeros((2 * m, 3))
    g[0::2, 0] = 1.0
    g[1::2, 1] = 1.0
    g[0::2, 2] = -q[:, 1]
    g[1::2, 2] = q[:, 0]
    return g


def alignment_projector(p_xy: npt.ArrayLike, aligned: Sequence[int] | None = None) -> np.ndarray:
    """S-transformation of horizontal position errors to "after a rigid fit on some readers".

    Args:
        p_xy: Horizontal reader positions, shape (M, 2) [m].
        aligned: Readers the rigid fit uses (all by default: the minimum-trace gauge); at
            least 2.

    Returns:
        ``S``, shape (2 M, 2 M), acting on interleaved ``(x_1, y_1, x_2, ...)`` errors.
    """
    p = np.asarray(p_xy, dtype=float)[:, :2]
    m = p.shape[0]
    g = rigid_motions(p)
    keep = np.arange(m) if aligned is None else np.asarray(aligned, dtype=np.int64)
    rows = np.concatenate([2 * keep, 2 * keep + 1])
    g_q = g[rows]
    select = np.zeros((rows.size, 2 * m))
    select[np.arange(rows.size), rows] = 1.0
    return np.eye(2 * m) - g @ np.linalg.solve(g_q.T @ g_q, g_q.T @ select)


@dataclass(frozen=True)
class SurveyAlignment:
    """A rigid horizontal fit of calibrated readers onto surveyed positions.

    Attributes:
        transform: Takes calibrated positions into the surveyed frame.
        readers: Indices of the surveyed readers.
        rms: RMS horizontal misfit of the surveyed readers after the fit [m].
        description: One line saying how the frame is defined.
        warnings: Things the user should check (heights that disagree, a possible mirror).
    """

    transform: Rigid2D
    readers: list[int]
    rms: float
    description: str
    warnings: list[str]


def align_to_survey(
    ids: Sequence[str],
    p_world_readers: np.ndarray,
    points: Mapping[str, np.ndarray],
    source: Path | None = None,
) -> SurveyAlignment:
    """Fit calibrated readers onto 2 or 3 (or more) surveyed reader positions.

    With 3 or more points spread out (not on a line), a mirror image is corrected too; with 2 a
    warning says that the mirror image cannot be told apart.

    Args:
        ids: Reader ids, M of them.
        p_world_readers: Calibrated positions, shape (M, 3) [m].
        points: Surveyed positions ``{reader id: [x, y, z]}`` [m] in the user frame.
        source: The survey file (named in errors).

    Raises:
        InputError: For an unknown reader id or fewer than 2 points.
    """
    unknown = [rid for rid in points if rid not in ids]
    if unknown:
        raise InputError(
            f"surveyed reader(s) {', '.join(unknown)} are not readers ({', '.join(ids)})",
            path=source,
            field=f"points.{unknown[0]}",
        )
    if len(points) < 2:
        raise InputError(
            "a survey needs at least 2 reader positions to fix the horizontal frame",
            path=source,
            field="points",
        )
    idx = [list(ids).index(rid) for rid in points]
    target = np.array([points[ids[j]] for j in idx])
    src = p_world_readers[idx]
    spread = target[:, :2] - target[:, :2].mean(axis=0)
    mirror_ok = len(idx) >= 3 and np.linalg.svd(spread, compute_uv=False)[-1] > 0.5
    transform = fit_rigid_2d(src, target, allow_mirror=mirror_ok)
    misfit = transform.apply(src)[:, :2] - target[:, :2]
    rms = float(np.sqrt(np.mean(np.sum(misfit**2, axis=1))))
    warnings = [
        f"surveyed height of {ids[j]} differs from the heights file by {100 * d:.0f} cm"
        for j, d in zip(idx, np.abs(p_world_readers[idx, 2] - target[:, 2]))
        if d > 0.05
    ]
    if not mirror_ok:
        far = int(np.argmax(np.abs(p_world_readers[:, 1])))
        warnings.append(
            "times of arrival cannot tell the layout from its mirror image and "
            f"{len(idx)} surveyed points (not spread out) cannot either: check that reader "
            f"{ids[far]} is on the correct side, or survey a third reader away from the line"
        )
    names = ", ".join(ids[j] for j in idx)
    mirrored = " (mirror image corrected)" if transform.mirrored else ""
    text = f"survey: rigid horizontal fit on {names}, RMS {1000 * rms:.1f} mm{mirrored}"
    return SurveyAlignment(transform, idx, rms, text, warnings)
