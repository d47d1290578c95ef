"""How the retargeting steps use the QP: no solve whose result is thrown away."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import ikfusion.retarget.robot as robot_module
from ikfusion.ik.qp import QpSolution
from ikfusion.ik.settings import SolverSettings
from ikfusion.retarget import load_source, retarget
from ikfusion.retarget.robot import RobotRetargeter
from ikfusion.retarget.robot_config import load_retarget_config
from ikfusion.retarget.robot_model import RobotModel


def test_a_trust_region_too_tight_is_not_relaxed_before_it_is_widened(
        shared_data: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # A step whose constraints cannot all hold inside the capsule trust region is solved again
    # without it; relaxing the trust-region problem first cost ~0.15 ms per such step for a
    # solution never used (issue #20: a short clip's first frame has several).
    returned: list[QpSolution] = []
    used: list[np.ndarray] = []
    solve_qp, damped = robot_module.solve_qp, robot_module.RobotRetargeter._damped

    def recording_solve(*args: object, **kwargs: object) -> QpSolution:
        solution = solve_qp(*args, **kwargs)  # type: ignore[arg-type]
        returned.append(solution)
        return solution

    def recording_damped(self: robot_module.RobotRetargeter, dq: np.ndarray,
                         previous: np.ndarray | None, factor: float) -> float:
        used.append(dq)
        return damped(self, dq, previous, factor)

    monkeypatch.setattr(robot_module, "solve_qp", recording_solve)
    monkeypatch.setattr(robot_module.RobotRetargeter, "_damped", recording_damped)
    _, metrics = retarget(load_source(shared_data / "mvnx" / "test_mocap.mvnx"), "g1")
    assert metrics["frames"] == 112
    relaxed = [s for s in returned if s.relaxed]
    assert relaxed  # this clip's first frame has starts the constraints cannot all hold in
    used_ids = {id(dq) for dq in used}
    thrown_away = [s for s in relaxed if id(s.dq) not in used_ids]
    assert not thrown_away, f"{len(thrown_away)} relaxed solves were computed and discarded"


@pytest.mark.parametrize("clip", ["mocap/cmu_01_01_hop_turn.bvh", "mvnx/test_mocap.mvnx"])
def test_the_first_frame_screens_its_starts_and_finds_the_exhaustive_searchs_basin(
        shared_data: Path, monkeypatch: pytest.MonkeyPatch, clip: str) -> None:
    # The first frame's 8 starts were each solved to the end (up to 30 steps: 30-40 ms, a
    # fifth of a short clip's retarget, issue #20). They are now screened in rounds of a few
    # steps, each keeping the better half; its answer is the exhaustive search's (every start
    # solved to the end): same basin, same tracking cost. hop_turn's winner is a random start.
    steps: list[int] = []
    damped = robot_module.RobotRetargeter._damped

    def counting_damped(self: robot_module.RobotRetargeter, *args: object) -> float:
        steps.append(1)
        return damped(self, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(robot_module.RobotRetargeter, "_damped", counting_damped)
    source = load_source(shared_data / clip)
    source = dataclasses.replace(source, time=source.time[:1], contacts=source.contacts[:1],
                                 p_world_segment=source.p_world_segment[:1],
                                 R_world_segment=source.R_world_segment[:1])
    config = load_retarget_config("g1")
    s = config.solver
    screened, exhaustive = [], []
    for solver, record in ((s, screened), (dataclasses.replace(
            s, first_frame_screen_steps=s.first_frame_steps), exhaustive)):
        steps.clear()
        retargeter = RobotRetargeter(RobotModel(dataclasses.replace(config, solver=solver)),
                                     SolverSettings.load().qp)
        trajectory = retargeter.solve(source)
        record += [len(steps), retargeter._cost(trajectory.q[0]), trajectory.q[0]]
    # rounds of 8, 4, 2 starts, then the best solved on
    assert screened[0] <= 2 * s.first_frame_starts * s.first_frame_screen_steps \
        + s.first_frame_steps
    assert screened[0] < 0.6 * exhaustive[0]
    assert screened[1] == pytest.approx(exhaustive[1], rel=1e-3)
    np.testing.assert_allclose(screened[2], exhaustive[2], atol=0.01)  # [rad, m]: one basin


def test_screening_costs_evaluate_no_compiled_step_and_equal_the_tasks_objective(
        shared_data: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Each of the first frame's 14 screened solves was ranked by a cost that ran the whole
    # compiled step (objective, Jacobians, capsule witnesses) plus Pinocchio's Jacobians:
    # ~0.3 ms each, ~4 ms of a short clip's command (issue #20). The cost needs placements
    # only; it must still be the tasks' weighted squared residuals.
    from ikfusion.ik.configuration import Configuration
    from ikfusion.retarget.compiled_step import RobotStep

    calls = {"step": 0}
    ranked: list[tuple[float, float]] = []
    step_call, cost = RobotStep.__call__, robot_module.RobotRetargeter._cost

    def counting_call(self: RobotStep, *args: np.ndarray) -> list[np.ndarray]:
        calls["step"] += 1
        return step_call(self, *args)

    def checked_cost(self: robot_module.RobotRetargeter, q: np.ndarray) -> float:
        before = calls["step"]
        value = cost(self, q)
        assert calls["step"] == before, "the screening cost ran the compiled step"
        plain = Configuration(self.robot.model, q)  # Pinocchio only: independent of the step
        truth = 0.0
        for task in (self.orientation_task, self.flat_task, self.position_task):
            if task.is_active():
                e = task.compute_error(plain)
                truth += float(np.sum(task.row_weights() * e * e))
        ranked.append((value, truth))
        return value

    monkeypatch.setattr(RobotStep, "__call__", counting_call)
    monkeypatch.setattr(robot_module.RobotRetargeter, "_cost", checked_cost)
    retarget(load_source(shared_data / "mocap" / "sfu_0005_Walking001.bvh"), "g1")
    assert len(ranked) == 14  # 8 starts, then 4, then 2
    values, truths = np.array(ranked).T
    np.testing.assert_allclose(values, truths, rtol=1e-12, atol=1e-15)


def test_a_step_after_one_where_a_limit_bound_goes_to_daqp_at_once(
        shared_data: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Most retargeting steps have a binding limit (joint range, velocity box, floor, capsule),
    # so the closed-form try before DAQP failed in ~70 % of the steps, and a limit that binds
    # in one step mostly binds in the next (issue #20: ~10 % of a clip's solve). After a DAQP
    # solve with a binding limit the next step skips the try (ClosedFormHint). Relaxed
    # problems (slack variables: more than nv) are solved without the hint, as before.
    import ikfusion.ik.qp as qp_module

    events: list[str] = []
    optimum, daqp = qp_module.equality_optimum, qp_module.call_daqp
    nv = RobotModel(load_retarget_config("g1", None)).model.nv

    def recording_optimum(H: np.ndarray, *args: object) -> np.ndarray | None:
        if len(H) == nv:
            events.append("closed form")
        return optimum(H, *args)  # type: ignore[arg-type]

    def recording_daqp(iterations: int, H: np.ndarray,
                       *args: object) -> tuple[np.ndarray | None, bool]:
        x, binding = daqp(iterations, H, *args)  # type: ignore[arg-type]
        if len(H) == nv:
            events.append("daqp binding" if binding else "daqp")
        return x, binding

    monkeypatch.setattr(qp_module, "equality_optimum", recording_optimum)
    monkeypatch.setattr(qp_module, "call_daqp", recording_daqp)
    _, metrics = retarget(load_source(shared_data / "mocap" / "sfu_0005_Walking001.bvh"), "g1")
    assert metrics["joint_limit_violations"] == 0 and metrics["relaxed_frames"] == 0
    assert events.count("daqp binding") > 10  # the case this is about happens on this clip
    after_binding = [b for a, b in zip(events, events[1:]) if a == "daqp binding"]
    assert "closed form" not in after_binding, (
        f"{after_binding.count('closed form')} closed-form tries right after a binding step")
