"""The evaluator: zero error against itself, known errors when the estimate is perturbed."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ikfusion.app.evaluate import drift_percent, evaluate
from ikfusion.cli import main
from ikfusion.errors import InputError
from ikfusion.ik import Motion
from ikfusion.mocap.model_motion import site_positions
from ikfusion.model import HumanModel
from ikfusion.results import write_result_folder
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.truth import write_truth


@pytest.fixture(scope="module")
def walk():
    model = HumanModel.default()
    return generate_gait(model, GaitParameters(duration=3.0, stand=0.5), rate=60.0)


def result_of(truth, q: np.ndarray, folder: Path) -> Path:
    n = len(truth.time)
    motion = Motion(truth.model, truth.time, q, truth.contact_names, truth.contacts,
                    np.zeros(n), np.ones(n, dtype=int), np.zeros(n, dtype=bool))
    return write_result_folder(motion, folder)


def test_truth_against_itself_is_exact(walk, tmp_path: Path) -> None:
    truth_file = write_truth(tmp_path / "truth.npz", walk)
    result = result_of(walk, walk.q, tmp_path / "result")
    e = evaluate(result, truth_file)
    assert e.frames == len(walk.time)
    assert e.joint_angle_rms_deg < 1e-3
    assert e.segment_orientation_rms_deg < 1e-3
    assert e.head_position_rms_m < 1e-5
    assert e.foot_slide_max_mm < 0.1
    assert e.truth_slide_mm == pytest.approx(e.foot_slide_mm, abs=1e-3)  # CSV: 1 um
    assert e.held_slide_max_mm < 0.1
    assert e.contact_agreement_pct == pytest.approx(100.0)
    assert e.joint_angle_jump_max_deg < 1e-3


def test_a_pop_is_measured_where_it_happens(walk, tmp_path: Path) -> None:
    """A knee that jumps by 2 deg at one frame and stays there: one 2 deg jump, at that frame;
    a constant error is no jump at all."""
    truth_file = write_truth(tmp_path / "truth.npz", walk)
    joint = walk.model.ball_joints["jRightKnee"]
    k = len(walk.time) // 2
    q = walk.q.copy()
    # turn the knee by 2 deg about its flexion axis from frame k on (x, y, z, w quaternion)
    flex = joint.spec.angles[0]
    axis = np.eye(3)["xyz".index(flex.axis)] * flex.sign
    half = np.radians(1.0)
    turn = pin.Quaternion(np.cos(half), *(np.sin(half) * axis))
    for i in range(k, len(q)):
        x, y, z, w = q[i, joint.idx_q:joint.idx_q + 4]
        turned = pin.Quaternion(w, x, y, z) * turn
        q[i, joint.idx_q:joint.idx_q + 4] = [turned.x, turned.y, turned.z, turned.w]
    e = evaluate(result_of(walk, q, tmp_path / "pop"), truth_file)
    assert e.joint_angle_jump_max_deg == pytest.approx(2.0, abs=0.05)
    assert e.joint_angle_jump_at == f"jRightKnee_flex at {walk.time[k]:.2f} s"


def test_known_offsets_are_measured(walk, tmp_path: Path) -> None:
    truth_file = write_truth(tmp_path / "truth.npz", walk)
    q = walk.q.copy()
    q[:, :3] += [0.0, 0.0, 0.05]  # 5 cm up, everything else exact
    e = evaluate(result_of(walk, q, tmp_path / "up"), truth_file)
    assert e.head_position_rms_m == pytest.approx(0.05, abs=1e-4)
    assert e.head_position_rms_xy_m < 1e-4
    q = walk.q.copy()
    q[:, 0] += 0.3  # a constant horizontal offset is removed by the start alignment ...
    assert evaluate(result_of(walk, q, tmp_path / "x"), truth_file).head_position_rms_m < 1e-4
    # ... but not when asked to compare as it is
    e = evaluate(tmp_path / "x", truth_file, align="none")
    assert e.head_position_rms_xy_m == pytest.approx(0.3, abs=1e-4)


def test_cli_json_and_bad_input(walk, tmp_path: Path, capsys) -> None:
    truth_file = write_truth(tmp_path / "truth.npz", walk)
    result = result_of(walk, walk.q, tmp_path / "result")
    assert main(["evaluate", str(result), str(truth_file), "--json"]) == 0
    metrics = json.loads(capsys.readouterr().out)
    for key in ("frames", "joint_angle_rms_deg", "segment_orientation_rms_deg",
                "head_position_rms_m", "head_position_rms_xy_m", "foot_slide_mm",
                "foot_slide_max_mm", "joint_angle_jump_max_deg", "held_slide_mm",
                "held_slide_max_mm", "contact_agreement_pct", "contact_missed_pct",
                "truth_slide_mm", "held_truth_slide_mm"):
        assert key in metrics
    (result / "sites.csv").write_text("time,site,x,y,z\n0.0,HeadTop,1,2,oops\n")
    assert main(["evaluate", str(result), str(truth_file)]) == 2
    err = capsys.readouterr().err
    assert "sites.csv" in err and "line 2" in err and "'z'" in err
    with pytest.raises(InputError):
        evaluate(tmp_path / "nowhere", truth_file)


def test_plots_are_written(walk, tmp_path: Path, capsys) -> None:
    pytest.importorskip("matplotlib", reason="plots need the plot extra (matplotlib)")
    truth_file = write_truth(tmp_path / "truth.npz", walk)
    result = result_of(walk, walk.q, tmp_path / "result")
    assert main(["evaluate", str(result), str(truth_file), "--plot", str(tmp_path / "p")]) == 0
    for name in ("trajectory.png", "joint_angles.png"):
        data = (tmp_path / "p" / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


@pytest.mark.parametrize("damage", ["truncate", "junk", "empty", "nan_time", "short_array"])
def test_a_damaged_truth_file_is_bad_input(walk, tmp_path: Path, capsys, damage: str) -> None:
    truth_file = write_truth(tmp_path / "truth.npz", walk)
    result = result_of(walk, walk.q, tmp_path / "result")
    data = truth_file.read_bytes()
    if damage == "truncate":
        truth_file.write_bytes(data[: len(data) // 2])
    elif damage == "junk":
        truth_file.write_bytes(b"junk" + data[4:])
    elif damage == "empty":
        truth_file.write_bytes(b"")
    else:
        with np.load(truth_file) as npz:
            arrays = {k: npz[k] for k in npz.files}
        if damage == "nan_time":
            arrays["time"][3] = np.nan
        else:
            arrays["joint_angles"] = arrays["joint_angles"][:-5]
        np.savez(truth_file, **arrays)
    assert main(["evaluate", str(result), str(truth_file)]) == 2
    err = capsys.readouterr().err
    assert "truth.npz" in err and "Traceback" not in err


def test_angles_through_the_euler_singularity_compare_like_with_like(walk,
                                                                      tmp_path: Path) -> None:
    """The right arm's axial rotation (the middle Euler angle of the shoulder) sweeps through
    90 deg and the solve reads it 1 deg low: a 1 deg error in that angle, no error elsewhere and
    no jump, although the two sides' principal Euler triples lie on different branches (180 deg
    apart in flexion and abduction) in the frames between 89 and 91 deg."""
    model = walk.model
    n = len(walk.time)
    rot = 90.0 - 30.0 * np.cos(np.linspace(0.0, 4.0 * np.pi, n))
    joint = model.ball_joints["jRightShoulder"]
    truth_q, est_q = walk.q.copy(), walk.q.copy()
    for k in range(n):
        for q, r in ((truth_q, rot[k]), (est_q, rot[k] - 1.0)):
            a = {"flex": 40.0, "rot": r, "abd": 25.0}
            R = joint.spec.rotation(np.radians([a[s.name] for s in joint.spec.angles]))
            q[k, joint.idx_q:joint.idx_q + 4] = pin.Quaternion(R).coeffs()
    truth = replace(walk, q=truth_q)
    truth_file = write_truth(tmp_path / "truth.npz", truth)
    e = evaluate(result_of(truth, est_q, tmp_path / "result"), truth_file)
    assert e.per_joint_rms_deg["jRightShoulder_flex"] < 1e-3
    assert e.per_joint_rms_deg["jRightShoulder_abd"] < 1e-3
    assert e.per_joint_rms_deg["jRightShoulder_rot"] == pytest.approx(1.0, abs=1e-3)
    assert e.joint_angle_jump_max_deg < 1e-3


def test_drift_is_the_end_error_over_the_distance_walked() -> None:
    """10 m straight at 1 m/s with a 3 cm sway at 1 Hz (not distance) and the estimate 5 cm to
    the side: 0.5 %; standing still has no meaningful ratio."""
    t = np.arange(0.0, 10.0 + 1e-9, 0.01)
    true = np.stack([t, 0.03 * np.sin(2 * np.pi * t), np.full_like(t, 1.0)], axis=1)
    est = true + [0.0, 0.05, 0.0]
    assert drift_percent(t, est, true) == pytest.approx(0.5, rel=0.02)
    still = np.zeros_like(true)
    assert drift_percent(t, still + [0.0, 0.05, 0.0], still) is None


def test_drift_of_a_result(walk, tmp_path: Path) -> None:
    truth_file = write_truth(tmp_path / "truth.npz", walk)
    assert evaluate(result_of(walk, walk.q, tmp_path / "exact"), truth_file).drift_percent == (
        pytest.approx(0.0, abs=1e-3))
    q = walk.q.copy()
    ramp = np.linspace(0.0, 0.2, len(q))
    q[:, 1] += ramp  # the root drifts 20 cm sideways by the end
    e = evaluate(result_of(walk, q, tmp_path / "drift"), truth_file)
    ticks = np.append(np.arange(walk.time[0], walk.time[-1], 1.0), walk.time[-1])
    track = np.stack([np.interp(ticks, walk.time, walk.q[:, k]) for k in range(2)], axis=1)
    walked = np.sum(np.linalg.norm(np.diff(track, axis=0), axis=1))
    last = walk.time >= walk.time[-1] - 1.0
    assert e.drift_percent == pytest.approx(100.0 * ramp[last].mean() / walked, rel=1e-3)


def result_with_contacts(truth, q: np.ndarray, contacts: np.ndarray, folder: Path) -> Path:
    n = len(truth.time)
    motion = Motion(truth.model, truth.time, q, truth.contact_names, contacts,
                    np.zeros(n), np.ones(n, dtype=int), np.zeros(n, dtype=bool))
    return write_result_folder(motion, folder)


def test_held_slide_and_detection_misses_are_told_apart(walk, tmp_path: Path) -> None:
    """Issue #19: the slide of the points the solver holds is measured over the solver's contact
    phases, apart from the truth's planted samples the solver released (detection misses)."""
    truth_file = write_truth(tmp_path / "truth.npz", walk)
    planted = np.asarray(walk.contacts, dtype=bool)
    # exact poses, the solver releases everything: nothing held slides, every plant is missed
    e = evaluate(result_with_contacts(walk, walk.q, np.zeros_like(planted), tmp_path / "off"),
                 truth_file)
    assert e.held_slide_max_mm == 0.0
    assert e.contact_missed_pct == pytest.approx(100.0)
    assert e.contact_agreement_pct == pytest.approx(100.0 * (1.0 - planted.mean()), abs=1e-6)
    # the body drifts at 0.1 m/s along x; the solver holds one phase of one point only
    speed = 0.1  # [m/s]
    q = walk.q.copy()
    q[:, 0] += speed * (walk.time - walk.time[0])
    column = planted[:, 0]
    start = int(np.argmax(column))
    end = start + int(np.argmin(column[start:])) if not column[start:].all() else len(column)
    held = np.zeros_like(planted)
    held[start:end, 0] = True
    e = evaluate(result_with_contacts(walk, q, held, tmp_path / "drift"), truth_file, align="none")
    held_for = walk.time[end - 1] - walk.time[start]
    assert e.held_slide_max_mm == pytest.approx(1e3 * speed * held_for, rel=1e-3)
    assert e.held_slide_mm == pytest.approx(e.held_slide_max_mm)
    # the truth's phases all drift (the old metric), most of them never held by the solver
    assert e.foot_slide_max_mm >= e.held_slide_max_mm
    assert 0.0 < e.contact_missed_pct < 100.0
    assert e.truth_slide_mm < 0.1  # the truth's own points do not drift
    assert e.held_truth_slide_mm < 0.1  # ... nor while the solver holds them
    # holding the point past the truth's phase (the foot is in swing): a false hold, measured
    late = held.copy()
    late[end:min(end + 12, len(late)), 0] = True
    e = evaluate(result_with_contacts(walk, walk.q, late, tmp_path / "late"), truth_file)
    P = site_positions(walk.model, walk.q, [walk.contact_names[0]])[:, 0, :2]
    stop = min(end + 12, len(late))
    moved = np.max(np.linalg.norm(P[start:stop] - P[start], axis=1))
    assert e.held_truth_slide_mm == pytest.approx(1e3 * moved, abs=0.01)
    assert e.held_truth_slide_mm > 1.0


def test_slide_beyond_the_truths_is_the_skating_a_solve_adds(walk, tmp_path: Path) -> None:
    """Issue #19: a solve that holds its points still while the true points slide in the truth's
    loose phases adds no skating; a solve that slides where the truth stands adds all of it."""
    speed = 0.1  # [m/s] along x
    drifting = walk.q.copy()
    drifting[:, 0] += speed * (walk.time - walk.time[0])
    # the truth slides in its phases, the estimate holds its points still
    truth_file = write_truth(tmp_path / "sliding_truth.npz", replace(walk, q=drifting))
    e = evaluate(result_of(walk, walk.q, tmp_path / "still"), truth_file)
    assert e.truth_slide_mm > 10.0 and e.foot_slide_mm < 0.1
    assert e.foot_slide_excess_mm is not None and e.foot_slide_excess_mm < 0.01
    # the truth stands in its phases, the estimate slides: every millimetre is the solve's
    truth_file = write_truth(tmp_path / "truth.npz", walk)
    e = evaluate(result_of(walk, drifting, tmp_path / "sliding"), truth_file)
    assert e.truth_slide_mm < 0.1 and e.foot_slide_mm > 10.0
    assert e.foot_slide_excess_mm == pytest.approx(e.foot_slide_mm, abs=0.1)
    # the walk's points lie on the floor: the excess on the floor is the same
    assert e.foot_slide_excess_on_floor_mm == pytest.approx(e.foot_slide_excess_mm)


def test_a_flip_is_the_largest_turn_of_a_joint_in_one_frame(walk, tmp_path: Path) -> None:
    """The estimate's own fastest joint, whatever the truth does: the exact walk's is the walk's
    (its joints' quaternions, frame to frame); a still pose whose knee turns by 30 deg from one
    frame to the next (a flip the truth does not have) turns 30 deg."""
    truth_file = write_truth(tmp_path / "truth.npz", walk)
    exact = evaluate(result_of(walk, walk.q, tmp_path / "exact"), truth_file)
    turns = [np.degrees(2.0 * np.arccos(np.clip(np.abs(np.sum(
        walk.q[1:, j.idx_q:j.idx_q + 4] * walk.q[:-1, j.idx_q:j.idx_q + 4], axis=1)), 0.0, 1.0)))
        for name, j in walk.model.ball_joints.items() if "BallFoot" not in name]
    assert exact.joint_angle_step_max_deg == pytest.approx(np.max(turns), abs=0.05)
    joint = walk.model.ball_joints["jRightKnee"]
    flex = joint.spec.angles[0]
    axis = np.eye(3)["xyz".index(flex.axis)] * flex.sign
    half = np.radians(15.0)
    turned = pin.Quaternion(np.cos(half), *(np.sin(half) * axis))
    q = np.repeat(walk.q[:1], len(walk.q), axis=0)
    k = len(q) // 2
    x, y, z, w = q[0, joint.idx_q:joint.idx_q + 4]
    flipped = pin.Quaternion(w, x, y, z) * turned
    q[k:, joint.idx_q:joint.idx_q + 4] = [flipped.x, flipped.y, flipped.z, flipped.w]
    e = evaluate(result_of(walk, q, tmp_path / "flip"), truth_file)
    assert e.joint_angle_step_max_deg == pytest.approx(30.0, abs=0.05)
