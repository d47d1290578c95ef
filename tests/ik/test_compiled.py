"""The compiled step function equals the NumPy tasks and Pinocchio's kinematics."""

from __future__ import annotations

import numpy as np
import pytest
from motions import smooth_motion

from ikfusion.ik import Configuration, Frame, Solver
from ikfusion.ik.compiled import CompiledKinematics
from ikfusion.ik.limits import JointRangeLimit
from ikfusion.ik.tasks import OrientationTask, PostureTask
from ikfusion.model import SENSOR_SEGMENTS, Body, HumanModel
from ikfusion.rotations import random_rotations


@pytest.mark.parametrize("height", [1.55, 1.95])
def test_compiled_residuals_equal_reference(rng, height: float) -> None:
    model = HumanModel.from_body(Body.from_height(height))
    segments = list(SENSOR_SEGMENTS)
    frames = [model.segment_frame_id(s) for s in segments]
    sites = [model.site_frame_id(s) for s in model.site_names]
    kin = CompiledKinematics(model.model, frames, list(model.ball_joints.values()), sites)
    geometry = kin.geometry(model.model)
    orientation = OrientationTask(frames, segments)
    posture = PostureTask.from_joints(model.ball_joints, {}, 1.0)
    limits = JointRangeLimit(model.ball_joints)
    for _ in range(5):
        q = model.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
        T = random_rotations(len(segments), rng)
        orientation.set_targets(T, np.ones(len(segments)))
        conf = Configuration(model.model, q)
        w_or = rng.uniform(0.0, 2.0, 3 * len(segments))
        w_post = rng.uniform(0.0, 2.0, 3 * len(model.ball_joints))
        H, c, e_or, angles, E_inv, p, J = kin(q, T, geometry, w_or, w_post)
        np.testing.assert_allclose(e_or[:, 0], orientation.compute_error(conf), atol=1e-10)
        J_or = orientation.compute_jacobian(conf)
        J_post = posture.compute_jacobian(conf)
        e_post = posture.compute_error(conf)
        H_ref = J_or.T @ (w_or[:, None] * J_or) + J_post.T @ (w_post[:, None] * J_post)
        c_ref = J_or.T @ (w_or * e_or[:, 0]) + J_post.T @ (w_post * e_post)
        np.testing.assert_allclose(H, H_ref, atol=1e-9)
        np.testing.assert_allclose(c[:, 0], c_ref, atol=1e-9)
        a = limits.angles(q)
        np.testing.assert_allclose(angles.reshape(-1, 3), a, atol=1e-10)
        np.testing.assert_allclose(E_inv.reshape(-1, 3, 3), limits.rate_matrices(a), atol=1e-9)
        np.testing.assert_allclose(p.reshape(-1, 3), conf.positions(sites), atol=1e-12)
        np.testing.assert_allclose(J.reshape(-1, 3, model.model.nv), conf.linear_jacobians(sites),
                                   atol=1e-12)


def test_compiled_and_reference_solvers_agree(human: HumanModel, rng) -> None:
    qs = smooth_motion(human, rng, frames=30)
    data = human.model.createData()
    import pinocchio as pin

    frames = []
    for k, q in enumerate(qs):
        pin.framesForwardKinematics(human.model, data, q)
        frames.append(Frame(k / 60, {s: data.oMf[human.segment_frame_id(s)].rotation.copy()
                                     for s in SENSOR_SEGMENTS}))
    fast = Solver(human, contacts=False).solve(frames)
    reference = Solver(human, contacts=False, compiled=False).solve(frames)
    np.testing.assert_allclose(fast.q, reference.q, atol=1e-7)


def test_compiled_sensed_pose_equals_numpy(human: HumanModel, rng) -> None:
    """The sensed pose and its contact points: the compiled function and the NumPy version."""
    solver = Solver(human)
    assert solver._kinematics is not None and solver._kinematics.sensed_function is not None
    n = len(human.segment_names)
    for trial in range(6):
        q = human.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
        T = random_rotations(n, rng)
        tracked = rng.random(n) < (0.3, 0.6, 0.9, 1.0, 1.0, 1.0)[trial]
        solver.orientation_task.set_targets(T, tracked.astype(float))
        q_sensed, p_sensed = solver._sensed_pose(q, tracked)
        np.testing.assert_allclose(q_sensed, solver._sensed_configuration(q, tracked, False),
                                   atol=1e-10)
        np.testing.assert_allclose(
            p_sensed, solver._contact_positions(solver._sensed_configuration(q, tracked)),
            atol=1e-10)
