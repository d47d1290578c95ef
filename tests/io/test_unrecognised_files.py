"""Errors about files that are not recordings name the file and the structure, never its text."""

from __future__ import annotations

from pathlib import Path

import pytest

from ikfusion.cli import main
from ikfusion.errors import InputError
from ikfusion.io import read_imu

SECRET = "root:x:0:0:SECRET-PASSWORD-HASH:/root:/bin/bash"


@pytest.mark.parametrize("name", ["passwd", "notes.txt", "data.csv", "X_00B40001.txt"])
def test_an_arbitrary_file_is_not_echoed(tmp_path: Path, capsys, name: str) -> None:
    path = tmp_path / name
    path.write_text(f"{SECRET}\nalice:x:1000:1000::/home/alice:/bin/sh\n")
    with pytest.raises(InputError) as err:
        read_imu(path)
    message = err.value.reason  # the text after the file's path
    assert "SECRET" not in message and "root" not in message and "alice" not in message
    assert err.value.path == path and err.value.line == 1
    assert main(["inspect", str(path)]) == 2
    captured = capsys.readouterr()
    assert "SECRET" not in captured.out + captured.err
    assert str(path) in captured.err


def test_a_long_bad_field_of_an_export_is_not_quoted(tmp_path: Path) -> None:
    path = tmp_path / "X_00B40002.txt"
    path.write_text("// Update Rate: 100Hz\nPacketCounter\tAcc_X\n1\t0.1\n2\t" + SECRET + "\n")
    with pytest.raises(InputError, match="a field of 47 characters") as err:
        read_imu(path)
    assert "SECRET" not in str(err.value) and err.value.line == 4 and err.value.field == "Acc_X"


def test_an_mt_manager_export_named_csv_is_read_as_one(tmp_path: Path) -> None:
    path = tmp_path / "export_00B40003.csv"
    path.write_text("// Update Rate: 100Hz\nPacketCounter,Acc_X,Acc_Y,Acc_Z\n"
                    "1,0,0,9.8\n2,0,0,9.8\n")
    rec = read_imu(path)
    assert list(rec.sensors) == ["00B40003"] and rec.rate_source == "Update Rate"
