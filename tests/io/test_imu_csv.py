"""The generic IMU CSV (``time,sensor,qw,qx,qy,qz[,ax,ay,az,gx,gy,gz]``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ikfusion.io import read_imu, read_imu_csv
from ikfusion.rotations import angle_between, matrix_to_quat_wxyz, random_rotations


def write_csv(path: Path, R: np.ndarray, drop: set[tuple[int, int]], rate: float = 100.0,
              jitter: float = 0.0, rng: np.random.Generator | None = None) -> None:
    lines = ["time,sensor,qw,qx,qy,qz,ax,ay,az,gx,gy,gz"]
    for k in range(R.shape[1]):
        for s in range(R.shape[0]):
            if (s, k) in drop:
                continue
            t = k / rate + (rng.uniform(-jitter, jitter) if rng is not None else 0.0)
            q = matrix_to_quat_wxyz(R[s, k])
            lines.append(f"{t:.5f},S{s}," + ",".join(f"{v:.9f}" for v in q)
                         + f",{s},{k},9.81,0.1,0.2,{k * 0.01:.2f}")
    path.write_text("\n".join(lines) + "\n")


def test_generic_csv_rows_rate_and_lost_samples(tmp_path: Path, rng) -> None:
    R = random_rotations(2 * 30, rng).reshape(2, 30, 3, 3)
    path = tmp_path / "imu.csv"
    write_csv(path, R, drop={(1, 4), (1, 5), (0, 29)}, jitter=0.001, rng=rng)
    rec = read_imu(path)
    assert rec.rate == 100.0 and len(rec) == 30 and rec.sensor_ids == ["S0", "S1"]
    s0, s1 = rec.sensors["S0"], rec.sensors["S1"]
    assert (s0.rows, s0.lost, s1.rows, s1.lost) == (29, 0, 28, 2)
    assert not s1.valid[4] and not s1.valid[5] and s1.valid[6]
    assert s0.span == (0, 29) and np.isnan(s0.R_world_sensor[29]).all()
    assert np.degrees(angle_between(s0.R_world_sensor[:29], R[0, :29])).max() < 1e-6
    np.testing.assert_array_equal(s1.acc[7], [1, 7, 9.81])
    np.testing.assert_allclose(s1.gyr[7], [0.1, 0.2, 0.07])
    assert any("S1: 2 lost packets" in w for w in rec.warnings)


def test_generic_csv_nan_fields_and_given_rate(tmp_path: Path) -> None:
    path = tmp_path / "imu.csv"
    path.write_text("time,sensor,qw,qx,qy,qz,ax\n0.0,a,1,0,0,0,1.5\n0.025,a,NaN,0,0,0,2.5\n"
                    "0.05,a,1,0,0,0,\n")
    rec = read_imu_csv(path, rate=40.0)
    s = rec.sensors["a"]
    assert rec.rate == 40.0 and s.valid.tolist() == [True, False, False]
    np.testing.assert_array_equal(s.acc[:, 0], [1.5, 2.5, np.nan])
    assert np.isnan(s.acc[:, 1:]).all()  # ay, az absent
    assert s.gyr is None


def test_generic_csv_repeated_instants_and_jitter(tmp_path: Path) -> None:
    path = tmp_path / "imu.csv"
    times = [k / 100 for k in range(40)]
    times[2] = 0.0235  # 0.35 sample late
    rows = [f"{t},a,1,0,0,0" for t in times]
    rows.insert(2, "0.01,a,0,1,0,0")  # a second row at 0.01 s
    path.write_text("time,sensor,qw,qx,qy,qz\n" + "\n".join(rows) + "\n")
    rec = read_imu_csv(path)
    assert any("already had" in w for w in rec.warnings)
    assert any("off the 100 Hz grid" in w for w in rec.warnings)
    np.testing.assert_array_equal(rec.sensors["a"].R_world_sensor[1], np.eye(3))
