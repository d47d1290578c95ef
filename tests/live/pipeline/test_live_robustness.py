"""The causal pipeline uses the past only; a killed recording is readable; dropouts go on."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ikfusion.app.evaluate import evaluate
from ikfusion.app.pipeline import solve_recording
from ikfusion.io.reader import read_imu
from ikfusion.io.sensor_map import load_sensor_map
from ikfusion.live.actor_stream import ActorStream
from ikfusion.live.frames import FrameAssembler
from ikfusion.live.kinematics import PoseKinematics
from ikfusion.live.replay import ReplaySource, recording_samples
from ikfusion.live.run import LiveActor, LiveLoop
from ikfusion.model import Body, HumanModel
from ikfusion.rotations import random_rotations


def _inputs(capture: Path):  # type: ignore[no-untyped-def]
    sensor_map = load_sensor_map(capture / "sensors.yaml")
    recording = read_imu(capture / "imu", sensor_map=sensor_map)
    return recording, sensor_map, HumanModel.from_body(Body.from_yaml(capture / "body.yaml"))


def test_the_causal_solve_does_not_look_ahead(capture: Path) -> None:
    """Every sample after 7 s replaced by nonsense: the poses up to 7 s do not change (the
    calibration, stance and bridging only use what came before)."""
    recording, sensor_map, model = _inputs(capture)
    before = solve_recording(recording, sensor_map, model, causal=True).motion
    rng = np.random.default_rng(5)
    cut = int(7.0 * recording.rate)
    for stream in recording.sensors.values():
        stream.R_world_sensor[cut:] = random_rotations(len(recording) - cut, rng)
        if stream.gyr is not None:
            stream.gyr[cut:] = rng.normal(0.0, 5.0, (len(recording) - cut, 3))
    after = solve_recording(recording, sensor_map, model, causal=True).motion
    np.testing.assert_array_equal(after.q[:cut], before.q[:cut])
    assert np.abs(after.q[cut:] - before.q[cut:]).max() > 0.1  # the nonsense did arrive


def test_a_sensor_dropping_out_mid_stream_does_not_stall(capture: Path) -> None:
    """The right forearm's sensor is silent from 7 to 8 s: every frame is still solved, on its
    deadline, with the forearm bridged from the past and met again when it returns."""
    recording, sensor_map, model = _inputs(capture)
    forearm = next(s for s, seg in sensor_map.items() if seg == "RightForeArm")
    samples = [s for s in recording_samples(recording, sensor_map)
               if not (s.sensor == forearm and 7.0 <= s.time_s < 8.0 - 1e-9)]
    stream = ActorStream(model, sensor_map, recording.rate)
    actor = LiveActor("a", 0, stream, FrameAssembler(sensor_map, recording.rate),
                      PoseKinematics(model))
    LiveLoop([actor], paced=False).run(ReplaySource([iter(samples)], speed=0.0))
    assert actor.frames == len(recording)
    assert actor.assembler.counters.missing == {forearm: 60}
    bridged = stream.bridged()
    assert bridged is not None and bridged.report["RightForeArm"].samples == 60
    assert bridged.report["RightForeArm"].longest_gap_s == 1.0


def test_a_killed_recording_leaves_a_readable_folder(capture: Path, tmp_path: Path) -> None:
    """SIGKILL while ``live --record`` runs: the result folder holds whole frames in every
    table, a summary of them, and ``evaluate`` reads it."""
    out = tmp_path / "record"
    process = subprocess.Popen(
        [sys.executable, "-m", "ikfusion", "live", "--replay", str(capture), "--speed", "0.5",
         "--record", str(out), "--quiet"], env=os.environ.copy(),
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        guard = time.monotonic() + 300.0  # only a guard against a hang, never asserted
        frames = 0
        while frames < 60 and process.poll() is None and time.monotonic() < guard:
            time.sleep(0.2)
            try:
                frames = json.loads((out / "summary.json").read_text())["frames"]
            except (OSError, ValueError, KeyError):
                pass
        assert process.poll() is None, "the replay ended before it could be killed"
        process.send_signal(signal.SIGKILL)
        process.wait()
    finally:
        if process.poll() is None:
            process.kill()
    summary = json.loads((out / "summary.json").read_text())
    # paced: the stream starts after the 6 s of calibration (its last frame), 240 frames in all
    assert summary["live"]["complete"] is False and 60 <= summary["frames"] < 241
    angles = np.loadtxt(out / "joint_angles.csv", delimiter=",", skiprows=1)
    assert len(angles) >= summary["frames"]
    segments = (out / "segments.csv").read_text().splitlines()[1:]
    assert len(segments) % 23 == 0 and all(len(r.split(",")) == 9 for r in segments)
    assert np.all(np.diff(angles[:, 0]) > 0)
    result = evaluate(out, capture / "truth.npz", align="none")
    assert result.frames >= summary["frames"] and np.isfinite(result.head_position_rms_m)
