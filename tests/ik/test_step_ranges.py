"""The projection's range rows from the step function equal the NumPy linearisation."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ikfusion.ik import Configuration, Solver
from ikfusion.ik.step_ranges import StepRangeRows
from ikfusion.model import HumanModel
from ikfusion.rotations import random_rotations


def test_step_range_rows_equal_numpy_rows(human: HumanModel, rng) -> None:
    """At poses near and beyond the limits, the same rows (to rounding) as the NumPy twin.

    Every ball joint is turned at random (many angles beyond a limit, some joints near gimbal
    lock), so the rows near a limit are many; the soft wall is idle (a new solver).
    """
    solver = Solver(human)
    assert solver.compiled is not None, "the compiled step function is needed here"
    tasks = solver.tasks
    rows = StepRangeRows(solver.compiled.kinematics, solver.compiled.geometry,
                         solver.compiled.rate_rows, tasks.joint_range,
                         len(tasks.orientation.frame_ids))
    model = human.model
    compared = 0
    for scale in (0.2, 0.6, 1.5):
        q = pin.integrate(model, human.neutral(), rng.normal(0.0, scale, model.nv))
        conf = Configuration(model, q)
        expected = tasks.joint_range.inequality(conf)
        got = rows.inequality(conf)
        assert got.G.shape == expected.G.shape
        np.testing.assert_allclose(got.G, expected.G, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(got.h, expected.h, rtol=0.0, atol=1e-9)
        compared += len(expected.h)
    assert compared > 10  # the comparison saw rows


def test_step_range_rows_at_sensed_rotations(human: HumanModel, rng) -> None:
    """Joints turned to uniformly random rotations (any Euler branch) give the same rows."""
    solver = Solver(human)
    assert solver.compiled is not None
    tasks = solver.tasks
    rows = StepRangeRows(solver.compiled.kinematics, solver.compiled.geometry,
                         solver.compiled.rate_rows, tasks.joint_range,
                         len(tasks.orientation.frame_ids))
    q = human.neutral().copy()
    for joint in human.ball_joints.values():
        quat = pin.Quaternion(random_rotations(1, rng)[0])
        q[joint.idx_q:joint.idx_q + 4] = quat.coeffs()
    conf = Configuration(human.model, q)
    expected = tasks.joint_range.inequality(conf)
    got = rows.inequality(conf)
    assert got.G.shape == expected.G.shape
    assert len(expected.h) > 10  # most random rotations lie beyond some limit
    np.testing.assert_allclose(got.G, expected.G, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got.h, expected.h, rtol=0.0, atol=1e-9)
