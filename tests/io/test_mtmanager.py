"""MT Manager exports: the real files' numbers, every variant, lost packets, bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ikfusion.cli import main
from ikfusion.errors import InputError
from ikfusion.io import read_mtmanager, write_mtmanager
from ikfusion.rotations import quat_wxyz_to_matrix, random_rotations, xsens_euler_to_matrix


def data_lines(path: Path) -> tuple[list[str], list[list[str]]]:
    """Header and data rows split by hand (independent of the reader)."""
    lines = [ln.rstrip("\n") for ln in path.read_text().splitlines()]
    start = next(i for i, ln in enumerate(lines) if ln.startswith("PacketCounter"))
    delim = "\t" if "\t" in lines[start] else ","
    return lines[start].split(delim), [ln.split(delim) for ln in lines[start + 1:] if ln.strip()]


def orientation_of(header: list[str], row: list[str]) -> np.ndarray:
    value = {h: float(v) if v.strip() else np.nan for h, v in zip(header, row)}
    if "Quat_q0" in value:
        return quat_wxyz_to_matrix([value[f"Quat_q{i}"] for i in range(4)])
    if "Mat[1][1]" in value:
        return np.array([[value[f"Mat[{i}][{j}]"] for j in (1, 2, 3)] for i in (1, 2, 3)])
    return xsens_euler_to_matrix(value["Roll"], value["Pitch"], value["Yaw"])


def all_exports(root: Path) -> list[Path]:
    return sorted(p for p in (root / "xsens").rglob("*.txt") if p.name[-12:-4].isalnum()
                  and "README" not in p.name and "corresponding" not in p.name)


def test_every_real_export_reads_with_its_numbers(shared_data: Path) -> None:
    files = all_exports(shared_data)
    assert len(files) >= 20
    for path in files:
        recording = read_mtmanager(path, rate=100.0)
        (stream,) = recording.sensors.values()
        header, rows = data_lines(path)
        assert stream.rows == len(rows), path
        for k in (0, len(rows) - 1):
            value = {h: float(v) if v.strip() else np.nan for h, v in zip(header, rows[k])}
            idx = k + (len(recording.time) - len(rows) if k else 0)
            for name, arr in (("Acc_X", stream.acc), ("Gyr_Z", stream.gyr)):
                if name in value:
                    assert arr is not None
                    np.testing.assert_allclose(arr[idx, "XYZ".index(name[-1])], value[name],
                                               equal_nan=True)
            if any(h in header for h in ("Quat_q0", "Mat[1][1]", "Roll")):
                np.testing.assert_allclose(stream.R_world_sensor[idx],
                                           orientation_of(header, rows[k]), atol=1e-6)


def test_readme_values_of_the_old_export(shared_data: Path) -> None:
    rec = read_mtmanager(shared_data / "xsens/formats/MT_012005D6_031-000_00B421AF.txt")
    s = rec.sensors["00B421AF"]
    np.testing.assert_allclose(s.acc[0], [3.030769, 5.254238, -7.714005])
    np.testing.assert_allclose(s.gyr[0], [0.005991, -0.032133, 0.022713])
    np.testing.assert_allclose(s.mag[0], [-0.045410, -0.266113, 0.897217])
    np.testing.assert_allclose(s.acc[-1], [2.657654, 5.012634, -7.581414])
    assert rec.rate == 100.0


def test_nan_fields_keep_the_rest_of_the_row(shared_data: Path) -> None:
    rec = read_mtmanager(shared_data / "xsens/formats/MT2022_ACC_00B42D4B.txt", rate=100.0)
    s = rec.sensors["00B42D4B"]
    np.testing.assert_allclose(s.acc[0], [0.074225, -0.040975, 9.922524])
    assert not s.valid.any()  # no orientation columns at all


def test_opensense_trial_inspect_json(shared_data: Path, capsys) -> None:
    trial = shared_data / "xsens/opensense_walk/MT_012005D6_009-001_"
    assert main(["inspect", str(trial), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)["sensors"]
    assert len(info) == 8
    for sid, sensor in info.items():
        assert sensor["rate"] == 100.0
        header, rows = data_lines(trial.parent / f"MT_012005D6_009-001_{sid}.txt")
        assert sensor["rows"] == len(rows)
        assert sensor["coordinate_system"] == "ENU"
        assert len(sensor["first_quat_wxyz"]) == 4
    out = subprocess.run([sys.executable, "-m", "ikfusion", "inspect", str(trial), "--json"],
                         capture_output=True, text=True, check=True)
    assert len(json.loads(out.stdout)["sensors"]) == 8


@pytest.mark.parametrize("delimiter", ["\t", ",", ";", " "])
@pytest.mark.parametrize("orientation", ["quat", "mat", "euler"])
def test_lost_packets_and_wrap(tmp_path: Path, rng, delimiter: str, orientation: str) -> None:
    n = 600
    counter = 65536 - 250 + np.arange(n)  # wraps once
    keep = rng.random(n) > 0.05
    keep[0] = keep[-1] = True
    R = random_rotations(1, rng)[0] @ np.stack([np.eye(3)] * n)
    write_mtmanager(tmp_path, "T_", "00B40001", counter[keep], R[keep], 60.0,
                    acc=rng.normal(size=(keep.sum(), 3)), delimiter=delimiter,
                    orientation=orientation)
    rec = read_mtmanager(tmp_path / "T_")
    s = rec.sensors["00B40001"]
    assert s.lost == int((~keep).sum())
    assert len(rec.time) == n
    np.testing.assert_allclose(np.diff(rec.time), 1 / 60.0)
    assert np.array_equal(s.valid, keep)
    np.testing.assert_allclose(s.R_world_sensor, R, atol=1e-6)  # gaps slerp-filled


def test_ned_export_is_converted_to_enu(tmp_path: Path) -> None:
    R_ned = np.eye(3)[None]  # sensor aligned with North-East-Down
    write_mtmanager(tmp_path, "N_", "00B40002", np.arange(1), R_ned, 100.0,
                    coordinate_system="NED")
    R = read_mtmanager(tmp_path / "N_").sensors["00B40002"].R_world_sensor[0]
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-6)  # sensor x points North
    np.testing.assert_allclose(R @ [0, 0, 1], [0, 0, -1], atol=1e-6)  # sensor z points down


@pytest.mark.parametrize(
    ("text", "line", "field"),
    [
        ("// Update Rate: 100.0Hz\nPacketCounter\tAcc_X\tAcc_Y\n1\t0.1\t0.2\n2\t0.1\n", 4, None),
        ("// Update Rate: 100.0Hz\nAcc_X\tAcc_Y\n0.1\t0.2\n", 2, "PacketCounter"),
        ("// Update Rate: 100.0Hz\nPacketCounter\tAcc_X\n1\tzero\n", 3, "Acc_X"),
        ("", 1, None),
    ],
)
def test_malformed_input_names_file_line_and_field(tmp_path: Path, capsys, text: str, line: int,
                                                   field: str | None) -> None:
    path = tmp_path / "X_00B40003.txt"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_mtmanager(path)
    assert err.value.path == path and err.value.line == line
    if field:
        assert err.value.field == field
    assert main(["inspect", str(path)]) == 2
    assert str(path) in capsys.readouterr().err


def test_folder_without_exports(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(InputError, match="no MT Manager exports"):
        read_mtmanager(tmp_path)


def test_nan_inside_data_fields(tmp_path: Path) -> None:
    path = tmp_path / "T_00B40004.txt"
    path.write_text("// Update Rate: 40.0Hz\n// an extra comment line\n"
                    "PacketCounter;Acc_X;Acc_Y;Acc_Z;Quat_q0;Quat_q1;Quat_q2;Quat_q3\n"
                    "10;1.0;NaN;3.0;1;0;0;0\n11;1.5;;3.5;NaN;0;0;0\n12;2.0;2.5;4.0;1;0;0;0\n")
    rec = read_mtmanager(path)
    s = rec.sensors["00B40004"]
    assert rec.rate == 40.0
    np.testing.assert_allclose(s.acc, [[1.0, np.nan, 3.0], [1.5, np.nan, 3.5], [2.0, 2.5, 4.0]])
    assert s.valid.tolist() == [True, False, True]
    assert s.lost == 0
