"""Simulated calibration sessions: a hall of readers, their internal tags and a swayed wand.

A calibration log (SPEC section 4) holds two kinds of transmissions:

- every reader's *calibration tag*, inside the reader's case, transmits a beacon every few
  seconds;
  its tag id is the reader's id; the other readers in range hear it, and by default the reader
  reports it too (distance 0: the tag sits at its antenna; ``self_reception=False`` leaves
  that out);
- a *wand* tag, swayed and walked through the hall, transmits at ``wand_rate``.

Times of arrival follow :func:`ikfusion.uwb.simulate.simulate_toa` (the shared measurement
model: transmit time + distance + reader clock offset + NLOS delay + noise, all in metres). The
transmit time is the transmission's time on the common timeline times the speed of light, so
``toa`` values are large numbers, as in real logs. The capture simulator reuses
:func:`simulate_calibration_log`; tests and benchmarks use :func:`hall_constellation` and
:func:`wand_path` as well.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import numpy.typing as npt

from .constellation import Constellation, make_constellation
from .geometry import evenly_spaced_on_border
from .simulate import SimulatedToa, simulate_toa
from .toa_log import ToaLog, toa_log_from_matrix, write_toa_csv

#: Speed of light [m/s]; converts transmit times on the common timeline to metres.
SPEED_OF_LIGHT = 299_792_458.0

WandPath = Literal["hall", "centre"]


@dataclass(frozen=True)
class SimulatedCalibration:
    """A simulated calibration session and its truth.

    Attributes:
        log: All receptions (reader tags and wand), sorted by reception time.
        truth: The true constellation (positions, clock offsets [m], coverage, sigma).
        wand_time: Transmit times of the wand, shape (N,) [s].
        p_world_wand: True wand positions at those times, shape (N, 3) [m].
        wand_tag: Tag id of the wand.
        nlos_receptions: Receptions delayed by NLOS (among those heard).
        receptions: Receptions heard in total.
        own_delays: Delay of each reader's own-tag reception relative to an over-the-air one,
            shape (M,) [m] (NaN without own receptions).
    """

    log: ToaLog
    truth: Constellation
    wand_time: np.ndarray
    p_world_wand: np.ndarray
    wand_tag: str
    nlos_receptions: int
    receptions: int
    own_delays: np.ndarray

    @property
    def heights(self) -> dict[str, float]:
        """True reader heights ``{reader id: z [m]}``, the content of a heights file."""
        return {rid: float(p[2]) for rid, p in zip(self.truth.ids, self.truth.positions)}

    def write(self, path: str | Path) -> Path:
        """Write the log as a TOA CSV (``time,tag,seq,reader,toa``); returns the path."""
        return write_toa_csv(path, self.log)


def hall_constellation(
    rng: np.random.Generator,
    *,
    n_readers: int = 12,
    size: tuple[float, float] = (20.0, 20.0),
    heights: tuple[float, float] = (1.0, 3.0),
    inset: float = 0.5,
    jitter: float = 1.0,
    clock_offset: float = 30.0,
    sigma: float = 0.03,
    coverage: float | None = None,
) -> Constellation:
    """Readers spread along the walls of a rectangular hall, with random heights and clocks.

    Readers sit ``inset`` inside the walls, evenly spaced along them with a random shift of up
    to ``jitter`` along the wall; the hall spans ``[0, size_x] x [0, size_y]``.

    Args:
        rng: Random generator.
        n_readers: Number of readers (ids ``R1`` ... ``Rn``).
        size: Hall size (x, y) [m].
        heights: Range of the uniformly drawn reader heights [m].
        inset: Distance of the readers from the walls [m].
        jitter: Largest random shift along the wall [m].
        clock_offset: Clock offsets are uniform in ``[-clock_offset, clock_offset]`` [m].
        sigma: Range noise written in the constellation [m].
        coverage: Coverage radius [m] (None: every reader hears everything).

    Returns:
        The true constellation; its ``area`` is the hall.
    """
    sx, sy = float(size[0]), float(size[1])
    inner = np.array([[inset, inset], [sx - inset, inset], [sx - inset, sy - inset],
                      [inset, sy - inset]])  # fmt: skip
    xy = evenly_spaced_on_border(inner, n_readers)
    shift = rng.uniform(-jitter, jitter, n_readers)
    along = _border_direction(inner, xy)
    xy = np.clip(xy + shift[:, None] * along, inset, [sx - inset, sy - inset])
    z = rng.uniform(heights[0], heights[1], n_readers)
    return make_constellation(
        np.column_stack([xy, z]),
        clock_offsets=rng.uniform(-clock_offset, clock_offset, n_readers),
        coverage=coverage,
        sigma=sigma,
        area=[[0.0, 0.0], [sx, 0.0], [sx, sy], [0.0, sy]],
        name="simulated_hall",
    )


def _border_direction(polygon: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Unit direction of the polygon edge nearest each point, shape (N, 2)."""
    edges = np.roll(polygon, -1, axis=0) - polygon
    out = np.empty_like(points)
    for i, p in enumerate(points):
        dist = []
        for a, e in zip(polygon, edges):
            t = np.clip((p - a) @ e / (e @ e), 0.0, 1.0)
            dist.append(float(np.linalg.norm(p - (a + t * e))))
        e = edges[int(np.argmin(dist))]
        out[i] = e / np.linalg.norm(e)
    return out


def wand_path(
    kind: WandPath = "hall",
    *,
    seconds: float = 60.0,
    rate: float = 10.0,
    size: tuple[float, float] = (20.0, 20.0),
    margin: float = 2.0,
    radius: float = 0.5,
    phase: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """A wand swayed while walking through the hall, or only swayed in a circle at its centre.

    ``"hall"``: the walker follows a figure of eight (a Lissajous curve, frequency ratio 1:2)
    spanning the hall inside ``margin`` of the walls once in ``seconds``, swaying the wand
    sideways (+-0.4 m) and up and down (0.5-2.1 m). ``"centre"``: the wand circles at
    ``radius`` around the hall centre (one turn per 6 s) with the same up-and-down sway.

    Args:
        kind: ``"hall"`` or ``"centre"``.
        seconds: Duration [s].
        rate: Transmission rate [Hz].
        size: Hall size (x, y) [m].
        margin: Distance kept from the walls on the hall path [m].
        radius: Circle radius of the centre path [m].
        phase: Phase shift of the sway [rad] (varies the path between seeds).

    Returns:
        ``(time, p_world_wand)``: shape (N,) [s] and (N, 3) [m].
    """
    n = max(int(round(seconds * rate)), 1)
    t = np.arange(n) / rate
    sx, sy = float(size[0]), float(size[1])
    cx, cy = sx / 2.0, sy / 2.0
    z = 1.3 + 0.8 * np.sin(2.0 * np.pi * 0.35 * t + phase)
    if kind == "hall":
        u = 2.0 * np.pi * t / max(seconds, 1e-9)
        ax, ay = cx - margin, cy - margin
        x = cx + ax * np.sin(u)
        y = cy + ay * np.sin(2.0 * u)
        dx, dy = ax * np.cos(u), 2.0 * ay * np.cos(2.0 * u)
        norm = np.maximum(np.hypot(dx, dy), 1e-9)
        sway = 0.4 * np.sin(2.0 * np.pi * 0.5 * t + phase)
        x = x - sway * dy / norm
        y = y + sway * dx / norm
    elif kind == "centre":
        a = 2.0 * np.pi * t / 6.0 + phase
        x = cx + radius * np.cos(a)
        y = cy + radius * np.sin(a)
    else:
        raise ValueError(f"wand path must be 'hall' or 'centre', got {kind!r}")
    return t, np.column_stack([x, y, z])


def simulate_calibration_log(
    constellation: Constellation,
    wand_time: npt.ArrayLike,
    p_world_wand: npt.ArrayLike,
    rng: np.random.Generator,
    *,
    reader_rate: float = 0.2,
    sigma: float | None = None,
    nlos_fraction: float = 0.05,
    nlos_delay: tuple[float, float] = (0.2, 2.0),
    miss_probability: float = 0.02,
    wand_tag: str = "WAND",
    seq_modulo: int = 65536,
    self_reception: bool = True,
    own_delay: float = 0.05,
) -> SimulatedCalibration:
    """Receptions of a calibration session: reader tags during the wand's time span, and the wand.

    Args:
        constellation: True readers (positions, clock offsets, coverage radius, sigma).
        wand_time: Wand transmit times on the common timeline, shape (N,) [s].
        p_world_wand: Wand positions at those times, shape (N, 3) [m].
        rng: Random generator.
        reader_rate: Transmissions per second of every reader's calibration tag [Hz]
            (0 for none); the tags start at random phases.
        sigma: Range noise [m] (the constellation's by default).
        nlos_fraction: Probability that a reception is NLOS-delayed.
        nlos_delay: Range of the uniform NLOS extra path [m].
        miss_probability: Probability that a reader misses a transmission.
        wand_tag: Tag id of the wand (must not be a reader id).
        seq_modulo: Sequence numbers wrap at this value.
        self_reception: Whether a reader also reports its own calibration tag (distance 0,
            never NLOS, same noise); without it only the other readers hear the tag.
        own_delay: That own reception travels an internal path: its delay relative to an
            over-the-air reception is drawn per reader, uniform in ``[-own_delay, own_delay]``
            [m].

    Returns:
        The log and its truth.

    Raises:
        ValueError: When the wand tag id is a reader id or the shapes disagree.
    """
    ids = constellation.ids
    if wand_tag in ids:
        raise ValueError(f"wand tag {wand_tag!r} must not be a reader id")
    t_wand = np.asarray(wand_time, dtype=float)
    p_wand = np.asarray(p_world_wand, dtype=float)
    if p_wand.shape != (t_wand.shape[0], 3):
        raise ValueError(f"wand positions must have shape ({t_wand.shape[0]}, 3)")

    def receive(p_tag: np.ndarray, t_tag: np.ndarray) -> SimulatedToa:
        return simulate_toa(
            p_tag, constellation, rng, tau=SPEED_OF_LIGHT * t_tag, sigma=sigma,
            nlos_fraction=nlos_fraction, nlos_delay=nlos_delay,
            miss_probability=miss_probability,
        )  # fmt: skip

    parts = []
    nlos = heard = 0
    delta = rng.uniform(-own_delay, own_delay, len(ids)) if own_delay > 0 else np.zeros(len(ids))
    wand = receive(p_wand, t_wand)
    parts.append(_receptions(t_wand, wand.toa, wand_tag, seq_modulo, constellation))
    nlos += int(np.count_nonzero(wand.nlos_delay > 0))
    heard += int(np.count_nonzero(np.isfinite(wand.toa)))
    if reader_rate > 0 and t_wand.size:
        start, stop = float(t_wand.min()), float(t_wand.max())
        for j, rid in enumerate(ids):
            t_tag = (
                start
                + rng.uniform(0.0, 1.0 / reader_rate)
                + np.arange(0.0, stop - start, 1.0 / reader_rate)
            )
            p_tag = np.repeat(constellation.positions[j][None], t_tag.shape[0], axis=0)
            sim = receive(p_tag, t_tag)
            toa = sim.toa.copy()
            toa[:, j] = toa[:, j] - sim.nlos_delay[:, j] + delta[j] if self_reception else np.nan
            parts.append(_receptions(t_tag, toa, rid, seq_modulo, constellation))
            delayed = sim.nlos_delay > 0
            delayed[:, j] = False
            nlos += int(np.count_nonzero(delayed & np.isfinite(toa)))
            heard += int(np.count_nonzero(np.isfinite(toa)))
    log = _concatenate(parts)
    return SimulatedCalibration(
        log=log,
        truth=constellation,
        wand_time=t_wand,
        p_world_wand=p_wand,
        wand_tag=wand_tag,
        nlos_receptions=nlos,
        receptions=heard,
        own_delays=delta if self_reception else np.full(len(ids), np.nan),
    )


def _receptions(
    t_transmit: np.ndarray, toa: np.ndarray, tag: str, seq_modulo: int, c: Constellation
) -> ToaLog:
    """A log of one tag's transmissions; ``time`` is the reception time on the common timeline."""
    n = t_transmit.shape[0]
    log = toa_log_from_matrix(t_transmit, [tag] * n, np.arange(n) % seq_modulo, toa, c.ids)
    if len(log) == 0:
        return log
    rows, cols = np.nonzero(np.isfinite(toa))
    flight = toa[rows, cols] - SPEED_OF_LIGHT * t_transmit[rows] - c.clock_offsets[cols]
    dist = np.maximum(flight, 0.0)
    return ToaLog(
        time=log.time + dist / SPEED_OF_LIGHT,
        tag=log.tag,
        seq=log.seq,
        reader=log.reader,
        toa=log.toa,
        line=log.line,
    )


def _concatenate(parts: list[ToaLog]) -> ToaLog:
    """One log from several, sorted by reception time."""
    time = np.concatenate([p.time for p in parts])
    order = np.argsort(time, kind="stable")
    return ToaLog(
        time=time[order],
        tag=np.concatenate([p.tag for p in parts])[order],
        seq=np.concatenate([p.seq for p in parts])[order],
        reader=np.concatenate([p.reader for p in parts])[order],
        toa=np.concatenate([p.toa for p in parts])[order],
        line=np.zeros(time.shape[0], dtype=np.int64),
    )
