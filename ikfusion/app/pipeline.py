"""From a recording to a solved motion: sensor map, calibration, frames, solver.

``solve_recording`` is what ``ikfusion solve`` runs: every mapped sensor's orientation becomes
its segment's orientation through the calibration, samples flagged invalid (lost packets, NaN, a
sensor that drops out) are bridged from what is known around them
(:mod:`ikfusion.imu.bridging`: interpolated offline, held and blended back in causally), and the
solver does the rest.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..ik import Frame, Motion, Solver
from ..ik.assumed import coverage_warning
from ..imu.bridging import BridgedSegments, BridgingSettings, bridge_segments
from ..imu.calibration import Calibration, calibrate_recording
from ..imu.stance import StanceThresholds, foot_still
from ..io.recording import ImuRecording
from ..model.human_model import HumanModel
from .correction import DriftCorrection


@dataclass
class SolvedRecording:
    """A solved recording with what was learned on the way."""

    motion: Motion
    calibration: Calibration
    warnings: list[str] = field(default_factory=list)
    bridged: dict[str, dict[str, object]] = field(default_factory=dict)


def segment_parents(model: HumanModel) -> dict[str, str | None]:
    """Segment -> its parent segment in the model's tree (None for the root)."""
    parents: dict[str, str | None] = {s: None for s in model.segment_names}
    for joint in model.ball_joints.values():
        parents[joint.spec.child] = joint.spec.parent
    return parents


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
                          bridged: BridgedSegments | None = None) -> list[Frame]:
    """One frame per sample: calibrated segment orientations (measured or bridged).

    Without ``bridged`` only the valid samples are tracked. The feet's stance from their IMUs
    (gyroscopes when recorded, else orientations; invalid samples left out) comes along for
    contact detection.
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
    for s, st in streams.items():
        if s in ("LeftFoot", "RightFoot"):
            R = np.where(st.valid[:, None, None], st.R_world_sensor, np.nan)
            gyr = None if st.gyr is None else np.where(st.valid[:, None], st.gyr, np.nan)
            still[s] = foot_still(R, recording.rate, gyr, stance)
    # per-sample lists made once (indexing NumPy arrays sample by sample costs more)
    rows = {s: list(R) for s, R in R_segment.items()}
    tracked_rows = {s: v.tolist() for s, v in tracked.items()}
    known = {s: np.isfinite(v).tolist() for s, v in still.items()}
    still_rows = {s: (v != 0).tolist() for s, v in still.items()}
    frames = []
    for k, t in enumerate(recording.time.tolist()):
        frames.append(Frame(t, {s: R[k] for s, R in rows.items() if tracked_rows[s][k]},
                            feet_still={s: v[k] for s, v in still_rows.items()
                                        if known[s][k]}))
    return frames


def knee_warning(motion: Motion) -> str | None:
    """A warning when the knees flex the wrong way (a heading or mounting mistake)."""
    columns = motion.model.angle_columns
    angles = motion.joint_angles()
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
                    causal: bool = False) -> SolvedRecording:
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
        causal: Bridge invalid samples with the past only (as live); by default each gap is
            interpolated across. ``SolvedRecording.bridged`` says what was bridged.
    """
    warnings = list(recording.warnings)
    warnings += recording.check_sensor_map(sensor_map)
    window_s = None if window is None else (window[0] / recording.rate,
                                            window[1] / recording.rate)
    cal = calibration or calibrate_recording(recording, sensor_map, window_s, forward=forward,
                                             pose=pose)
    warnings += cal.warnings
    solver = solver or Solver(model)
    st = solver.settings
    bridged = bridged_segments(recording, sensor_map, cal, segment_parents(model), causal)
    warnings += bridged.warnings
    frames = frames_from_recording(recording, sensor_map, cal,
                                   StanceThresholds(st.still_rate, st.still_duration), bridged)
    motion = solver.solve(frames, progress=progress, total=len(frames),
                          after_step=correction.after_frame if correction else None)
    if correction is not None:
        correction.place_start(motion)
    motion.warnings = warnings + motion.warnings
    knee = knee_warning(motion)
    if knee:
        motion.warnings.append(knee)
    assumed = coverage_warning(model.ball_joints, cal.R_sensor_segment)
    if assumed:
        motion.warnings.append(assumed)
    return SolvedRecording(motion, cal, motion.warnings, bridged.summary())
