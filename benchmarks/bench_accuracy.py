"""Accuracy over several motions: simulate -> solve (from the files, calibrated) -> evaluate.

Motions: the procedural walk (straight and in circles) and every clip in ../shared/data/mocap
(CMU and SFU skeletons: walking, jogging on a curve, hops with flight phases), each with perfect
sensors and with the default sensor errors. Prints one table: joint-angle RMS, segment
orientation RMS, head position RMS (IMU only, start aligned), foot slide per true contact phase.

Run: .venv/bin/python benchmarks/bench_accuracy.py [--noise default|none|both] [--seconds 20]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from ikfusion.app.evaluate import evaluate
from ikfusion.app.pipeline import solve_recording
from ikfusion.io import load_sensor_map, read_mtmanager
from ikfusion.model import Body, HumanModel
from ikfusion.results import write_result_folder
from ikfusion.sim.capture import truth_motion, write_capture
from ikfusion.sim.imu import ImuNoise

MOCAP = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mocap"


def run(motion: str, noise_name: str, seconds: float, folder: Path) -> dict[str, float]:
    truth = truth_motion(motion, seconds, 60.0)
    noise = ImuNoise() if noise_name == "default" else ImuNoise.none()
    capture = write_capture(folder / "capture", truth, noise, seed=3)
    model = HumanModel.from_body(Body.from_yaml(capture.folder / "body.yaml"))
    start = time.perf_counter()
    solved = solve_recording(read_mtmanager(capture.imu), load_sensor_map(capture.sensor_map),
                             model)
    elapsed = time.perf_counter() - start
    write_result_folder(solved.motion, folder / "result", extra_summary={"uwb": {"used": False}})
    e = evaluate(folder / "result", capture.folder / "truth.npz")
    return {"frames": e.frames, "angles": e.joint_angle_rms_deg,
            "orient": e.segment_orientation_rms_deg, "head": 100 * e.head_position_rms_m,
            "slide": e.foot_slide_mm, "slide_max": e.foot_slide_max_mm,
            "fps": len(solved.motion) / elapsed}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--noise", choices=["default", "none", "both"], default="both")
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()
    motions = ["gait:straight", "gait:circle"]
    if MOCAP.is_dir():
        motions += [str(p) for p in sorted(MOCAP.glob("*.bvh"))]
    else:
        print(f"(no mocap clips: {MOCAP} is absent)")
    noises = ["none", "default"] if args.noise == "both" else [args.noise]
    print(f"{'motion':<28} {'noise':<8} {'frames':>6} {'angles deg':>10} {'orient deg':>10} "
          f"{'head cm':>8} {'slide mm':>9} {'max mm':>8} {'frames/s':>9}")
    for motion in motions:
        for noise in noises:
            with tempfile.TemporaryDirectory() as tmp:
                r = run(motion, noise, args.seconds, Path(tmp))
            name = Path(motion).stem if motion.endswith(".bvh") else motion
            print(f"{name:<28} {noise:<8} {r['frames']:>6} {r['angles']:>10.2f} "
                  f"{r['orient']:>10.2f} {r['head']:>8.1f} {r['slide']:>9.1f} "
                  f"{r['slide_max']:>8.1f} {r['fps']:>9.0f}", flush=True)


if __name__ == "__main__":
    main()
