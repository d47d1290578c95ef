"""simulate -> solve -> evaluate through the command line, on perfect sensors."""

from __future__ import annotations

import json
from pathlib import Path

from ikfusion.cli import main


def test_simulate_solve_evaluate(tmp_path: Path, capsys) -> None:
    capture = tmp_path / "capture"
    assert main(["simulate", "--motion", "gait:straight", "--seconds", "9", "--noise", "none",
                 "--out", str(capture), "--quiet"]) == 0
    assert sorted(p.name for p in capture.iterdir()) == [".ikfusion.json", "body.yaml", "imu",
                                                         "sensors.yaml", "truth.npz"]
    assert len(list((capture / "imu").glob("SIM_*.txt"))) == 17
    result = tmp_path / "result"
    assert main(["solve", "--imu", str(capture / "imu" / "SIM_"), "--map",
                 str(capture / "sensors.yaml"), "--body", str(capture / "body.yaml"), "--out",
                 str(result), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(result), str(capture / "truth.npz"), "--json"]) == 0
    metrics = json.loads(capsys.readouterr().out)
    # Random mountings calibrated from the data, perfect sensors: the body follows closely.
    assert metrics["joint_angle_rms_deg"] < 2.0
    assert metrics["segment_orientation_rms_deg"] < 3.0
    assert metrics["head_position_rms_m"] < 0.1


def test_simulate_rejects_bad_options(tmp_path: Path, capsys) -> None:
    assert main(["simulate", "--seconds", "1", "--out", str(tmp_path / "c")]) == 2
    assert "--seconds" in capsys.readouterr().err
    assert not (tmp_path / "c").exists()
