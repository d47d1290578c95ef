"""``ikfusion inspect``: the SPEC JSON layout, the readable table, the installed command."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mt_raw import orientation, raw_table, row_dict

from ikfusion.cli import main
from ikfusion.io import write_mtmanager
from ikfusion.rotations import angle_between, quat_wxyz_to_matrix, random_rotations

KEYS = {"rows", "lost", "rate", "rate_source", "channels", "coordinate_system",
        "first_quat_wxyz", "last_quat_wxyz"}
PREFIX = "MT_012005D6_009-001_"


def check_opensense(info: dict, folder: Path) -> None:
    assert set(info) == {"sensors"}
    sensors = info["sensors"]
    assert len(sensors) == 8
    for sid, sensor in sensors.items():
        assert set(sensor) == KEYS
        names, rows, _ = raw_table(folder / f"{PREFIX}{sid}.txt")
        assert sensor["rows"] == len(rows) and sensor["lost"] == 0
        assert sensor["rate"] == 100.0 and sensor["coordinate_system"] == "ENU"
        assert sensor["rate_source"] == "Update Rate"
        assert sensor["channels"] == names
        for key, row in (("first_quat_wxyz", rows[0]), ("last_quat_wxyz", rows[-1])):
            q = np.array(sensor[key])
            assert len(q) == 4 and q[0] >= 0 and abs(np.linalg.norm(q) - 1) < 1e-6
            R_file = orientation(row_dict(names, row))
            assert np.degrees(angle_between(quat_wxyz_to_matrix(q), R_file)) < 1e-3


def test_inspect_json_through_main(shared_data: Path, capsys) -> None:
    folder = shared_data / "xsens/opensense_walk"
    assert main(["inspect", str(folder / PREFIX), "--json"]) == 0
    check_opensense(json.loads(capsys.readouterr().out), folder)


def test_inspect_json_through_the_installed_command(shared_data: Path) -> None:
    folder = shared_data / "xsens/opensense_walk"
    command = Path(sys.executable).parent / "ikfusion"
    done = subprocess.run([str(command), "inspect", str(folder), "--json"],
                          capture_output=True, text=True, check=False, timeout=120)
    assert done.returncode == 0, done.stderr
    check_opensense(json.loads(done.stdout), folder)
    assert "stops" in done.stderr  # warnings on stderr, stdout stays JSON


def test_inspect_table_with_a_map_and_lost_packets(tmp_path: Path, rng, capsys) -> None:
    n = 200
    keep = np.ones(n, dtype=bool)
    keep[[50, 51, 120]] = False
    R = random_rotations(n, rng)
    write_mtmanager(tmp_path, "T_", "00B40001", np.arange(n)[keep], R[keep], None,
                    acc=rng.normal(size=(keep.sum(), 3)), sample_time_fine=False)
    write_mtmanager(tmp_path, "T_", "00B40002", np.arange(n), R, None, sample_time_fine=False)
    smap = tmp_path / "map.yaml"
    smap.write_text("sensors:\n  00B40001: Pelvis\n  00B40002: Head\n")
    assert main(["inspect", str(tmp_path), "--rate", "40", "--map", str(smap)]) == 0
    out = capsys.readouterr().out
    assert "40 Hz, 200 samples (4.97 s)" in out
    line = next(ln for ln in out.splitlines() if ln.startswith("00B40001"))
    assert line.split()[:4] == ["00B40001", "Pelvis", "197", "3"]
    assert "acc quat" in line
    assert "3 lost packets in 2 gaps" in out
    assert main(["inspect", str(tmp_path), "--json"]) == 0  # no rate: shown without one
    captured = capsys.readouterr()
    sensor = json.loads(captured.out)["sensors"]["00B40001"]
    assert sensor["rate"] is None and sensor["rows"] == 197 and sensor["lost"] == 3
    assert "--rate HZ" in captured.err


@pytest.mark.parametrize("kind", ["csv", "mvnx"])
def test_inspect_other_formats(shared_data: Path, tmp_path: Path, capsys, kind: str) -> None:
    if kind == "mvnx":
        path = shared_data / "mvnx/test_mocap.mvnx"
    else:
        path = tmp_path / "imu.csv"
        path.write_text("time,sensor,qw,qx,qy,qz\n0.0,a,1,0,0,0\n0.01,a,1,0,0,0\n"
                        "0.0,b,0,1,0,0\n0.01,b,0,1,0,0\n")
    assert main(["inspect", str(path), "--json"]) == 0
    sensors = json.loads(capsys.readouterr().out)["sensors"]
    assert all(set(v) == KEYS for v in sensors.values())
    if kind == "csv":
        assert sensors["b"]["first_quat_wxyz"] == [0.0, 1.0, 0.0, 0.0]
        assert sensors["a"]["rate"] == 100.0 and sensors["a"]["rate_source"] == "time"
    else:
        assert len(sensors) == 11 and sensors["Pelvis"]["rate"] == 60.0
        assert sensors["Pelvis"]["rate_source"] == "frameRate"
