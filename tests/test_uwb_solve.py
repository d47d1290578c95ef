"""``solve`` with UWB: a simulated walk with tags and readers, corrected vs inertial only."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ikfusion.cli import main
from ikfusion.evaluate import evaluate

ROOM = Path(__file__).resolve().parents[1] / "configs" / "constellations" / "room_6x8.yaml"


@pytest.fixture(scope="module")
def capture(tmp_path_factory) -> Path:  # type: ignore[no-untyped-def]
    folder = tmp_path_factory.mktemp("uwb") / "capture"
    assert main(["simulate", "--motion", "gait", "--seconds", "25", "--readers", str(ROOM),
                 "--seed", "4", "--out", str(folder), "--quiet"]) == 0
    return folder


def _solve(capture: Path, out: Path, correction: str | None, *extra: str) -> Path:
    args = ["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
            "--body", str(capture / "body.yaml"), "--out", str(out), "--quiet", *extra]
    if correction:
        args += ["--toa", str(capture / "toa.csv"), "--readers", str(capture / "readers.yaml"),
                 "--tags", str(capture / "tags.yaml"), "--correction", correction]
    assert main(args) == 0
    return out


def test_simulated_capture_has_the_uwb_files(capture: Path) -> None:
    for name in ("toa.csv", "readers.yaml", "tags.yaml"):
        assert (capture / name).is_file()
    header = (capture / "toa.csv").read_text().splitlines()[0]
    assert header.split(",") == ["time", "tag", "seq", "reader", "toa"]


@pytest.mark.parametrize("mode", ["slide", "no-slide"])
def test_uwb_brings_the_head_to_the_truth(capture: Path, tmp_path: Path, mode: str) -> None:
    """With UWB the head is in the readers' frame, within a few centimetres of the truth, and
    closer than the inertial solve even when that one is given the true start position."""
    truth = capture / "truth.npz"
    imu_only = evaluate(_solve(capture, tmp_path / "imu", None), truth)
    aided_folder = _solve(capture, tmp_path / mode, mode)
    aided = evaluate(aided_folder, truth, align="none")
    assert aided.head_position_rms_m < 0.06
    assert aided.head_position_rms_m < imu_only.head_position_rms_m
    assert aided.joint_angle_rms_deg < 3.5
    summary = json.loads((aided_folder / "summary.json").read_text())
    uwb = summary["uwb"]
    assert uwb["used"] is True and uwb["correction"] == mode and uwb["smoothed"] is True
    assert Path(uwb["readers"]) == (capture / "readers.yaml").resolve()  # for evaluate --plot
    head = next(t for t in uwb["tags"].values())
    assert head["toas_used"] > 0.7 * head["toas"]  # most are used; the NLOS ones are rejected
    assert head["toas_rejected"] > 0


def test_causal_tracks_use_the_past_only(capture: Path, tmp_path: Path) -> None:
    """``--causal``: the filter as it would run live; still far better than IMU only, and
    smoothing over the recording only helps."""
    truth = capture / "truth.npz"
    causal = _solve(capture, tmp_path / "causal", "no-slide", "--causal")
    smoothed = _solve(capture, tmp_path / "smoothed", "no-slide")
    assert json.loads((causal / "summary.json").read_text())["uwb"]["smoothed"] is False
    head = {f: evaluate(f, truth, align="none").head_position_rms_m for f in (causal, smoothed)}
    assert head[causal] < 0.06
    assert head[smoothed] <= head[causal]


def test_uwb_needs_all_three_files(capture: Path, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    code = main(["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
                 "--toa", str(capture / "toa.csv"), "--out", str(tmp_path / "r"), "--quiet"])
    assert code == 2
    assert "--readers" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()
