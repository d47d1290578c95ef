"""The compiled retargeting step against the NumPy tasks, Pinocchio and finite differences."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from ikfusion.ik.configuration import Configuration
from ikfusion.ik.settings import SolverSettings
from ikfusion.paths import robots_dir
from ikfusion.retarget import load_source
from ikfusion.retarget import robot as robot_module
from ikfusion.retarget.capsules import CapsulePairs, closest_points, closest_points_sx
from ikfusion.retarget.compiled_step import CompiledConfiguration
from ikfusion.retarget.robot import RobotRetargeter
from ikfusion.retarget.robot_config import load_retarget_config
from ikfusion.retarget.robot_model import RobotModel
from ikfusion.retarget.source import HumanMotion


@pytest.fixture
def no_compile(monkeypatch: pytest.MonkeyPatch) -> None:
    """CasADi's virtual machine: the same function without a C compile in the test."""
    monkeypatch.setenv("IKFUSION_NO_COMPILE", "1")


def test_closest_points_graph_is_the_numpy_one() -> None:
    rng = np.random.default_rng(3)
    a1, b1, a2, b2 = (rng.normal(size=(60, 3)) for _ in range(4))
    b2[:10] = a2[:10] + 1e-3 * (b1[:10] - a1[:10])  # nearly parallel and short
    b1[10:20] = a1[10:20]                           # a point against a segment
    x = [ca.SX.sym(n, 3) for n in ("a1", "b1", "a2", "b2")]
    f = ca.Function("closest", x, list(closest_points_sx(*x)))
    p, q = closest_points(a1, b1, a2, b2)
    for k in range(len(a1)):
        pk, qk = f(a1[k], b1[k], a2[k], b2[k])
        np.testing.assert_allclose(np.asarray(pk).ravel(), p[k], atol=1e-12)
        np.testing.assert_allclose(np.asarray(qk).ravel(), q[k], atol=1e-12)


def _retargeter(config_file: Path) -> RobotRetargeter:
    config = load_retarget_config(robots_dir() / "human.urdf", config_file)
    return RobotRetargeter(RobotModel(config), SolverSettings.load().qp)


def test_step_outputs_match_numpy_and_pinocchio(human_as_robot: Path, no_compile: None) -> None:
    rt = _retargeter(human_as_robot)
    robot = rt.robot
    rt.position_task = robot_module.PositionTask([robot.frame_ids["Pelvis"]], ["Pelvis"])
    conf, warnings = rt._step_configuration()
    assert isinstance(conf, CompiledConfiguration) and warnings == []
    plain = Configuration(robot.model, robot.rest)
    reference = CapsulePairs(robot.config.capsules, robot.config.collision_pairs,
                             robot.frame_ids, activation=np.inf)
    rng = np.random.default_rng(5)
    for _ in range(3):
        q = pin.randomConfiguration(robot.model, -np.ones(robot.model.nq),
                                    np.ones(robot.model.nq))
        q[:3] = rng.normal(size=3)
        R = np.array([pin.exp3(rng.normal(size=3)) for _ in rt.segments])
        rt.orientation_task.set_targets(R, rng.uniform(0.5, 2.0, len(rt.segments)))
        rt.flat_task.set_targets(np.array([pin.exp3(rng.normal(size=3)) for _ in range(2)]),
                                 [1.0, 0.0])
        rt.position_task.set_targets(rng.normal(size=(1, 3)), [3.0])
        conf.update(q)
        plain.update(q)
        H, c = conf.tracking_objective()
        H_ref, c_ref = np.zeros_like(H), np.zeros_like(c)
        for task in (rt.orientation_task, rt.flat_task, rt.position_task):
            task.add_objective(plain, H_ref, c_ref)
        np.testing.assert_allclose(H, H_ref, atol=1e-9 * np.abs(H_ref).max())
        np.testing.assert_allclose(c, c_ref, atol=1e-9 * np.abs(c_ref).max())
        for fid in rt._foot_ids:
            np.testing.assert_allclose(conf.placement(fid).homogeneous,
                                       plain.placement(fid).homogeneous, atol=1e-12)
            np.testing.assert_allclose(conf.jacobian(fid), plain.jacobian(fid), atol=1e-12)
        distances = conf.capsule_distances()
        rows = conf.capsule_rows(range(len(rt.capsules.pairs)))
        assert distances is not None and rows is not None
        np.testing.assert_allclose(distances, reference._witnesses(plain)[2], atol=1e-12)
        np.testing.assert_allclose(rows, reference.inequality(plain).G, atol=1e-12)
        z, Jz = conf.sole_corners()
        corners = np.concatenate([f.corners @ plain.placement(fid).rotation.T
                                  + plain.placement(fid).translation
                                  for f, fid in zip(rt.feet, rt._foot_ids)])
        np.testing.assert_allclose(z, corners[:, 2], atol=1e-12)
        for i in range(robot.model.nv):  # heights' Jacobian by finite differences
            step = np.zeros(robot.model.nv)
            step[i] = 1e-7
            moved = Configuration(robot.model, pin.integrate(robot.model, q, step))
            z_moved = np.concatenate([f.corners @ moved.placement(fid).rotation.T
                                      + moved.placement(fid).translation
                                      for f, fid in zip(rt.feet, rt._foot_ids)])[:, 2]
            np.testing.assert_allclose(Jz[:, i], (z_moved - z) / 1e-7, atol=2e-6)


def test_a_walk_is_the_same_with_and_without_the_compiled_step(
        human_as_robot: Path, shared_data: Path, no_compile: None,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Robots whose joints the graph does not cover solve with NumPy: the same motion."""
    walk = load_source(shared_data / "mocap" / "sfu_0005_Walking001.bvh")
    n = min(len(walk), 120)
    source = HumanMotion(walk.time[:n], walk.segments, walk.p_world_segment[:n],
                         walk.R_world_segment[:n], walk.contact_names, walk.contacts[:n],
                         walk.hip_height, walk.source)
    compiled = _retargeter(human_as_robot).solve(source)

    def uncovered(*args: object, **kwargs: object) -> None:
        raise NotImplementedError("joint type not compiled")

    monkeypatch.setattr(robot_module, "robot_step", uncovered)
    plain_rt = _retargeter(human_as_robot)
    plain = plain_rt.solve(source)
    assert not isinstance(plain_rt._configuration, CompiledConfiguration)
    np.testing.assert_allclose(compiled.q, plain.q, atol=1e-6)
    np.testing.assert_array_equal(compiled.planted, plain.planted)
    assert compiled.planted.any()


def test_a_failed_compile_is_a_summary_warning(human_as_robot: Path, shared_data: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """No C compiler working: CasADi's virtual machine solves, and the summary says so."""
    from ikfusion.retarget import compiled_step
    from ikfusion.retarget.output import robot_metrics

    def failing(functions: object, key: str) -> tuple[None, str]:
        return None, "compiling the solver's step function failed (test)"

    monkeypatch.setattr(compiled_step, "native_functions", failing)
    monkeypatch.setattr(compiled_step, "cached_functions", lambda key, names: None)
    monkeypatch.setattr(compiled_step, "_BUILT", {})
    walk = load_source(shared_data / "mocap" / "sfu_0005_Walking001.bvh")
    source = HumanMotion(walk.time[:30], walk.segments, walk.p_world_segment[:30],
                         walk.R_world_segment[:30], walk.contact_names, walk.contacts[:30],
                         walk.hip_height, walk.source)
    trajectory = _retargeter(human_as_robot).solve(source)
    assert robot_metrics(trajectory, 1.0)["warnings"] == [
        "compiling the solver's step function failed (test)"]


def test_placements_and_checks_follow_every_new_pose(human_as_robot: Path,
                                                     no_compile: None) -> None:
    """Placements, Jacobians and the constraint check are those of the pose last set.

    The check (frame positions, witness distances, sole heights) comes from the light check
    function on a pose only checked and from the full call otherwise: the same values.
    """
    rt = _retargeter(human_as_robot)
    robot = rt.robot
    rt.position_task = robot_module.PositionTask([robot.frame_ids["Pelvis"]], ["Pelvis"])
    conf, _ = rt._step_configuration()
    assert isinstance(conf, CompiledConfiguration)
    plain = Configuration(robot.model, robot.rest)
    reference = CapsulePairs(robot.config.capsules, robot.config.collision_pairs,
                             robot.frame_ids, activation=np.inf)
    rng = np.random.default_rng(8)
    rt.position_task.set_targets(rng.normal(size=(1, 3)), [1.0])
    for n in range(6):
        q = pin.randomConfiguration(robot.model, -np.ones(robot.model.nq),
                                    np.ones(robot.model.nq))
        conf.update(q)
        plain.update(q)
        checked = [x.copy() for x in conf.constraint_values()]  # before any full call
        if n % 2:  # new targets at this pose: evaluated again, the kinematics the same
            conf.tracking_objective()
            rt.position_task.set_targets(rng.normal(size=(1, 3)), [1.0])
            conf.update(q)
        conf.tracking_objective()
        for p, d, z in (checked, conf.constraint_values()):
            for fid in rt._foot_ids:
                np.testing.assert_allclose(p[conf.frame_row(fid)],
                                           plain.placement(fid).translation, atol=1e-12)
            np.testing.assert_allclose(d, reference._witnesses(plain)[2], atol=1e-12)
            corners = np.concatenate([f.corners @ plain.placement(fid).rotation.T
                                      + plain.placement(fid).translation
                                      for f, fid in zip(rt.feet, rt._foot_ids)])
            np.testing.assert_allclose(z, corners[:, 2], atol=1e-12)
        fid = rt._foot_ids[n % 2]
        np.testing.assert_allclose(conf.placement(fid).homogeneous,
                                   plain.placement(fid).homogeneous, atol=1e-12)
        np.testing.assert_allclose(conf.jacobian(fid), plain.jacobian(fid), atol=1e-12)


def test_stacked_targets_leave_missing_segments_untracked() -> None:
    """Per-frame orientation targets of every mapped segment at once: NaN where none."""
    N = 5
    rng = np.random.default_rng(2)
    R = np.array([pin.exp3(rng.normal(size=3)) for _ in range(N)])
    p = rng.normal(size=(N, 3))
    targets = robot_module._Targets({"Head": R}, {"Pelvis": p}, np.zeros((N, 2), bool), 1.0)
    R_all, p_all = targets.stacked(["Pelvis", "Head"], ["Pelvis"])
    assert R_all.shape == (N, 2, 3, 3) and np.isnan(R_all[:, 0]).all()
    np.testing.assert_array_equal(R_all[:, 1], R)
    np.testing.assert_array_equal(p_all[:, 0], p)
