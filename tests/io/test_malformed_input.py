"""Bad input: an InputError naming file, line and column; the command line exits 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from ikfusion.cli import main
from ikfusion.errors import InputError
from ikfusion.io import read_imu_csv, read_mtmanager

HEADER = "// Update Rate: 100.0Hz\n// Filter Profile: human (46.1)\n"


@pytest.mark.parametrize(
    ("name", "text", "line", "field", "words"),
    [
        ("truncated line",
         HEADER + "PacketCounter\tAcc_X\tAcc_Y\tAcc_Z\n1\t0.1\t0.2\t9.8\n2\t0.1\t0.2\t9.8\n"
         "3\t0.1\n",
         6, "Acc_Y", "truncated"),
        ("truncated line, comma, with comments",
         HEADER + "PacketCounter,Acc_X,Acc_Y\n// note\n1,0.1,0.2\n\n2,0.1\n4,1,1\n",
         7, "Acc_Y", "truncated"),
        ("a line too long",
         HEADER + "PacketCounter;Acc_X\n1;0.1\n2;0.1;7\n", 5, "column 3 (after Acc_X)",
         "3 fields"),
        ("header without PacketCounter",
         HEADER + "SampleTimeFine\tAcc_X\tAcc_Y\n100\t0.1\t0.2\n", 3, "PacketCounter",
         "no PacketCounter"),
        ("data without a header",
         HEADER + "00001\t0.1\t0.2\n", 3, "PacketCounter", "no PacketCounter"),
        ("non-numeric field",
         HEADER + "PacketCounter\tAcc_X\tAcc_Y\n1\t0.1\t0.2\n2\tzero\t0.2\n", 5, "Acc_X",
         "not a number: 'zero'"),
        ("non-numeric field, space-delimited",
         HEADER + "PacketCounter Acc_X Acc_Y\n1 0.1 0.2\n2 0.1 0.2x\n", 5, "Acc_Y",
         "not a number"),
        ("fractional counter",
         HEADER + "PacketCounter\tAcc_X\n1\t0.1\n2.5\t0.2\n", 5, "PacketCounter", "whole"),
        ("empty file", "", 1, "PacketCounter", "empty file"),
        ("blank file", "\n  \n\n", 1, "PacketCounter", "empty file"),
        ("comments only", HEADER, 2, "PacketCounter", "no header line"),
        ("unknown coordinate system",
         HEADER + "// Coordinate system: XYZ\nPacketCounter\tAcc_X\n1\t0\n", 3,
         "Coordinate system", "unknown coordinate system"),
    ],
)
def test_bad_export_names_file_line_and_field(tmp_path: Path, capsys, name: str, text: str,
                                              line: int, field: str, words: str) -> None:
    path = tmp_path / "X_00B40003.txt"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_mtmanager(path)
    assert err.value.path == path, name
    assert err.value.line == line, name
    assert err.value.field == field, name
    assert words in str(err.value), name
    assert main(["inspect", str(path)]) == 2
    message = capsys.readouterr().err
    assert str(path) in message and f"line {line}" in message and repr(field) in message


def test_good_rows_around_a_nan_are_kept(tmp_path: Path) -> None:
    path = tmp_path / "X_00B40004.txt"
    path.write_text(HEADER + "PacketCounter\tAcc_X\tAcc_Y\tAcc_Z\n1\t0.1\t0.2\t9.8\n"
                    "2\tNaN\t\t9.7\n3\t0.3\t0.4\t9.6\n")
    s = read_mtmanager(path).sensors["00B40004"]
    assert s.acc[1, 2] == 9.7 and s.acc[2, 0] == 0.3
    assert s.received.all() and s.lost == 0


def test_folder_without_exports(tmp_path: Path, capsys) -> None:
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(InputError, match="no MT Manager exports") as err:
        read_mtmanager(tmp_path)
    assert err.value.path == tmp_path and "notes.txt" in str(err.value)
    assert main(["inspect", str(tmp_path)]) == 2
    assert str(tmp_path) in capsys.readouterr().err


def test_nothing_at_the_path(tmp_path: Path, capsys) -> None:
    assert main(["inspect", str(tmp_path / "missing_")]) == 2
    assert "no file, folder or trial prefix" in capsys.readouterr().err


def test_trial_files_that_disagree_on_the_rate(tmp_path: Path) -> None:
    (tmp_path / "T_00B40001.txt").write_text("// Update Rate: 100Hz\nPacketCounter\tAcc_X\n1\t0\n")
    (tmp_path / "T_00B40002.txt").write_text("// Update Rate: 60Hz\nPacketCounter\tAcc_X\n1\t0\n")
    with pytest.raises(InputError, match="disagree on the update rate"):
        read_mtmanager(tmp_path)


def test_bad_generic_csv(tmp_path: Path) -> None:
    path = tmp_path / "imu.csv"
    path.write_text("time,sensor,qw,qx,qy\n0,a,1,0,0\n")
    with pytest.raises(InputError) as err:
        read_imu_csv(path)
    assert (err.value.line, err.value.field) == (1, "qz")
    path.write_text("time,sensor,qw,qx,qy,qz\n0,a,1,0,0,0\n0.01,a,1,0,0,zero\n")
    with pytest.raises(InputError) as err:
        read_imu_csv(path)
    assert (err.value.line, err.value.field) == (3, "qz")
    path.write_text("time,sensor,qw,qx,qy,qz\n0,a,1,0,0,0\n0.01,a,1,0\n")
    with pytest.raises(InputError, match="truncated") as err:
        read_imu_csv(path)
    assert (err.value.line, err.value.field) == (3, "qy")
    path.write_text("")
    with pytest.raises(InputError, match="empty file"):
        read_imu_csv(path)
