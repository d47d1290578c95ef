"""Real mocap as ground truth: the model follows the clip, and an IMU-only solve follows it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikfusion.ik import Frame, Solver
from ikfusion.mocap.from_bvh import floor_plane, level_on_floor, motion_from_bvh
from ikfusion.mocap.model_motion import limb_contact_sites, site_positions
from ikfusion.model import SENSOR_SEGMENTS, TRUNK_CONTACT_SITES
from ikfusion.sim.imu import ImuNoise, simulate_imus
from ikfusion.sim.truth import write_truth


@pytest.fixture(scope="module")
def sfu_walk(request):
    root = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "mocap"
    path = root / "sfu_0005_Walking001.bvh"
    if not path.exists():
        pytest.skip(f"real recordings not available: {path} is absent (a user's clone)")
    return motion_from_bvh(path)


def test_truth_stands_on_the_floor_with_alternating_contacts(sfu_walk) -> None:
    truth = sfu_walk
    assert truth.info["body"]["height"] == pytest.approx(1.58, abs=0.05)
    P = site_positions(truth.model, truth.q, truth.contact_names)
    lowest = P[..., 2].min(axis=1)
    speed = np.linalg.norm(np.gradient(P, truth.time, axis=0), axis=2).min(axis=1)
    # the floor is where the feet stand still: those points stand on z = 0 within mocap noise
    assert abs(np.median(lowest[speed < 0.1])) < 0.005
    assert np.percentile(lowest, 2) > -0.02
    feet = truth.contacts[:, :2].any(axis=1), truth.contacts[:, 2:].any(axis=1)
    assert 0.3 < feet[0].mean() < 0.9 and 0.3 < feet[1].mean() < 0.9
    assert (feet[0] | feet[1]).mean() > 0.9  # walking: always a foot down


def test_a_tilted_raised_floor_is_found_and_levelled(sfu_walk) -> None:
    """A hall whose capture volume is tilted 2 deg and 5 cm off: levelling undoes it."""
    import pinocchio as pin

    truth = sfu_walk
    tilt = pin.exp3(np.radians(2.0) * np.array([0.6, 0.8, 0.0]))
    q = truth.q.copy()
    q[:, :3] = q[:, :3] @ tilt.T + [0.0, 0.0, 0.05]
    for k in range(len(q)):
        q[k, 3:7] = pin.Quaternion(tilt @ pin.Quaternion(truth.q[k, 3:7]).matrix()).coeffs()
    P = site_positions(truth.model, q, truth.contact_names)
    normal, _ = floor_plane(P, truth.time)
    assert np.degrees(np.arccos(normal @ tilt[:, 2])) < 0.3
    levelled = level_on_floor(q, P, truth.time)
    P0 = site_positions(truth.model, truth.q, truth.contact_names)
    P1 = site_positions(truth.model, levelled, truth.contact_names)
    assert np.abs(P1[..., 2] - P0[..., 2]).max() < 0.005  # heights as before the tilt


def test_imu_only_solve_follows_the_clip(sfu_walk, rng) -> None:
    truth = sfu_walk
    model = truth.model
    imus = simulate_imus(model, truth.time, truth.q, SENSOR_SEGMENTS, rng, ImuNoise.none(),
                         random_mounting=False)
    frames = [Frame(float(t), {s: imus.R_world_sensor[i, k] for i, s in enumerate(SENSOR_SEGMENTS)})
              for k, t in enumerate(truth.time)]
    motion = Solver(model).solve(frames)
    head_true = site_positions(model, truth.q, ["HeadTop"])[:, 0]
    head = site_positions(model, motion.q, ["HeadTop"])[:, 0]
    head += head_true[0] - head[0]  # IMUs cannot know where the walk started
    assert np.linalg.norm(head_true - head, axis=1).max() < 0.1


def test_truth_file_has_the_documented_keys(sfu_walk, tmp_path: Path) -> None:
    path = write_truth(tmp_path / "truth.npz", sfu_walk)
    with np.load(path) as npz:
        for key in ("time", "q", "segment_names", "p_world_segment", "quat_wxyz_world_segment",
                    "site_names", "p_world_site", "contact_names", "contacts",
                    "joint_angle_names", "joint_angles"):
            assert key in npz.files
        assert npz["p_world_site"].shape == (len(sfu_walk.time), len(sfu_walk.model.site_names), 3)
        assert npz["joint_angles"].shape == (len(sfu_walk.time), 66)


def test_bvh_to_model_to_bvh_keeps_positions_within_a_millimetre(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The model's own BVH, mapped back onto a body scaled to it and written again, lands on the
    same joint and End Site positions (the body dimensions are recovered from the skeleton)."""
    from ikfusion.io.bvh import read_bvh
    from ikfusion.mocap.from_bvh import motion_from_bvh
    from ikfusion.model import HumanModel
    from ikfusion.results.bvh_export import write_motion_bvh
    from ikfusion.sim.gait import GaitParameters, generate_gait

    model = HumanModel.default()
    walk = generate_gait(model, GaitParameters(duration=2.5), rate=60.0)
    write_motion_bvh(tmp_path / "first.bvh", model, walk.q, 1.0 / 60.0)
    back = motion_from_bvh(tmp_path / "first.bvh", rate=60.0)
    assert len(back.q) == len(walk.q)
    write_motion_bvh(tmp_path / "second.bvh", back.model, back.q, 1.0 / 60.0)
    first, second = read_bvh(tmp_path / "first.bvh"), read_bvh(tmp_path / "second.bvh")
    assert first.skeleton().joint_names == second.skeleton().joint_names
    a, b = first.world_poses(up="z"), second.world_poses(up="z")
    joints = np.linalg.norm(a.p_world_joint - b.p_world_joint, axis=2)
    ends = np.linalg.norm(a.p_world_end_site - b.p_world_end_site, axis=2)
    assert joints.max() < 1e-3, joints.max()
    assert ends.max() < 1e-3, ends.max()


def test_a_lying_clips_floor_is_fitted_to_the_limbs_only() -> None:
    """dm-getup-faceup: the floor stands under the feet, knees and palms, as before the trunk
    contact points existed; the model's guess of where the lying trunk's surface is (the
    solver's own points) does not shape the truth (fitted with them too, the floor moved 2.8 cm
    and tilted 2.2 deg against the limbs' one)."""
    clip = Path(__file__).resolve().parents[2] / "benchmarks" / "motions"
    truth = motion_from_bvh(clip / "deepmimic_getup_faceup.bvh.gz")
    limbs = limb_contact_sites(truth.model)
    assert set(TRUNK_CONTACT_SITES) <= set(truth.contact_names)  # labelled all the same
    assert not set(TRUNK_CONTACT_SITES) & set(limbs)
    normal, height = floor_plane(site_positions(truth.model, truth.q, limbs), truth.time)
    # level and at z = 0 to what the foot lock's root shifts leave (with the trunk points:
    # 2.2 deg, 2.8 cm)
    assert np.degrees(np.arccos(normal[2])) < 0.5
    assert abs(height) < 0.005
