"""Automatic reader calibration: positions and clock offsets from a calibration log.

A calibration log (SPEC section 4) holds the transmissions of the calibration tag inside every
reader (tag id = reader id) and of a wand tag swayed for about a minute inside and around the
constellation (any other tag id). Reader heights come from the user (``heights: {R1: 2.5}``).
:func:`calibrate` estimates, by maximum likelihood, the horizontal reader positions, the reader
clock offsets, the wand trajectory and every transmit time together (all in metres)::

    minimise   sum_i w_i (toa_i - tau_k(i) - ||p_m(i) - e_k(i)|| - b_m(i))^2 / 2
    subject to p_origin,xy = 0, p_axis,y = 0, b_origin = 0          (the gauge)

with ``w_i = 1 / sigma^2`` for kept receptions and 0 for rejected (NLOS) ones. The steps:

1. first estimate from the reader-to-reader transmissions (:mod:`.calibration_init`): a robust
   table of tag-to-reader offsets, classical MDS of the distances it gives, then least squares
   on the horizontal positions with the clock terms eliminated;
2. the wand trajectory and transmit times by positioning with those readers
   (:func:`~ikfusion.uwb.locate.locate`, with its NLOS rejection); readers the table could not
   place are placed from the wand fixes (resection);
3. the joint problem in CasADi/IPOPT with exact sparse derivatives (:mod:`.calibration_nlp`);
4. NLOS handling by iterative rejection: receptions later than ``threshold`` robust sigmas (or
   earlier than ``early_threshold``, impossible for a delay) get weight 0 and the problem is
   solved again from the previous solution; rejected receptions that agree again come back.
   It stops when the kept set no longer changes. The rejected fraction is reported.

A reader's reception of its own calibration tag (distance 0, through an internal path with an
unknown delay) helps the first estimate only; the joint problem leaves it out.

The posterior covariance of the readers is the inverse of the Gauss-Newton information
``J^T W J`` at the solution (gauge unknowns left out, wand and transmit times marginalised),
S-transformed to the error that remains after a rigid horizontal alignment on all readers (or
on the surveyed readers, :mod:`.calibration_frame`). It is written per reader as
``position_covariance``, so DOP maps (``ikfusion plan``) show how the wand path limits accuracy.

Modules: this one runs the steps; :mod:`.calibration_result` holds options and result,
:mod:`.calibration_files` the heights and survey files, :mod:`.calibration_init` step 1,
:mod:`.calibration_nlp` step 3, :mod:`.calibration_frame` gauges and alignments,
:mod:`.calibration_sim` simulated sessions and :mod:`.calibration_plot` the figure.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from .calibration_files import heights_from_mapping, load_heights, load_survey, survey_from_mapping
from .calibration_frame import Rigid2D, align_to_survey, alignment_projector, gauge_transform
from .calibration_init import fit_reader_geometry, placeable, reader_table, resect_readers
from .calibration_nlp import CalibrationNlp, Layout, Receptions, marginal_covariance
from .calibration_result import (
    CalibrationError,
    CalibrationOptions,
    OutlierReport,
    UwbCalibration,
)
from .constellation import Constellation, make_constellation
from .locate import estimate_range_sigma, locate
from .toa_log import ToaLog, group_transmissions, read_toa_csv

__all__ = [
    "MIN_READERS",
    "CalibrationError",
    "CalibrationOptions",
    "OutlierReport",
    "UwbCalibration",
    "calibrate",
    "load_heights",
    "load_survey",
]

#: Fewest readers a calibration accepts: with 4, every wand fix fits its receptions exactly.
MIN_READERS = 5
#: Receptions a wand transmission needs to say something about the readers (4 unknowns + 1).
_WAND_MIN = 5
#: Receptions (by other readers) a reader-tag transmission needs (1 transmit time + 1).
_TAG_MIN = 2


# --------------------------------------------------------------------------- the session


@dataclass(frozen=True)
class _Session:
    """The log grouped into transmissions over the readers.

    Attributes:
        ids: Reader ids (the heights' order).
        z: Reader heights, shape (M,) [m].
        time: Earliest reception time per transmission, shape (T,) [s].
        toa: Times of arrival, shape (T, M) [m], NaN where not heard.
        emitter: Reader index of a reader tag's transmission, -1 for the wand, shape (T,).
        source: The log file.
    """

    ids: tuple[str, ...]
    z: np.ndarray
    time: np.ndarray
    toa: np.ndarray
    emitter: np.ndarray
    source: Path | None

    @property
    def wand(self) -> np.ndarray:
        """Wand transmissions, shape (T,) bool."""
        return self.emitter < 0

    def other_readers_toa(self) -> np.ndarray:
        """``toa`` without each reader's reception of its own tag, shape (T, M) [m]."""
        toa = self.toa.copy()
        own = np.flatnonzero(self.emitter >= 0)
        toa[own, self.emitter[own]] = np.nan
        return toa


def _session(log: ToaLog, heights: Mapping[str, float], heights_source: Path | None) -> _Session:
    ids = tuple(heights)
    log_readers = sorted({str(r) for r in log.reader})
    unknown = [r for r in log_readers if r not in heights]
    if unknown:
        row = int(np.flatnonzero(log.reader.astype(str) == unknown[0])[0])
        raise InputError(
            f"reader {unknown[0]!r} is in the log but not in the heights file; add its height "
            f"(readers without height: {', '.join(unknown)})",
            path=log.source,
            line=int(log.line[row]) or None,
            field="reader",
        )
    if len(ids) < MIN_READERS:
        raise CalibrationError(
            f"calibration needs at least {MIN_READERS} readers, found {len(ids)} "
            f"({', '.join(ids)}): with 4 every wand fix fits its 4 times of arrival exactly and "
            "says nothing about the readers; add readers or survey their positions by hand",
            path=heights_source,
            field="heights",
        )
    silent = [r for r in ids if r not in set(log_readers)]
    if silent:
        raise CalibrationError(
            f"reader(s) {', '.join(silent)} of the heights file report no reception in the "
            "log: check that they are powered and recording, or remove them from the heights",
            path=heights_source,
            field=f"heights.{silent[0]}",
            readers=silent,
        )
    tr = group_transmissions(log, ids)
    index = {rid: j for j, rid in enumerate(ids)}
    emitter = np.array([index.get(str(t), -1) for t in tr.tag], dtype=np.int64)
    z = np.array([heights[r] for r in ids], dtype=float)
    return _Session(ids, z, tr.time, tr.toa, emitter, log.source)


def _check_wand(s: _Session, opts: CalibrationOptions) -> None:
    """Raise when there is too little wand or it leaves readers unobserved."""
    wand = s.toa[s.wand]
    n_good = int(np.count_nonzero(np.isfinite(wand).sum(axis=1) >= _WAND_MIN))
    if n_good < opts.min_wand_transmissions:
        raise CalibrationError(
            f"the log has {n_good} wand transmissions heard by {_WAND_MIN} readers or more "
            f"(at least {opts.min_wand_transmissions} needed): sway the wand tag (any tag whose "
            "id is not a reader id) for about a minute inside and around the readers",
            path=s.source,
            field="tag",
        )
    _check_observed(s.ids, np.isfinite(wand).sum(axis=0), opts.min_wand_receptions, s.source)


def _check_observed(
    ids: Sequence[str], counts: np.ndarray, needed: int, source: Path | None
) -> None:
    """Raise naming the readers with fewer than ``needed`` wand receptions."""
    weak = [j for j in range(len(ids)) if counts[j] < needed]
    if not weak:
        return
    names = ", ".join(ids[j] for j in weak)
    detail = ", ".join(f"{ids[j]}: {int(counts[j])}" for j in weak)
    raise CalibrationError(
        f"the wand path leaves reader(s) {names} unobserved (usable wand receptions {detail}; "
        f"at least {needed} needed): walk closer to reader(s) {names}, in their line of sight",
        path=source,
        field="reader",
        readers=[ids[j] for j in weak],
    )


def _gauge_readers(ids: Sequence[str], opts: CalibrationOptions) -> tuple[int, int]:
    names = {"origin": opts.origin or ids[0], "axis": opts.axis or ids[1]}
    out = []
    for key, rid in names.items():
        if rid not in ids:
            raise InputError(f"{key} reader {rid!r} is not a reader ({', '.join(ids)})", field=key)
        out.append(ids.index(rid))
    if out[0] == out[1]:
        raise InputError("origin and axis readers must differ", field="axis")
    return out[0], out[1]


# --------------------------------------------------------------------------- first estimate


@dataclass(frozen=True)
class _FirstEstimate:
    """Reader positions and clocks in the gauge frame, with wand fixes.

    Attributes:
        p_xy: Horizontal reader positions, shape (M, 2) [m].
        clocks: Clock offsets (origin's 0), shape (M,) [m].
        wand_rows: Session rows of the wand transmissions that have a fix, shape (W,).
        p_wand: Their fixes, shape (W, 3) [m].
        wand_used: Receptions the fixes kept, shape (W, M) bool.
        spread: Robust range spread of the wand fixes [m].
    """

    p_xy: np.ndarray
    clocks: np.ndarray
    wand_rows: np.ndarray
    p_wand: np.ndarray
    wand_used: np.ndarray
    spread: float


def _first_estimate(
    s: _Session, opts: CalibrationOptions, gauge: tuple[int, int]
) -> _FirstEstimate:
    tags = ~s.wand
    table = reader_table(s.toa[tags], s.emitter[tags])
    keep = placeable(table)
    anchors = gauge if keep[gauge[0]] and keep[gauge[1]] else None
    rng = np.random.default_rng(opts.seed)
    geometry = fit_reader_geometry(table, s.z, rng, placed=keep, anchors=anchors)
    placed = geometry.placed
    if np.count_nonzero(placed) < 4:
        missing = [s.ids[j] for j in np.flatnonzero(~placed)]
        raise CalibrationError(
            f"the reader-to-reader transmissions place only {int(np.count_nonzero(placed))} "
            f"readers (not placed: {', '.join(missing)}): check that every reader's "
            "calibration tag transmits and is heard by the other readers",
            path=s.source,
            field="tag",
            readers=missing,
        )
    p_xy, clocks = geometry.p_xy.copy(), geometry.clock_offsets.copy()
    wand_toa = s.toa[s.wand]
    sub = make_constellation(
        np.column_stack([p_xy[placed], s.z[placed]]),
        ids=[s.ids[j] for j in np.flatnonzero(placed)],
        clock_offsets=clocks[placed],
    )
    # The first geometry is a few centimetres off: locate with the spread the data show.
    spread = estimate_range_sigma(wand_toa[:, placed], sub)
    fixes = locate(wand_toa[:, placed], sub, sigma=spread, test_level=None, check_bounds=False)
    p_fix = np.where(fixes.ok[:, None], fixes.p_world_tag, np.nan)
    unplaced = np.flatnonzero(~placed)
    if unplaced.size:
        tau = np.where(fixes.ok, fixes.clock, np.nan)
        xy, b, ok = resect_readers(wand_toa, p_fix, tau, s.z, unplaced.tolist(), sigma=spread)
        if not np.all(ok):
            bad = [s.ids[j] for j, good in zip(unplaced, ok) if not good]
            raise CalibrationError(
                f"reader(s) {', '.join(bad)} could not be placed: too few readers hear their "
                "calibration tag and too few wand fixes reach them; walk closer to reader(s) "
                f"{', '.join(bad)} with the wand",
                path=s.source,
                field="reader",
                readers=bad,
            )
        p_xy[unplaced], clocks[unplaced] = xy, b
    try:
        to_gauge = gauge_transform(p_xy, *gauge)
    except ValueError as err:
        origin, axis = (s.ids[j] for j in gauge)
        raise CalibrationError(
            f"readers {origin} and {axis} are at one horizontal position, so they cannot fix "
            "the frame: choose other readers as origin and axis (--origin, --axis)",
            field="axis",
            readers=[origin, axis],
        ) from err
    wand_used = np.zeros(wand_toa.shape, dtype=bool)
    wand_used[:, placed] = fixes.used
    wand_used[:, ~placed] = np.isfinite(wand_toa[:, ~placed])
    good = fixes.ok & (wand_used.sum(axis=1) >= _WAND_MIN)
    return _FirstEstimate(
        p_xy=to_gauge.apply(p_xy),
        clocks=clocks - clocks[gauge[0]],
        wand_rows=np.flatnonzero(s.wand)[good],
        p_wand=to_gauge.apply(p_fix[good]),
        wand_used=wand_used[good],
        spread=float(spread),
    )


# --------------------------------------------------------------------------- joint problem


@dataclass(frozen=True)
class _Problem:
    """The joint problem over the usable transmissions.

    Attributes:
        nlp: The CasADi problem.
        rows: Session row of each problem transmission (wand first), shape (W + T,).
        base_fixed: Gauge unknowns, shape (nx,) bool.
        needed: Kept receptions each transmission needs to stay in, shape (W + T,).
        unused: Receptions of the log left out of the problem.
    """

    nlp: CalibrationNlp
    rows: np.ndarray
    base_fixed: np.ndarray
    needed: np.ndarray
    unused: int

    @property
    def layout(self) -> Layout:
        return self.nlp.layout

    @property
    def receptions(self) -> Receptions:
        return self.nlp.receptions


def _build_problem(
    s: _Session, first: _FirstEstimate, opts: CalibrationOptions, gauge: tuple[int, int]
) -> _Problem:
    toa = s.other_readers_toa()
    tag_rows = np.flatnonzero(~s.wand & (np.isfinite(toa).sum(axis=1) >= _TAG_MIN))
    if not opts.reader_links:
        tag_rows = tag_rows[:0]
    rows = np.concatenate([first.wand_rows, tag_rows])
    sub = toa[rows]
    with np.errstate(all="ignore"):
        shift = np.nanmin(np.where(np.isfinite(sub), sub, np.inf), axis=1)
    k, r = np.nonzero(np.isfinite(sub))
    n_wand = first.wand_rows.size
    layout = Layout(readers=len(s.ids), wand=n_wand, tags=tag_rows.size)
    receptions = Receptions(
        transmission=k,
        reader=r,
        emitter=np.where(k < n_wand, -1, s.emitter[rows[k]]),
        toa=sub[k, r] - shift[k],
    )
    nlp = CalibrationNlp(
        layout, receptions, s.z, max_iterations=opts.max_iterations, tolerance=opts.tolerance
    )
    base_fixed = np.zeros(layout.size, dtype=bool)
    origin, axis = gauge
    base_fixed[[2 * origin, 2 * origin + 1, 2 * axis + 1, layout.clock + origin]] = True
    needed = np.where(np.arange(rows.size) < n_wand, _WAND_MIN, _TAG_MIN)
    unused = int(np.count_nonzero(np.isfinite(s.toa))) - receptions.size
    return _Problem(nlp, rows, base_fixed, needed, unused)


def _start(p: _Problem, first: _FirstEstimate) -> np.ndarray:
    """The start: first estimate, wand fixes, transmit times as median per transmission."""
    layout = p.layout
    x = layout.pack(first.p_xy, first.clocks, first.p_wand, np.zeros(p.rows.size))
    offsets = p.nlp.residuals(x)  # toa - (0 + distance + clock)
    rec = p.receptions
    tau = np.zeros(p.rows.size)
    order = np.argsort(rec.transmission, kind="stable")
    bounds = np.searchsorted(rec.transmission[order], np.arange(p.rows.size + 1))
    for k in range(p.rows.size):
        tau[k] = np.median(offsets[order[bounds[k] : bounds[k + 1]]])
    x[layout.wand_tau :] = tau
    return x


def _initial_keep(p: _Problem, first: _FirstEstimate, x0: np.ndarray) -> np.ndarray:
    """Receptions kept in the first solve: those the wand fixes kept, tags within 4 spreads."""
    rec = p.receptions
    keep = np.abs(p.nlp.residuals(x0)) <= 4.0 * max(first.spread, 0.01)
    wand = rec.wand
    keep[wand] = first.wand_used[rec.transmission[wand], rec.reader[wand]]
    return keep


@dataclass(frozen=True)
class _Solution:
    x: np.ndarray
    keep: np.ndarray  # receptions kept (N,)
    active: np.ndarray  # transmissions with enough kept receptions (W + T,)
    rounds: int
    iterations: int
    converged_set: bool


def _robust_sigma(r: np.ndarray) -> float:
    """``1.4826 median |r|`` [m] (at least 0.1 mm)."""
    return float(max(1.4826 * np.median(np.abs(r)), 1e-4)) if r.size else 1e-4


def _active(p: _Problem, keep: np.ndarray) -> np.ndarray:
    counts = np.bincount(
        p.receptions.transmission, weights=keep.astype(float), minlength=p.rows.size
    )
    return counts >= p.needed


def _fixed(p: _Problem, active: np.ndarray) -> np.ndarray:
    fixed = p.base_fixed.copy()
    for k in np.flatnonzero(~active):
        fixed[p.layout.transmission_unknowns(int(k))] = True
    return fixed


def _solve_rounds(
    p: _Problem, x: np.ndarray, keep: np.ndarray, opts: CalibrationOptions, source: Path | None
) -> _Solution:
    """IPOPT solves alternating with NLOS rejection until the kept set stops changing."""
    iterations = 0
    rec_tx = p.receptions.transmission
    for rounds in range(1, opts.max_rounds + 1):
        active = _active(p, keep)
        used = keep & active[rec_tx]
        scale = _robust_sigma(p.nlp.residuals(x)[used])
        fixed = _fixed(p, active)
        lbx = np.where(fixed, x, -np.inf)
        ubx = np.where(fixed, x, np.inf)
        result = p.nlp.solve(x, used / scale**2, lbx, ubx)
        iterations += result.iterations
        if not result.success:
            raise CalibrationError(
                f"the calibration did not converge (IPOPT: {result.status} after "
                f"{result.iterations} iterations in round {rounds}): the wand path may be too "
                "short or too close to a line through the readers; sway the wand through the "
                "whole constellation for a minute",
                path=source,
            )
        x = result.x
        r = p.nlp.residuals(x)
        scale = _robust_sigma(r[used])
        new_keep = (r <= opts.threshold * scale) & (r >= -opts.early_threshold * scale)
        if np.array_equal(new_keep, keep):
            return _Solution(x, keep, _active(p, keep), rounds, iterations, True)
        keep = new_keep
    return _Solution(x, keep, _active(p, keep), opts.max_rounds, iterations, False)


# --------------------------------------------------------------------------- calibrate


def calibrate(
    log: ToaLog | str | Path,
    heights: Mapping[str, float] | str | Path,
    options: CalibrationOptions | None = None,
    *,
    survey: Mapping[str, npt.ArrayLike] | str | Path | None = None,
    **overrides: Any,
) -> UwbCalibration:
    """Calibrate reader positions and clock offsets from a calibration log.

    Args:
        log: The TOA log (or its CSV path): reader-tag transmissions (tag id = reader id) and
            a swayed wand (any other tag id).
        heights: Reader heights ``{reader id: z [m]}`` or a heights YAML file; they define the
            readers and their order.
        options: Settings; keyword ``overrides`` replace single fields, e.g.
            ``calibrate(log, heights, sigma=0.03)``.
        survey: Surveyed positions ``{reader id: [x, y, z]}`` [m] (or a YAML file with
            ``points:``) of 2 or 3 readers: the result is moved onto them by a rigid horizontal
            fit (with 3 non-collinear points a mirror image is corrected too). Without it the
            result is in the gauge frame (first reader at the origin, second on +x).
        **overrides: Fields of :class:`CalibrationOptions`.

    Returns:
        The calibration.

    Raises:
        CalibrationError: For fewer than 5 readers, a wand path that leaves readers unobserved
            or a problem that does not converge (the message says what to do).
        InputError: For malformed input (naming file, line and field).
    """
    opts = _options(options, overrides)
    start = time.perf_counter()
    timings: dict[str, float] = {}
    heights_source = None if isinstance(heights, Mapping) else Path(heights)
    if isinstance(heights, Mapping):
        height_map = heights_from_mapping(heights)
    else:
        height_map = load_heights(heights)
    toa_log = log if isinstance(log, ToaLog) else read_toa_csv(log)
    survey_points = _survey_points(survey)
    s = _session(toa_log, height_map, heights_source)
    _check_wand(s, opts)
    gauge = _gauge_readers(s.ids, opts)

    tic = time.perf_counter()
    first = _first_estimate(s, opts, gauge)
    timings["first_estimate"] = time.perf_counter() - tic

    tic = time.perf_counter()
    p = _build_problem(s, first, opts, gauge)
    x0 = _start(p, first)
    keep = _initial_keep(p, first, x0)
    _check_determined(p, s, x0, keep, first.spread, opts)
    _ = p.nlp.solver  # build before timing the solve
    timings["build"] = time.perf_counter() - tic

    tic = time.perf_counter()
    sol = _solve_rounds(p, x0, keep, opts, s.source)
    timings["solve"] = time.perf_counter() - tic

    tic = time.perf_counter()
    result = _assemble(p, s, sol, first, opts, gauge, survey_points)
    timings["covariance"] = time.perf_counter() - tic
    timings["total"] = time.perf_counter() - start
    return replace(result, timings=timings)


def _options(
    options: CalibrationOptions | None, overrides: Mapping[str, Any]
) -> CalibrationOptions:
    opts = options or CalibrationOptions()
    if overrides:
        unknown = set(overrides) - set(CalibrationOptions.__dataclass_fields__)
        if unknown:
            raise TypeError(f"unknown calibration option(s): {', '.join(sorted(unknown))}")
        opts = replace(opts, **overrides)
    if opts.sigma is not None and not opts.sigma > 0:
        raise InputError(f"sigma must be positive, got {opts.sigma}", field="sigma")
    if not opts.threshold > 0 or not opts.early_threshold > 0:
        raise InputError("rejection thresholds must be positive", field="threshold")
    if opts.max_rounds < 1 or opts.max_iterations < 1:
        raise InputError("max_rounds and max_iterations must be at least 1", field="max_rounds")
    return opts


def _survey_points(
    survey: Mapping[str, npt.ArrayLike] | str | Path | None,
) -> tuple[dict[str, np.ndarray], Path | None] | None:
    if survey is None:
        return None
    if isinstance(survey, Mapping):
        return survey_from_mapping(survey), None
    path = Path(survey)
    return load_survey(path), path


# --------------------------------------------------------------------------- the result


def _assemble(
    p: _Problem,
    s: _Session,
    sol: _Solution,
    first: _FirstEstimate,
    opts: CalibrationOptions,
    gauge: tuple[int, int],
    survey: tuple[dict[str, np.ndarray], Path | None] | None,
) -> UwbCalibration:
    m = len(s.ids)
    layout = p.layout
    rec = p.receptions
    kept = sol.keep & sol.active[rec.transmission]
    wand_counts = np.bincount(rec.reader[kept & rec.wand], minlength=m)
    _check_observed(s.ids, wand_counts, opts.min_wand_receptions, s.source)
    r = p.nlp.residuals(sol.x)
    fixed = _fixed(p, sol.active)
    n_kept, n_free = int(np.count_nonzero(kept)), int(np.count_nonzero(~fixed))
    if opts.sigma is None:
        sigma = float(math.sqrt(np.sum(r[kept] ** 2) / max(n_kept - n_free, 1)))
    else:
        sigma = float(opts.sigma)
    cov_xy, cov_clock = _gauge_covariance(p, s, sol.x, kept, fixed, sigma)
    p_xy, clocks, p_wand, _ = layout.unpack(sol.x)
    p_readers = np.column_stack([p_xy, s.z])
    frame, transform, aligned, survey_rms, warnings = _output_frame(s, p_readers, gauge, survey)
    s_pos = alignment_projector(p_xy, aligned)
    rot = np.kron(np.eye(m), transform.rotation)
    pos_cov = rot @ s_pos @ cov_xy @ s_pos.T @ rot.T
    s_clock = np.eye(m) - np.full((m, m), 1.0 / m)
    clock_cov = s_clock @ cov_clock @ s_clock.T
    constellation = _constellation(s.ids, transform.apply(p_readers), clocks, pos_cov, sigma, opts)
    constellation = replace(constellation, metadata={"frame": frame})
    initial = make_constellation(
        transform.apply(np.column_stack([first.p_xy, s.z])),
        ids=s.ids,
        clock_offsets=first.clocks,
        sigma=first.spread,
        name="first_estimate",
    )
    wand_active = sol.active[: layout.wand]
    result = UwbCalibration(
        constellation=constellation,
        initial=initial,
        position_covariance=pos_cov,
        clock_covariance=clock_cov,
        wand_time=s.time[p.rows[: layout.wand][wand_active]],
        p_world_wand=transform.apply(p_wand[wand_active]),
        sigma=sigma,
        residual_rms=float(np.sqrt(np.mean(r[kept] ** 2))) if n_kept else float("nan"),
        outliers=_outliers(p, sol, kept, m),
        rounds=sol.rounds,
        iterations=sol.iterations,
        frame=frame,
        survey_rms=survey_rms,
        timings={},
    )
    return replace(result, warnings=tuple(warnings + _warnings(result, sol, opts)))


def _gauge_covariance(
    p: _Problem,
    s: _Session,
    x: np.ndarray,
    kept: np.ndarray,
    fixed: np.ndarray,
    sigma: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Covariance of the horizontal reader positions (2M, 2M) and clocks (M, M), gauge frame."""
    m = len(s.ids)
    jac = p.nlp.jacobian(x)
    info = (jac.T.multiply(kept / sigma**2)) @ jac
    wanted = np.arange(3 * m)  # x1, y1, ..., xM, yM, b1, ..., bM
    try:
        cov = marginal_covariance(info, np.flatnonzero(~fixed), wanted)
    except np.linalg.LinAlgError as err:
        raise CalibrationError(
            "the calibration is not determined (singular information matrix): the wand path "
            "does not observe every reader from enough directions; sway the wand through the "
            "whole constellation",
            path=s.source,
        ) from err
    return cov[: 2 * m, : 2 * m], cov[2 * m :, 2 * m :]


def _check_determined(
    p: _Problem,
    s: _Session,
    x0: np.ndarray,
    keep: np.ndarray,
    sigma: float,
    opts: CalibrationOptions,
) -> None:
    """Refuse a problem whose readers the data cannot place (predicted error at the start)."""
    active = _active(p, keep)
    kept = keep & active[p.receptions.transmission]
    cov_xy, _ = _gauge_covariance(p, s, x0, kept, _fixed(p, active), sigma)
    projector = alignment_projector(x0[: 2 * len(s.ids)].reshape(-1, 2))
    var = np.diagonal(projector @ cov_xy @ projector.T)
    horizontal = np.sqrt(np.maximum(var[0::2] + var[1::2], 0.0))
    weak = [rid for rid, h in zip(s.ids, horizontal) if h > opts.max_sigma]
    if weak:
        names = ", ".join(weak)
        raise CalibrationError(
            f"the wand path does not determine reader(s) {names} (predicted horizontal error "
            f"up to {horizontal.max():.1f} m): distance and clock offset of a reader separate "
            "only when the wand is seen from different distances and directions; walk the "
            f"wand through the whole constellation, closer to reader(s) {names}",
            path=s.source,
            field="reader",
            readers=weak,
        )


def _warnings(result: UwbCalibration, sol: _Solution, opts: CalibrationOptions) -> list[str]:
    out = []
    for rid, sigma in zip(result.ids, result.horizontal_sigma):
        if sigma > opts.warn_sigma:
            out.append(
                f"reader {rid} is poorly determined (predicted horizontal error "
                f"{100 * sigma:.0f} cm): walk closer to reader {rid} and around it"
            )
    if not sol.converged_set:
        out.append(
            f"NLOS rejection still changed after {opts.max_rounds} rounds; the result uses the "
            "last round"
        )
    return out


def _output_frame(
    s: _Session,
    p_readers: np.ndarray,
    gauge: tuple[int, int],
    survey: tuple[dict[str, np.ndarray], Path | None] | None,
) -> tuple[str, Rigid2D, list[int] | None, float | None, list[str]]:
    """The output transform, its description, the aligned readers and the survey misfit."""
    origin, axis = gauge
    if survey is None:
        text = (
            f"gauge: {s.ids[origin]} at x = y = 0, {s.ids[axis]} on the +x axis, clock offset "
            f"of {s.ids[origin]} = 0; heights as given"
        )
        return text, Rigid2D.identity(), None, None, []
    fit = align_to_survey(s.ids, p_readers, survey[0], survey[1])
    return fit.description, fit.transform, fit.readers, fit.rms, fit.warnings


def _constellation(
    ids: Sequence[str],
    p_world_readers: np.ndarray,
    clocks: np.ndarray,
    cov_xy: np.ndarray,
    sigma: float,
    opts: CalibrationOptions,
) -> Constellation:
    """The calibrated readers with a 3x3 covariance each (horizontal block, height variance)."""
    base = make_constellation(
        p_world_readers,
        ids=ids,
        clock_offsets=clocks,
        coverage=opts.coverage,
        sigma=sigma,
        name="calibrated",
    )
    readers = []
    for j, reader in enumerate(base.readers):
        cov = np.zeros((3, 3))
        block = cov_xy[2 * j : 2 * j + 2, 2 * j : 2 * j + 2]
        cov[:2, :2] = 0.5 * (block + block.T)
        cov[2, 2] = opts.height_sigma**2
        readers.append(replace(reader, position_covariance=cov))
    return base.with_readers(readers)


def _outliers(p: _Problem, sol: _Solution, kept: np.ndarray, m: int) -> OutlierReport:
    rec = p.receptions
    inside = sol.active[rec.transmission]
    rejected = inside & ~kept
    per_total = np.bincount(rec.reader[inside], minlength=m)
    per_rejected = np.bincount(rec.reader[rejected], minlength=m)
    return OutlierReport(
        receptions=int(np.count_nonzero(inside)),
        rejected=int(np.count_nonzero(rejected)),
        wand_receptions=int(np.count_nonzero(inside & rec.wand)),
        wand_rejected=int(np.count_nonzero(rejected & rec.wand)),
        per_reader=per_rejected / np.maximum(per_total, 1),
        unused=p.unused + int(np.count_nonzero(~inside)),
    )
