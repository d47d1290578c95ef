"""Every task's Jacobian and the joint-range rate matrices against finite differences on the
configuration manifold (pin.integrate), at random configurations."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ikfusion.ik import Configuration
from ikfusion.ik.limits import JointRangeLimit
from ikfusion.ik.tasks import EvenChainTask, OrientationTask, PositionTask, PostureTask
from ikfusion.model import HumanModel
from ikfusion.rotations import random_rotations


def numeric_jacobian(model: HumanModel, task, q: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    nv = model.model.nv
    conf = Configuration(model.model, q)
    e0 = task.compute_error(conf)
    J = np.zeros((e0.size, nv))
    for k in range(nv):
        dq = np.zeros(nv)
        dq[k] = eps
        conf.update(pin.integrate(model.model, q, dq))
        ep = task.compute_error(conf)
        dq[k] = -eps
        conf.update(pin.integrate(model.model, q, dq))
        em = task.compute_error(conf)
        J[:, k] = (ep - em) / (2 * eps)
    return J


def make_tasks(model: HumanModel, rng: np.random.Generator):
    segments = ["Pelvis", "T8", "RightForeArm", "LeftLowerLeg", "Head"]
    orientation = OrientationTask([model.segment_frame_id(s) for s in segments], segments)
    orientation.set_targets(random_rotations(len(segments), rng), np.ones(len(segments)))
    sites = ["HeadTop", "LeftHeel", "RightHand"]
    position = PositionTask([model.site_frame_id(s) for s in sites], sites)
    position.set_targets(rng.normal(size=(3, 3)), np.ones(3))
    posture = PostureTask.from_joints(model.ball_joints, {}, 1.0)
    chain = EvenChainTask(model.ball_joints, [["jL5S1", "jL4L3", "jL1T12", "jT9T8"],
                                              ["jT1C7", "jC1Head"]], 1.0, model.segment_names)
    return {"orientation": orientation, "position": position, "posture": posture,
            "even_chain": chain}


@pytest.mark.parametrize("name", ["orientation", "position", "posture", "even_chain"])
def test_task_jacobians_match_finite_differences(human: HumanModel, rng, name: str) -> None:
    for _ in range(4):
        task = make_tasks(human, rng)[name]
        q = human.random_configuration(rng, margin_deg=10.0, p_world_pelvis=rng.normal(size=3))
        J = task.compute_jacobian(Configuration(human.model, q))
        Jn = numeric_jacobian(human, task, q)
        # Rotation errors far from the target: keep them below ~2 rad where log is smooth.
        np.testing.assert_allclose(J, Jn, atol=2e-5)


def test_objective_is_gauss_newton_of_the_task(human: HumanModel, rng) -> None:
    task = make_tasks(human, rng)["orientation"]
    conf = Configuration(human.model, human.random_configuration(rng))
    H, c = task.objective(conf)
    J, e = task.compute_jacobian(conf), task.compute_error(conf)
    w = task.row_weights()
    np.testing.assert_allclose(H, J.T @ (w[:, None] * J), atol=1e-12)
    np.testing.assert_allclose(c, J.T @ (w * e), atol=1e-12)


def test_joint_range_rates_match_finite_differences(human: HumanModel, rng) -> None:
    limits = JointRangeLimit(human.ball_joints, margin_deg=25.0)
    nv = human.model.nv
    for _ in range(5):
        q = human.random_configuration(rng, margin_deg=5.0)
        Einv = limits.rate_matrices(limits.angles(q))
        for n, joint in enumerate(human.ball_joints.values()):
            for k in range(3):
                dq = np.zeros(nv)
                dq[joint.idx_v + k] = 1e-6
                plus = limits.angles(pin.integrate(human.model, q, dq))[n]
                minus = limits.angles(pin.integrate(human.model, q, -dq))[n]
                np.testing.assert_allclose(Einv[n][:, k], (plus - minus) / 2e-6, atol=1e-5)


def test_joint_range_angles_equal_model_angles(human: HumanModel, rng) -> None:
    limits = JointRangeLimit(human.ball_joints, margin_deg=25.0)
    q = human.random_configuration(rng)
    angles = human.joint_angles(q)
    ours = np.degrees(limits.angles(q))
    for n, joint in enumerate(human.ball_joints.values()):
        for k, a in enumerate(joint.spec.angles):
            assert ours[n, k] == pytest.approx(angles[joint.spec.column(a.name)], abs=1e-9)
