"""From a recording to a solved motion: sensor map, calibration, frames, solver.

``solve_recording`` is what ``ikfusion solve`` runs: every mapped sensor's orientation becomes
its segment's orientation through the calibration, samples flagged invalid (lost packets, NaN, a
sensor that drops out) are bridged from what is known around them
(:mod:`ikfusion.imu.bridging`: interpolated offline, held and blended back in causally), and the
solver does the rest. ``causal=True`` feeds the recording frame by frame to the live pipeline's
:class:`~ikfusion.live.actor_stream.ActorStream` (calibration on the first seconds only, stance
and bridging from the past), so ``solve --causal`` and ``live --replay`` give the same poses.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from tqdm import tqdm

from ..errors import InputError
from ..ik import Frame, Motion, Solver
from ..ik.assumed import coverage_warning
from ..imu.bridging import BridgedSegments, BridgingSettings, bridge_segments
from ..imu.calibration import Calibration, calibrate_recording
from ..imu.flight import FlightPhases, FlightThresholds, detect_flight, world_acceleration
from ..imu.point_speed import faster_than, foot_point_offsets, foot_point_velocities
from ..imu.resting import RESTING_SEGMENTS, segment_resting
from ..imu.stance import StanceThresholds, foot_still, stance_thresholds, velocity_anchors
from ..io.recording import ImuRecording, SensorStream
from ..live.actor_stream import ActorStream
from ..live.replay import recording_frames
from ..model.human_model import HumanModel
from ..model.topology import segment_parents
from .correction import DriftCorrection

__all__ = ["SolvedRecording", "bridged_segments", "frames_from_recording", "knee_warning",
           "solve_recording"]


@dataclass
class SolvedRecording:
    """A solved recording with what was learned on the way."""

    motion: Motion
    calibration: Calibration
    warnings: list[str] = field(default_factory=list)
    bridged: dict[str, dict[str, object]] = field(default_factory=dict)


def bridged_segments(recording: ImuRecording, sensor_map: Mapping[str, str],
                     calibration: Calibration, parents: Mapping[str, str | None],
                     causal: bool = False,
                     settings: BridgingSettings | None = None) -> BridgedSegments:
    """Calibrated segment orientations (N, 3, 3) with their invalid samples bridged.

    Args:
        recording: The IMU recording (``valid`` flags say which samples are trusted).
        sensor_map: Sensor id -> segment.
        calibration: Sensor-to-segment calibration.
        parents: The model's segment tree (:func:`segment_parents`).
        causal: Bridge with the past only (as live); otherwise across each gap.
        settings: Bridging thresholds.
    """
    streams = recording.segment_streams(sensor_map)
    R_segment = calibration.segment_orientations(
        {s: st.R_world_sensor for s, st in streams.items()})
    return bridge_segments(R_segment, {s: streams[s].valid for s in R_segment},
                           recording.time, parents, causal=causal, settings=settings)


def frames_from_recording(recording: ImuRecording, sensor_map: Mapping[str, str],
                          calibration: Calibration,
                          stance: StanceThresholds | None = None,
                          bridged: BridgedSegments | None = None,
                          flight: FlightThresholds | None = None,
                          foot_points: Mapping[str, Mapping[str, np.ndarray]] | None = None,
                          release_speed: float = np.inf,
                          carry_anchors: bool = False) -> list[Frame]:
    """One frame per sample: calibrated segment orientations (measured or bridged).

    Without ``bridged`` only the valid samples are tracked. The feet's stance from their IMUs
    (gyroscopes when recorded, else orientations; invalid samples left out) and the rest of
    the knees and hands (their accelerometers, :mod:`ikfusion.imu.resting`) come along for
    contact detection, and so does, for the ``foot_points`` (foot segment -> contact point ->
    offset from its sensor in the segment frame [m], :func:`foot_point_offsets`) of feet
    with accelerometers and gyroscopes, whether each point moves faster than ``release_speed``
    [m/s] (:func:`points_moving`); the flight phases from the pelvis and feet accelerometers
    (:func:`flight_phases`) and the pelvis acceleration in the world frame. With
    ``carry_anchors`` (IMU only) the points' velocities come along too (``Frame.points_velocity``:
    a planted point the IMU says moves carries its anchor along).
    """
    streams = recording.segment_streams(sensor_map)
    if bridged is None:
        R_segment = calibration.segment_orientations(
            {s: np.where(st.valid[:, None, None], st.R_world_sensor, np.nan)
             for s, st in streams.items()})
    else:
        R_segment = bridged.R_world_segment
    tracked = {s: np.isfinite(R).all(axis=(1, 2)) for s, R in R_segment.items()}
    still = {}
    velocity: dict[str, np.ndarray] = {}
    for s, st in streams.items():
        if s in ("LeftFoot", "RightFoot"):
            R = np.where(st.valid[:, None, None], st.R_world_sensor, np.nan)
            gyr = None if st.gyr is None else np.where(st.valid[:, None], st.gyr, np.nan)
            acc = None if st.acc is None else np.where(st.valid[:, None], st.acc, np.nan)
            still[s] = foot_still(R, recording.rate, gyr, stance, acc)
            if (foot_points and s in foot_points and gyr is not None and acc is not None
                    and s in calibration.R_sensor_segment):
                anchors = velocity_anchors(R, still[s] == 1.0, recording.rate, gyr, stance, acc)
                velocity.update(foot_point_velocities(R, acc, gyr, anchors, recording.rate,
                                                      calibration.R_sensor_segment[s],
                                                      dict(foot_points[s])))
        elif s in RESTING_SEGMENTS and st.acc is not None:
            a = world_acceleration(st.R_world_sensor, st.acc)
            a[~st.valid] = np.nan
            still[s] = segment_resting(a, recording.rate)
    moving = faster_than(velocity, release_speed)
    airborne = flight_phases(recording, streams, flight).airborne.tolist()
    pelvis = streams.get("Pelvis")
    a_pelvis = None
    if pelvis is not None and pelvis.acc is not None:
        a_pelvis = world_acceleration(pelvis.R_world_sensor, pelvis.acc)
        a_pelvis[~pelvis.valid] = np.nan
    # per-sample dicts made together (indexing NumPy arrays sample by sample costs more)
    n = len(recording.time)
    orientations = _by_sample({s: list(R) for s, R in R_segment.items()}, tracked, n)
    # samples with every segment tracked carry their orientations stacked (views of one array)
    stacked: list[np.ndarray | None] = [None] * n
    if R_segment:
        every = np.logical_and.reduce(list(tracked.values())).tolist()
        stacked = [R if on else None
                   for R, on in zip(np.stack(list(R_segment.values()), axis=1), every)]
    feet_still = _by_sample({s: (v != 0).tolist() for s, v in still.items()},
                            {s: np.isfinite(v) for s, v in still.items()}, n)
    points_moving = _by_sample({p: (v == 1.0).tolist() for p, v in moving.items()},
                               {p: np.isfinite(v) for p, v in moving.items()}, n)
    points_velocity = _by_sample(
        {p: list(v) for p, v in velocity.items()} if carry_anchors else {},
        {p: np.isfinite(v).all(axis=1) for p, v in velocity.items()}, n)
    a_root: list[np.ndarray | None] = [None] * n
    if a_pelvis is not None:
        a_root = [a if ok else None
                  for a, ok in zip(a_pelvis, np.isfinite(a_pelvis).all(axis=1).tolist())]
    return [Frame(t, o, feet_still=f, points_moving=m, points_velocity=v, airborne=air,
                  root_acceleration=a, orientations_stacked=R)
            for t, o, f, m, v, air, a, R in zip(recording.time.tolist(), orientations,
                                                feet_still, points_moving, points_velocity,
                                                airborne, a_root, stacked)]


def _by_sample(values: Mapping[str, list[Any]], known: Mapping[str, np.ndarray],
               n: int) -> list[dict[str, Any]]:
    """Per sample k, ``{name: values[name][k]}`` over the names ``known[name][k]`` (in order).

    Args:
        values: Name -> its n per-sample values.
        known: Name -> (n,) bool, whether the sample's value is known.
        n: The number of samples.
    """
    names = list(values)
    if not names:
        return [{} for _ in range(n)]
    flags = zip(*(known[name].tolist() for name in names))
    return [dict(zip(names, row)) if all(ok) else
            {name: v for name, v, on in zip(names, row, ok) if on}
            for row, ok in zip(zip(*(values[name] for name in names)), flags)]


def flight_phases(recording: ImuRecording, streams: Mapping[str, SensorStream],
                  thresholds: FlightThresholds | None = None) -> FlightPhases:
    """Flight phases from the pelvis and feet accelerometers (none without a pelvis ``acc``).

    Invalid samples count as missing (NaN): a lost pelvis sample is not free fall.
    """
    def valid(stream: SensorStream, values: np.ndarray | None) -> np.ndarray | None:
        return None if values is None else np.where(stream.valid[:, None], values, np.nan)

    pelvis = streams.get("Pelvis")
    if pelvis is None or pelvis.acc is None:
        return FlightPhases(np.zeros(len(recording.time), dtype=bool), np.zeros(0, dtype=int), 0)
    feet = {s: st for s, st in streams.items() if s in ("LeftFoot", "RightFoot")}
    return detect_flight(
        recording.rate, valid(pelvis, pelvis.acc),
        {s: a for s, st in feet.items() if (a := valid(st, st.acc)) is not None},
        {s: valid(st, st.gyr) for s, st in feet.items()}, thresholds)


def knee_warning(motion: Motion) -> str | None:
    """A warning when the knees flex the wrong way (a heading or mounting mistake)."""
    knees = [f"j{side}Knee" for side in ("Right", "Left")
             if f"j{side}Knee" in motion.model.ball_joints]  # only theirs: the rest is not needed
    columns = [f"{knee}_{angle}" for knee in knees for angle in ("flex", "abd", "rot")]
    angles = motion.model.joint_angle_matrix(motion.q, joints=knees)
    for side in ("Right", "Left"):
        name = f"j{side}Knee_flex"
        if name in columns:
            flex = angles[:, columns.index(name)]
            if np.percentile(flex, 10) < -8.0 and np.median(flex) < 0.0:
                return (f"the {side.lower()} knee flexes the wrong way (median "
                        f"{np.median(flex):.0f} deg): the body heading or a sensor mounting is "
                        "wrong; check --forward and the sensor map")
    return None


def solve_recording(recording: ImuRecording, sensor_map: Mapping[str, str], model: HumanModel,
                    window: tuple[int, int] | None = None, pose: str = "npose",
                    forward: dict[str, str] | None = None, solver: Solver | None = None,
                    progress: bool = False,
                    correction: DriftCorrection | None = None,
                    calibration: Calibration | None = None,
                    causal: bool = False,
                    correction_for: Callable[[Calibration], DriftCorrection | None] | None = None
                    ) -> SolvedRecording:
    """Calibrate on the still pose at the start and solve every frame.

    Args:
        recording: The IMU recording.
        sensor_map: Sensor id -> segment (a ``SensorMap`` also brings its default mounting).
        model: The human model of the subject.
        window: Calibration window (sample indices); found automatically when omitted.
        pose: ``"npose"`` or ``"tpose"``.
        forward: ``{segment: axis}`` override of the body heading (see calibration).
        solver: A configured solver (default settings when omitted).
        progress: Show a progress bar.
        correction: Absolute tag positions (UWB) and how they correct the drift.
        calibration: A calibration already made (``window``, ``pose`` and ``forward`` are then
            not used).
        causal: Solve as live, with the past only: the recording is fed frame by frame to
            :class:`~ikfusion.live.actor_stream.ActorStream` (calibrated on its first
            ``calibration_s`` seconds, stance and bridging from the past, no placement of the
            frames before the first UWB fix); by default the whole recording is used.
            ``SolvedRecording.bridged`` says what was bridged.
        correction_for: Causal only: builds the correction from the calibration of the
            start-up buffer (instead of ``correction``).
    """
    warnings = list(recording.warnings)
    warnings += recording.check_sensor_map(sensor_map)
    window_s = None if window is None else (window[0] / recording.rate,
                                            window[1] / recording.rate)
    solver = solver or Solver(model)
    if causal:
        if correction_for is None and correction is not None:
            correction_for = lambda _cal: correction  # noqa: E731 - the same for any calibration
        return _solve_causal(recording, sensor_map, model, solver, warnings, window_s, pose,
                             forward, correction_for, calibration, progress)
    cal = calibration or calibrate_recording(recording, sensor_map, window_s, forward=forward,
                                             pose=pose)
    warnings += cal.warnings
    st = solver.settings
    bridged = bridged_segments(recording, sensor_map, cal, segment_parents(model), causal)
    warnings += bridged.warnings
    frames = frames_from_recording(recording, sensor_map, cal, stance_thresholds(st), bridged,
                                   foot_points=foot_point_offsets(model),
                                   release_speed=st.release_speed,
                                   carry_anchors=correction is None)
    motion = solver.solve(correction.frames(frames) if correction else frames,
                          progress=progress, total=len(frames),
                          after_step=correction.after_frame if correction else None)
    if correction is not None:
        correction.place_start(motion)
        warnings += correction.far_warnings()
    return _finish(motion, model, cal, warnings, bridged.summary())


def _solve_causal(recording: ImuRecording, sensor_map: Mapping[str, str], model: HumanModel,
                  solver: Solver, warnings: list[str], window_s: tuple[float, float] | None,
                  pose: str, forward: dict[str, str] | None,
                  correction_for: Callable[[Calibration], DriftCorrection | None] | None,
                  calibration: Calibration | None, progress: bool) -> SolvedRecording:
    """The recording fed frame by frame to the live pipeline's :class:`ActorStream`."""
    stream = ActorStream(model, sensor_map, recording.rate, solver=solver, window_s=window_s,
                         pose=pose, forward=forward, calibration=calibration,
                         correction_for=correction_for)
    poses = []
    for time_s, samples in tqdm(recording_frames(recording, sensor_map), total=len(recording),
                                disable=not progress, unit="frame"):
        poses += stream.push(time_s, samples)
    poses += stream.finish()
    if stream.calibration is None:
        raise InputError("the recording holds no sample of a mapped sensor", field="imu")
    motion = Motion.from_poses(model, poses, solver.contact_names, stream.all_warnings())
    bridged = stream.bridged()
    return _finish(motion, model, stream.calibration, warnings,
                   bridged.summary() if bridged else {})


def _finish(motion: Motion, model: HumanModel, cal: Calibration, warnings: list[str],
            bridged: dict[str, dict[str, object]]) -> SolvedRecording:
    """The warnings of the whole solve put together."""
    motion.warnings = warnings + motion.warnings
    knee = knee_warning(motion)
    if knee:
        motion.warnings.append(knee)
    assumed = coverage_warning(model.ball_joints, cal.R_sensor_segment)
    if assumed:
        motion.warnings.append(assumed)
    return SolvedRecording(motion, cal, motion.warnings, bridged)
