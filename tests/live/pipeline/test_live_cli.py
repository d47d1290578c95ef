"""``ikfusion live`` options: clear errors for bad input and for outputs not installed."""

from __future__ import annotations

from pathlib import Path

import pytest

from ikfusion.cli import main
from ikfusion.cli.live import host_port, optional_class
from ikfusion.errors import InputError


def test_an_output_module_that_is_absent_is_a_clear_input_error() -> None:
    with pytest.raises(InputError, match="--mvn is not available"):
        optional_class("ikfusion.live.no_such_module", "MvnStreamSink", "--mvn")


@pytest.mark.parametrize("text", ["localhost", "host:", ":9763", "host:0", "host:70000",
                                  "host:port"])
def test_host_port_is_checked(text: str) -> None:
    with pytest.raises(InputError, match="HOST:PORT"):
        host_port(text, "--mvn")


def test_a_missing_replay_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["live", "--replay", str(tmp_path / "nothing" / "here"), "--quiet"])
    assert code == 2 and "nothing" in capsys.readouterr().err


def test_a_recording_without_a_map_is_exit_2(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "trial.txt").write_text("x")
    assert main(["live", "--replay", str(tmp_path / "trial.txt"), "--quiet"]) == 2
    assert "--map" in capsys.readouterr().err
