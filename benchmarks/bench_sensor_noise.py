"""Real sensors' orientation noise against the simulator's default errors (issue #19).

Every recording with orientations in ``../shared/data`` (MT Manager exports of Xsens MTx/MTw/MTw2
sensors at 100 Hz, the sensor orientations of the MVN MVNX at 60 Hz; see its README.md for the
origins and licences) is measured sensor by sensor, and the same motion is measured again with
the simulator's orientation error laid over it: the error ``E_k = R_reported R_true^T`` that
:func:`ikfusion.sim.imu.simulate_imus` gives a still sensor at the file's rate (``--noise``
default or none), applied as ``E_k R_real_k``.

Columns: samples and rate; ``still %``: share of samples turning slower than ``--still`` deg/s
over 0.1 s (the motion itself, measured on the real file); per-sample turn RMS [deg] in those
still samples and in the slow ones (below ``--slow`` deg/s), real then simulated; ``gyro``:
RMS of the per-sample turn beyond the sensor's own gyroscope (``beyond_gyro_deg``, its mean, the
filter's bias estimate, removed) [deg], real then simulated (files with a gyroscope); ``ac 0.1s``:
autocorrelation of that residual 0.1 s apart (near 1: a slow error; near 0: white), real then
simulated. A last line gives the medians over the files.

Run: PYTHONPATH=. .venv/bin/python benchmarks/bench_sensor_noise.py [--noise default|none]
[--still 2] [--slow 30] [--seed 1].
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ikfusion.io import read_mtmanager
from ikfusion.io.mvnx import read_mvnx
from ikfusion.model import HumanModel
from ikfusion.rotations import quat_wxyz_to_matrix
from ikfusion.sim.imu import ImuNoise, simulate_imus
from ikfusion.sim.noise_stats import beyond_gyro_deg, rms, turn_speed_deg_s, turn_steps_deg

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@dataclass
class RealSensor:
    """One sensor's reported orientations.

    Attributes:
        name: Folder and sensor.
        rate: [Hz].
        R_world_sensor: (N, 3, 3), NaN where missing.
        gyr: (N, 3) [rad/s] in the sensor frame, or None.
    """

    name: str
    rate: float
    R_world_sensor: np.ndarray
    gyr: np.ndarray | None


def real_sensors(root: Path) -> Iterator[RealSensor]:
    """Every sensor with orientations under ``root`` (MT Manager exports, then MVNX files)."""
    for path in sorted((root / "xsens").rglob("*.txt")):
        sensor = path.stem[-8:]
        if len(path.stem) <= 8 or any(c not in "0123456789ABCDEF" for c in sensor):
            continue
        (stream,) = read_mtmanager(path, rate=100.0).sensors.values()
        R = stream.R_world_sensor
        if len(R) < 50 or not np.isfinite(R).any():
            continue  # a five-row format sample, or no orientation columns
        gyr = stream.gyr if stream.gyr is not None and np.isfinite(stream.gyr).any() else None
        yield RealSensor(f"{path.parent.name}/{sensor}", 100.0, R, gyr)
    for path in sorted((root / "mvnx").glob("*.mvnx")):
        take = read_mvnx(path)
        for k, label in enumerate(take.sensors):
            R = quat_wxyz_to_matrix(take.quat_wxyz_world_sensor[:, k])
            yield RealSensor(f"mvnx/{label}", take.frame_rate, R, None)


def simulated_error(n: int, rate: float, noise: ImuNoise, seed: int) -> np.ndarray:
    """The simulator's orientation error of a still sensor, ``R_reported R_true^T`` (n, 3, 3)."""
    model = HumanModel.default()
    q = np.tile(model.configuration(), (n, 1))
    imus = simulate_imus(model, np.arange(n) / rate, q, ["Pelvis"], np.random.default_rng(seed),
                         noise, random_mounting=False)
    R_true = model.segment_rotation(q[0], "Pelvis")
    return imus.R_world_sensor[0] @ R_true.T


@dataclass
class Row:
    """Measured figures of one sensor, real and simulated (see the module's columns)."""

    name: str
    rate: float
    n: int
    still_share: float
    still: tuple[float, float]
    slow: tuple[float, float]
    gyro: tuple[float, float]
    ac: tuple[float, float]


def _autocorrelation(x: np.ndarray, lag: int) -> float:
    x = x[np.isfinite(x).all(axis=1)]
    x = x - x.mean(axis=0)
    if len(x) <= lag or not np.any(x):
        return float("nan")
    return float(np.sum(x[:-lag] * x[lag:]) / np.sum(x * x))


def measure(sensor: RealSensor, E: np.ndarray, still: float, slow: float) -> Row:
    """Figures of a real sensor and of the same motion with the simulated error ``E``."""
    R_real = sensor.R_world_sensor
    R_sim = E @ R_real
    speed = turn_speed_deg_s(R_real, sensor.rate)[1:]
    is_still, is_slow = speed < still, speed < slow
    steps = [turn_steps_deg(R) for R in (R_real, R_sim)]
    row = Row(sensor.name, sensor.rate, len(R_real), 100.0 * float(np.mean(is_still)),
              (rms(steps[0][is_still]), rms(steps[1][is_still])),
              (rms(steps[0][is_slow]), rms(steps[1][is_slow])),
              (float("nan"), float("nan")), (float("nan"), float("nan")))
    if sensor.gyr is not None:
        lag = max(1, round(0.1 * sensor.rate))
        res = [beyond_gyro_deg(R, sensor.gyr, sensor.rate) for R in (R_real, R_sim)]
        res = [r - np.nanmean(r, axis=0) for r in res]
        row.gyro = (rms(res[0], axis=1), rms(res[1], axis=1))
        row.ac = (_autocorrelation(res[0], lag), _autocorrelation(res[1], lag))
    return row


def _pair(values: tuple[float, float], digits: int) -> str:
    return " ".join("-".rjust(7) if np.isnan(v) else f"{v:7.{digits}f}" for v in values)


def print_table(rows: list[Row], noise_name: str) -> None:
    """The table of the module's docstring, real then simulated in every pair of columns."""
    print(f"simulated: ImuNoise {noise_name}: {ImuNoise() if noise_name == 'default' else 'none'}")
    print(f"{'sensor':34s} {'Hz':>4s} {'n':>6s} {'still%':>6s} | {'still real':>10s} {'sim':>7s}"
          f" | {'slow real':>9s} {'sim':>7s} | {'gyro real':>9s} {'sim':>7s}"
          f" | {'ac0.1s re':>9s} {'sim':>7s}")
    for r in rows:
        print(f"{r.name[-34:]:34s} {r.rate:4.0f} {r.n:6d} {r.still_share:6.1f} | "
              f"   {_pair(r.still, 4)} |   {_pair(r.slow, 4)} |   {_pair(r.gyro, 4)} |   "
              f"{_pair(r.ac, 2)}")
    medians = [tuple(float(np.nanmedian([getattr(r, f)[i] for r in rows])) for i in (0, 1))
               for f in ("still", "slow", "gyro", "ac")]
    cells = " |".join(f"   {_pair(m, 2 if f == 'ac' else 4)}" for f, m in zip(
        ("still", "slow", "gyro", "ac"), medians))
    print(f"{'median over sensors':34s} {'':4s} {'':6s} {'':6s} |{cells}")

def main() -> None:
    """Measure every real sensor and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--noise", choices=["default", "none"], default="default")
    parser.add_argument("--still", type=float, default=2.0, help="still below [deg/s]")
    parser.add_argument("--slow", type=float, default=30.0, help="slow below [deg/s]")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    if not SHARED_DATA.is_dir():
        raise SystemExit(f"real recordings not available: {SHARED_DATA} is absent")
    noise = ImuNoise() if args.noise == "default" else ImuNoise.none()
    rows = []
    for k, sensor in enumerate(real_sensors(SHARED_DATA)):
        E = simulated_error(len(sensor.R_world_sensor), sensor.rate, noise, args.seed + k)
        rows.append(measure(sensor, E, args.still, args.slow))
    print_table(rows, args.noise)


if __name__ == "__main__":
    main()
