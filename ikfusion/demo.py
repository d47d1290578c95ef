"""The main job on embedded data: simulate a capture, solve it, write results, print a table.

The capture is a walk in circles in a 6 m x 8 m room (the 10-reader constellation of
``configs/constellations/room_6x8.yaml`` surrounds it), worn by the 17-sensor MVN layout with the
default sensor errors (orientation noise and heading wander). The body is solved from the sensor
orientations alone, written as a result folder, and scored against the ground truth.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .evaluate import Evaluation, evaluate
from .ik import Frame, Motion, Solver
from .model import SENSOR_SEGMENTS, HumanModel
from .results import write_result_folder
from .sim.gait import GaitParameters, generate_gait
from .sim.imu import ImuNoise, simulate_imus
from .sim.truth import TruthMotion, write_truth


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


def frames_from_imus(segments: list[str], time_s: np.ndarray, R_world_segment: np.ndarray,
                     ) -> list[Frame]:
    """Frames of segment orientation targets (S, N, 3, 3)."""
    return [Frame(float(t), {s: R_world_segment[i, k] for i, s in enumerate(segments)})
            for k, t in enumerate(time_s)]


def run_demo(out_dir: str | Path = "ikfusion-demo", seconds: float = 60.0, seed: int = 7,
             progress: bool = True) -> DemoResult:
    """Simulate, solve, write and evaluate.

    The sensors' mounting is known here (they are simulated aligned with their segments), so
    the demo measures the solver, not the sensor-to-segment calibration.
    """
    rng = np.random.default_rng(seed)
    out = Path(out_dir)
    model = HumanModel.default()
    truth = generate_gait(model, demo_walk(seconds), rate=60.0, progress=progress)
    # Put the walk in the middle of the room (the gait starts at the origin heading +X).
    truth.q[:, 0] += 3.0
    truth.q[:, 1] += 4.0 - 1.5
    segments = list(SENSOR_SEGMENTS)
    imus = simulate_imus(model, truth.time, truth.q, segments, rng, ImuNoise(),
                         random_mounting=False)
    frames = frames_from_imus(segments, truth.time, imus.R_world_sensor)
    start = time.perf_counter()
    motion = Solver(model).solve(frames, progress=progress, total=len(frames))
    elapsed = time.perf_counter() - start
    write_truth(out / "truth.npz", truth)
    write_result_folder(motion, out / "result", extra_summary={
        "source": "ikfusion demo: simulated walk in circles, 17 sensors, default noise"})
    return DemoResult(out, truth, motion, evaluate(out / "result", out / "truth.npz"), elapsed)


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
    lines.append(f"results in {result.out_dir}/result (truth: {result.out_dir}/truth.npz)")
    return "\n".join(lines)
