"""One actor solved frame by frame from the past only: what ``live`` and ``solve --causal`` run.

:class:`ActorStream` takes the samples of one frame at a time (sensor id -> ImuSample) and
returns the poses solved. Everything it does looks at the past only, so ``solve --causal`` of a
recording (which feeds it every frame of the file, :func:`ikfusion.app.pipeline.solve_recording`)
and ``live --replay`` of the same files give the same poses:

* calibration: the first ``calibration_s`` seconds (``configs/live.yaml``: a still N-pose, then a
  few steps for the heading) are buffered; the calibration of :mod:`ikfusion.imu.calibration`
  runs on that buffer alone, and the buffered frames are solved right after it (their poses
  come ``calibration_s`` late, every later frame as it arrives). This start-up buffer is the
  only look-ahead of the pipeline;
* lost or invalid samples: bridged from the past (:class:`~ikfusion.imu.bridging_stream.
  BridgeStream`);
* foot stance: from past samples (:class:`~ikfusion.imu.stance_stream.FootStillStream`, which
  recognises a stance ``still_duration`` after it starts), and the rest of the knees and hands
  from their accelerometers (:class:`~ikfusion.imu.resting_stream.SegmentRestingStream`), and
  whether each heel and toe moves (:class:`~ikfusion.imu.point_speed_stream.FootPointsStream`,
  for ``horizon`` after a stance);
* flight: from the pelvis and feet accelerometers sample by sample
  (:class:`~ikfusion.imu.flight_stream.FlightStream`, the twin of the offline detector). A
  frame is airborne when its sample is in a flight confirmed up to that sample (the detector's
  final decision waits ``lag`` samples, 83 ms at 60 Hz, which a live frame cannot): a flight
  starts on the frame that confirms it, at most ``lag`` frames after the offline start, and
  ends on the same frame. The pelvis acceleration in the world frame comes with every frame;
* UWB drift correction: applied after each frame from the fixes of that frame
  (:class:`~ikfusion.app.correction.DriftCorrection`); the buffered frames solved before the
  first fix are moved into the tag frame with it (they are sent together), later ones are not.
  In ``no-slide`` each frame is shaped before its solve (:meth:`~ikfusion.app.correction.
  DriftCorrection.shape`: tag tasks, the flight target of the pelvis, released feet) from the
  frame before, as offline. Stretches far from the tags are among :meth:`ActorStream.
  all_warnings`.
  When the correction comes from a :class:`TagFeed` (:class:`ikfusion.app.tag_stream.
  TagStream`), the TOA samples go to it as they arrive (:meth:`ActorStream.toa`) and it writes
  each frame's fixes just before the frame is corrected (also for a frame not solved).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from ..app.correction import DriftCorrection
from ..ik import Frame, Solver
from ..ik.pose import Pose
from ..imu.bridging import BridgedSegments, BridgingSettings, world_filled
from ..imu.bridging_stream import BridgeStream
from ..imu.calibration import Calibration, calibrate
from ..imu.flight import FlightThresholds, world_acceleration
from ..imu.flight_stream import FlightStream
from ..imu.point_speed import foot_point_offsets
from ..imu.point_speed_stream import FootPointsStream
from ..imu.resting import RESTING_SEGMENTS
from ..imu.resting_stream import SegmentRestingStream
from ..imu.stance import stance_thresholds
from ..imu.stance_stream import FootStillStream
from ..io.recording import normalize_sensor_id
from ..model.human_model import HumanModel
from ..model.topology import segment_parents
from ..rotations import quat_wxyz_to_matrix
from .samples import ImuSample, ToaSample
from .settings import LiveSettings

#: Segments whose sensor says whether the foot stands still.
FEET = ("LeftFoot", "RightFoot")


@dataclass(frozen=True)
class Reading:
    """One segment's sensor sample in a frame (None: missing or invalid).

    Attributes:
        R_world_sensor: (3, 3) orientation, or None.
        gyr: (3,) angular rate [rad/s] in the sensor frame, or None.
        acc: (3,) specific force [m/s^2] in the sensor frame, or None.
    """

    R_world_sensor: np.ndarray | None
    gyr: np.ndarray | None = None
    acc: np.ndarray | None = None


@runtime_checkable
class TagFeed(Protocol):
    """Where a causal solve's UWB fixes come from, frame by frame (a ``correction_for``)."""

    def __call__(self, calibration: Calibration) -> DriftCorrection | None:
        """The drift correction, once the calibration is known."""

    def add_toa(self, sample: ToaSample) -> None:
        """One TOA sample as it arrived."""

    def frame(self, k: int, time_s: float, readings: Mapping[str, Reading],
              still: Mapping[str, bool]) -> None:
        """Fill the fixes of frame ``k`` (at ``time_s`` [s]) from what arrived before it."""

    def status(self) -> str:
        """What to say on the status line ('' when all is well)."""


class ActorStream:
    """Causal solve of one actor, one frame at a time (see the module docstring).

    Args:
        model: The actor's body model.
        sensor_map: Sensor id -> segment (a ``SensorMap`` also brings its default mounting).
        rate: Nominal sample rate [Hz].
        solver: A configured solver (default settings when omitted).
        window_s: Calibration window [s] from the capture start (found in the buffer when
            omitted), ``pose`` and ``forward`` as :func:`ikfusion.imu.calibration.calibrate`.
        calibration: A calibration already made (nothing is buffered then).
        correction_for: Builds the UWB drift correction once the calibration is known (None:
            IMU only); its fixes are indexed by ``round(time * rate)``. A :class:`TagFeed`
            also fills them frame by frame, indexed from the first frame pushed
            (``round((time - first time) * rate)``, so a source on epoch times works).
        settings: ``configs/live.yaml``.
        bridging: ``configs/bridging.yaml``.
        solve_startup: Solve the frames of the start-up buffer once calibrated (every frame,
            as ``solve --causal``); False solves only its last one, so a live stream starts
            at once instead of catching up (the buffered samples still feed the bridging,
            the stance and the flight detection).
        flight: Flight detection thresholds (defaults when omitted).
    """

    def __init__(self, model: HumanModel, sensor_map: Mapping[str, str], rate: float, *,
                 solver: Solver | None = None, window_s: tuple[float, float] | None = None,
                 pose: str = "npose", forward: dict[str, str] | None = None,
                 calibration: Calibration | None = None,
                 correction_for: Callable[[Calibration], DriftCorrection | None] | None = None,
                 settings: LiveSettings | None = None,
                 bridging: BridgingSettings | None = None,
                 solve_startup: bool = True,
                 flight: FlightThresholds | None = None) -> None:
        self.model = model
        self.rate = float(rate)
        self.segment_of = {normalize_sensor_id(s): seg for s, seg in sensor_map.items()}
        self._segment_by_id: dict[str, str | None] = {}  # sensor id as sent -> segment
        self.sensor_ids = {seg: str(s) for s, seg in sensor_map.items()}
        self.default_forward: Mapping[str, str] | None = getattr(sensor_map, "forward", None)
        self.solver = solver or Solver(model)
        self.solver.reset()
        st = self.solver.settings
        self.settings = settings or LiveSettings.load()
        self._bridging = bridging
        self._thresholds = stance_thresholds(st)
        self.window_s, self.pose, self.forward = window_s, pose, forward
        self.correction_for = correction_for
        self.tag_feed = correction_for if isinstance(correction_for, TagFeed) else None
        self.solve_startup = solve_startup
        self.calibration: Calibration | None = None
        self.correction: DriftCorrection | None = None
        self.warnings: list[str] = []
        self.missing: list[str] = []  # sensors missing from the last frame
        self.frames = 0
        self.relaxed = 0
        self._buffer: list[tuple[float, dict[str, Reading]]] = []
        self._previous: float | None = None
        self._time0: float | None = None  # first frame time of a TagFeed's fix index [s]
        self._bridge: BridgeStream | None = None
        self._stance: dict[str, FootStillStream] = {}
        self._resting: dict[str, SegmentRestingStream] = {}
        self._points: dict[str, FootPointsStream] = {}
        self._flight = FlightStream(self.rate, flight)
        if calibration is not None:
            self._start(calibration)

    # ------------------------------------------------------------------ feeding
    def readings(self, samples: Mapping[str, ImuSample]) -> dict[str, Reading]:
        """The mapped sensors' samples by segment; the missing ones noted in :attr:`missing`."""
        mapped = {}
        for sensor, sample in samples.items():
            if sensor not in self._segment_by_id:
                self._segment_by_id[sensor] = self.segment_of.get(normalize_sensor_id(sensor))
            segment = self._segment_by_id[sensor]
            if segment is not None:
                mapped[segment] = sample
        out: dict[str, Reading] = {}
        if mapped:  # one conversion for the whole frame
            quats = np.array([s.q_world_sensor for s in mapped.values()], dtype=float)
            finite = np.isfinite(quats).all(axis=1)
            R_all = quat_wxyz_to_matrix(np.where(finite[:, None], quats, 1.0))
            for i, (segment, sample) in enumerate(mapped.items()):
                out[segment] = Reading(R_all[i], sample.gyr, sample.acc) if finite[i] \
                    else Reading(None)
        self.missing = [self.sensor_ids[s] for s in self.sensor_ids
                        if s not in out or out[s].R_world_sensor is None]
        return out

    def push(self, time_s: float, samples: Mapping[str, ImuSample], solve: bool = True
             ) -> list[Pose]:
        """Feed one frame's samples (sensor id -> sample; absent sensors are missing).

        ``solve`` False: the samples feed the bridging and the stance, the frame is not solved
        (a frame dropped because the solver fell behind).

        Returns:
            The poses solved now: none while the calibration buffer fills, the buffered frames
            when it is done, else this frame's.

        Raises:
            InputError: The calibration buffer holds no still pose (naming the sensors that
                moved) or a bad ``forward``.
        """
        readings = self.readings(samples)
        if self._time0 is None:
            self._time0 = float(time_s) if self.tag_feed is not None else 0.0
        if self.calibration is not None:
            pose = self._solve(time_s, readings, solve)
            return [] if pose is None else [pose]
        self._buffer.append((time_s, readings))
        if time_s - self._buffer[0][0] >= self.calibration_due - 0.5 / self.rate:
            return self._calibrate_buffer()
        return []

    def toa(self, sample: ToaSample) -> None:
        """One UWB time of arrival as it arrived (to the tag feed; ignored without one)."""
        if self.tag_feed is not None:
            self.tag_feed.add_toa(sample)

    def finish(self) -> list[Pose]:
        """At the end of the stream: the buffered frames when the buffer never filled."""
        return self._calibrate_buffer() if self.calibration is None and self._buffer else []

    @property
    def calibration_due(self) -> float:
        """Buffered seconds after which the calibration runs [s]."""
        due = self.settings.calibration_s
        if self.window_s is not None:
            due = max(due, self.window_s[1] + 0.5 * due)
        return due

    def status(self) -> str:
        """One short line: calibrating, or which sensors are missing."""
        if self.calibration is None:
            held = self._buffer[-1][0] - self._buffer[0][0] if self._buffer else 0.0
            return (f"calibrating: stand still in N-pose, then walk a few steps "
                    f"({held:.1f}/{self.calibration_due:.0f} s)")
        uwb = self.tag_feed.status() if self.tag_feed is not None else ""
        parts = [*(["missing " + ",".join(self.missing)] if self.missing else []),
                 *([uwb] if uwb else [])]
        return "; ".join(parts) or "ok"

    # ------------------------------------------------------------------ results
    def bridged(self) -> BridgedSegments | None:
        """What was bridged so far (None before the calibration)."""
        return None if self._bridge is None else self._bridge.result()

    def all_warnings(self) -> list[str]:
        """The calibration's, the bridging's, the solver's and the UWB correction's so far.

        The correction's are the stretches where a tag site stayed far from its fix
        (:meth:`~ikfusion.app.correction.DriftCorrection.far_warnings`).
        """
        bridged = self.bridged()
        return [*self.warnings, *(bridged.warnings if bridged else []),
                *self.solver.warnings(self.relaxed),
                *(self.correction.far_warnings() if self.correction is not None else [])]

    # ------------------------------------------------------------------ internals
    def _calibrate_buffer(self) -> list[Pose]:
        """Calibrate on the buffered frames, then solve them."""
        times = np.array([t for t, _ in self._buffer])
        R: dict[str, np.ndarray] = {}
        gyr: dict[str, np.ndarray | None] = {}
        acc: dict[str, np.ndarray | None] = {}
        for segment in self.sensor_ids:
            got = [r.get(segment) for _, r in self._buffer]
            valid = np.array([g is not None and g.R_world_sensor is not None for g in got])
            if not valid.any():
                self.warnings.append(f"{segment}: no sample of sensor "
                                     f"{self.sensor_ids[segment]} during the calibration; the "
                                     "segment is not tracked")
                continue
            R[segment] = world_filled(np.stack([
                g.R_world_sensor if g is not None and g.R_world_sensor is not None
                else np.full((3, 3), np.nan) for g in got]), valid)
            gyr[segment] = _stacked([None if g is None else g.gyr for g in got])
            acc[segment] = _stacked([None if g is None else g.acc for g in got])
        window = None
        if self.window_s is not None:
            window = (int(round((self.window_s[0] - times[0]) * self.rate)),
                      int(round((self.window_s[1] - times[0]) * self.rate)))
        cal = calibrate(R, self.rate, window, self.forward, self.pose, gyr=gyr, acc=acc,
                        default_forward=self.default_forward,
                        sensor_ids={s: self.sensor_ids[s] for s in R})
        self._start(cal)
        buffered, self._buffer = self._buffer, []
        last = len(buffered) - 1
        solved = [self._solve(t, r, self.solve_startup or i == last)
                  for i, (t, r) in enumerate(buffered)]
        poses = [p for p in solved if p is not None]
        self._place_buffer(poses)
        return poses

    def _place_buffer(self, poses: list[Pose]) -> None:
        """Move the buffered frames solved before the first UWB fix into the tag frame.

        They are all solved when the buffer's TOAs are in, so this looks at nothing later; a
        first fix after the buffer leaves the earlier frames where they were sent.
        """
        placed = None if self.correction is None else self.correction.placement
        if placed is None or self.correction is None:
            return
        k = placed[0]
        for pose in poses:
            offset = self.correction.placement_lacking(self._fix_index(pose.time))
            if offset.any():
                pose.q = pose.q.copy()  # the solver keeps the array it returned
                pose.q[:2] += offset[:2]
        self.correction.gap[:k + 1] = np.nan  # measured before the placement

    def _fix_index(self, time_s: float) -> int:
        """Index of the frame at ``time_s`` [s] in the correction's fixes."""
        return int(round((time_s - (self._time0 or 0.0)) * self.rate))

    def _start(self, calibration: Calibration) -> None:
        """Begin solving with ``calibration``."""
        self.calibration = calibration
        self.warnings += calibration.warnings
        sensed = [s for s in self.sensor_ids if s in calibration.R_sensor_segment]
        self._bridge = BridgeStream(sensed, segment_parents(self.model), self._bridging)
        self._stance = {f: FootStillStream(self.rate, self._thresholds) for f in FEET
                        if f in self.sensor_ids}
        self._resting = {s: SegmentRestingStream(self.rate) for s in RESTING_SEGMENTS
                         if s in self.sensor_ids}
        offsets = foot_point_offsets(self.model)
        self._points = {f: FootPointsStream(calibration.R_sensor_segment[f], offsets[f],
                                            self.solver.settings.release_speed)
                        for f in self._stance if f in offsets
                        and f in calibration.R_sensor_segment}
        self.correction = self.correction_for(calibration) if self.correction_for else None

    def _solve(self, time_s: float, readings: Mapping[str, Reading], solve: bool = True
               ) -> Pose | None:
        """Bridge, stance, flight, solve and correct one frame (``solve`` False: no solve)."""
        assert self.calibration is not None and self._bridge is not None
        mounting = self.calibration.R_sensor_segment
        measured = {s: None if r.R_world_sensor is None else r.R_world_sensor @ mounting[s]
                    for s, r in readings.items() if s in mounting}
        tracked = self._bridge.step(time_s, measured)
        still = {}
        moving: dict[str, bool] = {}
        for foot, stream in self._stance.items():
            r = readings.get(foot)
            value = stream.update(time_s, None if r is None else r.R_world_sensor,
                                  None if r is None else r.gyr, _acc(r))
            if np.isfinite(value):
                still[foot] = bool(value)
            if foot in self._points:
                moving.update(self._points[foot].update(
                    time_s, None if r is None else r.R_world_sensor, _acc(r), _gyr(r),
                    still.get(foot)))
        # knees and palms by their accelerometers, for the contacts only (the tags ignore them)
        resting = _still_now(self._resting, readings, time_s, _acc)
        self._flight.update(_acc(readings.get("Pelvis")),
                            {f: _acc(readings.get(f)) for f in FEET},
                            {f: _gyr(readings.get(f)) for f in FEET})
        k_fix = self._fix_index(time_s)
        if self.tag_feed is not None and self.correction is not None:
            self.tag_feed.frame(k_fix, time_s, readings, still)
        if not solve:
            return None
        frame = Frame(float(time_s), tracked, feet_still={**still, **resting},
                      points_moving=moving,
                      airborne=self._flight.flying,
                      root_acceleration=_root_acceleration(readings.get("Pelvis")))
        dt = 0.0 if self._previous is None else float(time_s - self._previous)
        k = 0
        if self.correction is not None:
            k = min(k_fix, len(self.correction.gap) - 1)
            frame = self.correction.shape(frame, k, dt)
        pose = self.solver.step(frame)
        if self.correction is not None:
            self.correction.after_frame(self.solver, pose, k, dt)
        self._previous = time_s
        self.frames += 1
        self.relaxed += int(pose.relaxed)
        return pose


def _still_now(streams: Mapping[str, FootStillStream], readings: Mapping[str, Reading],
               time_s: float, signal: Callable[[Reading | None], np.ndarray | None]
               ) -> dict[str, bool]:
    """Segment -> its stillness stream says it is still at ``time_s`` (unknown: left out).

    Args:
        streams: Segment -> its causal stillness detector.
        readings: This frame's readings by segment.
        time_s: Frame time [s].
        signal: The reading's rate the detector judges (``_gyr`` or ``_acc``).
    """
    out = {}
    for segment, stream in streams.items():
        r = readings.get(segment)
        value = stream.update(time_s, None if r is None else r.R_world_sensor, signal(r))
        if np.isfinite(value):
            out[segment] = bool(value)
    return out


def _acc(reading: Reading | None) -> np.ndarray | None:
    """The reading's specific force [m/s^2], None when missing."""
    return None if reading is None else reading.acc


def _gyr(reading: Reading | None) -> np.ndarray | None:
    """The reading's angular rate [rad/s], None when missing."""
    return None if reading is None else reading.gyr


def _root_acceleration(pelvis: Reading | None) -> np.ndarray | None:
    """``a_world_pelvis`` (3,) [m/s^2] from the pelvis unit's sample; None unless all finite."""
    if pelvis is None or pelvis.R_world_sensor is None or pelvis.acc is None:
        return None
    a = world_acceleration(pelvis.R_world_sensor[None], np.asarray(pelvis.acc)[None])[0]
    return a if np.isfinite(a).all() else None


def _stacked(values: list[np.ndarray | None]) -> np.ndarray | None:
    """(n, 3) from per-frame vectors, NaN where absent; None when none was given."""
    if all(v is None for v in values):
        return None
    return np.stack([np.full(3, np.nan) if v is None else np.asarray(v, dtype=float)
                     for v in values])
