"""A foot sensor silent for 2 s in a walk with UWB: the no-slide solve does not pop (#19/#22).

The foot's tag unit then has no IMU for 2 s. Its filter used to coast on the filled samples
with the sensor's own noise: the track went metres off while claiming centimetres, every TOA
was gated out, and the smoother spread the error back over the second before the gap. The
correction let the standing foot go on that track, the body had no support for a whole step,
and the hip popped when the other foot landed (bench_packet_loss: 3.4 -> 6.3 deg).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from ikfusion.app.evaluate import joint_angle_jump
from ikfusion.app.pipeline import solve_recording
from ikfusion.app.uwb_aiding import drift_correction, track_capture
from ikfusion.io.sensor_map import load_sensor_map
from ikfusion.paths import shipped_config
from ikfusion.sim.capture import truth_motion, write_capture
from ikfusion.sim.imu import ImuNoise
from ikfusion.uwb.constellation import load_constellation

SECONDS = 12.0
SILENT = ("LeftFoot", 5.0, 7.0)  # segment, from [s], to [s]


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 12 s walk in circles with the default sensor errors in the middle of the UWB room."""
    room = load_constellation(shipped_config("constellations", "room_6x8.yaml"))
    truth = truth_motion("gait", SECONDS, 60.0)
    truth.q[:, :2] += [3.0, 2.5]
    folder = tmp_path_factory.mktemp("walk") / "capture"
    write_capture(folder, truth, ImuNoise(), 4, constellation=room)
    return folder


def silenced(capture: Path, out: Path, segment: str, t0: float, t1: float) -> Path:
    """A copy of ``capture`` whose ``segment`` sensor sent no row from ``t0`` to ``t1`` [s]."""
    shutil.copytree(capture, out, ignore=shutil.ignore_patterns("imu"))
    (out / "imu").mkdir()
    sensors = load_sensor_map(capture / "sensors.yaml")
    for path in sorted((capture / "imu").glob("*.txt")):
        lines = path.read_text().splitlines(keepends=True)
        header = next(i for i, line in enumerate(lines) if line.startswith("PacketCounter"))
        data = lines[header + 1:]
        t = np.arange(len(data)) / 60.0
        keep = np.ones(len(data), dtype=bool)
        if sensors[path.stem.split("_")[-1]] == segment:
            keep = (t < t0) | (t >= t1)
        (out / "imu" / path.name).write_text(
            "".join(lines[: header + 1]) + "".join(row for row, k in zip(data, keep) if k))
    return out


def solve(folder: Path, uwb: bool) -> tuple[float, str, float]:
    """Solve no-slide (``uwb``) or IMU-only; evaluate against the truth.

    Returns:
        The largest joint-angle jump against the truth's change [deg], where, and the longest
        stretch without a planted point [s].
    """
    tracked = track_capture(folder)
    fix = (drift_correction(tracked.tags, tracked.tracks, tracked.recording.time, "no-slide")
           if uwb else None)
    motion = solve_recording(tracked.recording, tracked.sensor_map, tracked.model,
                             correction=fix, calibration=tracked.calibration).motion
    truth = np.load(folder / "truth.npz")
    names = [str(n) for n in truth["joint_angle_names"]]
    columns = [c for c in motion.model.angle_columns if c in names]
    solved = motion.joint_angles()[:, [motion.model.angle_columns.index(c) for c in columns]]
    true = truth["joint_angles"][:, [names.index(c) for c in columns]]
    jump, where = joint_angle_jump(motion.time, solved, true, columns)
    unsupported = longest_run(~np.asarray(motion.contacts, dtype=bool).any(axis=1))
    return jump, where, unsupported / 60.0


def longest_run(flags: np.ndarray) -> int:
    """The longest run of True in ``flags`` (samples)."""
    longest = run = 0
    for flag in flags.tolist():
        run = run + 1 if flag else 0
        longest = max(longest, run)
    return longest


def test_a_silent_foot_sensor_adds_no_pop_to_a_no_slide_walk(capture: Path,
                                                             tmp_path: Path) -> None:
    """The walk keeps a foot on the floor throughout (as the truth does), and the largest jump
    is the one the bridging of the silent sensor makes in the IMU-only solve too."""
    folder = silenced(capture, tmp_path / "silent", *SILENT)
    jump, where, unsupported = solve(folder, uwb=True)
    inertial, inertial_where, _ = solve(folder, uwb=False)
    assert unsupported < 0.1, f"no foot on the floor for {unsupported:.2f} s"
    assert jump < inertial + 0.5, \
        f"{jump:.1f} deg ({where}) against {inertial:.1f} IMU-only ({inertial_where})"
