"""Reduced sensor sets give plausible bodies: the real 5-sensor treadmill trial.

shared/data/xsens/movingreality_trial007 (SintMaartenskliniek/MovingReality, MIT): MTw2 sensors
on the lumbar spine, both shanks and both feet (its sensorspec.json), treadmill gait. The thighs,
trunk and arms carry no sensor; they must follow a plausible default (hinge knees, trunk over
the pelvis, arms hanging) and summary.json must say what is measured and what is assumed.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from ikfusion.cli import main
from ikfusion.model import HumanModel

TREADMILL_MAP = """\
# sensorspec.json: lumbar 00B47791, shanks 00B47786 (left) and 00B47795 (right),
# feet 00B4778E (left) and 00B47793 (right)
sensors:
  00B47791: Pelvis
  00B47786: LeftLowerLeg
  00B47795: RightLowerLeg
  00B4778E: LeftFoot
  00B47793: RightFoot
"""


def _columns(path: Path) -> tuple[list[str], list[list[str]]]:
    with path.open() as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


@pytest.fixture(scope="module")
def treadmill_result(tmp_path_factory: pytest.TempPathFactory) -> Path:
    trial = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "xsens" / (
        "movingreality_trial007")
    if not trial.is_dir():
        pytest.skip(f"real recordings not available: {trial} is absent (a user's clone)")
    spec = json.loads((trial / "sensorspec.json").read_text())
    assert {v[:8] for v in spec.values()} == {"00B47791", "00B47786", "00B47795", "00B4778E",
                                              "00B47793"}
    folder = tmp_path_factory.mktemp("treadmill")
    sensor_map = folder / "sensors.yaml"
    sensor_map.write_text(TREADMILL_MAP)
    out = folder / "result"
    # the MTw2 exports carry no rate line and empty SampleTimeFine: 100 Hz (the study's rate)
    assert main(["solve", "--imu", str(trial), "--map", str(sensor_map), "--rate", "100",
                 "--out", str(out), "--quiet"]) == 0
    return out


def test_treadmill_gait_is_plausible(treadmill_result: Path) -> None:
    header, rows = _columns(treadmill_result / "joint_angles.csv")
    angles = np.array(rows, dtype=float)
    assert np.isfinite(angles).all()
    for side in ("Right", "Left"):
        knee = angles[:, header.index(f"j{side}Knee_flex")]
        # gait: knees near straight in stance, bent in swing, never a crouch
        assert 0.0 <= np.median(knee) <= 40.0, side
        assert knee.max() < 90.0, side
        assert np.percentile(knee, 95) > 15.0, side  # ... and they do bend each stride
        abduction = angles[:, header.index(f"j{side}Hip_abd")]
        assert abs(np.median(abduction)) < 15.0, side
    # the head at standing height: the default subject's HeadTop in the N-pose, feet on the floor
    model = HumanModel.default()
    q = model.neutral()
    standing = model.site_position(q, "HeadTop")[2] - min(
        model.site_position(q, c)[2] for c in model.sites_of_kind("contact"))
    header, rows = _columns(treadmill_result / "sites.csv")
    head = np.array([float(r[header.index("z")]) for r in rows if r[1] == "HeadTop"])
    assert abs(np.median(head) - standing) < 0.06


def test_summary_says_what_is_measured_and_assumed(treadmill_result: Path) -> None:
    summary = json.loads((treadmill_result / "summary.json").read_text())
    segments = summary["segments"]
    assert sorted(segments["measured"]) == ["LeftFoot", "LeftLowerLeg", "Pelvis", "RightFoot",
                                            "RightLowerLeg"]
    assert {"RightUpperLeg", "LeftUpperLeg", "T8", "Head", "RightUpperArm"} <= set(
        segments["assumed"])
    assert any("knee angles are assumed" in w and "RightUpperLeg" in w
               for w in summary["warnings"])
