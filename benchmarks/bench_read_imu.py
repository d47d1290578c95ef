"""Reading speed of IMU recordings: real trials and synthetic 17-sensor trials.

Run: ``.venv/bin/python benchmarks/bench_read_imu.py`` (best of 3 runs per case). The real trials
come from ../shared/data/xsens (skipped when absent); the synthetic ones are written to a
temporary folder with :func:`ikfusion.io.write_mtmanager` (new layout: quaternion, acc, gyr,
mag) and by tiling the old 32-column OpenSense export (rotation matrix, 14 empty time columns).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from ikfusion.imu import calibrate_recording
from ikfusion.io import load_sensor_map, read_mtmanager, write_mtmanager
from ikfusion.paths import configs_dir
from ikfusion.rotations import exp_so3, random_rotations

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "xsens"


def best_of(fn, runs: int = 3) -> float:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def synthetic_new(folder: Path, sensors: int, rows: int, rng: np.random.Generator) -> Path:
    for k in range(sensors):
        R = random_rotations(1, rng)[0] @ exp_so3(np.outer(np.arange(rows) * 0.01,
                                                           rng.normal(size=3)))
        write_mtmanager(folder, "N_", f"00B4{k:04X}", 60000 + np.arange(rows), R, 100.0,
                        acc=rng.normal(size=(rows, 3)), gyr=rng.normal(size=(rows, 3)),
                        mag=rng.normal(size=(rows, 3)))
    return folder / "N_"


def synthetic_old(folder: Path, sensors: int, rows: int) -> Path:
    source = SHARED / "opensense_walk" / "MT_012005D6_009-001_00B421E6.txt"
    lines = source.read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("//") or ln.startswith("PacketCounter")]
    data = [ln.split("\t", 1)[1] for ln in lines[len(head):] if ln.strip()]
    body = [f"{(k + 400) % 65536:05d}\t{data[k % len(data)]}" for k in range(rows)]
    text = "\n".join(head + body) + "\n"
    for k in range(sensors):
        (folder / f"O_{0x00B40000 + k:08X}.txt").write_text(text)
    return folder / "O_"


def main() -> None:
    rng = np.random.default_rng(0)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        cases: list[tuple[str, Path]] = []
        for rows, label in ((6000, "60 s"), (15000, "150 s")):
            folder = Path(tmp) / f"new{rows}"
            folder.mkdir()
            cases.append((f"synthetic 17 x {label} (quat acc gyr mag)",
                          synthetic_new(folder, 17, rows, rng)))
        if SHARED.is_dir():
            folder = Path(tmp) / "old"
            folder.mkdir()
            cases.append(("synthetic 17 x 60 s (old 32-column export)",
                          synthetic_old(folder, 17, 6000)))
            cases += [("opensense_walk (8 sensors)", SHARED / "opensense_walk"),
                      ("movingreality_trial007 (5 sensors)",
                       SHARED / "movingreality_trial007" / "MT_012000E0_007-000_"),
                      ("static11 (11 sensors)", SHARED / "static11")]
        for name, path in cases:
            rec = read_mtmanager(path, rate=100.0)
            fields = sum(s.rows * len(s.channels) for s in rec.sensors.values())
            seconds = best_of(lambda p=path: read_mtmanager(p, rate=100.0))
            results.append((name, len(rec.sensors), max(s.rows for s in rec.sensors.values()),
                            seconds, fields / seconds / 1e6))
        if SHARED.is_dir():
            rec = read_mtmanager(SHARED / "opensense_walk")
            smap = load_sensor_map(configs_dir() / "sensors" / "lower8.yaml")
            seconds = best_of(lambda: calibrate_recording(rec, smap))
            calibration = f"calibrate_recording on opensense_walk (8 sensors): {seconds:.3f} s"
        else:
            calibration = "calibration: ../shared/data absent, skipped"
    print(f"{'case':<45} {'sensors':>7} {'rows':>6} {'read [s]':>9} {'Mfield/s':>9}")
    for name, sensors, rows, seconds, rate in results:
        print(f"{name:<45} {sensors:>7} {rows:>6} {seconds:>9.3f} {rate:>9.1f}")
    print(calibration)


if __name__ == "__main__":
    main()
