"""The causal live pipeline's tests: a short simulated capture with UWB readers (a folder of
their own beside the wire-format tests of tests/live)."""

from __future__ import annotations

from pathlib import Path

import pytest

from ikfusion.cli import main

ROOM = Path(__file__).resolve().parents[3] / "configs" / "constellations" / "room_6x8.yaml"


@pytest.fixture(scope="package")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 10 s gait (2 s N-pose, then walking) at 60 Hz with three UWB tags."""
    folder = tmp_path_factory.mktemp("live") / "capture"
    assert main(["simulate", "--motion", "gait", "--seconds", "10", "--readers", str(ROOM),
                 "--seed", "3", "--out", str(folder), "--quiet"]) == 0
    return folder
