"""Bridging missing samples sample by sample, from the past only (live and ``--causal``).

The causal rule of :mod:`ikfusion.imu.bridging`, one frame at a time: during a gap a segment's
orientation relative to its *neighbour* continues with the last relative rate, decaying with
``rate_decay_s``; when its sensor returns, the difference is removed at ``blend_rate_deg`` at
most. A segment's neighbour is its nearest sensed ancestor; the root's is its nearest sensed
descendant (breadth first), read as measured (not bridged) since the root is bridged first.
A segment whose neighbour has no orientation either is held still in the world. Nothing is
known before a sensor's first sample: the segment stays untracked until then.

:meth:`BridgeStream.result` gives the same :class:`~ikfusion.imu.bridging.BridgedSegments`
report (``summary.json`` ``bridged``, warnings) as the whole-recording functions.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..rotations import exp_so3, log_so3
from .bridging import BridgedSegments, BridgingSettings, bridging_report

_EYE = np.eye(3)
_EYE.flags.writeable = False


class _SegmentBridge:
    """The causal bridge of one segment (see the module docstring)."""

    def __init__(self, settings: BridgingSettings) -> None:
        self.settings = settings
        self.out: np.ndarray | None = None      # last output R_world_segment
        # last two (time, R_world_reference, output): the relative orientation is worked out
        # only when a gap needs it, not on every frame
        self.history: list[tuple[float, np.ndarray, np.ndarray]] = []
        self.gap: tuple[float, np.ndarray, np.ndarray] | None = None  # t_last, rel_last, omega
        self.blend: tuple[float, np.ndarray, float] | None = None  # t_back, offset, angle

    def _held(self, time_s: float) -> np.ndarray:
        """The relative orientation carried through the gap to ``time_s``."""
        assert self.gap is not None
        t_last, rel_last, omega = self.gap
        tau = self.settings.rate_decay_s
        return rel_last @ exp_so3(omega * tau * (1.0 - np.exp(-(time_s - t_last) / tau)))

    def step(self, time_s: float, R: np.ndarray | None, ref: np.ndarray | None
             ) -> tuple[np.ndarray | None, bool]:
        """(R_world_segment or None when untracked, whether it was bridged) at one frame."""
        R_ref = _EYE if ref is None else ref
        if R is None:
            if self.out is None:
                return None, False
            if self.gap is None:
                self._start_gap()
            out = R_ref @ self._held(time_s)
            self._keep(time_s, out, R_ref)
            return out, True
        if self.gap is not None:  # the sensor is back: blend the offset out
            rel = R_ref.T @ R
            offset = log_so3(rel.T @ self._held(time_s))
            angle = float(np.linalg.norm(offset))
            self.blend = (time_s, offset, angle) if angle >= 1e-9 else None
            self.gap = None
        out = R
        if self.blend is not None:
            t_back, offset, angle = self.blend
            left = 1.0 - self.settings.blend_rate * (time_s - t_back) / angle
            if left > 0.0:
                out = R_ref @ (R_ref.T @ R) @ exp_so3(min(left, 1.0) * offset)
            else:
                self.blend = None
        self._keep(time_s, out, R_ref)
        return out, False

    def _start_gap(self) -> None:
        """Freeze the last relative orientation and its rate at the start of a gap."""
        t1, ref1, out1 = self.history[-1]
        rel1 = ref1.T @ out1
        omega = np.zeros(3)
        if len(self.history) == 2:
            t0, ref0, out0 = self.history[0]
            rel0 = ref0.T @ out0
            if t1 > t0:
                omega = log_so3(rel0.T @ rel1) / (t1 - t0)
        self.gap = (t1, rel1, omega)

    def _keep(self, time_s: float, out: np.ndarray, R_ref: np.ndarray) -> None:
        self.out = out
        self.history = [*self.history[-1:], (time_s, R_ref, out)]


class BridgeStream:
    """Causal bridging of every sensed segment of one actor, one frame at a time.

    Args:
        segments: The sensed segments.
        parents: Segment -> parent segment in the model's tree (None for the root).
        settings: Thresholds (``configs/bridging.yaml`` when omitted).
    """

    def __init__(self, segments: list[str], parents: Mapping[str, str | None],
                 settings: BridgingSettings | None = None) -> None:
        self.settings = settings or BridgingSettings.load()
        self.neighbours = stream_neighbours(segments, parents)
        depth = {s: len(_ancestors(s, parents)) for s in segments}
        self.order = sorted(segments, key=lambda s: depth[s])
        self._bridges = {s: _SegmentBridge(self.settings) for s in segments}
        self._time: list[float] = []
        self._bridged: dict[str, list[bool]] = {s: [] for s in segments}
        self._untracked: dict[str, list[bool]] = {s: [] for s in segments}

    def step(self, time_s: float, R_world_segment: Mapping[str, np.ndarray | None]
             ) -> dict[str, np.ndarray]:
        """The tracked segments' orientations at one frame (measured, bridged or blended).

        Args:
            time_s: Frame time [s].
            R_world_segment: Segment -> calibrated (3, 3) orientation, None when its sample is
                missing or invalid.
        """
        self._time.append(time_s)
        out: dict[str, np.ndarray] = {}
        for s in self.order:
            nb = self.neighbours[s]
            ref = None if nb is None else out.get(nb, R_world_segment.get(nb))
            R, bridged = self._bridges[s].step(time_s, R_world_segment.get(s), ref)
            self._bridged[s].append(bridged)
            self._untracked[s].append(R is None)
            if R is not None:
                out[s] = R
        return out

    def result(self) -> BridgedSegments:
        """What was bridged so far: the report and warnings (orientations are not kept)."""
        time = np.asarray(self._time, dtype=float)
        bridged = {s: np.asarray(v, dtype=bool) for s, v in self._bridged.items()}
        untracked = {s: np.asarray(v, dtype=bool) for s, v in self._untracked.items()}
        return bridging_report({}, bridged, untracked, time, self.neighbours, self.settings,
                               causal=True)


def _ancestors(segment: str, parents: Mapping[str, str | None]) -> list[str]:
    chain, p = [], parents.get(segment)
    while p is not None and p not in chain:
        chain.append(p)
        p = parents.get(p)
    return chain


def stream_neighbours(segments: list[str], parents: Mapping[str, str | None]
                      ) -> dict[str, str | None]:
    """Each sensed segment's neighbour: nearest sensed ancestor, else nearest sensed descendant."""
    sensed = set(segments)
    children: dict[str, list[str]] = {}
    for child, parent in parents.items():
        if parent is not None:
            children.setdefault(parent, []).append(child)
    out: dict[str, str | None] = {}
    for s in segments:
        up = [a for a in _ancestors(s, parents) if a in sensed]
        if up:
            out[s] = up[0]
            continue
        queue, found = list(children.get(s, [])), None
        while queue and found is None:
            c = queue.pop(0)
            if c in sensed:
                found = c
            queue += children.get(c, [])
        out[s] = found
    return out
