"""The main job on embedded data: simulate a capture, solve it, write results, print a table.

The capture is a walk in circles in a 6 m x 8 m room (the 10-reader constellation of
``configs/constellations/room_6x8.yaml`` surrounds it), worn by the 17-sensor MVN layout with
random mountings and the default sensor errors (orientation noise and heading wander), written
as MT Manager files. The body is calibrated on the N-pose at the start and solved from those
files alone, written as a result folder, and scored against the ground truth.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .evaluate import Evaluation, evaluate
from .ik import Motion
from .io.reader import read_imu
from .io.sensor_map import load_sensor_map
from .model import Body, HumanModel
from .pipeline import solve_recording
from .results import write_result_folder
from .sim.capture import write_capture
from .sim.gait import GaitParameters, generate_gait
from .sim.imu import ImuNoise
from .sim.truth import TruthMotion


@dataclass
class DemoResult:
    """What the demo produced."""

    out_dir: Path
    truth: TruthMotion
    motion: Motion
    evaluation: Evaluation
    solve_seconds: float


def demo_walk(seconds: float) -> GaitParameters:
    """Walking in circles (radius 1.5 m) in the middle of the 6 m x 8 m room."""
    return GaitParameters(path="circle", radius=1.5, duration=seconds, stand=2.0, speed=1.1,
                          step_length=0.6)


def run_demo(out_dir: str | Path = "ikfusion-demo", seconds: float = 60.0, seed: int = 7,
             progress: bool = True) -> DemoResult:
    """Simulate a capture into files, solve it from the files alone, write and evaluate."""
    out = Path(out_dir)
    truth = generate_gait(HumanModel.default(), demo_walk(seconds), rate=60.0, progress=progress)
    # Put the walk in the middle of the room (the gait starts at the origin heading +X).
    truth.q[:, 0] += 3.0
    truth.q[:, 1] += 4.0 - 1.5
    capture = write_capture(out / "capture", truth, ImuNoise(), seed)
    recording = read_imu(capture.imu)
    model = HumanModel.from_body(Body.from_yaml(capture.folder / "body.yaml"))
    start = time.perf_counter()
    solved = solve_recording(recording, load_sensor_map(capture.sensor_map), model,
                             progress=progress)
    elapsed = time.perf_counter() - start
    write_result_folder(solved.motion, out / "result", extra_summary={
        "source": "ikfusion demo: simulated walk in circles, 17 sensors, default noise",
        "calibration": {"method": solved.calibration.method}, "uwb": {"used": False}})
    evaluation = evaluate(out / "result", capture.folder / "truth.npz")
    return DemoResult(out, truth, solved.motion, evaluation, elapsed)


def table(result: DemoResult) -> str:
    """The accuracy and speed table printed by ``ikfusion demo``."""
    e = result.evaluation
    m = result.motion
    walked = float(np.sum(np.linalg.norm(np.diff(result.truth.q[::60, :2], axis=0), axis=1)))
    rows = [
        ("capture", f"{m.time[-1] - m.time[0]:.0f} s walk in circles, {walked:.0f} m, "
                    f"17 IMUs at {m.rate:.0f} Hz, default sensor noise"),
        ("joint angle RMS", f"{e.joint_angle_rms_deg:.2f} deg"),
        ("segment orientation RMS", f"{e.segment_orientation_rms_deg:.2f} deg"),
        ("head position RMS (IMU only)", f"{100 * e.head_position_rms_m:.1f} cm 3-D, "
                                         f"{100 * e.head_position_rms_xy_m:.1f} cm horizontal"),
        ("foot slide per contact",
         f"{e.foot_slide_mm:.1f} mm mean, {e.foot_slide_max_mm:.1f} mm max"),
        ("speed", f"{len(m) / result.solve_seconds:.0f} frames/s "
                  f"({1e3 * np.median(m.solve_time):.2f} ms median per frame)"),
    ]
    width = max(len(r[0]) for r in rows)
    lines = [f"{name:<{width}}  {value}" for name, value in rows]
    lines.append(f"results in {result.out_dir}/result, capture and truth in "
                 f"{result.out_dir}/capture")
    lines.append(f"see it: ikfusion view {result.out_dir}/result --truth "
                 f"{result.out_dir}/capture/truth.npz")
    return "\n".join(lines)
