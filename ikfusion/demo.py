"""The main job on embedded data: simulate a capture, solve it three ways, print a table.

The capture is a walk in circles in a 6 m x 8 m room (the 10-reader constellation of
``configs/constellations/room_6x8.yaml`` surrounds it), worn by the 17-sensor MVN layout with
random mountings and the default sensor errors (orientation noise and heading wander), with UWB
tags on the head and both feet, written as MT Manager files and a TOA log. The body is
calibrated on the N-pose at the start, the tags are tracked once by their IMU + UWB filters, and
the recording is solved from those files three times: IMU only, UWB with ``slide`` and with
``no-slide`` correction (SPEC: the default when UWB is given). Each result is written and scored
against the ground truth.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .correction import DriftCorrection
from .evaluate import Evaluation, evaluate
from .ik import Motion
from .imu.calibration import calibrate_recording
from .io.reader import read_imu
from .io.sensor_map import load_sensor_map
from .model import Body, HumanModel
from .paths import shipped_config
from .pipeline import solve_recording
from .results import write_result_folder
from .sim.capture import Capture, write_capture
from .sim.gait import GaitParameters, generate_gait
from .sim.imu import ImuNoise
from .sim.truth import TruthMotion
from .uwb.constellation import load_constellation
from .uwb_aiding import UwbInputs, drift_correction, track_recording_tags, uwb_summary

#: The three solves: column label, result folder, correction mode (None: IMU only).
MODES = (("IMU only", "result_imu_only", None),
         ("UWB slide", "result_slide", "slide"),
         ("UWB no-slide", "result", "no-slide"))


@dataclass
class ModeResult:
    """One solve of the demo capture.

    Attributes:
        label: Column heading of the table.
        folder: Its result folder.
        motion: The solved motion.
        evaluation: Scored against the truth (IMU only: after the start alignment).
        solve_seconds: Wall time of the solve [s].
        gap_m: Mean and largest remaining horizontal gap of the correction [m] (None: no UWB).
    """

    label: str
    folder: Path
    motion: Motion
    evaluation: Evaluation
    solve_seconds: float
    gap_m: tuple[float, float] | None


@dataclass
class DemoResult:
    """What the demo produced."""

    out_dir: Path
    truth: TruthMotion
    modes: list[ModeResult]

    @property
    def motion(self) -> Motion:
        """The default mode's motion (UWB no-slide)."""
        return self.modes[-1].motion


def demo_walk(seconds: float) -> GaitParameters:
    """Walking in circles (radius 1.5 m) in the middle of the 6 m x 8 m room."""
    return GaitParameters(path="circle", radius=1.5, duration=seconds, stand=2.0, speed=1.1,
                          step_length=0.6)


def run_demo(out_dir: str | Path = "ikfusion-demo", seconds: float = 60.0, seed: int = 7,
             progress: bool = True) -> DemoResult:
    """Simulate a capture into files, solve it three ways from the files, write and evaluate."""
    out = Path(out_dir)
    truth = generate_gait(HumanModel.default(), demo_walk(seconds), rate=60.0, progress=progress)
    # Put the walk in the middle of the room (the gait starts at the origin heading +X).
    truth.q[:, 0] += 3.0
    truth.q[:, 1] += 4.0 - 1.5
    room = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    capture = write_capture(out / "capture", truth, ImuNoise(), seed, constellation=room)
    return DemoResult(out, capture.truth, _solve_three_ways(capture, out, progress))


def _solve_three_ways(capture: Capture, out: Path, progress: bool) -> list[ModeResult]:
    """Calibrate and track the tags once, then solve in every mode of :data:`MODES`."""
    recording = read_imu(capture.imu)
    sensor_map = load_sensor_map(capture.sensor_map)
    model = HumanModel.from_body(Body.from_yaml(capture.folder / "body.yaml"))
    calibration = calibrate_recording(recording, sensor_map)
    files = UwbInputs(capture.folder / "toa.csv", capture.folder / "readers.yaml",
                      capture.folder / "tags.yaml")
    tags, tracks = track_recording_tags(recording, sensor_map, model, calibration, files)
    results = []
    for label, name, mode in MODES:
        correction: DriftCorrection | None = None
        if mode is not None:
            correction = drift_correction(tags, tracks, recording.time, mode)
        start = time.perf_counter()
        solved = solve_recording(recording, sensor_map, model, progress=progress,
                                 correction=correction, calibration=calibration)
        elapsed = time.perf_counter() - start
        uwb = {"used": False} if correction is None else uwb_summary(tracks, correction)
        folder = write_result_folder(solved.motion, out / name, extra_summary={
            "source": f"ikfusion demo: simulated walk in circles, 17 sensors, default noise, "
                      f"{label}",
            "calibration": {"method": calibration.method}, "uwb": uwb})
        gap = None if correction is None else _gap(correction)
        results.append(ModeResult(label, Path(folder), solved.motion,
                                  evaluate(folder, capture.folder / "truth.npz"), elapsed, gap))
    return results


def _gap(correction: DriftCorrection) -> tuple[float, float]:
    """Mean and largest remaining horizontal gap of a correction over the solve [m]."""
    gap = correction.gap[np.isfinite(correction.gap)]
    return (float(gap.mean()), float(gap.max())) if gap.size else (0.0, 0.0)


def table(result: DemoResult) -> str:
    """The accuracy and speed table printed by ``ikfusion demo``, one column per mode."""
    m = result.motion
    walked = float(np.sum(np.linalg.norm(np.diff(result.truth.q[::60, :2], axis=0), axis=1)))

    def row(name: str, cell: Callable[[ModeResult], str]) -> tuple[str, list[str]]:
        return name, [cell(r) for r in result.modes]

    rows = [
        ("", [r.label for r in result.modes]),
        row("joint angle RMS [deg]", lambda r: f"{r.evaluation.joint_angle_rms_deg:.2f}"),
        row("segment orientation RMS [deg]",
            lambda r: f"{r.evaluation.segment_orientation_rms_deg:.2f}"),
        row("head position RMS 3-D [cm]",
            lambda r: f"{100 * r.evaluation.head_position_rms_m:.1f}"),
        row("head position RMS horizontal [cm]",
            lambda r: f"{100 * r.evaluation.head_position_rms_xy_m:.1f}"),
        row("foot slide per contact [mm]", lambda r: f"{r.evaluation.foot_slide_mm:.1f} mean, "
                                                     f"{r.evaluation.foot_slide_max_mm:.1f} max"),
        row("UWB gap left [cm]", lambda r: "-" if r.gap_m is None else
            f"{100 * r.gap_m[0]:.1f} mean, {100 * r.gap_m[1]:.1f} max"),
        row("speed [frames/s]", lambda r: f"{len(r.motion) / r.solve_seconds:.0f} "
                                          f"({1e3 * np.median(r.motion.solve_time):.2f} ms/frame)"),
    ]
    width = max(len(name) for name, _ in rows)
    cols = [max(len(cells[i]) for _, cells in rows) for i in range(len(result.modes))]
    lines = [f"capture: {m.time[-1] - m.time[0]:.0f} s walk in circles, {walked:.0f} m, "
             f"17 IMUs at {m.rate:.0f} Hz with default noise, UWB tags on head and feet, "
             f"10 readers"]
    lines += [f"{name:<{width}}  " + "  ".join(f"{c:>{w}}" for c, w in zip(cells, cols))
              for name, cells in rows]
    lines.append("IMU-only positions are shifted to the true start (absolute position is not "
                 "observable without UWB).")
    lines.append(f"results in {result.out_dir}/result (UWB no-slide), result_slide and "
                 f"result_imu_only; capture and truth in {result.out_dir}/capture")
    lines.append(f"see it: ikfusion view {result.out_dir}/result --truth "
                 f"{result.out_dir}/capture/truth.npz")
    return "\n".join(lines)
