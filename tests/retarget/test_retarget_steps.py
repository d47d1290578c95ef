"""How the retargeting steps use the QP: no solve whose result is thrown away."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import ikfusion.retarget.robot as robot_module
from ikfusion.ik.qp import QpSolution
from ikfusion.retarget import load_source, retarget


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
