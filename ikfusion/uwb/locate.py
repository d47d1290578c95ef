"""UWB positioning per transmission: tag position and transmit time from times of arrival.

Measurement model (all in metres, SPEC section 4)::

    toa_m = tau + ||p_world_reader_m - p_world_tag|| + clock_offset_m + nlos_m + e_m,
    e_m ~ N(0, sigma^2),   nlos_m >= 0.

The unknowns are ``p_world_tag`` (3-D, or its x, y when the tag height is known) and the
transmit time ``tau`` ("clock free"), or only the position when ``tau`` is known to be zero
(two-way ranges: ``clock="zero"``). Each transmission is solved independently:

1. a closed-form start with no prior (Bancroft, :mod:`ikfusion.uwb.initial_guess`);
2. weighted Gauss-Newton to convergence;
3. NLOS handling (``reject_nlos=True``), one-sided because NLOS delays are positive: Baarda's
   data snooping removes, one at a time, the measurement with the largest positive normalised
   residual ``e_m / (sigma sqrt(1 - h_mm))`` above ``threshold``, while at least two redundant
   measurements remain (with one, the culprit cannot be identified). When that needs more than
   one rejection, a one-sided robust fit (iteratively reweighted; only measurements arriving
   *later* than the fit predicts are down-weighted) also runs, and the path whose fix agrees
   with more measurements wins. Rejected measurements that agree with the final fit come back.
   A fix that still rejects many measurements (or has none) is searched again from the best
   consensus of random subsets (RANSAC with the closed form). Finally a chi-square test at
   level ``test_level`` flags fixes that stay inconsistent, and a fix that rejected two or more
   measurements, more than it kept redundant ones, is flagged as ambiguous (another set of late
   measurements would explain the data about as well); both get status ``rejected``.
4. a fix far outside the capture area gets status ``outside_area``, one under the floor or far
   above the readers ``bad_height`` (:mod:`ikfusion.uwb.bounds`).

Everything runs as batched numpy over all transmissions at once (missing and rejected
measurements are zero weights), so long logs locate quickly.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import numpy.typing as npt
from scipy.stats import chi2

from ..atomic import atomic_write_text
from ..errors import InputError
from .bounds import CaptureBounds, capture_bounds, outside
from .constellation import Constellation
from .initial_guess import bancroft, subset_starts
from .linalg import inverse_batched, solve_batched
from .toa_log import Transmissions
from .toa_model import toa_residuals

ClockMode = Literal["free", "zero"]

#: Reweighting passes of the robust fit; it only proposes rejections, so 1 mm is close enough.
_ROBUST_ITERATIONS = 12
_ROBUST_TOLERANCE = 1e-3
#: Gauss-Newton iterations between two rejections (the final fit iterates to convergence).
_INNER_ITERATIONS = 3
#: A fix that rejected this many receptions is searched again from a grid (wrong basin?).
_RESCUE_REJECTIONS = 3

#: Columns of a fix CSV (SPEC section 5, ``ikfusion locate``).
FIX_COLUMNS = ("time", "tag", "seq", "x", "y", "z", "clock", "used", "rejected", "status")


class FixStatus(enum.IntEnum):
    """Why a transmission has, or has no, fix. ``label`` is the word written in fix CSVs."""

    OK = 0
    TOO_FEW_READERS = 1
    REJECTED = 2
    DIVERGED = 3
    BAD_GEOMETRY = 4
    OUTSIDE_AREA = 5
    BAD_HEIGHT = 6

    @property
    def label(self) -> str:
        """Lower-case name: ``ok``, ``too_few_readers``, ``rejected``, ``diverged``, ..."""
        return self.name.lower()


@dataclass(frozen=True)
class LocateOptions:
    """Settings of :func:`locate`.

    Attributes:
        height: Known tag height [m] (scalar, or one per transmission); None solves in 3-D.
        clock: ``"free"`` estimates the transmit time; ``"zero"`` fixes it at 0 (two-way ranges).
        sigma: Range noise [m]; None takes the constellation's ``sigma``; ``"auto"`` estimates
            it from the data first (:func:`estimate_range_sigma`), the right choice for real
            ranges whose spread is not known.
        reject_nlos: Detect and reject late (NLOS) measurements and test each fix.
        threshold: One-sided rejection threshold on normalised residuals [sigma].
        robust_c: Late residuals beyond ``robust_c`` sigma are down-weighted in the robust
            fit by ``(robust_c sigma / e)^2`` [sigma].
        test_level: False-alarm probability of the final chi-square test; None disables it.
        max_iterations: Gauss-Newton iterations per fit.
        tolerance: Convergence threshold on the step length [m].
        check_bounds: A fix outside the capture area or below the floor / far above the
            readers (:mod:`ikfusion.uwb.bounds`) gets status ``outside_area`` / ``bad_height``
            instead of ``ok``; off only where the "readers" are not a capture space (a wand
            locating a reader during calibration).
    """

    height: float | npt.ArrayLike | None = None
    clock: ClockMode = "free"
    sigma: float | Literal["auto"] | None = None
    reject_nlos: bool = True
    threshold: float = 3.5
    robust_c: float = 2.5
    test_level: float | None = 1e-3
    max_iterations: int = 25
    tolerance: float = 1e-5
    check_bounds: bool = True


@dataclass(frozen=True)
class Fixes:
    """Positioning results, one row per transmission.

    Attributes:
        p_world_tag: Tag position, shape (T, 3) [m]; NaN without a fix. In 2-D mode ``z`` is
            the known height.
        clock: Estimated transmit time ``tau``, shape (T,) [m]; 0 with ``clock="zero"``, NaN
            without a fix.
        cov: Covariance of ``(x, y, z, tau)``, shape (T, 4, 4) [m^2], from the range noise
            (rows and columns of parameters that are not estimated are 0); NaN without a fix.
        used: Measurements in the final fit, shape (T, M) (bool).
        rejected: Measurements rejected as NLOS, shape (T, M) (bool).
        status: :class:`FixStatus` code per transmission, shape (T,) (int8).
        reader_ids: The M reader ids indexing ``used`` and ``rejected``.
    """

    p_world_tag: np.ndarray
    clock: np.ndarray
    cov: np.ndarray
    used: np.ndarray
    rejected: np.ndarray
    status: np.ndarray
    reader_ids: tuple[str, ...]

    def __len__(self) -> int:
        return int(self.status.shape[0])

    @property
    def ok(self) -> np.ndarray:
        """Transmissions with a fix, shape (T,) (bool)."""
        return self.status == FixStatus.OK

    def status_labels(self) -> list[str]:
        """Status words per transmission (``ok``, ``too_few_readers``, ...)."""
        labels = [s.label for s in FixStatus]
        return [labels[int(s)] for s in self.status]

    def status_counts(self) -> dict[str, int]:
        """Number of transmissions per status word (all statuses listed)."""
        return {s.label: int(np.count_nonzero(self.status == s)) for s in FixStatus}


@dataclass
class _Batch:
    """Centred problem data shared by the solver steps."""

    s: np.ndarray  # reader positions minus their centroid, (M, 3) [m]
    y: np.ndarray  # pseudo-ranges, shifted per transmission, (T, M) [m]
    w0: np.ndarray  # base weights 1/sigma^2 where measured, else 0, (T, M)
    h: np.ndarray  # known height minus centroid z, (T,) [m] (unused in 3-D)
    dims: int
    clock: bool

    @property
    def k(self) -> int:
        return self.dims + int(self.clock)


def locate(
    toa: npt.ArrayLike,
    constellation: Constellation,
    options: LocateOptions | None = None,
    **overrides: object,
) -> Fixes:
    """Locate every transmission of a (T, M) matrix of times of arrival.

    Args:
        toa: Times of arrival [m], shape (T, M) with columns in the constellation's reader
            order; NaN where a reader did not hear the transmission.
        constellation: Reader positions and clock offsets (and the default ``sigma``).
        options: Solver settings; keyword ``overrides`` replace single fields, e.g.
            ``locate(toa, c, height=1.2, clock="zero")``.
        **overrides: Fields of :class:`LocateOptions`.

    Returns:
        The fixes.

    Raises:
        InputError: On wrong shapes or settings.
    """
    opts = options or LocateOptions()
    if overrides:
        unknown = set(overrides) - set(LocateOptions.__dataclass_fields__)
        if unknown:
            raise TypeError(f"unknown locate option(s): {', '.join(sorted(unknown))}")
        opts = LocateOptions(**{**opts.__dict__, **overrides})  # type: ignore[arg-type]
    z = np.asarray(toa, dtype=float)
    m = len(constellation.readers)
    if z.ndim != 2 or z.shape[1] != m:
        raise InputError(f"toa must have shape (T, {m}) for {m} readers, got {z.shape}")
    if opts.clock not in ("free", "zero"):
        raise InputError(f"clock must be 'free' or 'zero', got {opts.clock!r}")
    if opts.sigma == "auto":
        sigma = estimate_range_sigma(z, constellation, height=opts.height, clock=opts.clock)
    else:
        sigma = constellation.sigma if opts.sigma is None else float(opts.sigma)
    if not sigma > 0:
        raise InputError(f"sigma must be positive, got {sigma}")
    t_count = z.shape[0]
    batch, centre, y_shift = _prepare(z, constellation, opts, sigma)
    k = batch.k
    avail = batch.w0 > 0
    n_avail = avail.sum(axis=1)
    status = np.full(t_count, FixStatus.OK, dtype=np.int8)
    status[n_avail < k] = FixStatus.TOO_FEW_READERS
    rows = np.flatnonzero(n_avail >= k)
    x = np.full((t_count, k), np.nan)
    used = avail.copy()
    used[n_avail < k] = False
    rejected = np.zeros_like(avail)
    if rows.size:
        sub = _subset(batch, rows)
        xs, used_s, rej_s, st_s = _solve(sub, opts)
        x[rows] = xs
        used[rows] = used_s
        rejected[rows] = rej_s
        status[rows] = st_s
    fixes = _assemble(batch, x, used, rejected, status, centre, y_shift, constellation.ids)
    if opts.check_bounds:
        _mark_outside(fixes, capture_bounds(constellation))
    return fixes


def _mark_outside(fixes: Fixes, bounds: CaptureBounds) -> None:
    """Give fixes outside the bounds their status and no position (in place)."""
    area, height = outside(fixes.p_world_tag, bounds)
    fixes.status[area] = FixStatus.OUTSIDE_AREA
    fixes.status[height & ~area] = FixStatus.BAD_HEIGHT
    bad = area | height
    fixes.p_world_tag[bad] = np.nan
    fixes.clock[bad] = np.nan
    fixes.cov[bad] = np.nan


def estimate_range_sigma(
    toa: npt.ArrayLike,
    constellation: Constellation,
    *,
    height: float | npt.ArrayLike | None = None,
    clock: ClockMode = "free",
    iterations: int = 4,
) -> float:
    """Robust estimate of the range noise of a log, from the residuals of its own fixes.

    The scale of residuals is ``1.4826 median(|e|)`` (the median absolute residual about zero,
    so a bias common to all receptions counts as noise), inflated by ``sqrt(n / (n - k))`` for
    the ``k`` parameters each fix absorbs. It starts from fixes without NLOS rejection (whose
    residuals NLOS delays inflate), then alternates fixing with NLOS rejection at the current
    estimate and re-estimating from the receptions kept, until it moves by less than 2 %.

    Args:
        toa: Times of arrival, shape (T, M) [m], NaN where missing.
        constellation: The readers.
        height: Known tag height [m] or None for 3-D.
        clock: ``"free"`` or ``"zero"``.
        iterations: Maximum re-estimations with NLOS rejection.

    Returns:
        The estimated range sigma [m].

    Raises:
        InputError: When no transmission has more measurements than unknowns.
    """
    z = np.asarray(toa, dtype=float)
    k = (3 if height is None else 2) + int(clock == "free")
    fixes = locate(z, constellation, height=height, clock=clock, reject_nlos=False, sigma=1.0)
    sigma = _residual_scale(z, fixes, constellation, k)
    for _ in range(iterations):
        fixes = locate(z, constellation, height=height, clock=clock, sigma=sigma, test_level=None)
        new = _residual_scale(z, fixes, constellation, k)
        done = abs(new - sigma) < 0.02 * sigma
        sigma = new
        if done:
            break
    return sigma


def _residual_scale(z: np.ndarray, fixes: Fixes, constellation: Constellation, k: int) -> float:
    """``1.4826 median |e| sqrt(n / (n - k))`` over the used receptions of redundant fixes."""
    n = fixes.used.sum(axis=1)
    rows = fixes.ok & (n > k)
    if not np.any(rows):
        raise InputError(
            f"cannot estimate the range noise: no transmission has more than {k} receptions"
        )
    tau = np.where(np.isfinite(fixes.clock), fixes.clock, 0.0)
    res = toa_residuals(z[rows], fixes.p_world_tag[rows], tau[rows], constellation)
    e = np.abs(res[fixes.used[rows]])
    inflation = np.sqrt(np.mean(n[rows]) / (np.mean(n[rows]) - k))
    return float(1.4826 * np.median(e) * inflation)


def locate_transmissions(
    transmissions: Transmissions,
    constellation: Constellation,
    options: LocateOptions | None = None,
    **overrides: object,
) -> Fixes:
    """:func:`locate` on grouped transmissions (columns matched to the constellation by id).

    Raises:
        InputError: When the transmissions were grouped over other reader ids.
    """
    if tuple(transmissions.reader_ids) != constellation.ids:
        raise InputError(
            "transmissions were grouped over readers "
            f"{', '.join(transmissions.reader_ids)}, not the constellation's "
            f"{', '.join(constellation.ids)}"
        )
    return locate(transmissions.toa, constellation, options, **overrides)


def write_fixes_csv(path: str | Path, transmissions: Transmissions, fixes: Fixes) -> Path:
    """Write fixes as CSV ``time,tag,seq,x,y,z,clock,used,rejected,status`` (atomically).

    ``used`` and ``rejected`` are reader ids joined with ``;`` (empty when none). Coordinates
    and clock are blank for transmissions without a fix. Positions and clock have 0.1 mm
    resolution, time 1 us.

    Returns:
        The path written.
    """
    labels = fixes.status_labels()
    used = _id_lists(fixes.used, fixes.reader_ids)
    rejected = _id_lists(fixes.rejected, fixes.reader_ids)
    p = fixes.p_world_tag
    ok = fixes.status == FixStatus.OK
    lines = [",".join(FIX_COLUMNS)]
    for i in range(len(fixes)):
        if ok[i]:
            coords = f"{p[i, 0]:.4f},{p[i, 1]:.4f},{p[i, 2]:.4f},{fixes.clock[i]:.4f}"
        else:
            coords = ",,,"
        lines.append(
            f"{transmissions.time[i]:.6f},{transmissions.tag[i]},{transmissions.seq[i]},"
            f"{coords},{used[i]},{rejected[i]},{labels[i]}"
        )
    return atomic_write_text(Path(path), "\n".join(lines) + "\n")


# --------------------------------------------------------------------------- internals


def _id_lists(mask: np.ndarray, reader_ids: Sequence[str]) -> list[str]:
    """``;``-joined reader ids per row of a (T, M) mask (each distinct pattern joined once)."""
    if mask.shape[0] == 0:
        return []
    patterns, inverse = np.unique(mask, axis=0, return_inverse=True)
    text = [";".join(r for r, on in zip(reader_ids, row) if on) for row in patterns]
    return [text[j] for j in inverse.ravel()]


def _prepare(
    z: np.ndarray, constellation: Constellation, opts: LocateOptions, sigma: float
) -> tuple[_Batch, np.ndarray, np.ndarray]:
    """Centre the geometry and shift pseudo-ranges so the squares stay well conditioned."""
    t_count = z.shape[0]
    readers = constellation.positions
    centre = readers.mean(axis=0)
    y = z - constellation.clock_offsets[None, :]
    avail = np.isfinite(y)
    clock = opts.clock == "free"
    if clock and t_count:
        with np.errstate(invalid="ignore"):
            shift = np.where(avail.any(axis=1), np.nanmin(np.where(avail, y, np.inf), axis=1), 0)
    else:
        shift = np.zeros(t_count)
    y = np.where(avail, y - shift[:, None], 0.0)
    if opts.height is None:
        dims = 3
        h = np.zeros(t_count)
    else:
        dims = 2
        try:
            h = np.broadcast_to(np.asarray(opts.height, dtype=float), (t_count,)).copy()
        except ValueError as err:
            raise InputError(
                f"height must be one value or one per transmission ({t_count}): {err}"
            ) from err
        if not np.all(np.isfinite(h)):
            raise InputError("the known tag height must be finite")
        h -= centre[2]
    w0 = np.where(avail, 1.0 / sigma**2, 0.0)
    return _Batch(readers - centre, y, w0, h, dims, clock), centre, shift


def _subset(batch: _Batch, rows: np.ndarray) -> _Batch:
    return _Batch(batch.s, batch.y[rows], batch.w0[rows], batch.h[rows], batch.dims, batch.clock)


def _position(x: np.ndarray, b: _Batch) -> np.ndarray:
    p = np.empty((x.shape[0], 3))
    p[:, : b.dims] = x[:, : b.dims]
    if b.dims == 2:
        p[:, 2] = b.h
    return p


def _predict(x: np.ndarray, b: _Batch) -> tuple[np.ndarray, list[np.ndarray]]:
    """Predicted pseudo-ranges (T, M) and the Jacobian columns wrt the k parameters (T, M)."""
    p = _position(x, b)
    diff = [p[:, i, None] - b.s[None, :, i] for i in range(3)]
    dist = np.maximum(np.sqrt(diff[0] ** 2 + diff[1] ** 2 + diff[2] ** 2), 1e-9)
    inv = 1.0 / dist
    jac = [diff[i] * inv for i in range(b.dims)]
    if b.clock:
        jac.append(np.ones_like(dist))
        return dist + x[:, b.dims, None], jac
    return dist, jac


def _normal(jac: list[np.ndarray], w: np.ndarray) -> np.ndarray:
    """Normal matrices ``J^T W J``, shape (T, k, k)."""
    k = len(jac)
    normal = np.empty((w.shape[0], k, k))
    for i in range(k):
        wi = w * jac[i]
        for j in range(i, k):
            normal[:, i, j] = normal[:, j, i] = np.einsum("tm,tm->t", wi, jac[j])
    return normal


def _gauss_newton(
    x: np.ndarray, b: _Batch, w: np.ndarray, opts: LocateOptions, iterations: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Iterate Gauss-Newton on every row until its step is below the tolerance.

    Returns:
        ``(x, converged, singular)``.
    """
    x = x.copy()
    t_count = x.shape[0]
    converged = np.zeros(t_count, dtype=bool)
    singular = np.zeros(t_count, dtype=bool)
    active = np.flatnonzero(np.all(np.isfinite(x), axis=1))
    for _ in range(opts.max_iterations if iterations is None else iterations):
        if active.size == 0:
            break
        everything = active.size == t_count
        sub = b if everything else _subset(b, active)
        xa = x if everything else x[active]
        wa = w if everything else w[active]
        pred, jac = _predict(xa, sub)
        wr = wa * (sub.y - pred)
        rhs = np.stack([np.einsum("tm,tm->t", wr, col) for col in jac], axis=1)
        step, ok = solve_batched(_normal(jac, wa), rhs)
        x[active] = xa + step
        size = np.sqrt(np.einsum("tk,tk->t", step, step))
        singular[active[~ok]] = True
        done = ~ok | (size < opts.tolerance) | ~np.isfinite(size)
        converged[active[done & ok & np.isfinite(size)]] = True
        active = active[~done]
    return x, converged, singular


def _robust_fit(x: np.ndarray, b: _Batch, w: np.ndarray, opts: LocateOptions) -> np.ndarray:
    """One-sided IRLS: down-weight measurements that arrive later than the fit predicts.

    A late residual ``e > c sigma`` gets the weight factor ``(c sigma / e)^2`` (its influence
    falls off as ``1/e``); early residuals keep full weight, since no physical effect makes a
    signal arrive before the line-of-sight time.
    """
    x = x.copy()
    sigma = 1.0 / np.sqrt(np.where(w > 0, w, 1.0))
    active = np.flatnonzero(np.all(np.isfinite(x), axis=1))
    for _ in range(_ROBUST_ITERATIONS):
        if active.size == 0:
            break
        sub = _subset(b, active)
        xa = x[active]
        pred, _ = _predict(xa, sub)
        late = (sub.y - pred) / sigma[active]
        c = opts.robust_c
        factor = np.where(late > c, (c / np.maximum(late, c)) ** 2, 1.0)
        x_new, _, _ = _gauss_newton(xa, sub, w[active] * factor, opts, iterations=1)
        finite = np.all(np.isfinite(x_new), axis=1)
        x_new[~finite] = xa[~finite]
        moved = np.linalg.norm(x_new - xa, axis=1)
        x[active] = x_new
        active = active[finite & (moved >= _ROBUST_TOLERANCE)]
    return x


def _normalised_residuals(
    x: np.ndarray, b: _Batch, w: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residuals, normalised residuals ``e / (sigma sqrt(1 - h))`` and validity per row."""
    pred, jac = _predict(x, b)
    e = b.y - pred
    inv, ok = inverse_batched(_normal(jac, w))
    inv = np.nan_to_num(inv)
    k = len(jac)
    leverage = np.zeros_like(e)
    for i in range(k):
        for j in range(k):
            leverage += jac[i] * inv[:, i, j, None] * jac[j]
    leverage *= w
    with np.errstate(divide="ignore", invalid="ignore"):
        zn = e * np.sqrt(w) / np.sqrt(np.maximum(1.0 - leverage, 1e-12))
    zn = np.where(w > 0, zn, np.nan)
    return e, zn, ok


def _solve(b: _Batch, opts: LocateOptions) -> tuple[np.ndarray, ...]:
    """Fix every row of a batch that has at least k measurements."""
    late_c = opts.robust_c if opts.reject_nlos else None
    x0, ok0 = bancroft(b.s, b.y, b.w0, dims=b.dims, clock=b.clock, height=b.h, late_c=late_c)
    x0[~ok0] = np.nan
    x, used, status = _fit(x0, b, opts)
    # Rescue: a transmission without an acceptable fix, or whose fix rejected many receptions
    # (a wrong basin agrees with few of them), starts again from the best consensus of random
    # subsets; the new fix wins when it is acceptable and agrees with more receptions.
    retry_mask = status != FixStatus.OK
    if opts.reject_nlos:
        n_rejected = ((b.w0 > 0) & ~used).sum(axis=1)
        n_avail = (b.w0 > 0).sum(axis=1)
        retry_mask |= n_rejected >= np.maximum(_RESCUE_REJECTIONS, (n_avail - b.k + 1) // 2)
    retry = np.flatnonzero(retry_mask)
    if retry.size:
        sub = _subset(b, retry)
        xg = subset_starts(
            sub.s, sub.y, sub.w0, dims=b.dims, clock=b.clock, height=sub.h, late_c=opts.robust_c
        )
        xr, used_r, status_r = _fit(xg, sub, opts)
        n_old, c_old = _consensus(x[retry], sub, used[retry], opts.threshold)
        n_new, c_new = _consensus(xr, sub, used_r, opts.threshold)
        was_ok = status[retry] == FixStatus.OK
        agrees_more = (n_new > n_old) | ((n_new == n_old) & (c_new < c_old))
        better = (status_r == FixStatus.OK) & (~was_ok | agrees_more)
        x[retry[better]] = xr[better]
        used[retry[better]] = used_r[better]
        status[retry[better]] = FixStatus.OK
        status[retry[~better & ~ok0[retry] & ~was_ok]] = FixStatus.BAD_GEOMETRY
    rejected = (b.w0 > 0) & ~used
    x[status != FixStatus.OK] = np.nan
    return x, used, rejected, status


def _fit(x0: np.ndarray, b: _Batch, opts: LocateOptions) -> tuple[np.ndarray, ...]:
    """Gauss-Newton from ``x0``, NLOS rejection, then the status of each row."""
    t_count = b.y.shape[0]
    used = b.w0 > 0
    x, converged, singular = _gauss_newton(x0, b, b.w0, opts)
    if opts.reject_nlos:
        x, used = _reject_late(x, x0, b, used, opts)
        x, converged, singular = _gauss_newton(x, b, b.w0 * used, opts)
    status = np.full(t_count, FixStatus.OK, dtype=np.int8)
    finite = np.all(np.isfinite(x), axis=1)
    span = float(np.max(np.linalg.norm(b.s, axis=1))) if b.s.size else 0.0
    far = np.linalg.norm(_position(np.nan_to_num(x), b), axis=1) > 10.0 * span + 100.0
    status[~converged | ~finite | far] = FixStatus.DIVERGED
    status[singular & (status == FixStatus.DIVERGED)] = FixStatus.BAD_GEOMETRY
    if opts.reject_nlos and opts.test_level is not None:
        status[(status == FixStatus.OK) & ~_passes(x, b, used, opts)] = FixStatus.REJECTED
    if opts.reject_nlos:
        # More receptions rejected (two or more) than redundant ones kept: another set of late
        # receptions would explain the data about as well, so the fix is not trusted.
        n_rejected = ((b.w0 > 0) & ~used).sum(axis=1)
        ambiguous = (n_rejected >= 2) & (n_rejected > used.sum(axis=1) - b.k)
        status[(status == FixStatus.OK) & ambiguous] = FixStatus.REJECTED
    return x, used, status


def _chi_square(x: np.ndarray, b: _Batch, used: np.ndarray) -> np.ndarray:
    """Weighted sum of squared residuals of the used measurements, shape (T,)."""
    pred, _ = _predict(x, b)
    e = b.y - pred
    return np.sum(np.where(used, e * e * b.w0, 0.0), axis=1)


def _reject_late(
    x: np.ndarray, x0: np.ndarray, b: _Batch, used: np.ndarray, opts: LocateOptions
) -> tuple[np.ndarray, np.ndarray]:
    """Reject late measurements; returns the refitted parameters and the used mask.

    Rows whose least-squares fit ``x`` shows no late outlier and passes the chi-square test are
    left alone. The others go through path B, data snooping from ``x``. Where path B needs
    more than one rejection or ends inconsistent, path A also runs: a one-sided robust fit
    from the better (robust cost) of ``x0`` and ``x``, rejection of what it sees late, then
    snooping. Path A resists several simultaneous NLOS delays, which can pull the
    least-squares fit into a wrong basin (a mirror solution over a weak sub-geometry); the
    path whose fit agrees with more measurements wins (ties: smaller chi-square). Finally,
    rejected measurements that agree with the fit come back.
    """
    k = b.k
    x = x.copy()
    used = used.copy()
    finite = np.all(np.isfinite(x), axis=1)
    _, zn, _ = _normalised_residuals(np.nan_to_num(x), b, b.w0 * used)
    late = np.nanmax(np.where(used, zn, -np.inf), axis=1)
    rows = np.flatnonzero(finite & ((late > opts.threshold) | ~_passes(x, b, used, opts)))
    if rows.size == 0:
        return x, used
    sub = _subset(b, rows)
    xs, used_s = x[rows], used[rows]
    # Path B: snoop from the least-squares fit.
    xb, used_b = _snoop(xs.copy(), sub, used_s.copy(), opts)
    hard = ((used_s.sum(axis=1) - used_b.sum(axis=1)) > 1) | ~_passes(xb, sub, used_b, opts)
    xs, used_s = xb, used_b
    h = np.flatnonzero(hard)
    if h.size:
        hb = _subset(sub, h)
        used_h = used[rows[h]]
        # Path A: robust fit from the better start, reject what it sees late (largest first,
        # keeping k + 1 measurements), snoop.
        x0h, xh = x0[rows[h]], x[rows[h]]
        c0 = _robust_cost(x0h, hb, used_h, opts.robust_c)
        ch = _robust_cost(xh, hb, used_h, opts.robust_c)
        xr = _robust_fit(np.where((c0 < ch)[:, None], x0h, xh), hb, hb.w0 * used_h, opts)
        pred, _ = _predict(xr, hb)
        lateness = np.where(used_h, (hb.y - pred) * np.sqrt(hb.w0), -np.inf)
        spare = np.maximum(used_h.sum(axis=1) - (k + 1), 0)
        rank = np.argsort(np.argsort(-lateness, axis=1), axis=1)
        used_a = used_h & ~((lateness > opts.threshold) & (rank < spare[:, None]))
        xa, _, _ = _gauss_newton(xr, hb, hb.w0 * used_a, opts, _INNER_ITERATIONS)
        xa, used_a = _snoop(xa, hb, used_a, opts)
        na, ca = _consensus(xa, hb, used_a, opts.threshold)
        nb, cb = _consensus(xs[h], hb, used_s[h], opts.threshold)
        take_a = (na > nb) | ((na == nb) & (ca <= cb))
        xs[h[take_a]] = xa[take_a]
        used_s[h[take_a]] = used_a[take_a]
    # Restore rejected measurements that agree with the final fit.
    pred, _ = _predict(np.nan_to_num(xs), sub)
    agree = (sub.w0 > 0) & ~used_s & (np.abs(sub.y - pred) * np.sqrt(sub.w0) <= opts.threshold)
    back = np.flatnonzero(agree.any(axis=1))
    if back.size:
        used_s[back] |= agree[back]
        bb = _subset(sub, back)
        xs[back], _, _ = _gauss_newton(xs[back], bb, bb.w0 * used_s[back], opts)
    x[rows] = xs
    used[rows] = used_s
    return x, used


def _passes(x: np.ndarray, b: _Batch, used: np.ndarray, opts: LocateOptions) -> np.ndarray:
    """Chi-square test of each fit at ``opts.test_level`` (True without redundancy)."""
    chi = _chi_square(np.nan_to_num(x), b, used)
    dof = used.sum(axis=1) - b.k
    level = 1e-3 if opts.test_level is None else opts.test_level
    table = np.concatenate([[np.inf], chi2.isf(level, np.arange(1, b.y.shape[1] + 1))])
    limit = table[np.maximum(dof, 0)]
    return np.all(np.isfinite(x), axis=1) & (chi <= limit)


def _robust_cost(x: np.ndarray, b: _Batch, used: np.ndarray, c: float) -> np.ndarray:
    """One-sided robust cost of fixes (late residuals count logarithmically), shape (T,)."""
    pred, _ = _predict(np.nan_to_num(x), b)
    r = (b.y - pred) * np.sqrt(b.w0)
    loss = np.where(r > c, c * c * (1.0 + 2.0 * np.log(np.maximum(r, c) / c)), r * r)
    cost = np.sum(np.where(used, loss, 0.0), axis=1)
    return np.where(np.all(np.isfinite(x), axis=1) & np.isfinite(cost), cost, np.inf)


def _consensus(
    x: np.ndarray, b: _Batch, used: np.ndarray, threshold: float
) -> tuple[np.ndarray, np.ndarray]:
    """Measurements within ``threshold`` sigma of a fix, and the fit's chi-square, per row.

    Rows with a non-finite fix have consensus -1 and chi-square infinity.
    """
    pred, _ = _predict(np.nan_to_num(x), b)
    r = (b.y - pred) * np.sqrt(b.w0)
    inliers = np.sum((b.w0 > 0) & (np.abs(r) <= threshold), axis=1)
    chi = np.sum(np.where(used, r * r, 0.0), axis=1)
    finite = np.all(np.isfinite(x), axis=1) & np.isfinite(chi)
    return np.where(finite, inliers, -1), np.where(finite, chi, np.inf)


def _snoop(
    x: np.ndarray, b: _Batch, used: np.ndarray, opts: LocateOptions
) -> tuple[np.ndarray, np.ndarray]:
    """Baarda data snooping, one-sided: drop the latest outlier per round, refit, repeat."""
    k = b.k
    active = np.flatnonzero(np.all(np.isfinite(x), axis=1))
    for _ in range(b.y.shape[1]):
        active = active[used[active].sum(axis=1) - k >= 2]
        if active.size == 0:
            break
        sub = _subset(b, active)
        _, zn, ok = _normalised_residuals(x[active], sub, sub.w0 * used[active])
        zn = np.where(np.isfinite(zn), zn, -np.inf)
        worst = np.argmax(zn, axis=1)
        hit = ok & (zn[np.arange(active.size), worst] > opts.threshold)
        if not np.any(hit):
            break
        rows = active[hit]
        used[rows, worst[hit]] = False
        rb = _subset(b, rows)
        x[rows], _, _ = _gauss_newton(x[rows], rb, rb.w0 * used[rows], opts, _INNER_ITERATIONS)
        active = rows
    return x, used


def _assemble(
    b: _Batch,
    x: np.ndarray,
    used: np.ndarray,
    rejected: np.ndarray,
    status: np.ndarray,
    centre: np.ndarray,
    y_shift: np.ndarray,
    reader_ids: Sequence[str],
) -> Fixes:
    """Un-centre the parameters and compute the fix covariance."""
    t_count = x.shape[0]
    ok = status == FixStatus.OK
    p = np.full((t_count, 3), np.nan)
    clock = np.full(t_count, np.nan)
    cov = np.full((t_count, 4, 4), np.nan)
    if np.any(ok):
        rows = np.flatnonzero(ok)
        sub = _subset(b, rows)
        xs = x[rows]
        p[rows] = _position(xs, sub) + centre
        clock[rows] = xs[:, b.dims] + y_shift[rows] if b.clock else 0.0
        _, jac = _predict(xs, sub)
        inv, good = inverse_batched(_normal(jac, sub.w0 * used[rows]))
        idx = list(range(b.dims)) + ([3] if b.clock else [])
        full = np.zeros((rows.size, 4, 4))
        full[:, np.ix_(idx, idx)[0], np.ix_(idx, idx)[1]] = inv
        cov[rows] = full
        bad = rows[~good]
        status[bad] = FixStatus.BAD_GEOMETRY
        p[bad] = np.nan
        clock[bad] = np.nan
        cov[bad] = np.nan
    return Fixes(
        p_world_tag=p,
        clock=clock,
        cov=cov,
        used=used,
        rejected=rejected,
        status=status,
        reader_ids=tuple(reader_ids),
    )
