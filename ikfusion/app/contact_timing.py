"""When the solver plants and releases each contact point, against the truth's contact phases.

Each edge of the truth's contact state of a point (a plant: free -> planted, a release:
planted -> free) is matched with the solver's nearest edge of the same kind on that point
within ``window`` seconds; the signed offset ``t_solver - t_truth`` [s] says how late (positive)
or early (negative) the solver was. Truth edges without a solver edge that near are counted as
unmatched (a missed or merged step), not averaged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class EdgeTiming:
    """Timing of one kind of edge (plant or release) of one contact point.

    Attributes:
        mean_ms: Mean signed offset solver - truth [ms] over matched edges (NaN: none).
        median_ms: Median signed offset [ms] (NaN: none).
        matched: Truth edges with a solver edge within the window.
        unmatched: Truth edges without.
    """

    mean_ms: float
    median_ms: float
    matched: int
    unmatched: int

    def as_dict(self) -> dict[str, float | int]:
        """Plain dictionary (for JSON)."""
        return {"mean_ms": self.mean_ms, "median_ms": self.median_ms,
                "matched": self.matched, "unmatched": self.unmatched}


def _edges(time: np.ndarray, state: np.ndarray, rising: bool) -> np.ndarray:
    """Times [s] of the first sample after each rising (or falling) edge of ``state``."""
    step = np.diff(state.astype(np.int8))
    return time[1:][step == (1 if rising else -1)]


def edge_offsets(time: np.ndarray, truth: np.ndarray, solver: np.ndarray, rising: bool,
                 window: float = 0.25) -> tuple[np.ndarray, int]:
    """Signed offsets [s] of the solver's edges from the truth's, and the unmatched count.

    Args:
        time: (N,) sample times [s].
        truth: (N,) the truth's contact state of one point.
        solver: (N,) the solver's at the same times.
        rising: Plants (True) or releases (False).
        window: Largest offset that still matches [s].
    """
    t_true = _edges(time, truth, rising)
    t_solver = _edges(time, solver, rising)
    offsets = []
    unmatched = 0
    for t in t_true:
        if not len(t_solver):
            unmatched += 1
            continue
        nearest = t_solver[int(np.argmin(np.abs(t_solver - t)))]
        if abs(nearest - t) <= window:
            offsets.append(nearest - t)
        else:
            unmatched += 1
    return np.asarray(offsets, dtype=float), unmatched


def contact_timing(time: np.ndarray, truth: np.ndarray, solver: np.ndarray,
                   names: list[str], window: float = 0.25) -> dict[str, dict[str, EdgeTiming]]:
    """Per contact point, the timing of its plants and releases against the truth.

    Args:
        time: (N,) sample times [s].
        truth: (N, k) the truth's contact states.
        solver: (N, k) the solver's at the same times.
        names: (k,) the points' names.
        window: Largest offset that still matches [s].

    Returns:
        ``{name: {"plant": EdgeTiming, "release": EdgeTiming}}``.
    """
    out: dict[str, dict[str, EdgeTiming]] = {}
    for i, name in enumerate(names):
        out[name] = {}
        for kind, rising in (("plant", True), ("release", False)):
            offsets, unmatched = edge_offsets(time, truth[:, i], solver[:, i], rising, window)
            ms = 1e3 * offsets
            out[name][kind] = EdgeTiming(
                float(np.mean(ms)) if len(ms) else float("nan"),
                float(np.median(ms)) if len(ms) else float("nan"), len(ms), unmatched)
    return out
