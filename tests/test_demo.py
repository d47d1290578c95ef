"""`ikfusion demo` end to end on a short capture: files written, table printed."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from ikfusion.app.evaluate import evaluate, phase_slides
from ikfusion.cli import main


def test_demo_writes_results_and_prints_the_table(tmp_path: Path, capsys) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--seconds", "6", "--quiet"]) == 0
    text = capsys.readouterr().out
    for label in ("joint angle RMS", "head position RMS", "foot slide", "frames/s",
                  "UWB gap remaining", "joint-angle jump"):
        assert label in text
    # the heading row: one column per mode, in this order
    assert ["IMU", "only", "UWB", "slide", "UWB", "no-slide"] in [line.split()
                                                               for line in text.splitlines()]
    assert f"ikfusion view {out}/result --truth {out}/capture/truth.npz" in text
    assert (out / "capture" / "truth.npz").is_file()
    assert (out / "capture" / "sensors.yaml").is_file()
    assert len(list((out / "capture" / "imu").glob("SIM_*.txt"))) == 17
    for folder in ("result", "result_slide", "result_imu_only"):
        for name in ("joint_angles.csv", "segments.csv", "sites.csv", "contacts.csv",
                     "motion.bvh", "motion.mot", "summary.json"):
            assert (out / folder / name).is_file()
    for name in ("toa.csv", "readers.yaml", "tags.yaml"):
        assert (out / "capture" / name).is_file()
    used = {f: json.loads((out / f / "summary.json").read_text())["uwb"]
            for f in ("result", "result_slide", "result_imu_only")}
    assert not used["result_imu_only"]["used"]
    assert used["result"]["used"] and used["result"]["correction"] == "no-slide"
    assert used["result_slide"]["used"] and used["result_slide"]["correction"] == "slide"
    for folder in ("result", "result_slide", "result_imu_only"):  # the keys `solve` writes
        summary = json.loads((out / folder / "summary.json").read_text())
        assert {"method", "heading_deg", "window_s"} <= set(summary["calibration"])
        assert summary["source"].startswith("ikfusion demo")
    # UWB puts the body where it is: scored in the readers' frame, without any alignment
    # (about 1.5 cm on this capture; IMU only, unaligned, is metres away)
    for folder in ("result", "result_slide"):
        score = evaluate(out / folder, out / "capture" / "truth.npz", align="none")
        assert np.isfinite(score.head_position_rms_m) and score.head_position_rms_m < 0.10
    # no-slide never moves a planted point; slide visibly does
    assert _own_planted_slide_mm(out / "result") <= 1.0
    assert _own_planted_slide_mm(out / "result_slide") > 1.0

    # The OpenSim motion of the simulated walk: Rajagopal's knee flexion is our knee flexion.
    angles = np.genfromtxt(out / "result" / "joint_angles.csv", delimiter=",", names=True)
    lines = (out / "result" / "motion.mot").read_text().splitlines()
    start = lines.index("endheader") + 1
    mot = np.genfromtxt(lines[start:], delimiter="\t", names=True)
    np.testing.assert_allclose(mot["time"], angles["time"], atol=1e-6)
    np.testing.assert_allclose(mot["knee_angle_r"], angles["jRightKnee_flex"], atol=0.1)
    assert np.ptp(mot["knee_angle_r"]) > 30.0  # it walked


def _own_planted_slide_mm(folder: Path) -> float:
    """Largest slide of the solve's own planted points over its own contact phases [mm]."""
    rows = list(csv.reader((folder / "sites.csv").open()))[1:]
    times = sorted({float(r[0]) for r in rows})
    frame = {t: k for k, t in enumerate(times)}
    names = ["LeftHeel", "LeftToe", "RightHeel", "RightToe"]
    points = np.zeros((len(times), 4, 3))
    for r in rows:
        if r[1] in names:
            points[frame[float(r[0])], names.index(r[1])] = [float(v) for v in r[2:5]]
    table = np.genfromtxt(folder / "contacts.csv", delimiter=",", names=True)
    contacts = np.column_stack([table[n] > 0.5 for n in names])
    return 1e3 * max(phase_slides(points, contacts))
