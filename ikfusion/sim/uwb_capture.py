"""Simulated UWB of a capture: TOA logs of body tags, and the IMU units the tags sit on.

Tags sit on the model's tag sites (``HeadTop``, ``LeftFootTop``, ``RightFootTop``) and transmit
at ``tx_rate`` on their own, unsynchronised schedules: tag ``j`` transmits at
``t_k = phase_j + k (1 + drift_j) / tx_rate`` on the common timeline (``drift_j`` up to
``drift_ppm``), and its transmit time in metres (SPEC section 4) is
``tau_k = c t_k + offset_j + w_k`` with ``w`` an integrated random walk (the tag clock's wander).
Receptions follow :func:`ikfusion.uwb.simulate.simulate_toa` (noise, a fraction of NLOS delays,
coverage radius), then blockage windows silence all but some readers and no-coverage windows
silence all of them.

The IMU unit of a tag is the sensor of the segment that carries its site (Head, LeftFoot,
RightFoot), with the lever arm from that sensor to the tag: :func:`imu_units_from_simulation`
builds the input of :func:`ikfusion.uwb.tracking.track_tags` from simulated IMUs
(:func:`ikfusion.uwb.imu_units.imu_units_from_recording` does so from a real recording).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import InputError
from ..mocap.model_motion import TruthMotion, site_positions
from ..rotations import continuous_quaternions
from ..uwb.constellation import Constellation, save_constellation
from ..uwb.imu_units import FOOT_TAG_SITES, tag_segment
from ..uwb.simulate import simulate_toa
from ..uwb.toa_log import ToaLog, write_toa_csv
from ..uwb.tracking import SPEED_OF_LIGHT, ImuUnit, TagInfo, save_tags
from .imu import SimulatedImus


@dataclass(frozen=True)
class Blockage:
    """A window in which only some readers hear the tags.

    Attributes:
        start: Window start [s].
        end: Window end [s].
        audible: Ids of the readers that still hear.
    """

    start: float
    end: float
    audible: tuple[str, ...]


@dataclass(frozen=True)
class UwbCaptureOptions:
    """Settings of :func:`simulate_uwb`.

    Attributes:
        tx_rate: Transmissions per second per tag [Hz].
        sigma: TOA noise [m]; None takes the constellation's ``sigma``.
        nlos_fraction: Probability that a reception is NLOS-delayed.
        nlos_delay: Range of the uniform NLOS delay [m].
        miss_probability: Probability that a reader misses a transmission.
        drift_ppm: Largest tag schedule drift [ppm].
        clock_walk: Random walk of the tag clock rate [m/s/sqrt(s)].
        blockages: Windows with only some readers audible.
        no_coverage: ``(start, end)`` windows [s] with no reception at all.
    """

    tx_rate: float = 10.0
    sigma: float | None = None
    nlos_fraction: float = 0.1
    nlos_delay: tuple[float, float] = (0.2, 2.0)
    miss_probability: float = 0.0
    drift_ppm: float = 20.0
    clock_walk: float = 0.01
    blockages: tuple[Blockage, ...] = ()
    no_coverage: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class SimulatedUwb:
    """A simulated TOA log with its truth, one row per transmission (all tags, time order).

    Attributes:
        log: The receptions, as written to ``toa.csv``.
        constellation: The readers.
        tags: Tag id -> :class:`TagInfo`.
        tx_tag: Tag id per transmission, shape (T,).
        tx_seq: Transmission number, shape (T,).
        tx_time: Transmit time on the common timeline, shape (T,) [s].
        p_world_tag: True tag position at transmit time, shape (T, 3) [m].
        tau: True transmit time, shape (T,) [m].
        toa: Times of arrival, shape (T, M) [m], NaN where not received.
        nlos_delay: NLOS delay of each reception, shape (T, M) [m] (0 for LOS or no reception).
    """

    log: ToaLog
    constellation: Constellation
    tags: dict[str, TagInfo]
    tx_tag: np.ndarray
    tx_seq: np.ndarray
    tx_time: np.ndarray
    p_world_tag: np.ndarray
    tau: np.ndarray
    toa: np.ndarray
    nlos_delay: np.ndarray
    info: dict[str, object] = field(default_factory=dict)


def default_tags(actor: str = "A") -> dict[str, TagInfo]:
    """Three tags ``T1`` (HeadTop), ``T2`` (LeftFootTop), ``T3`` (RightFootTop)."""
    sites = ("HeadTop", "LeftFootTop", "RightFootTop")
    return {f"T{i + 1}": TagInfo(f"T{i + 1}", actor, s) for i, s in enumerate(sites)}


def simulate_uwb(truth: TruthMotion, constellation: Constellation, rng: np.random.Generator,
                 options: UwbCaptureOptions | None = None,
                 tags: Mapping[str, TagInfo] | None = None) -> SimulatedUwb:
    """Simulate the TOAs of body tags along a ground-truth motion.

    Args:
        truth: The motion (its time is the common timeline).
        constellation: The readers.
        rng: Random generator (schedules, noise, NLOS).
        options: Settings.
        tags: Tags to simulate; :func:`default_tags` when omitted.

    Returns:
        The :class:`SimulatedUwb`.
    """
    opts = options or UwbCaptureOptions()
    tag_map = dict(tags) if tags is not None else default_tags()
    sites = [t.site for t in tag_map.values()]
    p_sites = site_positions(truth.model, truth.q, sites)
    parts = [_simulate_tag(truth.time, p_sites[:, j], constellation, rng, opts)
             for j in range(len(sites))]
    tag_ids = np.concatenate([np.full(len(p[0]), t, dtype=object)
                              for t, p in zip(tag_map, parts)])
    time, seq, p, tau, toa, delay = (np.concatenate([part[i] for part in parts])
                                     for i in range(6))
    _silence(toa, delay, time, constellation, opts)
    order = np.argsort(time, kind="stable")
    tag_ids, time, seq, p, tau, toa, delay = (a[order] for a in
                                              (tag_ids, time, seq, p, tau, toa, delay))
    heard = np.isfinite(toa).any(axis=1)
    rows, cols = np.nonzero(np.isfinite(toa))
    log = ToaLog(time=time[rows], tag=tag_ids[rows], seq=seq[rows],
                 reader=np.asarray(constellation.ids, dtype=object)[cols], toa=toa[rows, cols],
                 line=np.zeros(rows.shape[0], dtype=np.int64))
    return SimulatedUwb(log, constellation, tag_map, tag_ids[heard], seq[heard], time[heard],
                        p[heard], tau[heard], toa[heard], delay[heard])


def _simulate_tag(time: np.ndarray, p_world_site: np.ndarray, constellation: Constellation,
                  rng: np.random.Generator, opts: UwbCaptureOptions) -> tuple[np.ndarray, ...]:
    """One tag: transmit times, numbers, positions, tau, TOAs (T, M) and NLOS delays."""
    period = 1.0 / opts.tx_rate
    drift = rng.uniform(-1.0, 1.0) * opts.drift_ppm * 1e-6
    phase = rng.uniform(0.0, period)
    count = int(np.floor((time[-1] - time[0] - phase) / (period * (1.0 + drift)))) + 1
    k = np.arange(max(count, 0))
    t_tx = time[0] + phase + k * period * (1.0 + drift)
    t_tx = t_tx[t_tx <= time[-1]]
    seq = int(rng.integers(0, 1000)) + np.arange(t_tx.shape[0], dtype=np.int64)
    p = np.stack([np.interp(t_tx, time, p_world_site[:, i]) for i in range(3)], axis=1)
    rate_wander = np.cumsum(rng.normal(0.0, opts.clock_walk * np.sqrt(period), t_tx.shape[0]))
    walk = np.cumsum(rate_wander * period)
    tau = SPEED_OF_LIGHT * t_tx + rng.uniform(0.0, 1.0e4) + walk
    sim = simulate_toa(p, constellation, rng, tau=tau, sigma=opts.sigma,
                       nlos_fraction=opts.nlos_fraction, nlos_delay=opts.nlos_delay,
                       miss_probability=opts.miss_probability)
    return t_tx, seq, p, sim.tau, sim.toa.copy(), sim.nlos_delay.copy()


def _silence(toa: np.ndarray, delay: np.ndarray, time: np.ndarray,
             constellation: Constellation, opts: UwbCaptureOptions) -> None:
    """Remove receptions in blockage and no-coverage windows (in place)."""
    ids = list(constellation.ids)
    for b in opts.blockages:
        inside = (time >= b.start) & (time < b.end)
        blocked = np.array([rid not in b.audible for rid in ids])
        toa[np.ix_(inside, blocked)] = np.nan
    for start, end in opts.no_coverage:
        toa[(time >= start) & (time < end)] = np.nan
    delay[~np.isfinite(toa)] = 0.0


def write_uwb_files(folder: str | Path, sim: SimulatedUwb) -> dict[str, Path]:
    """Write ``toa.csv``, ``readers.yaml`` and ``tags.yaml`` (SPEC sections 3-4) into ``folder``.

    Returns:
        ``{"toa": path, "readers": path, "tags": path}``.
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    return {"toa": write_toa_csv(out / "toa.csv", sim.log),
            "readers": save_constellation(sim.constellation, out / "readers.yaml"),
            "tags": save_tags(sim.tags, out / "tags.yaml")}


def imu_units_from_simulation(truth: TruthMotion, imus: SimulatedImus,
                              tags: Mapping[str, TagInfo],
                              with_height: bool = True) -> dict[str, ImuUnit]:
    """The IMU units of the tags from simulated IMUs (the input of ``track_tags``).

    Args:
        truth: The motion the IMUs were simulated on.
        imus: The simulated IMUs (must include the segments carrying the tag sites).
        tags: The tags.
        with_height: Attach the true tag height [m] (for the optional height aid).

    Raises:
        InputError: When a tag's segment carries no simulated IMU.
    """
    model = truth.model
    data = model.model.createData()
    pin.framesForwardKinematics(model.model, data, truth.q[0])
    out = {}
    for tag_id, tag in tags.items():
        segment = tag_segment(model, tag.site)
        if segment not in imus.segments:
            raise InputError(f"tag {tag_id} on {tag.site} needs an IMU on {segment}; simulated "
                             f"IMUs are on {', '.join(imus.segments)}", field="segments")
        i = imus.segments.index(segment)
        sensor = data.oMf[model.site_frame_id(segment)]
        R_world_sensor = sensor.rotation @ imus.R_segment_sensor[i]
        p_tag = data.oMf[model.site_frame_id(tag.site)].translation
        lever = R_world_sensor.T @ (p_tag - sensor.translation)
        height = None
        if with_height:
            height = site_positions(model, truth.q, [tag.site])[:, 0, 2]
        out[tag_id] = ImuUnit(imus.time, imus.R_world_sensor[i], imus.acc[i], imus.gyr[i],
                              lever, height, foot=tag.site in FOOT_TAG_SITES)
    return out


def tags_on_sites(sites: Sequence[str], actor: str = "A") -> dict[str, TagInfo]:
    """Tags ``T1..Tn`` on the given sites."""
    return {f"T{i + 1}": TagInfo(f"T{i + 1}", actor, s) for i, s in enumerate(sites)}


def smooth_truth(truth: TruthMotion, sigma_seconds: float = 0.05) -> TruthMotion:
    """A copy of ``truth`` with its configurations low-pass filtered (Gaussian, renormalised).

    The gait generator solves each frame's IK separately, which leaves millimetre jitter in the
    motion; differentiated twice for simulated accelerometers that is several m/s^2 of
    "true" acceleration that no real body makes, and it dominates inertial coasting. Smoothing
    the configurations (quaternion blocks renormalised) gives a physically plausible truth.

    Args:
        truth: The motion.
        sigma_seconds: Standard deviation of the Gaussian kernel [s].
    """
    dt = float(np.median(np.diff(truth.time))) if len(truth.time) > 1 else 1.0
    sigma = max(sigma_seconds / dt, 1e-9)
    half = int(np.ceil(4.0 * sigma))
    offsets = np.arange(-half, half + 1)
    kernel = np.exp(-0.5 * (offsets / sigma) ** 2)
    kernel /= kernel.sum()
    model = truth.model.model
    blocks = [joint.idx_q + (3 if joint.nq == 7 else 0) for joint in model.joints[1:]
              if joint.nq in (4, 7)]
    q = truth.q.copy()
    for start in blocks:  # q and -q are one rotation: average along one continuous hemisphere
        q[:, start:start + 4] = continuous_quaternions(q[:, start:start + 4])
    padded = np.pad(q, ((half, half), (0, 0)), mode="edge")
    q = np.stack([np.convolve(padded[:, j], kernel, mode="valid")
                  for j in range(q.shape[1])], axis=1)
    for start in blocks:
        block = q[:, start:start + 4]
        block /= np.linalg.norm(block, axis=1, keepdims=True)
    return TruthMotion(truth.model, truth.time.copy(), q, list(truth.contact_names),
                       truth.contacts.copy(), truth.source, dict(truth.info))
