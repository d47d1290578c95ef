"""evaluate --plot draws what was scored: same alignment, both sides, readers, readable axes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ikfusion.app.evaluate import evaluate
from ikfusion.cli import main
from ikfusion.ik import Motion
from ikfusion.mocap.model_motion import moved_configurations
from ikfusion.model import HumanModel
from ikfusion.paths import configs_dir
from ikfusion.results import write_result_folder
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.truth import write_truth
from ikfusion.uwb import load_constellation

pytest.importorskip("matplotlib", reason="plots need the plot extra (matplotlib)")

from matplotlib.image import imread  # noqa: E402

from ikfusion.app.evaluate_plot import (  # noqa: E402
    draw_joint_angles,
    draw_trajectory,
    trajectory_view,
)

ROOM = configs_dir() / "constellations" / "room_6x8.yaml"
OFFSET = np.array([0.8, -0.6, 0.0])  # the estimate's error: the whole body displaced [m]


@pytest.fixture(scope="module")
def model() -> HumanModel:
    return HumanModel.default()


def _capture(model, path: str, folder: Path, uwb_readers: Path | None = None):
    truth = generate_gait(model, GaitParameters(path=path, duration=3.0, stand=0.5), rate=30.0)
    truth.q[:, 0] += 2.0  # inside the room
    truth.q[:, 1] += 3.0
    truth_file = write_truth(folder / "truth.npz", truth)
    q = moved_configurations(truth.q, np.eye(3), OFFSET)
    n = len(truth.time)
    motion = Motion(truth.model, truth.time, q, truth.contact_names, truth.contacts,
                    np.zeros(n), np.ones(n, dtype=int), np.zeros(n, dtype=bool))
    result = write_result_folder(motion, folder / "result")
    if uwb_readers is not None:
        summary = json.loads((result / "summary.json").read_text())
        summary["uwb"] = {"used": True, "readers_file": str(uwb_readers)}
        (result / "summary.json").write_text(json.dumps(summary))
    return truth, truth_file, result


def _head_xy(truth) -> np.ndarray:
    from ikfusion.mocap.model_motion import site_positions

    return site_positions(truth.model, truth.q, ["HeadTop"])[:, 0, :2]


def _rms_xy(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def test_an_unaligned_score_is_plotted_unaligned(model, tmp_path):
    # Reported: the plot shifted every estimate onto the true start, "start aligned", even
    # when the metrics were not aligned. With --align none the offset must stay visible.
    truth, truth_file, result = _capture(model, "circle", tmp_path)
    scored = evaluate(result, truth_file, align="none")
    view = trajectory_view(result, truth_file, scored)
    np.testing.assert_allclose(view.truth_xy, _head_xy(truth), atol=1e-5)
    np.testing.assert_allclose(view.estimate_xy, _head_xy(truth) + OFFSET[:2], atol=1e-5)
    assert "not aligned" in view.label and "start aligned" not in view.label
    assert _rms_xy(view.estimate_xy, view.truth_xy) == pytest.approx(
        scored.head_position_rms_xy_m, rel=1e-6)
    fig = draw_trajectory(view)
    lines = fig.axes[0].lines
    np.testing.assert_allclose(np.column_stack(lines[1].get_data()), view.estimate_xy)
    assert lines[1].get_label() == view.label


def test_an_aligned_score_is_plotted_with_the_metrics_shift(model, tmp_path):
    truth, truth_file, result = _capture(model, "circle", tmp_path)
    scored = evaluate(result, truth_file)  # IMU only: aligned on the pelvis start
    assert scored.aligned_start
    view = trajectory_view(result, truth_file, scored)
    np.testing.assert_allclose(view.shift_xy, -OFFSET[:2], atol=1e-5)
    np.testing.assert_allclose(view.estimate_xy, view.truth_xy, atol=1e-5)
    assert "start aligned" in view.label
    assert _rms_xy(view.estimate_xy, view.truth_xy) == pytest.approx(
        scored.head_position_rms_xy_m, abs=1e-6)


def test_readers_and_area_from_the_summary_are_drawn(model, tmp_path):
    truth, truth_file, result = _capture(model, "circle", tmp_path, uwb_readers=ROOM)
    scored = evaluate(result, truth_file)  # used UWB: not aligned
    view = trajectory_view(result, truth_file, scored)
    room = load_constellation(ROOM)
    np.testing.assert_allclose(view.readers_xy, room.positions[:, :2])
    np.testing.assert_allclose(view.area, room.area)
    # Every reader, the area and both tracks lie inside the limits.
    for xy in (view.readers_xy, view.area, view.truth_xy, view.estimate_xy):
        assert np.all(xy[:, 0] > view.xlim[0]) and np.all(xy[:, 0] < view.xlim[1])
        assert np.all(xy[:, 1] > view.ylim[0]) and np.all(xy[:, 1] < view.ylim[1])
    fig = draw_trajectory(view)
    offsets = np.concatenate([c.get_offsets() for c in fig.axes[0].collections
                              if len(c.get_offsets()) == len(room.readers)])
    np.testing.assert_allclose(offsets, room.positions[:, :2])


def test_a_straight_walk_is_not_a_strip(model, tmp_path, capsys):
    # Reported: a straight walk drew as a thin unreadable strip. Through the command line, the
    # image keeps a shape within 3:1, on one scale in x and y.
    _, truth_file, result = _capture(model, "straight", tmp_path)
    out = tmp_path / "plots"
    assert main(["evaluate", str(result), str(truth_file), "--plot", str(out)]) == 0
    capsys.readouterr()
    height, width = imread(out / "trajectory.png").shape[:2]
    assert width / height < 3.6  # 3:1 box plus labels
    view = trajectory_view(result, truth_file, evaluate(result, truth_file))
    assert view.shape <= 3.0 + 1e-9
    span = np.ptp(view.truth_xy, axis=0)
    assert span[0] > 5 * span[1]  # the walk itself is long and thin


def test_joint_angles_show_both_sides(model, tmp_path):
    truth, truth_file, result = _capture(model, "circle", tmp_path)
    fig = draw_joint_angles(result, truth_file)
    names = list(truth.model.angle_columns)
    angles = truth.model.joint_angle_matrix(truth.q)
    titles = [ax.get_ylabel() for ax in fig.axes]
    for side in ("Left", "Right"):
        for joint in ("Hip", "Knee", "Ankle", "Shoulder"):
            name = f"j{side}{joint}_flex"
            ax = fig.axes[titles.index(f"{name} [deg]")]
            t, y = ax.lines[0].get_data()
            np.testing.assert_allclose(y, angles[:, names.index(name)], atol=1e-6)
