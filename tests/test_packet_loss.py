"""Lost packets and a sensor that drops out do not make joints jump; the summary says what was
bridged.

A short simulated walk with perfect sensors (every frame-to-frame change of a joint angle that
differs from the truth's is then the solve's own doing) loses rows of its MT Manager files as an
Awinda station loses packets: at random on every sensor, or the left foot sensor for 2 s.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ikfusion.app.evaluate import joint_angle_jump
from ikfusion.app.pipeline import solve_recording
from ikfusion.cli import main as cli
from ikfusion.io.reader import read_imu
from ikfusion.io.sensor_map import load_sensor_map
from ikfusion.model import Body, HumanModel
from ikfusion.sim.capture import Capture, truth_motion, write_capture
from ikfusion.sim.imu import ImuNoise
from ikfusion.sim.uwb_capture import smooth_truth

SECONDS = 8.0
DROPOUT = ("LeftFoot", 3.0, 5.0)  # segment, from [s], to [s]


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Capture:
    """An 8 s walk at 60 Hz, perfect sensors.

    The truth is low-pass filtered as for UWB captures: the synthetic gait turns a knee by up to
    18 deg in one frame, which no bridging of a lost sample could guess.
    """
    truth = smooth_truth(truth_motion("gait", SECONDS, 60.0))
    return write_capture(tmp_path_factory.mktemp("walk") / "capture", truth, ImuNoise.none(), 4)


def lose_rows(capture: Capture, out: Path, loss: float, rng: np.random.Generator,
              silent: tuple[str, float, float] | None = None) -> Path:
    """The capture's IMU folder copied to ``out`` without some data rows (PacketCounter gaps).

    ``loss`` of the rows of every sensor go at random; ``silent`` = (segment, t0, t1): that
    segment's sensor sends nothing from t0 to t1 [s].
    """
    sensors = load_sensor_map(capture.sensor_map)
    out.mkdir(parents=True)
    for path in sorted((capture.folder / "imu").glob("*.txt")):
        lines = path.read_text().splitlines(keepends=True)
        header = next(i for i, line in enumerate(lines) if line.startswith("PacketCounter"))
        data = lines[header + 1:]
        keep = rng.random(len(data)) >= loss
        if silent is not None and sensors[path.stem.split("_")[-1]] == silent[0]:
            t = np.arange(len(data)) / 60.0
            keep &= (t < silent[1]) | (t >= silent[2])
        out.joinpath(path.name).write_text(
            "".join(lines[: header + 1]) + "".join(row for row, k in zip(data, keep) if k))
    return out


def largest_jump(capture: Capture, imu: Path, causal: bool = False) -> tuple[float, str]:
    """The solve's largest joint-angle jump against the truth's change [deg], and where."""
    sensor_map = load_sensor_map(capture.sensor_map)
    model = HumanModel.from_body(Body.from_yaml(capture.folder / "body.yaml"))
    motion = solve_recording(read_imu(imu, sensor_map=sensor_map), sensor_map, model,
                             causal=causal).motion
    truth = np.load(capture.folder / "truth.npz")
    names = [str(n) for n in truth["joint_angle_names"]]
    columns = [c for c in motion.model.angle_columns if c in names]
    solved = motion.joint_angles()[:, [motion.model.angle_columns.index(c) for c in columns]]
    true = truth["joint_angles"][:, [names.index(c) for c in columns]]
    return joint_angle_jump(motion.time, solved, true, columns)


@pytest.mark.parametrize("loss", [0.05, 0.2])
def test_random_packet_loss_does_not_make_joints_jump(capture: Capture, tmp_path: Path,
                                                      loss: float) -> None:
    imu = lose_rows(capture, tmp_path / "imu", loss, np.random.default_rng(7))
    jump, where = largest_jump(capture, imu)
    assert jump < 5.0, f"{jump:.1f} deg in one frame ({where})"


@pytest.mark.parametrize("causal", [False, True])
def test_a_foot_sensor_back_after_2_s_does_not_jump(capture: Capture, tmp_path: Path,
                                                    causal: bool) -> None:
    imu = lose_rows(capture, tmp_path / "imu", 0.0, np.random.default_rng(7), DROPOUT)
    jump, where = largest_jump(capture, imu, causal)
    assert jump < 5.0, f"{jump:.1f} deg in one frame ({where})"


def test_the_summary_lists_the_bridged_gaps(capture: Capture, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    imu = lose_rows(capture, tmp_path / "imu", 0.0, np.random.default_rng(7), DROPOUT)
    out = tmp_path / "result"
    assert cli(["solve", "--imu", str(imu), "--map", str(capture.sensor_map), "--body",
                str(capture.folder / "body.yaml"), "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    foot = summary["bridged"]["LeftFoot"]
    assert foot["samples"] == 120
    np.testing.assert_allclose(foot["gaps"], [[DROPOUT[1], DROPOUT[2]]], atol=1e-6)
    assert foot["longest_gap_s"] == pytest.approx(2.0)
    assert set(summary["bridged"]) == {"LeftFoot"}
    warning = [w for w in summary["warnings"] if w.startswith("LeftFoot")]
    assert warning and "2.00 s at 3.00-5.00 s" in warning[0]
    assert "LeftFoot" in capsys.readouterr().err
