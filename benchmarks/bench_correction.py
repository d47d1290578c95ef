"""Drift correction modes on one simulated UWB capture, and a 1 m gap injected at once.

A walk in circles in the 6 m x 8 m room of ``configs/constellations/room_6x8.yaml`` (10 readers,
sigma 3 cm, 10 % NLOS, default IMU errors) is solved from its files with ``--correction off``,
``slide`` and ``no-slide``; then the tag fixes are moved by 1 m at once half-way through (as if
the inertial body had drifted 1 m) and solved again in both modes.

Columns: head 3-D RMS against the truth [cm] (readers' frame, no alignment); slide of planted
contact points per contact phase of the solve itself after the first fix has placed the body
(mean and max [mm]); joint-angle RMS difference from the uncorrected solve [deg]; for the
injected gap, the largest extra change of a body joint angle from one frame to the next compared
with the same mode's solve without the gap [deg/frame] (it also counts contacts that let go a
frame earlier or later in one of the two), the time until the remaining gap is below 5 cm [s],
and the pop (below) while it closes [deg/frame]; ``pop deg``: the largest error of a per-frame
change of a body joint angle against the truth's change in the same frame [deg/frame]
(``ikfusion.app.evaluate.joint_angle_jump``, toes left out), which angle and when.

The whole table is printed twice: with the default sensor errors, whose orientation noise alone
changes joint angles by up to about 1.5 deg from one frame to the next, and with perfect sensors,
where what is left are the pops the solve makes (contacts that let go, the correction).

Run: .venv/bin/python benchmarks/bench_correction.py [--seconds 40] [--seed 4] [--noise both]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from ikfusion.app.correction import DriftCorrection
from ikfusion.app.evaluate import joint_angle_jump, phase_slides
from ikfusion.app.pipeline import solve_recording
from ikfusion.app.uwb_aiding import TrackedCapture, drift_correction, track_capture
from ikfusion.cli import main as cli
from ikfusion.mocap.model_motion import site_positions
from ikfusion.model import HumanModel
from ikfusion.paths import shipped_config

GAP_M = 1.0


def own_phase_slides_mm(model: HumanModel, q: np.ndarray, names: list[str],
                        contacts: np.ndarray) -> np.ndarray:
    """Per contact phase of the solve itself, the largest horizontal slide [mm]."""
    return 1e3 * np.array(phase_slides(site_positions(model, q, names), contacts))


def run_mode(tracked: TrackedCapture, mode: str, shift_from: float | None
             ) -> dict[str, object]:
    """Solve the capture with one correction mode (fixes moved by ``GAP_M`` from a time on)."""
    time = tracked.recording.time
    correction: DriftCorrection = drift_correction(tracked.tags, tracked.tracks, time, mode)
    if shift_from is not None:
        jump = np.where(time[:, None] >= shift_from, [GAP_M, 0.0, 0.0], 0.0)
        for fixes in correction.fixes:  # new arrays: the tracks are shared by every mode
            fixes.p_world = fixes.p_world + jump
    solved = solve_recording(tracked.recording, tracked.sensor_map, tracked.model,
                             correction=correction, calibration=tracked.calibration)
    return {"motion": solved.motion, "gap": correction.gap, "time": time}


def pop(motion, truth: dict, window: tuple[float, float] = (-np.inf, np.inf)
        ) -> tuple[float, str]:
    """Largest |per-frame change of a body joint angle - the truth's change| [deg], and where.

    Over the frames of ``window`` [s] (from its start to its end, both included).
    """
    names = list(truth["joint_angle_names"])
    columns = [c for c in motion.model.angle_columns if c in names]
    solved = motion.joint_angles()[:, [motion.model.angle_columns.index(c) for c in columns]]
    true = truth["joint_angles"][:, [names.index(c) for c in columns]]
    n = min(len(solved), len(true))
    time, solved, true = motion.time[-n:], solved[-n:], true[-n:]
    inside = (time >= window[0] - 1e-9) & (time <= window[1] + 1e-9)
    return joint_angle_jump(time[inside], solved[inside], true[inside], columns)


def head_rms_cm(motion, truth: dict) -> float:
    names = list(truth["site_names"])
    p_true = truth["p_world_site"][:, names.index("HeadTop")]
    p = site_positions(motion.model, motion.q, ["HeadTop"])[:, 0]
    n = min(len(p), len(p_true))
    return float(100 * np.sqrt(np.mean(np.sum((p[-n:] - p_true[-n:]) ** 2, axis=1))))


def body_columns(motion) -> list[int]:
    """Joint-angle columns of the body (the unsensed toes left out)."""
    return [i for i, c in enumerate(motion.model.angle_columns) if "BallFoot" not in c]


def table(seconds: float, seed: int, noise: str) -> None:
    """Simulate, solve every mode, print one table."""
    with tempfile.TemporaryDirectory() as tmp:
        capture = Path(tmp) / "capture"
        room = shipped_config("constellations", "room_6x8.yaml")
        assert cli(["simulate", "--motion", "gait", "--seconds", str(seconds),
                    "--readers", str(room), "--seed", str(seed), "--noise", noise,
                    "--out", str(capture), "--quiet"]) == 0
        truth = dict(np.load(capture / "truth.npz", allow_pickle=True))
        inject = 0.5 * seconds
        tracked = track_capture(capture)
        runs = {"off": run_mode(tracked, "off", None)}
        for mode in ("slide", "no-slide"):
            runs[mode] = run_mode(tracked, mode, None)
            runs[f"{mode}, 1 m gap at {inject:.0f} s"] = run_mode(tracked, mode, inject)
    angles_off = runs["off"]["motion"].joint_angles()
    floor = []  # the uncorrected solve's pops over each closing window
    sensors = "default sensor errors" if noise == "default" else "perfect sensors"
    print(f"\n{seconds:.0f} s walk in circles, room_6x8 (10 readers), seed {seed}, {sensors}")
    print(f"{'mode':<26} {'head cm':>8} {'slide mm':>9} {'max mm':>7} {'d angles':>9} "
          f"{'gap adds':>9} {'closed s':>9} {'closing':>8} {'pop deg':>8}")
    for name, r in runs.items():
        motion = r["motion"]
        contact_points = list(motion.contact_names)
        # The first fix places the whole body, planted points included, in the readers'
        # frame at once: that is a placement, not a slide, so phases are measured after it.
        placed = int(np.flatnonzero(np.isfinite(r["gap"]))[0]) + 1 if name != "off" else 0
        slides = own_phase_slides_mm(motion.model, motion.q[placed:], contact_points,
                                     motion.contacts[placed:])
        angles = motion.joint_angles()
        d_rms = float(np.sqrt(np.mean((angles - angles_off) ** 2)))
        closed, gap_adds, closing = "-", "-", "-"
        if "gap" in name:
            same = runs[name.split(",")[0]]["motion"].joint_angles()
            n = min(len(same), len(angles))
            body = body_columns(motion)
            gap_adds = f"{np.abs(np.diff(angles[:n, body] - same[:n, body], axis=0)).max():.2f}"
            gap, time = r["gap"], r["time"]
            below = np.flatnonzero((time >= inject) & (gap < 0.05))
            closed = f"{time[below[0]] - inject:.1f}" if len(below) else "never"
            end = time[below[0]] if len(below) else time[-1]
            closing = f"{pop(motion, truth, (inject, end))[0]:.2f}"
            floor.append(f"{pop(runs['off']['motion'], truth, (inject, end))[0]:.2f} "
                         f"({inject:.1f}-{end:.1f} s)")
        jump, where = pop(motion, truth)
        print(f"{name:<26} {head_rms_cm(motion, truth):>8.1f} {slides.mean():>9.2f} "
              f"{slides.max():>7.2f} {d_rms:>9.2f} {gap_adds:>9} {closed:>9} {closing:>8} "
              f"{jump:>8.2f}  "
              f"({where})", flush=True)
    print(f"the uncorrected solve's pop deg over the same windows: {', '.join(floor)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=40.0)
    parser.add_argument("--seed", type=int, default=4)
    parser.add_argument("--noise", choices=["default", "none", "both"], default="both")
    args = parser.parse_args()
    for noise in (["default", "none"] if args.noise == "both" else [args.noise]):
        table(args.seconds, args.seed, noise)


if __name__ == "__main__":
    main()
