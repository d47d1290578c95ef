"""``live --replay`` against ``solve --causal``: one code path, the same poses."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ikfusion.app.evaluate import evaluate
from ikfusion.cli import main


def _table(path: Path) -> np.ndarray:
    return np.loadtxt(path, delimiter=",", skiprows=1)


def _long_table(path: Path) -> np.ndarray:
    rows = [line.split(",") for line in path.read_text().splitlines()[1:]]
    return np.array([[float(v) for i, v in enumerate(r) if i != 1] for r in rows])


def test_replay_gives_the_poses_of_the_causal_solve(capture: Path, tmp_path: Path) -> None:
    """Replayed as fast as possible (with its UWB tags), the live result folder holds the
    frames and poses of ``solve --causal`` of the same files, within 1e-6."""
    live, offline = tmp_path / "live", tmp_path / "offline"
    assert main(["live", "--replay", str(capture), "--speed", "0", "--record", str(live),
                 "--quiet"]) == 0
    assert main(["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
                 "--body", str(capture / "body.yaml"), "--toa", str(capture / "toa.csv"),
                 "--readers", str(capture / "readers.yaml"), "--tags", str(capture / "tags.yaml"),
                 "--causal", "--out", str(offline), "--quiet"]) == 0
    for name in ("joint_angles.csv", "contacts.csv"):
        a, b = _table(live / name), _table(offline / name)
        assert a.shape == b.shape == (600, a.shape[1])
        np.testing.assert_allclose(a, b, atol=1e-6, rtol=0)
    for name in ("segments.csv", "sites.csv"):
        np.testing.assert_allclose(_long_table(live / name), _long_table(offline / name),
                                   atol=1e-6, rtol=0)
    summary = json.loads((live / "summary.json").read_text())
    assert summary["frames"] == 600 and summary["live"]["complete"] is True
    assert summary["uwb"]["used"] is True and summary["uwb"]["smoothed"] is False
    assert summary["live"]["frames_dropped"] == 0
    assert summary["calibration"] == json.loads(
        (offline / "summary.json").read_text())["calibration"]


def test_live_head_is_in_the_tag_frame_from_the_first_frame(capture: Path,
                                                             tmp_path: Path) -> None:
    """The frames of the start-up buffer are sent once the first UWB fix placed the body, so
    the head follows the truth in the readers' frame from the first frame on (as offline)."""
    live = tmp_path / "live"
    assert main(["live", "--replay", str(capture), "--speed", "0", "--record", str(live),
                 "--quiet"]) == 0
    result = evaluate(live, capture / "truth.npz", align="none")
    assert result.head_position_rms_m < 0.06
