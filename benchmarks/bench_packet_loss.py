"""Lost packets and a sensor dropout on one simulated 30 s walk with UWB.

A walk in circles in the 6 m x 8 m room of ``configs/constellations/room_6x8.yaml`` (default
sensor errors) is simulated once; then its MT Manager files lose rows as the Awinda station
loses packets (gaps in the PacketCounter): 0, 2, 5, 10 and 20 % of the rows of every sensor at
random, and, separately, the left foot sensor silent for 2 s (rows removed). Each variant is read,
calibrated, its tags tracked, and solved IMU-only and with UWB (``no-slide`` correction); the
result folders are compared with the truth by ``ikfusion.app.evaluate``.

Columns: joint-angle RMS against the truth [deg] (UWB solve), head 3-D RMS IMU-only (start
aligned as ``evaluate`` does) [m] and with UWB [cm], foot slide per contact phase of the truth
[mm] (UWB solve), the largest joint-angle jump (``joint_angle_jump_max_deg``: error of a
frame-to-frame change against the truth's, toes left out) over both solves [deg] and where, and
the share of segment samples bridged [%] (``summary.json`` ``bridged``).

Run: .venv/bin/python benchmarks/bench_packet_loss.py [--seconds 30] [--seed 4]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ikfusion.app.evaluate import evaluate
from ikfusion.app.pipeline import solve_recording
from ikfusion.app.uwb_aiding import drift_correction, track_capture
from ikfusion.cli import main as cli
from ikfusion.io.sensor_map import load_sensor_map
from ikfusion.paths import shipped_config
from ikfusion.results import write_result_folder

LOSSES = (0.0, 0.02, 0.05, 0.10, 0.20)
DROPOUT_S = 2.0


def drop_rows(src: Path, dst: Path, keep: np.ndarray) -> None:
    """Copy one MT Manager file keeping the data rows where ``keep`` (header and comments kept)."""
    lines = src.read_text().splitlines(keepends=True)
    header = next(i for i, line in enumerate(lines) if line.startswith("PacketCounter"))
    data = lines[header + 1:]
    dst.write_text("".join(lines[: header + 1]) + "".join(
        line for line, k in zip(data, keep) if k))


def lossy_capture(capture: Path, out: Path, loss: float, rng: np.random.Generator,
                  silent: tuple[str, float, float] | None = None) -> Path:
    """A copy of ``capture`` whose IMU files lost rows.

    Args:
        capture: The folder ``simulate`` wrote.
        out: Where to write the copy.
        loss: Share of the rows of every sensor lost at random.
        rng: Random source (reproducible with a seed).
        silent: ``(segment, t0, t1)``: that segment's sensor sends nothing from t0 to t1 [s].
    """
    shutil.copytree(capture, out, ignore=shutil.ignore_patterns("imu"))
    (out / "imu").mkdir()
    mapping = dict(load_sensor_map(capture / "sensors.yaml").items())
    time = np.load(capture / "truth.npz")["time"]
    for path in sorted((capture / "imu").glob("*.txt")):
        rows = sum(1 for line in path.read_text().splitlines()
                   if line and line[0].isdigit())
        keep = rng.random(rows) >= loss
        sensor = path.stem.split("_")[-1]
        if silent is not None and mapping.get(sensor) == silent[0]:
            t = time[:rows] - time[0]
            keep &= ~((t >= silent[1]) & (t < silent[2]))
        drop_rows(path, out / "imu" / path.name, keep)
    return out


def solve_variant(folder: Path, results: Path) -> dict[str, object]:
    """Solve one capture IMU-only and with UWB; evaluate both against its truth."""
    tracked = track_capture(folder)
    out: dict[str, object] = {}
    for name, mode in (("imu", None), ("uwb", "no-slide")):
        fix = None if mode is None else drift_correction(tracked.tags, tracked.tracks,
                                                         tracked.recording.time, mode)
        solved = solve_recording(tracked.recording, tracked.sensor_map, tracked.model,
                                 correction=fix, calibration=tracked.calibration)
        extra = {"uwb": {"used": mode is not None},
                 "bridged": getattr(solved, "bridged", {})}
        write_result_folder(solved.motion, results / name, extra_summary=extra)
        out[name] = evaluate(results / name, folder / "truth.npz")
        out[f"{name}_bridged"] = extra["bridged"]
        out[f"{name}_warnings"] = solved.warnings
    return out


def bridged_share(bridged: dict) -> float:
    """Share of the segment samples bridged [%] (mean over bridged segments' lists)."""
    shares = [float(v.get("share", 0.0)) for v in bridged.values()] if bridged else []
    return 100.0 * float(np.mean(shares)) if shares else 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--seed", type=int, default=4)
    parser.add_argument("--losses", type=float, nargs="*", default=list(LOSSES),
                        help="shares of rows lost at random")
    parser.add_argument("--capture", type=Path, help="reuse a capture simulate wrote (with "
                        "--readers) instead of simulating one")
    parser.add_argument("--no-dropout", action="store_true", help="skip the 2 s foot dropout")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        capture = args.capture or tmp / "capture"
        if args.capture is None:
            room = shipped_config("constellations", "room_6x8.yaml")
            assert cli(["simulate", "--motion", "gait", "--seconds", str(args.seconds),
                        "--readers", str(room), "--seed", str(args.seed),
                        "--out", str(capture), "--quiet"]) == 0
        scenarios: list[tuple[str, float, tuple[str, float, float] | None]] = [
            (f"{100 * loss:.0f} % lost", loss, None) for loss in args.losses]
        if not args.no_dropout:
            t0 = 0.5 * args.seconds
            scenarios.append((f"LeftFoot off {t0:.0f}-{t0 + DROPOUT_S:.0f} s", 0.0,
                              ("LeftFoot", t0, t0 + DROPOUT_S)))
        print(f"\n{args.seconds:.0f} s walk in circles, room_6x8, seed {args.seed}, default "
              "sensor errors")
        print(f"{'scenario':<22} {'joint deg':>9} {'head IMU m':>10} {'head UWB cm':>11} "
              f"{'slide mm':>9} {'jump deg':>9} {'bridged %':>9}  where")
        for k, (name, loss, silent) in enumerate(scenarios):
            rng = np.random.default_rng([args.seed, round(1000 * loss), int(silent is not None)])
            folder = lossy_capture(capture, tmp / f"v{k}", loss, rng, silent)
            r = solve_variant(folder, tmp / f"r{k}")
            imu, uwb = r["imu"], r["uwb"]
            jump = max((imu, uwb), key=lambda e: e.joint_angle_jump_max_deg)
            print(f"{name:<22} {uwb.joint_angle_rms_deg:>9.2f} {imu.head_position_rms_m:>10.2f} "
                  f"{100 * uwb.head_position_rms_m:>11.1f} {uwb.foot_slide_mm:>9.1f} "
                  f"{jump.joint_angle_jump_max_deg:>9.1f} "
                  f"{bridged_share(r['uwb_bridged']):>9.2f}  {jump.joint_angle_jump_at}",
                  flush=True)


if __name__ == "__main__":
    main()
