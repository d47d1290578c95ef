"""`ikfusion demo` end to end on a short capture: files written, table printed."""

from __future__ import annotations

from pathlib import Path

from ikfusion.cli import main


def test_demo_writes_results_and_prints_the_table(tmp_path: Path, capsys) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--seconds", "6", "--quiet"]) == 0
    text = capsys.readouterr().out
    for label in ("joint angle RMS", "head position RMS", "foot slide", "frames/s"):
        assert label in text
    assert (out / "capture" / "truth.npz").is_file()
    assert (out / "capture" / "sensors.yaml").is_file()
    assert len(list((out / "capture" / "imu").glob("SIM_*.txt"))) == 17
    for name in ("joint_angles.csv", "segments.csv", "sites.csv", "contacts.csv", "motion.bvh",
                 "summary.json"):
        assert (out / "result" / name).is_file()
