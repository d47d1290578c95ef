"""UWB in the live pipeline: the tags tracked as the TOA samples arrive, from the past only."""

from __future__ import annotations

import csv
import dataclasses
import heapq
import json
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import yaml

from ikfusion.app.evaluate import evaluate
from ikfusion.cli import main
from ikfusion.io.reader import read_imu
from ikfusion.live.actor_stream import ActorStream
from ikfusion.live.frames import FrameAssembler
from ikfusion.live.kinematics import PoseKinematics
from ikfusion.live.record import ResultRecorder
from ikfusion.live.replay import recording_samples, toa_samples
from ikfusion.live.run import LiveActor, LiveLoop
from ikfusion.live.samples import Sample, ToaSample
from ikfusion.live.settings import LiveSettings
from ikfusion.live.setup import source_setups
from ikfusion.uwb.toa_log import read_toa_csv


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


def _write(path: Path, rows: list[dict[str, str]]) -> Path:
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path


def _causal(capture: Path, toa: Path, out: Path) -> np.ndarray:
    assert main(["solve", "--imu", str(capture / "imu"), "--map", str(capture / "sensors.yaml"),
                 "--body", str(capture / "body.yaml"), "--toa", str(toa),
                 "--readers", str(capture / "readers.yaml"), "--tags", str(capture / "tags.yaml"),
                 "--causal", "--out", str(out), "--quiet"]) == 0
    return np.loadtxt(out / "joint_angles.csv", delimiter=",", skiprows=1)


def test_the_causal_tag_fixes_do_not_look_ahead(capture: Path, tmp_path: Path) -> None:
    """Every TOA after 3.5 s replaced by nonsense (the readers file no longer fits): the poses
    up to 3.5 s do not change. Before, each tag was judged (``tag_fit``) over the whole log, so
    later nonsense took the UWB out of the first seconds too."""
    cut_s = 3.5
    rng = np.random.default_rng(2)
    rows = _rows(capture / "toa.csv")
    for row in rows:
        if float(row["time"]) >= cut_s:
            row["toa"] = f"{float(row['toa']) + rng.uniform(-30.0, 30.0):.5f}"
    bad = _write(tmp_path / "toa.csv", rows)
    clean = _causal(capture, capture / "toa.csv", tmp_path / "clean")
    garbled = _causal(capture, bad, tmp_path / "garbled")
    cut = int(np.searchsorted(clean[:, 0], cut_s))
    assert cut > 100
    np.testing.assert_array_equal(garbled[:cut], clean[:cut])
    assert np.abs(garbled[cut:] - clean[cut:]).max() > 1e-6  # the nonsense did arrive


def _session(capture: Path, tmp_path: Path) -> Path:
    tags = yaml.safe_load((capture / "tags.yaml").read_text())
    actor = next(iter(tags["tags"].values()))["actor"]
    path = tmp_path / "session.yaml"
    path.write_text(yaml.safe_dump({
        "toa": str(capture / "toa.csv"), "readers": str(capture / "readers.yaml"),
        "tags": str(capture / "tags.yaml"),
        "actors": {actor: {"imu": str(capture / "imu"), "map": str(capture / "sensors.yaml"),
                           "body": str(capture / "body.yaml")}}}))
    return path


class _Stream:
    """A live source: the given samples, then the end."""

    def __init__(self, samples: Iterator[Sample]) -> None:
        self._samples = samples

    def samples(self) -> Iterator[Sample]:
        return self._samples

    def close(self) -> None:
        pass


def _live(capture: Path, tmp_path: Path,
          trouble: Callable[[Iterator[Sample]], Iterator[Sample]] | None = None
          ) -> tuple[Path, LiveLoop]:
    """The capture streamed as a live source (``--udp``/``--lsl`` with a session file), its
    samples in time order passed through ``trouble``."""
    setups = source_setups(None, None, None, _session(capture, tmp_path), 60.0)
    (setup,) = setups
    settings = LiveSettings.load()
    stream = ActorStream(setup.model, setup.sensor_map, setup.rate, correction_for=setup.uwb,
                         settings=settings)
    out = tmp_path / "live"
    recorder = ResultRecorder(out, setup.model, stream.solver.contact_names, settings.flush_s,
                              "z", False)
    actor = LiveActor(setup.name, 0, stream, FrameAssembler(setup.sensor_map, setup.rate,
                                                            settings.deadline_periods,
                                                            settings.clock_jump_s, None),
                      PoseKinematics(setup.model), recorder)
    loop = LiveLoop([actor], paced=False)
    recording = read_imu(capture / "imu", sensor_map=setup.sensor_map)
    imu = recording_samples(recording, setup.sensor_map, None)
    toa = toa_samples(read_toa_csv(capture / "toa.csv"))
    samples: Iterator[Sample] = heapq.merge(imu, toa, key=lambda s: s.time_s)
    loop.run(_Stream(trouble(samples) if trouble is not None else samples))
    summary = {"live": actor.summary()}
    if setup.uwb is not None and setup.uwb.correction is not None:
        aiding = setup.uwb.aiding()
        summary["uwb"] = aiding.summary()
        recorder.set_summary(summary)
        recorder.close(aiding.warnings)
    else:
        recorder.close([])
    return out, loop


def test_a_live_source_uses_its_toa_samples(capture: Path, tmp_path: Path) -> None:
    """A live source (not a replay) with a session naming the UWB files: its TOA samples move
    the body into the readers' frame (before, they were counted and dropped)."""
    out, loop = _live(capture, tmp_path)
    assert loop.toa_samples > 1000
    assert json.loads((out / "summary.json").read_text())["uwb"]["used"] is True
    assert evaluate(out, capture / "truth.npz", align="none").head_position_rms_m < 0.06


def _troubled(samples: Iterator[Sample]) -> Iterator[Sample]:
    """R1 vanishes at 5 s, the head tag is silent from 6 to 7.5 s, and the TOAs of 8-8.5 s
    arrive 0.6 s late (after their frames)."""
    late: list[ToaSample] = []
    for s in samples:
        while late and late[0].time_s + 0.6 <= s.time_s:
            yield late.pop(0)
        if isinstance(s, ToaSample):
            if s.reader == "R1" and s.time_s >= 5.0:
                continue
            if s.tag == "T1" and 6.0 <= s.time_s < 7.5:
                continue
            if 8.0 <= s.time_s < 8.5:
                late.append(s)
                continue
        yield s
    yield from late


def test_a_vanishing_reader_a_silent_tag_and_late_toas_do_not_stop_the_stream(
        capture: Path, tmp_path: Path) -> None:
    """The stream goes on with the past: every frame solved, the reader reported lost, the late
    TOAs dropped and counted, and the head still follows the truth."""
    tags = yaml.safe_load((capture / "tags.yaml").read_text())["tags"]
    assert tags["T1"]["site"] == "HeadTop"
    statuses: list[str] = []
    out, loop = _live(capture, tmp_path, _troubled)
    statuses.append(loop.actors[0].stream.status())
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == 600
    warnings = " | ".join(summary["warnings"])
    assert "UWB reader R1 lost" in warnings
    assert "arrived after their frame" in warnings
    assert "R1" in statuses[0]  # still lost at the end: on the status line
    assert evaluate(out, capture / "truth.npz", align="none").head_position_rms_m < 0.1


def test_a_source_on_epoch_times_gives_the_same_poses(capture: Path, tmp_path: Path) -> None:
    """A live source stamping its IMU and TOA samples with epoch times (1.79e9 s): the same
    poses as from the same stamps counted from zero (before, the UWB fix arrays were indexed by
    ``round(time * rate)`` and grown to 1e11 frames).

    The same stamps: an epoch time holds the capture's time only to 2.4e-7 s, and that
    rounding, a property of the stamps, reaches the poses through the time steps (up to a few
    hundredths of a degree, more where a contact decision sits on its threshold). Counted from
    zero after the same rounding, nothing in the pipeline may depend on where time starts."""
    epoch = 1.79e9

    def shifted(samples: Iterator[Sample]) -> Iterator[Sample]:
        for s in samples:
            yield dataclasses.replace(s, time_s=s.time_s + epoch)

    def rounded(samples: Iterator[Sample]) -> Iterator[Sample]:
        for s in samples:
            yield dataclasses.replace(s, time_s=(s.time_s + epoch) - epoch)

    (tmp_path / "base").mkdir()
    (tmp_path / "epoch").mkdir()
    base, _ = _live(capture, tmp_path / "base", rounded)
    moved, loop = _live(capture, tmp_path / "epoch", shifted)
    a = np.loadtxt(base / "joint_angles.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(moved / "joint_angles.csv", delimiter=",", skiprows=1)
    assert a.shape == b.shape and len(a) > 500
    np.testing.assert_allclose(b[:, 0] - epoch, a[:, 0], atol=1e-5)
    np.testing.assert_allclose(b[:, 1:], a[:, 1:], rtol=0.0, atol=1e-6)
    summary = json.loads((moved / "summary.json").read_text())
    assert summary["uwb"]["used"] is True
