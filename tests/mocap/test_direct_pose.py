"""Segment orientations onto the model in closed form (the retarget source without a solver)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import ikfusion.mocap.from_bvh as from_bvh
from ikfusion.mocap.direct_pose import configurations_from_orientations
from ikfusion.mocap.model_motion import segment_poses
from ikfusion.model.human_model import HumanModel
from ikfusion.retarget import load_source
from ikfusion.rotations import angle_between


@pytest.fixture(scope="module")
def model() -> HumanModel:
    return HumanModel.default()


def _orientations(model: HumanModel, q: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
    p, R = segment_poses(model, q)
    return {s: R[:, i] for i, s in enumerate(model.segment_names)}, p[:, 0]


def test_poses_inside_the_ranges_are_reproduced_exactly(model: HumanModel,
                                                        rng: np.random.Generator) -> None:
    q_true = np.array([model.random_configuration(rng, margin_deg=3.0) for _ in range(40)])
    q_true[:, :3] += rng.normal(0.0, 1.0, (40, 3))
    R_true, p_pelvis = _orientations(model, q_true)
    q, limited = configurations_from_orientations(model, R_true, p_pelvis)
    p_true, _ = segment_poses(model, q_true)
    p, R = segment_poses(model, q)
    assert not limited.any()
    assert np.abs(p - p_true).max() < 1e-9  # every segment origin [m]
    for i, s in enumerate(model.segment_names):
        assert np.degrees(angle_between(R[:, i], R_true[s])).max() < 1e-6, s


def test_a_joint_past_its_range_stops_there_and_its_parent_takes_half_the_excess(
        model: HumanModel) -> None:
    knee = model.ball_joint("jRightKnee").spec
    flex = next(a for a in knee.angles if a.name == "flex")
    q_true = model.configuration({"jRightKnee_flex": flex.lower_deg - 20.0,  # hyperextended
                                  "jRightAnkle_flex": 10.0})[None]
    R_true, p_pelvis = _orientations(model, q_true)
    q, limited = configurations_from_orientations(model, R_true, p_pelvis)
    assert limited.all()
    angles = model.joint_angles(q[0])
    assert angles["jRightKnee_flex"] == pytest.approx(flex.lower_deg, abs=1e-6)
    # the shank swung forward past the knee: the thigh flexes forward by half of it
    assert angles["jRightHip_flex"] == pytest.approx(10.0, abs=1e-6)
    _, R = segment_poses(model, q)
    names = model.segment_names

    def error(segment: str) -> float:
        return float(np.degrees(angle_between(R[0, names.index(segment)], R_true[segment][0])))

    # the thigh and the shank miss by half each (the least-squares split of equal weights) ...
    assert error("RightUpperLeg") == pytest.approx(10.0, abs=1e-6)
    assert error("RightLowerLeg") == pytest.approx(10.0, abs=1e-6)
    # ... the foot below and everything else keep their own orientations
    for segment in ("RightFoot", "RightToe", "Pelvis", "LeftFoot", "Head", "LeftHand"):
        assert error(segment) < 1e-6, segment


def test_retarget_source_from_a_bvh_runs_no_per_frame_solver(
        shared_data: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    clip = shared_data / "mocap" / "cmu_02_01_walk.bvh"
    solved = from_bvh.motion_from_bvh(clip)  # the per-frame QP, as the source was before
    p_qp, _ = segment_poses(solved.model, solved.q)

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the retarget source ran the per-frame solver")

    monkeypatch.setattr(from_bvh, "Solver", refuse)
    source = load_source(clip)
    # where no joint range binds (this walk), the same targets as the solver's within 2 mm
    segments = solved.model.segment_names
    assert source.segments == segments
    assert np.linalg.norm(source.p_world_segment - p_qp, axis=2).max() < 0.002
    assert (source.contacts == solved.contacts).mean() > 0.99
