"""Drift correction modes on one simulated UWB capture, and a 1 m gap injected at once.

A walk in circles in the 6 m x 8 m room of ``configs/constellations/room_6x8.yaml`` (10 readers,
sigma 3 cm, 10 % NLOS, default IMU errors) is solved from its files with ``--correction off``,
``slide`` and ``no-slide``; then the tag fixes are moved by 1 m at once half-way through (as if
the inertial body had drifted 1 m) and solved again in both modes.

Columns: head 3-D RMS against the truth [cm] (readers' frame, no alignment); slide of planted
contact points per contact phase of the solve itself after the first fix has placed the body
(mean and max [mm]); joint-angle RMS
difference from the uncorrected solve [deg]; the largest extra change of any joint angle from
one frame to the next compared with the uncorrected solve [deg/frame] (which angle, when); for
the injected gap, the same compared with the mode's solve without the gap (what the gap adds,
also without the unsensed toe joints), and the time until the remaining gap is below 5 cm [s];
``pop deg``: the largest error of a per-frame change of a body joint angle (toes left out)
against the truth's change in the same frame [deg/frame], the pops the solve makes at contact
hand-overs whatever the mode (compare with ``off``).

Run: .venv/bin/python benchmarks/bench_correction.py [--seconds 40] [--seed 4]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from ikfusion.cli import main as cli
from ikfusion.correction import DriftCorrection
from ikfusion.evaluate import phase_slides
from ikfusion.imu.calibration import calibrate_recording
from ikfusion.io import load_sensor_map, read_imu
from ikfusion.model import Body, HumanModel
from ikfusion.paths import shipped_config
from ikfusion.pipeline import solve_recording
from ikfusion.sim.truth import site_positions
from ikfusion.uwb_aiding import UwbInputs, drift_correction, track_recording_tags

GAP_M = 1.0


def own_phase_slides_mm(model: HumanModel, q: np.ndarray, names: list[str],
                        contacts: np.ndarray) -> np.ndarray:
    """Per contact phase of the solve itself, the largest horizontal slide [mm]."""
    return 1e3 * np.array(phase_slides(site_positions(model, q, names), contacts))


def run_mode(capture: Path, mode: str, shift_from: float | None) -> dict[str, object]:
    """Solve the capture with one correction mode (fixes moved by ``GAP_M`` from a time on)."""
    sensor_map = load_sensor_map(capture / "sensors.yaml")
    recording = read_imu(capture / "imu", sensor_map=sensor_map)
    model = HumanModel.from_body(Body.from_yaml(capture / "body.yaml"))
    calibration = calibrate_recording(recording, sensor_map, None)
    files = UwbInputs(capture / "toa.csv", capture / "readers.yaml", capture / "tags.yaml")
    tags, tracks = track_recording_tags(recording, sensor_map, model, calibration, files)
    correction: DriftCorrection = drift_correction(tags, tracks, recording.time, mode)
    if shift_from is not None:
        later = recording.time >= shift_from
        for fixes in correction.fixes:
            fixes.p_world[later, 0] += GAP_M
    solved = solve_recording(recording, sensor_map, model, correction=correction,
                             calibration=calibration)
    return {"motion": solved.motion, "gap": correction.gap, "time": recording.time}


def pop_deg(motion, truth: dict) -> float:
    """Largest |per-frame change of a body joint angle - the truth's change| [deg]."""
    names = list(truth["joint_angle_names"])
    body = [c for c in motion.model.angle_columns if "BallFoot" not in c]
    solved = motion.joint_angles()[:, [motion.model.angle_columns.index(c) for c in body]]
    true = truth["joint_angles"][:, [names.index(c) for c in body]]
    n = min(len(solved), len(true))
    return float(np.abs(np.diff(solved[-n:] - true[-n:], axis=0)).max())


def head_rms_cm(motion, truth: dict) -> float:
    names = list(truth["site_names"])
    p_true = truth["p_world_site"][:, names.index("HeadTop")]
    p = site_positions(motion.model, motion.q, ["HeadTop"])[:, 0]
    n = min(len(p), len(p_true))
    return float(100 * np.sqrt(np.mean(np.sum((p[-n:] - p_true[-n:]) ** 2, axis=1))))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=40.0)
    parser.add_argument("--seed", type=int, default=4)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        capture = Path(tmp) / "capture"
        room = shipped_config("constellations", "room_6x8.yaml")
        assert cli(["simulate", "--motion", "gait", "--seconds", str(args.seconds),
                    "--readers", str(room), "--seed", str(args.seed), "--out", str(capture),
                    "--quiet"]) == 0
        truth = dict(np.load(capture / "truth.npz", allow_pickle=True))
        inject = 0.5 * args.seconds
        runs = {"off": run_mode(capture, "off", None)}
        for mode in ("slide", "no-slide"):
            runs[mode] = run_mode(capture, mode, None)
            runs[f"{mode}, 1 m gap at {inject:.0f} s"] = run_mode(capture, mode, inject)
    reference = runs["off"]["motion"]
    angles_off = reference.joint_angles()
    print(f"{args.seconds:.0f} s walk in circles, room_6x8 (10 readers), seed {args.seed}")
    print(f"{'mode':<26} {'head cm':>8} {'slide mm':>9} {'max mm':>7} {'d angles':>9} "
          f"{'jump deg':>9} {'gap jump':>9} {'closed s':>9} {'pop deg':>8}")
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
        extra = np.abs(np.diff(angles - angles_off, axis=0))
        k, j = np.unravel_index(int(np.argmax(extra)), extra.shape)
        jump = float(extra[k, j])
        where = f"{motion.model.angle_columns[j]} at {motion.time[k + 1]:.2f} s"
        closed, gap_jump = "-", "-"
        if "gap" in name:
            # what the gap itself adds: the same mode's solve without it as the reference
            same = runs[name.split(",")[0]]["motion"].joint_angles()
            n = min(len(same), len(angles))
            added = np.abs(np.diff(angles[:n] - same[:n], axis=0))
            ka, ja = np.unravel_index(int(np.argmax(added)), added.shape)
            gap_jump = f"{added[ka, ja]:.2f}"
            where += f"; gap: {motion.model.angle_columns[ja]} at {motion.time[ka + 1]:.2f} s"
            body = [i for i, c in enumerate(motion.model.angle_columns) if "BallFoot" not in c]
            kb, jb = np.unravel_index(int(np.argmax(added[:, body])), added[:, body].shape)
            where += (f"; without the unsensed toes {added[kb, body[jb]]:.2f} deg at "
                      f"{motion.model.angle_columns[body[jb]]}")
            gap, time = r["gap"], r["time"]
            after = time >= inject
            below = np.flatnonzero(after & (gap < 0.05))
            closed = f"{time[below[0]] - inject:.1f}" if len(below) else "never"
        print(f"{name:<26} {head_rms_cm(motion, truth):>8.1f} {slides.mean():>9.2f} "
              f"{slides.max():>7.2f} {d_rms:>9.2f} {jump:>9.2f} {gap_jump:>9} {closed:>9} "
              f"{pop_deg(motion, truth):>8.2f}  "
              f"({where})", flush=True)


if __name__ == "__main__":
    main()
