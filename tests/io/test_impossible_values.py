"""Infinite and physically impossible values make their sample invalid, with a counted warning."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikfusion.errors import InputError
from ikfusion.io import read_imu_csv, read_mtmanager
from ikfusion.rotations import matrix_to_quat_wxyz, random_rotations


def quat_file(path: Path, n: int, rng: np.random.Generator,
              damage: dict[tuple[int, str], str]) -> np.ndarray:
    """A quaternion + Acc + Gyr export; ``damage[(row, column)]`` replaces a field's text."""
    names = ["PacketCounter", "Acc_X", "Acc_Y", "Acc_Z", "Gyr_X", "Gyr_Y", "Gyr_Z",
             "Quat_q0", "Quat_q1", "Quat_q2", "Quat_q3"]
    q = matrix_to_quat_wxyz(random_rotations(n, rng))
    lines = []
    for k in range(n):
        fields = [f"{k:05d}", "0.1", "0.2", "9.8", "0.01", "0.02", "0.03",
                  *(f"{v:.6f}" for v in q[k])]
        for (row, column), text in damage.items():
            if row == k:
                fields[names.index(column)] = text
        lines.append("\t".join(fields))
    path.write_text("// Update Rate: 100.0Hz\n" + "\t".join(names) + "\n" + "\n".join(lines) + "\n")
    return q


def test_inf_and_1e308_in_data_fields_make_the_sample_invalid(tmp_path: Path, rng) -> None:
    n = 60
    damage = {(10, "Acc_X"): "inf", (20, "Gyr_Z"): "1e308", (30, "Acc_Z"): "-Infinity",
              (40, "Quat_q2"): "5.0", (45, "Quat_q0"): "inf"}
    quat_file(tmp_path / "I_00B40001.txt", n, rng, damage)
    rec = read_mtmanager(tmp_path / "I_")
    s = rec.sensors["00B40001"]
    bad = np.zeros(n, dtype=bool)
    bad[[10, 20, 30, 40, 45]] = True
    np.testing.assert_array_equal(s.valid, ~bad)  # good data around every bad sample kept
    assert s.received.all() and s.lost == 0
    assert np.isfinite(s.acc[~bad]).all() and np.isfinite(s.gyr[~bad]).all()
    assert np.isnan(s.acc[[10, 30]]).all() and np.isnan(s.gyr[20]).all()
    assert np.isnan(s.R_world_sensor[[40, 45]]).all()
    message = next(w for w in rec.warnings if "impossible" in w)
    assert "00B40001" in message and "Acc 2" in message and "Gyr 1" in message \
        and "Quat 2" in message


def test_impossible_matrix_and_euler_rows(tmp_path: Path, rng) -> None:
    R = random_rotations(30, rng)
    rows = []
    for k in range(30):
        mat = R[k].copy()
        euler = [10.0, 20.0, 30.0]
        if k == 7:
            mat = mat * 3.0  # not a rotation
        if k == 12:
            euler = [10.0, 20.0, 720.5]  # beyond +-360 deg
        rows.append("\t".join([f"{k:05d}", *(f"{v:.6f}" for v in mat.ravel()),
                               *(f"{v:.3f}" for v in euler)]))
    mat_names = [f"Mat[{i}][{j}]" for i in (1, 2, 3) for j in (1, 2, 3)]
    (tmp_path / "E_00B40002.txt").write_text(
        "// Update Rate: 100.0Hz\n" + "\t".join(["PacketCounter", *mat_names, "Roll", "Pitch",
                                                 "Yaw"]) + "\n" + "\n".join(rows) + "\n")
    rec = read_mtmanager(tmp_path / "E_")
    s = rec.sensors["00B40002"]
    # row 7 falls back to its (valid) Euler angles; row 12 uses its valid matrix
    assert s.valid.all()
    message = next(w for w in rec.warnings if "impossible" in w)
    assert "Mat 1" in message and "Euler 1" in message


def test_imu_csv_impossible_values_and_a_wild_time(tmp_path: Path) -> None:
    lines = ["time,sensor,qw,qx,qy,qz,ax,ay,az"]
    for k in range(20):
        ax = "inf" if k == 5 else ("1e308" if k == 9 else "0.1")
        lines.append(f"{k * 0.01:.2f},pelvis,1,0,0,0,{ax},0,9.8")
    path = tmp_path / "imu.csv"
    path.write_text("\n".join(lines) + "\n")
    rec = read_imu_csv(path)
    s = rec.sensors["pelvis"]
    expected = np.ones(20, dtype=bool)
    expected[[5, 9]] = False
    np.testing.assert_array_equal(s.valid, expected)
    assert any("impossible" in w and "pelvis" in w and "Acc 2" in w for w in rec.warnings)
    lines[8] = "1e12,pelvis,1,0,0,0,0.1,0,9.8"  # a time stamp from nowhere (line 9)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="time jumps") as err:
        read_imu_csv(path)
    assert err.value.line == 9 and err.value.field == "time"
