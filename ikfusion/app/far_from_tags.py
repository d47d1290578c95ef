"""When the solved body stayed far from its tags: no silent failure of the correction.

Per tag, the horizontal distance between the solved tag site and the tag's fix is followed over
the frames; every stretch where it stays above ``distance`` [m] for longer than ``duration`` [s]
is reported with when (start and end) and how much (largest and mean distance). Frames without a
fix neither start nor break a stretch: a stretch ends at the first frame back within
``distance``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FarInterval:
    """A stretch where a solved tag site stayed far from its fix.

    Attributes:
        site: The tag site.
        start: First frame time beyond the distance [s].
        end: Last frame time beyond it [s].
        max_m: Largest horizontal distance [m].
        mean_m: Mean horizontal distance over the stretch's frames with a fix [m].
    """

    site: str
    start: float
    end: float
    max_m: float
    mean_m: float

    def as_dict(self) -> dict[str, object]:
        """The ``summary.json`` entry (``uwb.far_from_tags``)."""
        return {"site": self.site, "start_s": round(self.start, 3), "end_s": round(self.end, 3),
                "max_m": round(self.max_m, 4), "mean_m": round(self.mean_m, 4)}

    def message(self, distance: float) -> str:
        """The warning of ``summary.json`` and the terminal."""
        return (f"UWB correction: {self.site} stayed more than {100 * distance:.0f} cm from its "
                f"tag from t = {self.start:.2f} s to {self.end:.2f} s "
                f"({self.end - self.start:.2f} s; up to {100 * self.max_m:.1f} cm, mean "
                f"{100 * self.mean_m:.1f} cm): the motion there is not where the tags say")


def far_intervals(site: str, time: np.ndarray, distance_m: np.ndarray, distance: float,
                  duration: float) -> list[FarInterval]:
    """The stretches where ``distance_m`` stays above ``distance`` longer than ``duration``.

    Args:
        site: The tag site (named in the result).
        time: (N,) frame times [s].
        distance_m: (N,) solved site to fix, horizontal [m]; NaN where there is no fix.
        distance: Threshold [m].
        duration: Shortest stretch reported [s].
    """
    out: list[FarInterval] = []
    start: int | None = None
    last = -1
    for k, d in enumerate(distance_m):
        if not np.isfinite(d):
            continue
        if d > distance:
            if start is None:
                start = k
            last = k
        elif start is not None:
            out += _interval(site, time, distance_m, start, last, duration)
            start = None
    if start is not None:
        out += _interval(site, time, distance_m, start, last, duration)
    return out


def _interval(site: str, time: np.ndarray, distance_m: np.ndarray, start: int, last: int,
              duration: float) -> list[FarInterval]:
    """The stretch ``start..last`` (frame indices) when it lasted longer than ``duration``."""
    if time[last] - time[start] <= duration:
        return []
    d = distance_m[start:last + 1]
    d = d[np.isfinite(d)]
    return [FarInterval(site, float(time[start]), float(time[last]), float(d.max()),
                        float(d.mean()))]
