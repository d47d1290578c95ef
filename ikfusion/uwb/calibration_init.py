"""First estimate of reader positions and clock offsets from reader-to-reader transmissions.

The calibration tag inside reader ``j`` transmits at unknown times ``tau_k``; reader ``m`` hears
it at ``toa_km = tau_k + d_jm + b_m + nlos + noise`` with ``d_jm = ||p_j - p_m||`` and ``b_m``
the clock offset of reader ``m`` [m]. Differencing receptions of one transmission removes
``tau_k``, so each tag ``j`` yields the row ``A_jm = d_jm + b_m + c_j`` up to a constant ``c_j``
of its own (:func:`reader_table`, a robust median polish of the (transmission x reader) table).

When reader ``j`` also reports its own tag (``d_jj = 0``, so ``A_jj = b_j + c_j``), the pair
difference ``D_jm = A_jm - A_jj = d_jm + b_m - b_j`` and the two directions give the distance
``(D_jm + D_mj) / 2`` and the clock difference ``(D_jm - D_mj) / 2``: classical MDS of the
horizontal distances at the known heights (missing pairs completed by shortest paths) gives a
start (:func:`distance_start`).

Without own receptions the two directions do *not* give the distance: with ``g = b - c`` from
the antisymmetric part (``A_jm - A_mj = g_m - g_j``), the symmetric part is
``(A_jm + A_mj + g_j + g_m) / 2 = d_jm + beta_j + beta_m`` with an unknown term ``beta`` per
reader (its clock offset up to a constant common to all). Distances and ``beta`` then separate
only through geometry: ``L`` linked pairs must exceed the ``3 M - 3`` unknowns (horizontal
positions and ``beta``), so every reader must hear most of the others (with all pairs linked:
redundant from 7 readers on, square with 6, short with 5).

:func:`fit_reader_geometry` solves ``A_jm = ||p_j - p_m|| + b_m + c_j`` (own receptions
included, with zero distance) by variable projection: the clock terms are linear and
eliminated exactly for given positions, and Levenberg-Marquardt runs on the horizontal
positions alone, from the MDS start when there is one, then from random starts until several
starts agree on the best cost. :func:`resect_readers` places readers the table cannot (too few
partners) from the wand: it is positioning with the roles swapped (the wand fixes are the
"readers", the reader is the "tag" at its known height and its clock offset is the "transmit
time"), solved by :func:`~ikfusion.uwb.locate.locate`.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse.csgraph import shortest_path

from .calibration_frame import gauge_transform
from .constellation import make_constellation
from .locate import locate

#: Starts of the geometry fit that must reach the best cost before the search stops.
_AGREEING_STARTS = 3
#: Relative cost difference under which two starts count as the same minimum.
_SAME_COST = 1e-2
#: Function evaluations of one Levenberg-Marquardt run.
_MAX_NFEV = 300


@dataclass(frozen=True)
class ReaderTable:
    """Robust per-pair values of the reader-to-reader transmissions.

    Attributes:
        offset: ``A[j, m] = d_jm + b_m + c_j`` [m] for tag ``j`` heard by reader ``m``, shape
            (M, M); NaN where reader ``m`` never heard ``j``'s tag; the diagonal holds
            ``b_j + c_j`` when readers report their own tags.
        count: Receptions behind each value, shape (M, M).
        transmissions: Reader-tag transmissions per tag, shape (M,).
    """

    offset: np.ndarray
    count: np.ndarray
    transmissions: np.ndarray

    def own(self, min_count: int = 3) -> np.ndarray:
        """Readers that report their own calibration tag, shape (M,) bool."""
        return np.diagonal(self.count) >= min_count


def _linked(table: ReaderTable, min_count: int) -> np.ndarray:
    linked = (table.count >= min_count) | (table.count.T >= min_count)
    np.fill_diagonal(linked, False)
    return linked


@dataclass(frozen=True)
class ReaderGeometry:
    """Horizontal reader positions and clock offsets fitted to a :class:`ReaderTable`.

    Attributes:
        p_xy: Horizontal positions, shape (M, 2) [m]; NaN for readers not placed. The frame has
            the first placed reader at the origin and the second on the +x axis.
        clock_offsets: Clock offsets relative to the first placed reader, shape (M,) [m]; NaN
            for readers not placed.
        placed: Readers the table places, shape (M,) bool.
        rms: Weighted RMS of the fit over the table values [m].
        determined: Whether the table determines the placed readers (Jacobian of full rank);
            False with 5 or 6 readers, when only the wand can decide.
        starts: Random starts used.
    """

    p_xy: np.ndarray
    clock_offsets: np.ndarray
    placed: np.ndarray
    rms: float
    determined: bool
    starts: int


def reader_table(
    toa: np.ndarray, emitter: np.ndarray, *, min_receptions: int = 2, iterations: int = 20
) -> ReaderTable:
    """Median polish of every reader tag's (transmission x reader) table of times of arrival.

    For tag ``j`` the model ``toa_km = t_k + A_jm`` (``t_k`` absorbs the transmit time) is fitted
    by alternating medians over transmissions and readers, which late (NLOS) receptions barely
    move as long as they are a minority.

    Args:
        toa: Times of arrival of reader-tag transmissions, shape (T, M) [m], NaN where not
            heard (a reader's reception of its own tag is kept: ``A_jj = b_j + c_j``).
        emitter: Reader index of the tag of each transmission, shape (T,).
        min_receptions: Transmissions heard by fewer readers are skipped.
        iterations: Largest number of polish sweeps.

    Returns:
        The table.
    """
    z_all = np.asarray(toa, dtype=float)
    m_count = z_all.shape[1]
    offset = np.full((m_count, m_count), np.nan)
    count = np.zeros((m_count, m_count), dtype=np.int64)
    sent = np.zeros(m_count, dtype=np.int64)
    for j in range(m_count):
        z = z_all[emitter == j]
        z = z[np.isfinite(z).sum(axis=1) >= min_receptions]
        sent[j] = z.shape[0]
        if z.shape[0] == 0:
            continue
        heard = np.isfinite(z)
        cols = np.flatnonzero(heard.any(axis=0))
        z = z[:, cols] - np.nanmin(z, axis=1, keepdims=True)
        t = np.nanmedian(z, axis=1)
        a = np.zeros(cols.size)
        for _ in range(iterations):
            a_new = np.nanmedian(z - t[:, None], axis=0)
            t = np.nanmedian(z - a_new[None, :], axis=1)
            done = np.max(np.abs(a_new - a)) < 1e-7
            a = a_new
            if done:
                break
        offset[j, cols] = a
        count[j, cols] = heard[:, cols].sum(axis=0)
    return ReaderTable(offset=offset, count=count, transmissions=sent)


def placeable(table: ReaderTable, *, min_count: int = 3, min_partners: int = 3) -> np.ndarray:
    """Readers the table can place: linked with at least ``min_partners`` other such readers.

    Readers with fewer links are removed repeatedly (removing one can strand another).

    Returns:
        Shape (M,) bool.
    """
    linked = _linked(table, min_count)
    keep: np.ndarray = np.asarray(linked.any(axis=1))
    while True:
        partners = (linked & keep[None, :]).sum(axis=1)
        new = keep & (partners >= min_partners)
        if np.array_equal(new, keep):
            return keep
        keep = new


def fit_reader_geometry(
    table: ReaderTable,
    heights: np.ndarray,
    rng: np.random.Generator,
    *,
    placed: np.ndarray | None = None,
    anchors: Sequence[int] | None = None,
    start_xy: np.ndarray | None = None,
    min_count: int = 3,
    max_starts: int = 20,
) -> ReaderGeometry:
    """Fit ``A_jm = ||p_j - p_m|| + b_m + c_j`` for horizontal positions and clock terms.

    Args:
        table: The reader-to-reader table.
        heights: Reader heights, shape (M,) [m].
        rng: Random generator for the starts.
        placed: Readers to fit (default :func:`placeable`).
        anchors: Two placed readers fixing the frame (origin, +x axis); default: the first
            two placed readers.
        start_xy: Approximate horizontal positions, shape (M, 2) [m], in any frame: the fit
            then runs once from them instead of from the MDS and random starts.
        min_count: Table values from fewer receptions are not used.
        max_starts: Largest number of random starts.

    Returns:
        The fitted geometry (all NaN, ``determined=False`` when fewer than 3 readers can be
        placed).
    """
    m_count = heights.shape[0]
    keep = placeable(table, min_count=min_count) if placed is None else np.asarray(placed)
    idx = np.flatnonzero(keep)
    nan_out = ReaderGeometry(
        p_xy=np.full((m_count, 2), np.nan),
        clock_offsets=np.full(m_count, np.nan),
        placed=np.zeros(m_count, dtype=bool),
        rms=float("nan"),
        determined=False,
        starts=0,
    )
    if idx.size < 3:
        return nan_out
    a0, a1 = (int(idx[0]), int(idx[1])) if anchors is None else (anchors[0], anchors[1])
    problem = _GeometryProblem(table, heights, idx, (a0, a1), min_count)
    best, best_cost, agree, starts = None, np.inf, 0, 0
    scale = problem.scale()
    given = start_xy is not None
    if start_xy is None:
        start_xy = distance_start(table, heights, keep, min_count=min_count)
    first = None if start_xy is None else _start_vector(problem, start_xy, (a0, a1), rng)
    for starts in range(1, (1 if given else max_starts) + 1):
        use_first = starts == 1 and first is not None
        x0 = first if use_first else rng.uniform(-scale, scale, problem.n_free)
        sol = least_squares(
            problem.residual, x0, jac=problem.jacobian, method="lm", max_nfev=_MAX_NFEV
        )
        if sol.cost < best_cost * (1.0 - _SAME_COST):
            best, best_cost, agree = sol, sol.cost, 1
        elif sol.cost <= best_cost * (1.0 + _SAME_COST) + 1e-12:
            agree += 1
        if agree >= _AGREEING_STARTS:
            break
    if best is None:  # pragma: no cover - least_squares always returns a solution
        return nan_out
    p_xy = problem.positions(best.x)
    clocks = problem.clock_offsets(p_xy)
    jac = problem.jacobian(best.x)
    sv = np.linalg.svd(jac, compute_uv=False) if jac.size else np.zeros(1)
    determined = bool(jac.shape[0] > jac.shape[1] and sv[-1] > 1e-6 * sv[0])
    out_xy = np.full((m_count, 2), np.nan)
    out_b = np.full(m_count, np.nan)
    out_xy[idx] = p_xy[idx]
    out_b[idx] = clocks[idx]
    mask = np.zeros(m_count, dtype=bool)
    mask[idx] = True
    return ReaderGeometry(
        p_xy=out_xy,
        clock_offsets=out_b,
        placed=mask,
        rms=float(np.sqrt(2.0 * best.cost / problem.weight_sum)),
        determined=determined,
        starts=starts,
    )


def _start_vector(
    problem: _GeometryProblem,
    start_xy: np.ndarray,
    anchors: tuple[int, int],
    rng: np.random.Generator,
) -> np.ndarray:
    """The free unknowns of a start given as positions in any frame (NaN rows: random)."""
    start = np.array(start_xy, dtype=float)[:, :2]
    known = np.all(np.isfinite(start), axis=1)
    if known[anchors[0]] and known[anchors[1]]:
        start[known] = gauge_transform(start[known], *_local(known, anchors)).apply(start[known])
    lo, hi = np.nanmin(start, axis=0), np.nanmax(start, axis=0)
    start[~known] = rng.uniform(lo, hi, (int(np.count_nonzero(~known)), 2))
    return start.ravel()[problem.free]


def _local(mask: np.ndarray, anchors: tuple[int, int]) -> tuple[int, int]:
    """Indices of two readers within the subset ``mask``."""
    position = np.cumsum(mask) - 1
    return int(position[anchors[0]]), int(position[anchors[1]])


def distance_start(
    table: ReaderTable, heights: np.ndarray, placed: np.ndarray, *, min_count: int = 3
) -> np.ndarray | None:
    """Horizontal positions by classical MDS of the distances own receptions give.

    ``d_jm = (D_jm + D_mj) / 2`` with ``D_jm = A_jm - A_jj`` for pairs heard both ways by
    readers that hear their own tags; horizontal distances ``sqrt(d^2 - dz^2)``; pairs not
    linked get the shortest path through linked ones (an upper bound, corrected by the fit
    that follows).

    Returns:
        Shape (M, 2) [m] (NaN for readers left out), or None when fewer than 3 placed readers
        report their own tag or their links are not connected.
    """
    own = table.own(min_count) & placed
    idx = np.flatnonzero(own)
    if idx.size < 3:
        return None
    a = table.offset[np.ix_(idx, idx)]
    n = table.count[np.ix_(idx, idx)]
    diff = a - np.diagonal(a)[:, None]  # D_jm = d_jm + b_m - b_j
    both = (n >= min_count) & (n.T >= min_count)
    np.fill_diagonal(both, False)
    dist = 0.5 * (diff + diff.T)
    dz = heights[idx][:, None] - heights[idx][None, :]
    horizontal = np.sqrt(np.clip(np.where(both, dist, 0.0) ** 2 - dz**2, 0.0, None))
    graph = np.where(both, np.maximum(horizontal, 1e-6), 0.0)
    full = shortest_path(graph, method="D", directed=False)
    if not np.all(np.isfinite(full)):
        return None
    centred = -0.5 * _double_centre(full**2)
    values, vectors = np.linalg.eigh(centred)
    top = np.argsort(values)[::-1][:2]
    xy = vectors[:, top] * np.sqrt(np.clip(values[top], 0.0, None))
    out = np.full((heights.shape[0], 2), np.nan)
    out[idx] = xy
    return out


def _double_centre(matrix: np.ndarray) -> np.ndarray:
    return matrix - matrix.mean(axis=0) - matrix.mean(axis=1)[:, None] + matrix.mean()


class _GeometryProblem:
    """Variable projection of the reader-table model onto the horizontal positions."""

    def __init__(
        self,
        table: ReaderTable,
        heights: np.ndarray,
        idx: np.ndarray,
        anchors: tuple[int, int],
        min_count: int,
    ) -> None:
        m_count = heights.shape[0]
        inside = np.zeros(m_count, dtype=bool)
        inside[idx] = True
        use = (table.count >= min_count) & inside[:, None] & inside[None, :]
        use &= np.isfinite(table.offset)
        self.j, self.m = np.nonzero(use)
        self.w = np.sqrt(table.count[self.j, self.m].astype(float))
        self.weight_sum = float(np.sum(self.w**2))
        self.a = table.offset[self.j, self.m]
        self.z = heights
        self.m_count = m_count
        self.origin = anchors[0]
        # Clock terms b_m (all but the origin's) and c_j, one column each.
        n = self.j.size
        b_cols = [k for k in idx if k != self.origin]
        c_tags = np.unique(self.j)
        design = np.zeros((n, len(b_cols) + c_tags.size))
        b_col = {k: i for i, k in enumerate(b_cols)}
        for r, (jj, mm) in enumerate(zip(self.j, self.m)):
            if mm in b_col:
                design[r, b_col[mm]] = 1.0
            design[r, len(b_cols) + int(np.searchsorted(c_tags, jj))] = 1.0
        self.b_cols = np.array(b_cols, dtype=np.int64)
        self.design = design
        weighted = design * self.w[:, None]
        u, s, _ = np.linalg.svd(weighted, full_matrices=False)
        basis = u[:, s > 1e-9 * max(s.max(initial=0.0), 1.0)]
        self.projector = np.eye(n) - basis @ basis.T
        free = np.zeros((m_count, 2), dtype=bool)
        free[idx] = True
        free[anchors[0]] = False
        free[anchors[1], 1] = False
        self.free = np.flatnonzero(free.ravel())
        self.n_free = self.free.size

    def scale(self) -> float:
        """A starting spread [m] from the spread of the table values."""
        spread = np.nanpercentile(self.a, 90) - np.nanpercentile(self.a, 10) if self.a.size else 0
        return float(np.clip(spread, 5.0, 200.0))

    def positions(self, x: np.ndarray) -> np.ndarray:
        p = np.zeros(2 * self.m_count)
        p[self.free] = x
        return p.reshape(self.m_count, 2)

    def _distances(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        diff = p[self.j] - p[self.m]
        dist = np.sqrt(np.sum(diff**2, axis=1) + (self.z[self.j] - self.z[self.m]) ** 2)
        return diff, np.maximum(dist, 1e-9)

    def residual(self, x: np.ndarray) -> np.ndarray:
        _, dist = self._distances(self.positions(x))
        return self.projector @ (self.w * (self.a - dist))

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        diff, dist = self._distances(self.positions(x))
        u = diff / dist[:, None]
        n = self.j.size
        full = np.zeros((n, 2 * self.m_count))
        rows = np.arange(n)
        for k in range(2):
            full[rows, 2 * self.j + k] -= u[:, k] * self.w
            full[rows, 2 * self.m + k] += u[:, k] * self.w
        return self.projector @ full[:, self.free]

    def clock_offsets(self, p: np.ndarray) -> np.ndarray:
        """The clock terms ``b`` that best fit given positions (origin's is 0)."""
        _, dist = self._distances(p)
        rhs = self.w * (self.a - dist)
        sol = np.linalg.lstsq(self.design * self.w[:, None], rhs, rcond=None)[0]
        b = np.zeros(self.m_count)
        b[self.b_cols] = sol[: self.b_cols.size]
        return b


def resect_readers(
    toa: np.ndarray,
    p_world_wand: np.ndarray,
    tau_wand: np.ndarray,
    heights: np.ndarray,
    readers: Sequence[int],
    *,
    sigma: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Place readers from located wand transmissions (positioning with the roles swapped).

    Args:
        toa: Wand times of arrival, shape (T, M) [m], NaN where not heard.
        p_world_wand: Wand fixes, shape (T, 3) [m]; NaN rows are skipped.
        tau_wand: Transmit times of those fixes, shape (T,) [m].
        heights: Reader heights, shape (M,) [m].
        readers: Indices of the readers to place.
        sigma: Range noise [m].

    Returns:
        ``(p_xy, clock_offsets, ok)`` for the given readers: shape (R, 2) [m], (R,) [m] and
        (R,) bool (False where too few fixes heard the reader, or no fix was found).
    """
    n = len(readers)
    p_xy = np.full((n, 2), np.nan)
    clocks = np.full(n, np.nan)
    ok = np.zeros(n, dtype=bool)
    good = np.all(np.isfinite(p_world_wand), axis=1) & np.isfinite(tau_wand)
    for i, m in enumerate(readers):
        rows = np.flatnonzero(good & np.isfinite(toa[:, m]))
        if rows.size < 4:
            continue
        wand = make_constellation(
            p_world_wand[rows], clock_offsets=tau_wand[rows], sigma=sigma,
            ids=[f"w{k}" for k in range(rows.size)],
        )  # fmt: skip
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            fix = locate(toa[rows, m][None, :], wand, height=float(heights[m]), test_level=None,
                         check_bounds=False)
        if fix.ok[0]:
            p_xy[i] = fix.p_world_tag[0, :2]
            clocks[i] = fix.clock[0]
            ok[i] = True
    return p_xy, clocks, ok
