"""Where the rate comes from (SPEC 4): `// Update Rate:`, else SampleTimeFine or UTC, else --rate.

``inspect`` shows what it can without a rate.
"""

from __future__ import annotations

import json
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pytest

from ikfusion.cli import main
from ikfusion.errors import InputError
from ikfusion.io import read_imu, read_imu_csv, read_mtmanager, write_mtmanager
from ikfusion.rotations import random_rotations

UTC_NAMES = ["UTC_Nano", "UTC_Year", "UTC_Month", "UTC_Day", "UTC_Hour", "UTC_Minute",
             "UTC_Second", "UTC_Valid"]


def utc_file(path: Path, rate: float, counter: np.ndarray, start: datetime) -> None:
    """An export whose only time is the UTC columns (no rate line, SampleTimeFine empty)."""
    lines = ["PacketCounter\tSampleTimeFine\t" + "\t".join(UTC_NAMES) + "\tAcc_X\tAcc_Y\tAcc_Z"]
    for c in counter:
        t = start + timedelta(seconds=float(c - counter[0]) / rate)
        utc = [t.microsecond * 1000, t.year, t.month, t.day, t.hour, t.minute, t.second, 7]
        lines.append(f"{c % 65536:05d}\t\t" + "\t".join(str(v) for v in utc) + "\t0\t0\t9.8")
    path.write_text("// General information:\n// Coordinate system: ENU\n"
                    + "\n".join(lines) + "\n")


def test_rate_from_utc_columns_across_a_new_year(tmp_path: Path, rng) -> None:
    counter = np.arange(400)[rng.random(400) > 0.1]  # lost packets do not bias the rate
    utc_file(tmp_path / "U_00B40001.txt", 40.0, counter, datetime(2023, 12, 31, 23, 59, 55))
    rec = read_mtmanager(tmp_path / "U_")
    assert rec.rate == pytest.approx(40.0, abs=1e-3) and rec.rate_source == "UTC"
    assert rec.sensors["00B40001"].lost == int(counter[-1] - counter[0] + 1 - len(counter))


def test_sources_and_their_order(tmp_path: Path, rng) -> None:
    R = random_rotations(100, rng)
    write_mtmanager(tmp_path, "F_", "00B40002", np.arange(100), R, None,
                    sample_time_fine=np.arange(100) * 10000.0 / 60.0)
    rec = read_mtmanager(tmp_path / "F_", rate=40.0)  # the file's own time wins over --rate
    assert rec.rate == pytest.approx(60.0, abs=1e-3) and rec.rate_source == "SampleTimeFine"
    assert any("(40 Hz) is not used" in w for w in rec.warnings)
    write_mtmanager(tmp_path, "H_", "00B40003", np.arange(100), R, 100.0)
    assert read_mtmanager(tmp_path / "H_").rate_source == "Update Rate"
    write_mtmanager(tmp_path, "G_", "00B40004", np.arange(100), R, None, sample_time_fine=False)
    rec = read_mtmanager(tmp_path / "G_", rate=50.0)
    assert rec.rate == 50.0 and rec.rate_source == "--rate"
    with pytest.raises(InputError) as err:
        read_mtmanager(tmp_path / "G_")
    assert "--rate" in str(err.value) and "read_mtmanager(" not in str(err.value)
    assert err.value.path == tmp_path / "G_00B40004.txt"


def test_imu_csv_rate_source(tmp_path: Path) -> None:
    path = tmp_path / "imu.csv"
    path.write_text("time,sensor,qw,qx,qy,qz\n" + "\n".join(
        f"{k / 50:.3f},s,1,0,0,0" for k in range(20)) + "\n")
    assert read_imu_csv(path).rate_source == "time"
    assert read_imu_csv(path, rate=50.0).rate_source == "--rate"


def test_inspect_mt2022_export_without_rate(shared_data: Path, capsys) -> None:
    path = shared_data / "xsens/formats/MT2022_ACC_GYRO_ROT_EULER_TAB_00B42D4F.txt"
    assert main(["inspect", str(path), "--json"]) == 0
    sensor = json.loads(capsys.readouterr().out)["sensors"]["00B42D4F"]
    assert sensor["rate"] is None and sensor["rate_source"] == "unknown"
    assert sensor["rows"] == 5 and sensor["lost"] == 0
    assert sensor["first_quat_wxyz"] is not None and "Roll" in sensor["channels"]
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "rate unknown (give --rate HZ)" in out and "00B42D4F" in out
    assert main(["inspect", str(path), "--rate", "60", "--json"]) == 0
    sensor = json.loads(capsys.readouterr().out)["sensors"]["00B42D4F"]
    assert sensor["rate"] == 60.0 and sensor["rate_source"] == "--rate"


@pytest.mark.parametrize(("where", "rate", "source"), [
    ("formats/MT2022_ACC_00B42D4B.txt", None, "unknown"),
    ("formats/MT2022_ACC_GYRO_ROT_MAT_COMMA_00B42D4B.txt", None, "unknown"),
    ("formats/MT46_01-000_", 100.0, "Update Rate"),
    ("formats/MT_012005D6_031-000_", 100.0, "Update Rate"),
    ("opensense_walk", 100.0, "Update Rate"),
    ("movingreality_trial007/MT_012000E0_007-000_", None, "unknown"),
    ("static11", 100.0, "Update Rate"),
])
def test_rate_and_source_of_the_real_files(shared_data: Path, where: str, rate: float | None,
                                           source: str) -> None:
    rec = read_imu(shared_data / "xsens" / where, require_rate=False)
    assert rec.rate_source == source
    assert (rec.rate == rate) if rate is not None else not rec.rate_known
    assert all(s.rows > 0 for s in rec.sensors.values())
