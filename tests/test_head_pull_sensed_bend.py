"""Issue #19: the head tag's pull stores no bend of a sensed joint that snaps back.

On the floor the head's fix pulls the head through every joint the planted points leave free
(:func:`ikfusion.app.tag_tasks.body_targets`). Lying back onto the shoulder blades in a get-up
from the back, the pull turned the left hip 2.7 -> 7.4 -> 13 deg away from its sensors over two
frames; when the sacrum took the body the bend snapped back: the clip's largest joint jump.
The pull now fades as a joint between two sensed segments turns away from its sensors
(:func:`ikfusion.app.tag_tasks.sensed_bend_scale`, ``tag_body_joint_bend_deg``). The bound
ships at 3 deg: on the benchmark's get-ups it ends the pops and costs the head 0.2-1.1 cm.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from room_captures import joint_error_jump, room_clip_solved

from ikfusion.app.correction import CorrectionSettings
from ikfusion.app.tag_tasks import sensed_bend_scale
from ikfusion.ik.sensed_pose import Persistence
from ikfusion.model.human_model import HumanModel

MOTIONS = Path(__file__).resolve().parents[1] / "benchmarks" / "motions"
BOUND_DEG = 3.0  # the sensors' own relative-orientation error, about


def test_the_pull_fades_smoothly_to_nothing_at_the_bound() -> None:
    """Full weight with the joints on their sensors, none from the bound on, falling
    monotonically and without a step in between; a bound of 0 leaves the pull alone."""
    bound = np.radians(3.0)
    bends = np.linspace(0.0, 2.0 * bound, 401)
    scale = np.array([sensed_bend_scale(b, bound) for b in bends])
    assert scale[0] == 1.0 and np.all(scale[bends >= bound] == 0.0)
    assert np.all(np.diff(scale) <= 0.0) and np.max(np.abs(np.diff(scale))) < 0.02
    assert 0.0 < sensed_bend_scale(0.5 * bound, bound) < 1.0
    assert sensed_bend_scale(np.radians(30.0), 0.0) == 1.0


def test_the_largest_bend_is_the_angle_of_the_most_turned_joint() -> None:
    """A hip turned 7 deg about a skew axis and a knee 2 deg from the sensed pose: the
    largest bend is the hip's 7 deg, whatever the axis (the turn between the two
    relative orientations, not a sum or a component)."""
    model = HumanModel.default()
    persistence = Persistence(model.model, 1.0)
    q_warm = model.neutral()
    q = q_warm.copy()
    hip = model.model.joints[model.model.getJointId("jLeftHip")]
    knee = model.model.joints[model.model.getJointId("jLeftKnee")]
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    q[hip.idx_q:hip.idx_q + 4] = pin.Quaternion(
        pin.exp3(np.radians(7.0) * axis)).coeffs()
    q[knee.idx_q:knee.idx_q + 4] = pin.Quaternion(
        pin.exp3(np.radians(2.0) * np.array([0.0, 1.0, 0.0]))).coeffs()
    sensed = np.arange(hip.idx_v, hip.idx_v + 6)  # the hip's and the knee's columns
    bent = persistence.bend(q_warm, q, sensed)
    assert np.degrees(persistence.largest(bent)) == pytest.approx(7.0, abs=1e-6)
    assert persistence.largest(np.zeros(model.model.nv)) == 0.0


@pytest.fixture(scope="module")
def lying_back(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The first 9 s of the DeepMimic get-up from the back (as the benchmark's clip) in the UWB
    room, solved no-slide with the pull bounded at 3 deg of a sensed joint's turn (as shipped,
    ``configs/correction.yaml``; set here so the test holds if the default changes): lying
    back onto the shoulder blades at about 6.2 s."""
    shipped = CorrectionSettings.load.__func__  # type: ignore[attr-defined]

    def bounded(cls: type[CorrectionSettings], path: str | Path | None = None,
                **overrides: Any) -> CorrectionSettings:
        return shipped(cls, path, **{"tag_body_joint_bend_deg": BOUND_DEG, **overrides})

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(CorrectionSettings, "load", classmethod(bounded))
        assert CorrectionSettings.load().tag_body_joint_bend_deg == BOUND_DEG
        return room_clip_solved(MOTIONS / "deepmimic_getup_faceup.bvh.gz", 9.0,
                                tmp_path_factory.mktemp("lying_back"), "no-slide")


def test_lying_back_onto_the_shoulder_blades_bends_no_hip_in_a_frame(
        lying_back: tuple[Path, Path]) -> None:
    """Unbounded (as before, e3e5965, and as shipped) the left hip's error against the truth
    changed by 5.5 deg in one frame at 6.20 s (its flexion, the clip's largest jump); the same
    capture's perfect-IMU solve without UWB jumps 4.2 deg over the whole clip. Bounded: at most
    that plus the acceptance's 1 deg (benchmarks/motions: jump-ref)."""
    capture, out = lying_back
    jump, where = joint_error_jump(capture, out, start=5.5)
    assert jump < 4.2 + 1.0, where
