"""Bridging the samples a sensor did not deliver (lost packets, NaN, a sensor that drops out).

A segment whose sample is missing is not left to the solver's priors (it would go wherever the
posture and persistence tasks put it and jump back when its sensor returns): its orientation is
filled from what is known around the gap, so the solver always has a target and nothing jumps.

Offline (the whole recording is known), per gap of a segment's valid samples:

* short gaps inside the recording (up to ``short_gap_s``): slerp of ``R_world_segment`` between
  the samples on either side;
* longer gaps, and gaps at the start or the end: the segment is carried by its *neighbour* (the
  nearest sensed segment up the tree, already bridged itself: segments are processed from the
  root to the leaves; for the root the most rigidly attached sensed segment). The relative
  orientation ``R_neighbour_segment = R_world_neighbour^T R_world_segment`` is slerped between
  the gap's two ends (held at the start or end of the recording), so the body's global motion
  during the gap is kept and the returning sensor is met exactly.

Causal (``causal=True``, no look-ahead, as live): during a gap the relative orientation to the
neighbour continues with the last relative rate, decaying with time constant ``rate_decay_s``;
when the sensor returns, the difference between the bridged and the measured relative
orientation is removed at ``blend_rate_deg`` [deg/s] at most. A gap at the very start stays
untracked (nothing is known yet). The thresholds are in ``configs/bridging.yaml``.

:func:`bridge_segments` returns the filled orientations, which samples were bridged, a
``summary.json`` block (``bridged``) and warnings for segments with much bridging or a long gap.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..rotations import exp_so3, log_so3, matrix_to_quat_wxyz, quat_wxyz_to_matrix, slerp
from ..settings_files import ShippedSettings

__all__ = ["BridgedSegments", "BridgingSettings", "SegmentBridging", "bridge_segments",
           "bridging_report", "runs_of", "world_filled"]


@dataclass(frozen=True)
class BridgingSettings(ShippedSettings):
    """How gaps are bridged and when they are worth a warning.

    Attributes:
        short_gap_s: Offline, gaps inside the recording up to this long are slerped in the world
            frame [s]; longer ones follow the neighbour.
        blend_rate_deg: Causal, the largest rate at which a returning sensor's offset from the
            bridged orientation is removed [deg/s].
        rate_decay_s: Causal, time constant of the decay of the last relative rate [s].
        warn_share: Share of bridged samples of a segment above which a warning is given.
        warn_gap_s: Gap length above which a warning is given [s].
        listed_gaps: At most this many (merged) gaps are listed per segment in the summary.
        merge_s: Gaps closer than this are listed as one [s].
    """

    short_gap_s: float
    blend_rate_deg: float
    rate_decay_s: float
    warn_share: float
    warn_gap_s: float
    listed_gaps: int
    merge_s: float

    @property
    def blend_rate(self) -> float:
        """``blend_rate_deg`` in [rad/s]."""
        return float(np.radians(self.blend_rate_deg))

    shipped_file = "bridging.yaml"
    what = "bridging settings"


@dataclass
class SegmentBridging:
    """What was bridged for one segment.

    Attributes:
        samples: Samples bridged.
        share: Bridged samples / all samples.
        longest_gap_s: Longest gap [s].
        gaps: Merged gaps ``[t0, t1]`` [s] (at most ``listed_gaps``, the longest, in time
            order): from the first missing sample to when the sensor was back.
        gap_count: Gaps before merging.
        neighbour: The segment it followed in long gaps (None: the world slerp only).
        untracked: Samples left without a target (causal start gap, no sample at all).
        longest_at: ``(t0, t1)`` of the longest gap [s].
    """

    samples: int
    share: float
    longest_gap_s: float
    gaps: list[list[float]]
    gap_count: int
    neighbour: str | None
    untracked: int = 0
    longest_at: tuple[float, float] = (0.0, 0.0)

    def as_dict(self) -> dict[str, object]:
        """Plain dictionary for ``summary.json``."""
        return {"samples": self.samples, "share": round(self.share, 5),
                "longest_gap_s": round(self.longest_gap_s, 4),
                "gaps": [[round(a, 4), round(b, 4)] for a, b in self.gaps],
                "gap_count": self.gap_count, "neighbour": self.neighbour,
                "untracked": self.untracked}


@dataclass
class BridgedSegments:
    """Segment orientations with their gaps filled.

    Attributes:
        R_world_segment: Segment -> (N, 3, 3); NaN only where nothing could be bridged.
        bridged: Segment -> (N,) True where the orientation was bridged, not measured.
        report: Segment -> :class:`SegmentBridging` for segments with a bridged sample.
        warnings: Messages for the user (much bridging, long gaps).
        causal: Whether the bridging looked only at the past.
    """

    R_world_segment: dict[str, np.ndarray]
    bridged: dict[str, np.ndarray]
    report: dict[str, SegmentBridging] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    causal: bool = False

    def summary(self) -> dict[str, dict[str, object]]:
        """The ``bridged`` block of ``summary.json``: segment -> what was bridged."""
        return {s: r.as_dict() for s, r in self.report.items()}

    def tracked(self, segment: str) -> np.ndarray:
        """(N,) True where the segment has an orientation target (measured or bridged)."""
        return np.isfinite(self.R_world_segment[segment]).all(axis=(1, 2))


def runs_of(mask: np.ndarray) -> np.ndarray:
    """(k, 2) start and end (exclusive) indices of the True runs of ``mask``."""
    edges = np.diff(np.r_[0, np.asarray(mask, dtype=np.int8), 0])
    return np.column_stack([np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)])


def _transpose(R: np.ndarray) -> np.ndarray:
    return np.swapaxes(R, -1, -2)


def _slerp_matrices(R0: np.ndarray, R1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotations from ``R0`` to ``R1`` (each (3, 3)) at fractions ``t`` (n,)."""
    return quat_wxyz_to_matrix(slerp(matrix_to_quat_wxyz(R0), matrix_to_quat_wxyz(R1), t))


def _fill_gap(R: np.ndarray, a: int, b: int) -> None:
    """Fill ``R[a:b]`` in place: slerp between ``R[a-1]`` and ``R[b]``, held at either end."""
    n = len(R)
    if a > 0 and b < n:
        R[a:b] = _slerp_matrices(R[a - 1], R[b], (np.arange(a, b) - a + 1.0) / (b - a + 1.0))
    elif a > 0:
        R[a:b] = R[a - 1]
    elif b < n:
        R[a:b] = R[b]


def world_filled(R: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """A copy of ``R`` with every gap of ``valid`` slerped (held at the ends)."""
    out = np.where(valid[:, None, None], R, np.nan)
    if valid.any():
        for a, b in runs_of(~valid):
            _fill_gap(out, int(a), int(b))
    return out


def _rigidity(R_a: np.ndarray, R_b: np.ndarray, valid: np.ndarray) -> float:
    """RMS angle [rad] of ``R_a^T R_b`` from its mean over the samples both have."""
    rel = _transpose(R_a[valid]) @ R_b[valid]
    if not len(rel):
        return np.inf
    u, _, vt = np.linalg.svd(rel.mean(axis=0))
    mean = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    return float(np.sqrt(np.mean(np.sum(log_so3(_transpose(mean) @ rel) ** 2, axis=-1))))


def _order_and_neighbours(segments: list[str], parents: Mapping[str, str | None],
                          R: Mapping[str, np.ndarray], valid: Mapping[str, np.ndarray]
                          ) -> tuple[list[str], dict[str, str | None]]:
    """Processing order (root to leaves) and each segment's neighbour.

    A segment's neighbour is its nearest sensed ancestor; a segment without one (the root)
    takes the sensed segment whose orientation relative to it varies least.
    """
    def ancestors(s: str) -> list[str]:
        chain, p = [], parents.get(s)
        while p is not None and p not in chain:
            chain.append(p)
            p = parents.get(p)
        return chain

    depth = {s: len(ancestors(s)) for s in segments}
    order = sorted(segments, key=lambda s: depth[s])
    neighbours: dict[str, str | None] = {}
    for s in order:
        up = [a for a in ancestors(s) if a in R]
        if up:
            neighbours[s] = up[0]
            continue
        others = [o for o in segments if o != s]
        scores = {o: _rigidity(R[s], R[o], valid[s] & valid[o]) for o in others}
        best = min(others, key=lambda o: scores[o]) if others else None
        neighbours[s] = best if best is not None and np.isfinite(scores[best]) else None
    return order, neighbours


def _offline_segment(R: np.ndarray, valid: np.ndarray, R_ref: np.ndarray | None,
                     short: int) -> np.ndarray:
    """One segment's orientations with every gap filled (see the module docstring)."""
    out = np.where(valid[:, None, None], R, np.nan)
    rel = None if R_ref is None else _transpose(R_ref) @ out
    n = len(R)
    for a, b in runs_of(~valid):
        a, b = int(a), int(b)
        inside = a > 0 and b < n
        if rel is None or R_ref is None or (inside and b - a <= short):
            _fill_gap(out, a, b)
        else:
            _fill_gap(rel, a, b)
            out[a:b] = R_ref[a:b] @ rel[a:b]
    return out


def _causal_segment(R: np.ndarray, valid: np.ndarray, R_ref: np.ndarray | None,
                    time: np.ndarray, settings: BridgingSettings) -> np.ndarray:
    """One segment's orientations, each gap bridged from the past only; returns blended in."""
    out = np.where(valid[:, None, None], R, np.nan)
    ref = np.broadcast_to(np.eye(3), R.shape) if R_ref is None else R_ref
    n = len(R)
    gaps = runs_of(~valid)
    for g, (a, b) in enumerate(gaps):
        a, b = int(a), int(b)
        if a == 0:
            continue  # nothing known yet: untracked until the first sample
        rel_last = ref[a - 1].T @ out[a - 1]
        omega = np.zeros(3)
        if a >= 2 and np.isfinite(out[a - 2]).all():
            dt = time[a - 1] - time[a - 2]
            omega = log_so3((ref[a - 2].T @ out[a - 2]).T @ rel_last) / dt
        tau = settings.rate_decay_s
        elapsed = time[a:b] - time[a - 1]
        turn = omega[None, :] * (tau * (1.0 - np.exp(-elapsed / tau)))[:, None]
        rel_gap = rel_last @ exp_so3(turn)
        out[a:b] = ref[a:b] @ rel_gap
        if b >= n:
            continue
        # The sensor is back: remove the offset at a bounded rate until the next gap.
        rel_held = rel_last @ exp_so3(omega * tau * (1.0 - np.exp(-(time[b] - time[a - 1])
                                                                   / tau)))
        end = int(gaps[g + 1][0]) if g + 1 < len(gaps) else n
        rel_meas = _transpose(ref[b:end]) @ out[b:end]
        offset = log_so3(rel_meas[0].T @ rel_held)
        angle = float(np.linalg.norm(offset))
        if angle < 1e-9:
            continue
        left = np.clip(1.0 - settings.blend_rate * (time[b:end] - time[b]) / angle, 0.0, 1.0)
        k = np.flatnonzero(left > 0.0)
        out[b:b + len(k)] = ref[b:b + len(k)] @ rel_meas[k] @ exp_so3(
            left[k, None] * offset[None, :])
    return out


def _report(bridged: np.ndarray, untracked: np.ndarray, time: np.ndarray, rate: float,
            neighbour: str | None, settings: BridgingSettings) -> SegmentBridging:
    """What was bridged of one segment, its gaps merged and the longest listed."""
    runs = runs_of(bridged | untracked)
    starts = time[runs[:, 0]]
    ends = starts + (runs[:, 1] - runs[:, 0]) / rate
    merged: list[list[float]] = []
    for t0, t1 in zip(starts, ends):
        if merged and t0 - merged[-1][1] < settings.merge_s:
            merged[-1][1] = float(t1)
        else:
            merged.append([float(t0), float(t1)])
    if len(merged) > settings.listed_gaps:
        merged = sorted(sorted(merged, key=lambda g: g[0] - g[1])[: settings.listed_gaps])
    n = len(bridged)
    i = int(np.argmax(runs[:, 1] - runs[:, 0])) if len(runs) else -1
    return SegmentBridging(
        samples=int(bridged.sum()), share=float(bridged.sum() / n) if n else 0.0,
        longest_gap_s=float(ends[i] - starts[i]) if len(runs) else 0.0,
        gaps=merged, gap_count=len(runs), neighbour=neighbour, untracked=int(untracked.sum()),
        longest_at=(float(starts[i]), float(ends[i])) if len(runs) else (0.0, 0.0))


def _gap_warning(segment: str, r: SegmentBridging, time: np.ndarray, rate: float,
                 settings: BridgingSettings) -> str | None:
    """A warning about a segment's longest gap when it is long, else None."""
    if r.longest_gap_s <= settings.warn_gap_s:
        return None
    t0, t1 = r.longest_at
    end = t1 >= float(time[-1]) + 0.5 / rate
    where = f"from {t0:.2f} s to the end" if end else f"at {t0:.2f}-{t1:.2f} s"
    how = (f"held relative to {r.neighbour}" if end else f"bridged following {r.neighbour}") \
        if r.neighbour else "bridged by slerp"
    return (f"{segment}: no valid sample of its sensor for {r.longest_gap_s:.2f} s {where}; "
            f"{how}")


def _share_warning(report: Mapping[str, SegmentBridging],
                   settings: BridgingSettings) -> str | None:
    """One warning naming the segments with more than ``warn_share`` bridged, else None."""
    many = [f"{s} {100 * r.share:.1f} %" for s, r in report.items()
            if r.share > settings.warn_share]
    if not many:
        return None
    return ("samples bridged (lost packets or invalid samples; see summary.json 'bridged'): "
            + ", ".join(many))


def bridge_segments(R_world_segment: Mapping[str, np.ndarray], valid: Mapping[str, np.ndarray],
                    time: np.ndarray, parents: Mapping[str, str | None], causal: bool = False,
                    settings: BridgingSettings | None = None) -> BridgedSegments:
    """Fill every segment's invalid samples so that nothing jumps (see the module docstring).

    Args:
        R_world_segment: Segment -> (N, 3, 3) calibrated orientations; samples where ``valid``
            is False are not read (they may be NaN or anything).
        valid: Segment -> (N,) True where the sample was received and is trusted.
        time: (N,) sample times [s].
        parents: Segment -> its parent segment in the model's tree (None for the root); the
            segments of the model without a sensor may appear too.
        causal: Use only the past at each sample (live); otherwise the whole recording.
        settings: Thresholds.

    Returns:
        The :class:`BridgedSegments`.
    """
    st = settings or BridgingSettings.load()
    time = np.asarray(time, dtype=float)
    n = len(time)
    rate = float((n - 1) / (time[-1] - time[0])) if n > 1 and time[-1] > time[0] else 1.0
    segments = list(R_world_segment)
    R = {s: np.asarray(R_world_segment[s], dtype=float) for s in segments}
    ok = {s: np.asarray(valid[s], dtype=bool) & np.isfinite(R[s]).all(axis=(1, 2))
          for s in segments}
    order, neighbours = _order_and_neighbours(segments, parents, R, ok)
    out: dict[str, np.ndarray] = {}
    used: dict[str, str | None] = {}
    for s in order:
        if ok[s].all():
            out[s] = R[s]
            continue
        nb = neighbours[s]
        if nb is None or not ok[nb].any():
            R_ref = None
        elif nb in out:
            R_ref = out[nb]
        else:  # the root's neighbour, not bridged yet: its own world slerp
            R_ref = world_filled(R[nb], ok[nb])
        if R_ref is not None and not np.isfinite(R_ref).all():
            R_ref = None
        used[s] = nb if R_ref is not None else None
        if not ok[s].any():
            out[s] = np.full_like(R[s], np.nan)
        elif causal:
            out[s] = _causal_segment(R[s], ok[s], R_ref, time, st)
        else:
            out[s] = _offline_segment(R[s], ok[s], R_ref, max(1, int(round(st.short_gap_s
                                                                              * rate))))
    untracked = {s: ~np.isfinite(out[s]).all(axis=(1, 2)) for s in used}
    bridged = {s: ~ok[s] & ~untracked[s] for s in used}
    result = bridging_report(out, bridged, untracked, time, used, st, causal)
    result.bridged = {s: ~ok[s] for s in segments} | bridged
    return result


def bridging_report(R_world_segment: dict[str, np.ndarray], bridged: Mapping[str, np.ndarray],
                    untracked: Mapping[str, np.ndarray], time: np.ndarray,
                    neighbours: Mapping[str, str | None], settings: BridgingSettings,
                    causal: bool = False) -> BridgedSegments:
    """The report of a bridging: per segment with a bridged or untracked sample, and warnings.

    Args:
        R_world_segment: The bridged orientations (kept in the result; may be empty).
        bridged: Segment -> (N,) True where the orientation was bridged.
        untracked: Segment -> (N,) True where the segment had no orientation at all.
        time: (N,) frame times [s].
        neighbours: Segment -> the segment it followed (None: none).
        settings: Thresholds of the warnings and the listing.
        causal: Whether the bridging looked only at the past.
    """
    n = len(time)
    rate = float((n - 1) / (time[-1] - time[0])) if n > 1 and time[-1] > time[0] else 1.0
    result = BridgedSegments(R_world_segment, dict(bridged), causal=causal)
    for s in bridged:
        if not (bridged[s].any() or untracked[s].any()):
            continue
        r = _report(bridged[s], untracked[s], time, rate, neighbours.get(s), settings)
        result.report[s] = r
        warning = _gap_warning(s, r, time, rate, settings)
        if warning:
            result.warnings.append(warning)
    share = _share_warning(result.report, settings)
    if share:
        result.warnings.append(share)
    return result
