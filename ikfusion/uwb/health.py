"""How well the UWB data of a solve fit the constellation: per tag and per reader.

The tag filters (:mod:`ikfusion.uwb.ekf`) absorb a reader whose clock jumps, NLOS receptions
and readers that go silent by rejecting or missing their times of arrival; this module counts
those rejections so that ``summary.json`` can say which reader was rejected how often and when,
and decides whether a tag's data fit the constellation at all (permuted reader ids, a wrong
readers file: almost every TOA rejected), so that such a tag does not pull the body.

The two thresholds come from simulated clean captures with the default 10 % NLOS
(``benchmarks/bench_uwb_health.py`` prints the figures they are set from).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .ekf import UnitTrack

#: A reader whose share of rejected TOAs exceeds this is reported as faulty. Healthy readers
#: of clean simulated captures (10 % NLOS) reach at most 0.18 (8 walks of 20 s in room_6x8
#: and small_6, seeds 1-4; ``bench_uwb_health.py`` prints the figures).
READER_REJECTED_SHARE_LIMIT = 0.3
#: A tag whose filter used fewer of its received transmissions than this share does not fit
#: the constellation (clean simulated captures use at least 0.975 of them).
TAG_USED_SHARE_MIN = 0.5
#: A tag whose share of rejected TOAs exceeds this does not fit the constellation either
#: (clean simulated captures reject at most 0.19, NLOS mostly).
TAG_REJECTED_SHARE_MAX = 0.5
#: Fewer evaluated TOAs than this say too little for a warning about a reader.
_MIN_RECEPTIONS = 30
#: Length of the bins in which rejections and silences are located [s].
_BIN_S = 1.0
#: At most this many windows are listed per reader (the longest first, then in time order).
_MAX_WINDOWS = 8


@dataclass(frozen=True)
class TagFit:
    """How a tag's data fit the constellation.

    Attributes:
        received: Transmissions heard by at least one reader.
        used: Transmissions with at least one TOA used by the filter.
        toas_used: TOAs that updated the filter.
        toas_rejected: TOAs rejected by its gate.
        problem: Why the tag must not aid the solve (with numbers), or None when it may.
    """

    received: int
    used: int
    toas_used: int
    toas_rejected: int
    problem: str | None

    @property
    def rejected_share(self) -> float:
        """Share of the evaluated TOAs that were rejected (0 with none evaluated)."""
        evaluated = self.toas_used + self.toas_rejected
        return self.toas_rejected / evaluated if evaluated else 0.0


def tag_fit(track: UnitTrack) -> TagFit:
    """Judge one tag's track: does it fit the constellation well enough to aid a solve?"""
    t = track.totals
    return fit_from_counts(int(t.transmissions), int(t.transmissions_used), int(t.toas_used),
                           int(t.toas_rejected))


def fit_from_counts(received: int, used: int, toas_used: int, toas_rejected: int) -> TagFit:
    """:func:`tag_fit` from the counts of a tag's transmissions and TOAs (any stretch)."""
    fit = TagFit(received, used, toas_used, toas_rejected, None)
    if fit.received == 0:
        problem = "no transmission received"
    elif fit.used < TAG_USED_SHARE_MIN * fit.received:
        problem = (f"only {fit.used} of {fit.received} transmissions fit the readers "
                   f"(at least {TAG_USED_SHARE_MIN:.0%} expected)")
    elif fit.rejected_share > TAG_REJECTED_SHARE_MAX:
        problem = (f"{fit.toas_rejected} of {fit.toas_used + fit.toas_rejected} TOAs rejected "
                   f"({fit.rejected_share:.0%}, at most {TAG_REJECTED_SHARE_MAX:.0%} expected)")
    else:
        return fit
    return TagFit(fit.received, fit.used, fit.toas_used, fit.toas_rejected, problem)


def reader_report(tracks: Sequence[UnitTrack], reader_ids: Sequence[str]
                  ) -> dict[str, dict[str, Any]]:
    """Per reader, over the given tag tracks: TOAs received and rejected, and when.

    Returns:
        ``{reader id: {received, evaluated, rejected, rejected_share, rejected_windows,
        silent_windows}}``: TOAs received, TOAs the filters evaluated (none before a filter
        starts), TOAs they rejected and their share of the evaluated ones, and windows
        ``[t0, t1]`` [s] (1 s bins, 0.1 s resolution) where most of the reader's evaluated TOAs were
        rejected, or where it heard nothing while other readers heard the tags.
    """
    if not tracks:
        return {}
    time = np.concatenate([t.tx_time for t in tracks])
    heard = np.concatenate([t.tx_heard for t in tracks])
    evaluated = np.concatenate([t.tx_used | t.tx_rejected for t in tracks])
    rejected = np.concatenate([t.tx_rejected for t in tracks])
    start = float(time.min()) if time.size else 0.0
    bins = np.floor((time - start) / _BIN_S).astype(int)
    n_bins = int(bins.max()) + 1 if bins.size else 0
    tx_per_bin = np.bincount(bins, weights=heard.any(axis=1), minlength=n_bins)
    out: dict[str, dict[str, Any]] = {}
    for j, rid in enumerate(reader_ids):
        heard_bin = np.bincount(bins, weights=heard[:, j], minlength=n_bins)
        evaluated_bin = np.bincount(bins, weights=evaluated[:, j], minlength=n_bins)
        rejected_bin = np.bincount(bins, weights=rejected[:, j], minlength=n_bins)
        n_evaluated, n_rejected = int(evaluated[:, j].sum()), int(rejected[:, j].sum())
        mostly_rejected = (rejected_bin >= 3) & (rejected_bin > 0.5 * evaluated_bin)
        silent = (heard_bin == 0) & (tx_per_bin >= 3)
        out[rid] = {
            "received": int(heard[:, j].sum()),
            "evaluated": n_evaluated,
            "rejected": n_rejected,
            "rejected_share": round(n_rejected / n_evaluated, 4) if n_evaluated else 0.0,
            "rejected_windows": _windows(mostly_rejected, start),
            "silent_windows": _windows(silent, start),
        }
    return out


def faulty_readers(report: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Warnings for readers whose rejected share exceeds :data:`READER_REJECTED_SHARE_LIMIT`.

    One warning per such reader; when most readers are, one warning for the whole file (the
    readers file does not fit the log, e.g. permuted ids).
    """
    faulty = [rid for rid, e in report.items() if e["evaluated"] >= _MIN_RECEPTIONS
              and e["rejected_share"] > READER_REJECTED_SHARE_LIMIT]
    limit = f"a healthy reader stays below {READER_REJECTED_SHARE_LIMIT:.0%}"
    if len(faulty) > len(report) // 2:
        return [f"UWB: {len(faulty)} of {len(report)} readers have most of their TOAs rejected "
                f"({limit}): the readers file does not fit the TOA log (ids permuted, "
                "positions or clock offsets wrong?)"]
    warnings = []
    for rid in faulty:
        e = report[rid]
        when = f", mostly in {e['rejected_windows']} s" if e["rejected_windows"] else ""
        warnings.append(f"UWB reader {rid}: {e['rejected']} of {e['evaluated']} TOAs rejected "
                        f"({e['rejected_share']:.0%}; {limit}){when}: check its position, "
                        "clock and line of sight")
    return warnings


def _windows(flags: np.ndarray, start: float) -> list[list[float]]:
    """Runs of True bins as ``[t0, t1]`` [s]; the longest :data:`_MAX_WINDOWS`, in time order."""
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    runs = list(zip(edges[0::2], edges[1::2]))
    runs = sorted(sorted(runs, key=lambda r: r[0] - r[1])[:_MAX_WINDOWS])
    return [[round(float(start + a * _BIN_S), 1), round(float(start + b * _BIN_S), 1)]
            for a, b in runs]
