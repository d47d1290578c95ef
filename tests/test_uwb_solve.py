"""``solve`` with UWB: a simulated walk with tags and readers, corrected vs inertial only."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from ikfusion.app.evaluate import evaluate
from ikfusion.cli import main

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
    assert Path(uwb["readers_file"]) == (capture / "readers.yaml").resolve()  # for evaluate --plot
    head = next(t for t in uwb["tags"].values())
    assert head["toas_used"] > 0.7 * head["toas_received"]  # the NLOS ones are rejected
    assert head["aiding"] is True and head["problem"] is None
    assert set(uwb["readers"]) == {f"R{i}" for i in range(1, 11)}
    assert not [w for w in summary["warnings"] if "UWB" in w]  # a clean capture: no alarm
    assert 0.0 <= uwb["gap_mean_m"] <= uwb["gap_max_m"] < 0.5  # measured during the solve
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


def _summary(folder: Path) -> dict:  # type: ignore[type-arg]
    return json.loads((folder / "summary.json").read_text())


def _solve_with(capture: Path, out: Path, toa: Path, readers: Path) -> Path:
    assert main(["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
                 "--body", str(capture / "body.yaml"), "--toa", str(toa), "--readers",
                 str(readers), "--tags", str(capture / "tags.yaml"), "--out", str(out),
                 "--quiet"]) == 0
    return out


def test_permuted_reader_ids_do_not_pull_the_body(capture: Path, tmp_path: Path,
                                                  capsys) -> None:  # type: ignore[no-untyped-def]
    """Reader ids shifted by one in readers.yaml: no TOA fits, so no tag may aid the solve
    (it used to say ``used: true`` with no warning and a head metres off); the result is no
    worse than IMU only, and summary.json and the terminal say why, with numbers."""
    data = yaml.safe_load((capture / "readers.yaml").read_text())
    ids = [r["id"] for r in data["readers"]]
    for reader, rid in zip(data["readers"], ids[1:] + ids[:1]):
        reader["id"] = rid
    permuted = tmp_path / "readers.yaml"
    permuted.write_text(yaml.safe_dump(data, sort_keys=False))
    truth = capture / "truth.npz"
    imu_only = evaluate(_solve(capture, tmp_path / "imu", None), truth)
    folder = _solve_with(capture, tmp_path / "permuted", capture / "toa.csv", permuted)
    result = evaluate(folder, truth)
    assert result.head_position_rms_m <= imu_only.head_position_rms_m + 0.005
    summary = _summary(folder)
    uwb = summary["uwb"]
    assert uwb["used"] is False
    for tag in uwb["tags"].values():
        assert tag["aiding"] is False and tag["transmissions_received"] > 100
        assert tag["transmissions_used"] < 0.5 * tag["transmissions_received"]
    err = capsys.readouterr().err
    for tag_id in uwb["tags"]:
        assert any(tag_id in w and "does not aid" in w for w in summary["warnings"])
        assert f"UWB tag {tag_id}" in err


def test_header_only_toa_log_is_not_used(capture: Path, tmp_path: Path) -> None:
    """A TOA log with its header only: nothing aids the solve, and the summary says so."""
    empty = tmp_path / "toa.csv"
    empty.write_text("time,tag,seq,reader,toa\n")
    folder = _solve_with(capture, tmp_path / "r", empty, capture / "readers.yaml")
    summary = _summary(folder)
    assert summary["uwb"]["used"] is False
    assert all(t["transmissions_received"] == 0 for t in summary["uwb"]["tags"].values())
    assert any("IMU-only" in w for w in summary["warnings"])


def test_reader_faults_are_reported(capture: Path, tmp_path: Path) -> None:
    """A reader whose clock jumps by 1.5 m at 10 s, one with 40 % NLOS and two readers silent
    from 8 s to 13 s: the filter absorbs them (the head stays on the truth), and summary.json
    says which reader was rejected how often and when; only the faulty ones are warned about."""
    lines = (capture / "toa.csv").read_text().splitlines()
    rng = np.random.default_rng(1)
    out = [lines[0]]
    for line in lines[1:]:
        t, tag, seq, reader, toa = line.split(",")
        value = float(toa)
        if reader in ("R7", "R8") and 8.0 <= float(t) < 13.0:
            continue
        if reader == "R3" and float(t) >= 10.0:
            value += 1.5
        if reader == "R5" and rng.random() < 0.4:
            value += rng.uniform(0.3, 2.0)
        out.append(f"{t},{tag},{seq},{reader},{value:.5f}")
    faulty = tmp_path / "toa.csv"
    faulty.write_text("\n".join(out) + "\n")
    folder = _solve_with(capture, tmp_path / "r", faulty, capture / "readers.yaml")
    summary = _summary(folder)
    uwb = summary["uwb"]
    assert uwb["used"] is True
    assert evaluate(folder, capture / "truth.npz", align="none").head_position_rms_m < 0.06
    readers = uwb["readers"]
    assert readers["R3"]["rejected_share"] > 0.5
    (t0, t1), = readers["R3"]["rejected_windows"]
    assert 9.0 <= t0 <= 11.0 and t1 >= 24.0
    assert readers["R5"]["rejected_share"] > 0.3
    for rid in ("R7", "R8"):
        (t0, t1), = readers[rid]["silent_windows"]  # 1 s bins
        assert 7.0 <= t0 <= 9.0 and 11.5 <= t1 <= 14.0
    warned = {rid for rid in readers if any(f"reader {rid}:" in w for w in summary["warnings"])}
    assert warned == {"R3", "R5"}
