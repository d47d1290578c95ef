"""Reader placement: choose N mounting points that minimise the expected position error.

The objective is the 95th percentile, over a grid of the capture area at the tag height, of the
expected position sigma (``sigma * DOP``, see :mod:`ikfusion.uwb.dop`). Each candidate mounting
point contributes a fixed information matrix ``sum_g h h^T / sigma^2`` at every grid point, so a
layout's covariance at every point is one small inverse of a sum. The search:

1. greedy: add readers one at a time; while a layout has fewer readers than unknowns, pick the
   one that maximises the mean log-determinant of the (slightly regularised) information (the
   D-optimal choice), then the one that lowers the objective most;
2. local refinement: best-improvement swaps of one chosen reader for one unused candidate until
   no swap helps;
3. the same refinement started from the start layout (the user's own readers when given, else
   the naive layout evenly spaced along the border); the start's points join the candidates, so
   the search can keep any of them.

The search scores layouts on a coarse grid; the result is then chosen on the fine grid of the
DOP map (:func:`ikfusion.uwb.dop.area_points`, the grid ``ikfusion plan`` reports on) among
the start and the searched layouts. The optimiser is therefore monotone: it never returns a
layout whose reported 95th percentile is worse than its start's (ties keep the start).

Uncovered grid points make the objective infinite; to rank such layouts anyway the information
carries a weak prior (1 km on every unknown), which changes finite results by under 1e-9.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from .constellation import Constellation, make_constellation
from .dop import Mode, area_points, compute_dop, min_readers, summarize
from .geometry import evenly_spaced_on_border, perimeter_points

#: Prior standard deviation on every unknown, so every layout has a finite score [m].
_PRIOR_SIGMA = 1e3
#: Weight of the mean sigma added to the 95th percentile as a tie-breaker.
_MEAN_WEIGHT = 1e-3


@dataclass(frozen=True)
class PlacementResult:
    """Outcome of :func:`optimize_placement`.

    Every objective is the 95th-percentile expected sigma over the evaluation grid (uncovered
    points count as infinite).

    Attributes:
        chosen: Chosen reader positions, shape (N, 3) [m].
        start: The layout the search started from (the user's, or the naive one), (N, 3) [m].
        naive: The naive layout (evenly spaced along the border), shape (N, 3) [m].
        objective: Objective of the chosen layout [m]; never above ``start_objective``.
        start_objective: Objective of the start layout [m].
        naive_objective: Objective of the naive layout [m].
        candidates: The candidate mounting points searched, shape (C, 3) [m].
        evaluations: Layouts scored during the search.
        kept_start: Whether no searched layout beat the start, so the start is returned.
    """

    chosen: np.ndarray
    start: np.ndarray
    naive: np.ndarray
    objective: float
    start_objective: float
    naive_objective: float
    candidates: np.ndarray
    evaluations: int
    kept_start: bool

    @property
    def improvement(self) -> float:
        """Relative reduction of the objective against the start (0.25 = 25 % lower)."""
        if not np.isfinite(self.start_objective):
            return 1.0 if np.isfinite(self.objective) else 0.0
        return 1.0 - self.objective / self.start_objective

    def constellation(self, template: Constellation, name: str = "optimized") -> Constellation:
        """The chosen layout as a constellation with the template's range, sigma and area."""
        c = make_constellation(
            self.chosen,
            coverage=template.range,
            sigma=template.sigma,
            area=template.area,
            name=name,
        )
        return c


def border_candidates(
    area: npt.ArrayLike, *, spacing: float, heights: Sequence[float]
) -> np.ndarray:
    """Mounting points along the area border, every ``spacing`` metres, at each height.

    Returns:
        Shape (C, 3) [m].
    """
    if spacing <= 0:
        raise InputError(f"candidate spacing must be positive, got {spacing}")
    xy = perimeter_points(area, spacing)
    return np.concatenate([np.column_stack([xy, np.full(len(xy), z)]) for z in heights])


def perimeter_layout(area: npt.ArrayLike, n: int, heights: Sequence[float]) -> np.ndarray:
    """The naive layout: ``n`` readers at equal spacing along the border, heights alternating.

    Returns:
        Shape (n, 3) [m].
    """
    xy = evenly_spaced_on_border(area, n)
    z = np.array([heights[i % len(heights)] for i in range(n)], dtype=float)
    return np.column_stack([xy, z])


class _Scorer:
    """Expected-sigma objective over area points for layouts drawn from a candidate set.

    Each candidate stores, per point, the sums that make up the information matrix:
    ``A = w u u^T`` (position block), ``b = w u`` and ``s = w`` (clock terms). A layout's sums
    give the position information with the clock eliminated, ``P = A - b b^T / s`` (Schur
    complement), whose inverse trace has a closed form for 2x2 and 3x3 matrices.
    """

    def __init__(
        self,
        candidates: np.ndarray,
        points: np.ndarray,
        *,
        mode: Mode,
        clock: bool,
        sigma: float,
        coverage: float | None,
    ) -> None:
        diff = points[None, :, :] - candidates[:, None, :]
        dist = np.linalg.norm(diff, axis=2)
        self.dims = 3 if mode == "3d" else 2
        u = diff[..., : self.dims] / np.maximum(dist, 1e-12)[..., None]
        w = (dist > 1e-9) / sigma**2
        if coverage is not None:
            w = w * (dist <= coverage)
        self.clock = clock
        pairs = [(i, j) for i in range(self.dims) for j in range(i, self.dims)]
        self.pairs = pairs
        # Per candidate c and point g: unique entries of A, then b, then s.
        cols = [w * u[..., i] * u[..., j] for i, j in pairs]
        if clock:
            cols += [w * u[..., i] for i in range(self.dims)] + [w]
        self.sums = np.stack(cols, axis=-1)
        self.eps = 1.0 / _PRIOR_SIGMA**2
        self.count = 0

    def _position_info(self, total: np.ndarray) -> list[np.ndarray]:
        """Unique entries of the clock-eliminated position information."""
        n_pairs = len(self.pairs)
        entries = [total[..., i] for i in range(n_pairs)]
        if self.clock:
            b = [total[..., n_pairs + i] for i in range(self.dims)]
            s = total[..., n_pairs + self.dims] + self.eps
            entries = [e - b[i] * b[j] / s for e, (i, j) in zip(entries, self.pairs)]
        return [e + self.eps if i == j else e for e, (i, j) in zip(entries, self.pairs)]

    def sigma(self, total: np.ndarray) -> np.ndarray:
        """Expected position sigma at every point, from summed entries (..., G, n)."""
        self.count += int(np.prod(total.shape[:-2])) if total.ndim > 2 else 1
        e = self._position_info(total)
        if self.dims == 2:
            a, d, b = e
            det = a * b - d * d
            trace_num = a + b
        else:
            a, d, f_, b, g_, c = e  # pairs: xx, xy, xz, yy, yz, zz
            det = a * (b * c - g_ * g_) - d * (d * c - g_ * f_) + f_ * (d * g_ - b * f_)
            trace_num = (b * c - g_ * g_) + (a * c - f_ * f_) + (a * b - d * d)
        with np.errstate(divide="ignore", invalid="ignore"):
            var = trace_num / det
        var = np.where(np.isfinite(var) & (var > 0), var, self.dims * _PRIOR_SIGMA**2)
        return np.sqrt(np.minimum(var, self.dims * _PRIOR_SIGMA**2))

    def objective(self, sig: np.ndarray) -> np.ndarray:
        """95th percentile plus a small multiple of the mean, over the last axis."""
        return np.percentile(sig, 95, axis=-1, method="higher") + _MEAN_WEIGHT * sig.mean(-1)

    def logdet(self, total: np.ndarray) -> np.ndarray:
        """Mean over points of log det of the regularised information, over the last axis."""
        e = self._position_info(total)
        if self.dims == 2:
            a, d, b = e
            det = a * b - d * d
        else:
            a, d, f_, b, g_, c = e
            det = a * (b * c - g_ * g_) - d * (d * c - g_ * f_) + f_ * (d * g_ - b * f_)
        value = np.log(np.maximum(det, 1e-300))
        if self.clock:
            value = value + np.log(total[..., -1] + self.eps)
        return value.mean(axis=-1)

    def score(self, chosen: Sequence[int]) -> float:
        return float(self.objective(self.sigma(self.sums[list(chosen)].sum(axis=0))))


def _greedy(scorer: _Scorer, n: int, k_min: int) -> list[int]:
    chosen: list[int] = []
    total = np.zeros(scorer.sums.shape[1:])
    n_cand = scorer.sums.shape[0]
    for _ in range(n):
        free = np.array([c for c in range(n_cand) if c not in chosen])
        trial = total[None] + scorer.sums[free]
        if len(chosen) + 1 < k_min:
            pick = int(free[np.argmax(scorer.logdet(trial))])
        else:
            pick = int(free[np.argmin(scorer.objective(scorer.sigma(trial)))])
        chosen.append(pick)
        total = total + scorer.sums[pick]
    return chosen


def _refine(scorer: _Scorer, chosen: list[int], max_rounds: int) -> tuple[list[int], float]:
    chosen = list(chosen)
    best = scorer.score(chosen)
    n_cand = scorer.sums.shape[0]
    for _ in range(max_rounds):
        total = scorer.sums[chosen].sum(axis=0)
        free = np.array([c for c in range(n_cand) if c not in chosen])
        if free.size == 0:
            break
        best_swap: tuple[int, int] | None = None
        best_value = best
        for slot, current in enumerate(chosen):
            base = total - scorer.sums[current]
            values = scorer.objective(scorer.sigma(base[None] + scorer.sums[free]))
            j = int(np.argmin(values))
            if values[j] < best_value * (1 - 1e-9):
                best_value = float(values[j])
                best_swap = (slot, int(free[j]))
        if best_swap is None:
            break
        chosen[best_swap[0]] = best_swap[1]
        best = best_value
    return chosen, best


def optimize_placement(
    area: npt.ArrayLike,
    n: int,
    *,
    start: npt.ArrayLike | None = None,
    candidates: npt.ArrayLike | None = None,
    mount_heights: Sequence[float] = (0.5, 2.5),
    spacing: float = 1.0,
    height: float = 1.5,
    mode: Mode = "3d",
    clock: bool = True,
    sigma: float = 0.03,
    coverage: float | None = None,
    grid_step: float | None = None,
    eval_step: float | None = None,
    max_rounds: int = 100,
) -> PlacementResult:
    """Choose ``n`` reader positions minimising the 95th-percentile expected sigma.

    Args:
        area: Capture-area polygon, shape (K, 2) [m].
        n: Number of readers to place.
        start: The layout to improve, shape (n, 3) [m] (e.g. the user's readers); by default
            the naive layout. Its points join the candidates.
        candidates: Mounting points, shape (C, 3) [m]; by default the area border every
            ``spacing`` metres at each of ``mount_heights``.
        mount_heights: Heights of the default candidates and of the naive layout [m].
        spacing: Spacing of the default candidates along the border [m].
        height: Tag height at which the objective is evaluated [m].
        mode: ``"3d"`` or ``"2d"`` (tag height known).
        clock: Whether the transmit time is unknown.
        sigma: Range noise [m].
        coverage: Reader coverage radius [m] or None.
        grid_step: Spacing of the search grid [m]; by default 1/30 of the larger side.
        eval_step: Spacing of the grid on which the result is chosen and its objectives are
            reported [m]; by default the DOP map's (:func:`ikfusion.uwb.dop.map_step`).
        max_rounds: Maximum swap rounds of each local refinement.

    Returns:
        The chosen layout, never worse than ``start``, with the start and the naive layout.

    Raises:
        InputError: When ``n`` is below the readers needed for a fix or above the candidates,
            or ``start`` does not hold ``n`` finite positions.
    """
    poly = np.asarray(area, dtype=float)
    heights = [float(z) for z in mount_heights]
    if not heights:
        raise InputError("give at least one mounting height")
    k_min = min_readers(mode, clock)
    cand = (
        border_candidates(poly, spacing=spacing, heights=heights)
        if candidates is None
        else np.atleast_2d(np.asarray(candidates, dtype=float))
    )
    if cand.ndim != 2 or cand.shape[1] != 3:
        raise InputError(f"candidates must have shape (C, 3), got {cand.shape}")
    if n < k_min:
        raise InputError(f"{mode} positioning needs at least {k_min} readers, asked for {n}")
    naive = perimeter_layout(poly, n, heights)
    first = naive if start is None else np.atleast_2d(np.asarray(start, dtype=float))
    if first.shape != (n, 3) or not np.all(np.isfinite(first)):
        raise InputError(f"the start layout must hold {n} finite [x, y, z], got {first.shape}")
    if n > len(cand):
        raise InputError(f"cannot choose {n} readers among {len(cand)} candidate points")
    cand = _with_points(cand, first)
    size = float(np.max(poly.max(axis=0) - poly.min(axis=0)))
    step = size / 30.0 if grid_step is None else float(grid_step)
    points = area_points(poly, height, step)
    scorer = _Scorer(cand, points, mode=mode, clock=clock, sigma=sigma, coverage=coverage)
    start_idx = _snap(first, cand)
    searched = [
        _refine(scorer, _greedy(scorer, n, k_min), max_rounds)[0],
        _refine(scorer, start_idx, max_rounds)[0],
    ]
    snapped = _snap(naive, cand)
    if len(set(snapped)) == n:
        searched.append(_refine(scorer, snapped, max_rounds)[0])
    fine = area_points(poly, height, eval_step)

    def reported(layout: list[int] | np.ndarray) -> float:
        positions = cand[layout] if isinstance(layout, list) else layout
        dop = compute_dop(fine, positions, mode=mode, clock=clock, coverage=coverage, sigma=sigma)
        return summarize(dop.expected_sigma).p95

    start_value = reported(start_idx)
    best, best_value = start_idx, start_value
    for layout in searched:
        value = reported(layout)
        if value < best_value:
            best, best_value = layout, value
    return PlacementResult(
        chosen=cand[best],
        start=first,
        naive=naive,
        objective=best_value,
        start_objective=start_value,
        naive_objective=reported(naive),
        candidates=cand,
        evaluations=scorer.count,
        kept_start=best is start_idx,
    )


def _with_points(candidates: np.ndarray, extra: np.ndarray) -> np.ndarray:
    """``candidates`` followed by the rows of ``extra`` that are not already among them."""
    d = np.linalg.norm(extra[:, None, :] - candidates[None, :, :], axis=2)
    new = extra[~np.any(d < 1e-9, axis=1)]
    return np.concatenate([candidates, new]) if len(new) else candidates


def _snap(layout: np.ndarray, candidates: np.ndarray) -> list[int]:
    """Nearest candidate to each layout point."""
    d = np.linalg.norm(layout[:, None, :] - candidates[None, :, :], axis=2)
    return [int(i) for i in np.argmin(d, axis=1)]
