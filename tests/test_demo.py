"""`ikfusion demo` end to end on a short capture: files written, table printed."""

from __future__ import annotations

from pathlib import Path

import numpy as np

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
                 "motion.mot", "summary.json"):
        assert (out / "result" / name).is_file()
    # The OpenSim motion of the simulated walk: Rajagopal's knee flexion is our knee flexion.
    angles = np.genfromtxt(out / "result" / "joint_angles.csv", delimiter=",", names=True)
    lines = (out / "result" / "motion.mot").read_text().splitlines()
    start = lines.index("endheader") + 1
    mot = np.genfromtxt(lines[start:], delimiter="\t", names=True)
    np.testing.assert_allclose(mot["time"], angles["time"], atol=1e-6)
    np.testing.assert_allclose(mot["knee_angle_r"], angles["jRightKnee_flex"], atol=0.1)
    assert np.ptp(mot["knee_angle_r"]) > 30.0  # it walked
