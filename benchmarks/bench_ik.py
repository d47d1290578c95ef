"""Benchmark of the whole-body solver: time per frame, Gauss-Newton steps and accuracy.

The full 17-sensor body follows a simulated 60 Hz walk (ikfusion.sim.gait) from exact segment
orientations. Each QP backend of our solver is timed, and the same orientation task set on the
same model is solved with Pink (pin-pink, benchmark-only: `pip install pin-pink`) at several
iterations per frame, so the table compares time per frame at comparable orientation error.

Run: .venv/bin/python benchmarks/bench_ik.py [--seconds 10] [--repeat 3]

On a shared machine, ``--repeat N`` runs every row N times and keeps the run with the lowest
median (the others were slowed by other processes; the results are the same every run).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from functools import partial

import numpy as np
import pinocchio as pin

from ikfusion.ik import Frame, Solver
from ikfusion.model import SENSOR_SEGMENTS, HumanModel
from ikfusion.rotations import angle_between
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.truth import orientation_frames


def orientation_rms_deg(model: HumanModel, frames: list[Frame], qs: np.ndarray) -> float:
    data = model.model.createData()
    errors = []
    for frame, q in zip(frames, qs):
        pin.framesForwardKinematics(model.model, data, q)
        for s, R in frame.orientations.items():
            errors.append(angle_between(R, data.oMf[model.segment_frame_id(s)].rotation))
    return float(np.degrees(np.sqrt(np.mean(np.square(errors)))))


def run_ours(model: HumanModel, frames: list[Frame], backend: str,
             contacts: bool = True) -> dict[str, float]:
    solver = Solver(model, backend=backend, contacts=contacts)
    solver.step(frames[0])  # compile / warm up
    motion = solver.solve(frames)
    ms = 1e3 * motion.solve_time[1:]
    return {"median_ms": float(np.median(ms)), "p95_ms": float(np.percentile(ms, 95)),
            "steps": float(motion.iterations[1:].mean()),
            "orientation_rms_deg": orientation_rms_deg(model, frames, motion.q)}


def run_pink(model: HumanModel, frames: list[Frame], iterations: int, q0: np.ndarray,
             dt: float) -> dict[str, float] | None:
    try:
        import pink
        from pink.tasks import FrameTask, PostureTask
    except ImportError:
        return None
    configuration = pink.Configuration(model.model, model.model.createData(), q0)
    tasks = {s: FrameTask(s, position_cost=0.0, orientation_cost=1.0) for s in SENSOR_SEGMENTS}
    posture = PostureTask(cost=1e-3)
    posture.set_target(q0)
    times, qs = [], []
    for frame in frames:
        start = time.perf_counter()
        for s, R in frame.orientations.items():
            tasks[s].set_target(pin.SE3(R, np.zeros(3)))
        for _ in range(iterations):
            velocity = pink.solve_ik(configuration, [*tasks.values(), posture], dt,
                                     solver="daqp", limits=[], safety_break=False)
            configuration.integrate_inplace(velocity, dt)
        times.append(time.perf_counter() - start)
        qs.append(configuration.q.copy())
    ms = 1e3 * np.array(times[1:])
    return {"median_ms": float(np.median(ms)), "p95_ms": float(np.percentile(ms, 95)),
            "steps": float(iterations),
            "orientation_rms_deg": orientation_rms_deg(model, frames, np.array(qs))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--repeat", type=int, default=1,
                        help="runs per row; the one with the lowest median is reported")
    args = parser.parse_args()
    rate = 60.0
    model = HumanModel.default()
    truth = generate_gait(model, GaitParameters(duration=args.seconds, stand=1.0), rate=rate)
    # stacked as the application's frames are (ikfusion.app.pipeline): the solver reads them
    frames = orientation_frames(model, truth.q, truth.time, SENSOR_SEGMENTS, stacked=True)
    repeat = max(1, args.repeat)

    def best(run: Callable[[], dict[str, float] | None]) -> dict[str, float] | None:
        results = [run() for _ in range(repeat)]
        kept = [r for r in results if r is not None]
        return min(kept, key=lambda r: r["median_ms"]) if kept else None

    rows: list[tuple[str, dict[str, float]]] = []
    for backend in ("daqp", "proxqp", "osqp"):
        ours = best(partial(run_ours, model, frames, backend))
        assert ours is not None
        rows.append((f"ikfusion {backend}", ours))
    # The task set Pink solves: orientations and posture only (no contacts, floor, limits).
    ours = best(partial(run_ours, model, frames, "daqp", False))
    assert ours is not None
    rows.append(("ikfusion daqp, orientation only", ours))
    for iterations in (1, 2, 3):
        result = best(partial(run_pink, model, frames, iterations, truth.q[0], 1.0 / rate))
        if result is not None:
            rows.append((f"pink daqp x{iterations}", result))
    print(f"17-sensor body, simulated walk, {len(frames)} frames at {rate:.0f} Hz"
          + (f", best of {repeat} runs" if repeat > 1 else ""))
    print(f"{'solver':<32} {'median ms':>10} {'p95 ms':>8} {'GN steps':>9} {'orient. RMS deg':>16}")
    for name, r in rows:
        print(f"{name:<32} {r['median_ms']:>10.3f} {r['p95_ms']:>8.3f} {r['steps']:>9.2f} "
              f"{r['orientation_rms_deg']:>16.4f}")
    ours = rows[3][1]
    for name, r in rows[4:]:
        print(f"time ratio {name} / ikfusion orientation only: "
              f"{r['median_ms'] / ours['median_ms']:.2f} "
              f"(orientation RMS {r['orientation_rms_deg']:.4f} vs "
              f"{ours['orientation_rms_deg']:.4f} deg)")


if __name__ == "__main__":
    main()
