"""The compiled step's QP (ikfusion.ik.frame_problem) is the NumPy tasks' QP (issue #20).

The compiled build reads the step function's outputs in place, stacks the QP in one packed
buffer, reads the sites only when a task or a limit weighs them and finds the angles at gimbal
lock from the structural nonzeros of the range rows: each shortcut is checked here against the
plain NumPy build of the same step.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ikfusion.ik import Frame, Solver
from ikfusion.ik.frame_problem import build_frame_problem
from ikfusion.ik.limits.joint_range import LinearisedRanges
from ikfusion.ik.tasks import EvenChainTask
from ikfusion.model import SENSOR_SEGMENTS, Body, HumanModel
from ikfusion.rotations import random_rotations


def _problems(solver: Solver, q: np.ndarray, frame: Frame):
    """The compiled and the NumPy QP of the first step of ``frame`` at ``q`` (after a frame)."""
    solver.step(frame)  # a previous frame: damping, velocity bounds, chain share held
    targets = solver.targets.load(frame, None)
    conf, tasks, s = solver._configuration, solver.tasks, solver.settings
    tasks.damping.set_reference(solver._last.q)
    tasks.velocity.set_previous(solver._last.q, 1 / 60)
    active = solver._base_tasks(frame)
    conf.update(q)
    fast = build_frame_problem(conf, tasks, active, targets.row_weights, solver.compiled,
                               s.levenberg_marquardt)
    fast_qp = {n: getattr(fast.qp, n).copy() for n in ("H", "c", "G", "h", "A", "b")}
    plain = build_frame_problem(conf, tasks, active, targets.row_weights, None,
                                s.levenberg_marquardt)
    return fast, fast_qp, plain


@pytest.mark.parametrize("contacts", [False, True])
def test_the_compiled_qp_is_the_numpy_qp_near_many_limits(human: HumanModel, contacts: bool,
                                                          rng: np.random.Generator) -> None:
    solver = Solver(human, contacts=contacts)
    assert solver.compiled is not None
    q = human.neutral()
    for joint in human.ball_joints.values():  # turned far: many angles near or past a limit
        q[joint.idx_q:joint.idx_q + 4] = pin.Quaternion(random_rotations(1, rng)[0]).coeffs()
    frame = Frame(0.0, dict(zip(SENSOR_SEGMENTS, random_rotations(len(SENSOR_SEGMENTS), rng))))
    fast, fast_qp, plain = _problems(solver, q, frame)
    up, down = fast.rows.up, fast.rows.down
    assert up.sum() + down.sum() >= 10  # the rows stacked from both limits
    np.testing.assert_array_equal(up, plain.rows.up)
    np.testing.assert_array_equal(down, plain.rows.down)
    scale = np.abs(plain.qp.H).max()
    np.testing.assert_allclose(fast_qp["H"], plain.qp.H, atol=1e-9 * scale)
    np.testing.assert_allclose(fast_qp["c"], plain.qp.c, atol=1e-9 * scale)
    for name in ("G", "h", "A", "b"):
        np.testing.assert_allclose(fast_qp[name], getattr(plain.qp, name), atol=1e-8,
                                   err_msg=name)
    assert fast.qp.packed is not None and np.shares_memory(fast.qp.G, fast.qp.packed)


def test_angles_at_gimbal_lock_are_found_from_the_rows_nonzeros() -> None:
    """The shoulder of test_compiled's gimbal-lock case: its first and third angles have no
    rate, and the compiled build gives them endless room as the search of G's rows does."""
    human = HumanModel.from_body(Body(ranges=(("jRightShoulder", "rot", -90.0, 90.0),)))
    solver = Solver(human, contacts=False)
    q = human.configuration({"jRightShoulder_flex": 170.0, "jRightShoulder_rot": 90.0,
                             "jRightShoulder_abd": -23.0})
    frame = Frame(0.0, {s: np.eye(3) for s in SENSOR_SEGMENTS})
    fast, _, _ = _problems(solver, q, frame)
    ranges = fast.rows.ranges
    n = list(human.ball_joints).index("jRightShoulder")
    searched = LinearisedRanges(ranges.G, ranges.rooms.copy()).without_still_angles()
    assert np.isinf(ranges.room_up[[3 * n, 3 * n + 2]]).all()
    np.testing.assert_array_equal(ranges.room_up, searched.room_up)
    np.testing.assert_array_equal(ranges.room_down, searched.room_down)


def test_chain_row_weights_follow_the_tracked_segments_and_the_weight(
        human: HumanModel) -> None:
    segments = human.segment_names
    task = EvenChainTask(human.ball_joints, [["jL5S1", "jL4L3", "jL1T12", "jT9T8"]], 2.0,
                         segments)
    assert task.row_weights().tolist() == [2.0] * 9
    tracked = np.zeros(len(segments), dtype=bool)
    tracked[task.shared[1]] = True
    task.set_tracked(tracked)
    assert task.row_weights().tolist() == [2.0] * 3 + [0.0] * 3 + [2.0] * 3
    task.weight = 0.5
    assert task.row_weights().tolist() == [0.5] * 3 + [0.0] * 3 + [0.5] * 3
    task.active = np.ones(3, dtype=bool)
    assert task.row_weights().tolist() == [0.5] * 9
