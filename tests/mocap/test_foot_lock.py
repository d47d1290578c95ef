"""The truth read from a BVH clip does not skate: planted points hold, clean clips are kept."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikfusion.app.evaluate import phase_slides
from ikfusion.mocap.foot_lock import lock_planted_points
from ikfusion.mocap.from_bvh import motion_from_bvh
from ikfusion.mocap.model_motion import TruthMotion, site_positions
from ikfusion.model import HumanModel
from ikfusion.results.bvh_export import write_motion_bvh
from ikfusion.sim.gait import GaitParameters, generate_gait


@pytest.fixture(scope="module")
def walk() -> TruthMotion:
    return generate_gait(HumanModel.default(), GaitParameters(duration=6.0), rate=60.0)


def _slides_mm(truth: TruthMotion) -> np.ndarray:
    P = site_positions(truth.model, truth.q, truth.contact_names)
    return 1000.0 * np.array(phase_slides(P, truth.contacts))


def test_a_clip_whose_feet_skate_gives_a_truth_whose_planted_points_hold(
        walk: TruthMotion, tmp_path: Path) -> None:
    """The walk's root travels 10 % too far in the file (legs as walked): the feet skate by
    several centimetres per step in the clip, and hold within a few mm in the truth."""
    q = walk.q.copy()
    q[:, :2] = q[0, :2] + 1.1 * (q[:, :2] - q[0, :2])
    write_motion_bvh(tmp_path / "skating.bvh", walk.model, q, 1.0 / 60.0)
    raw = motion_from_bvh(tmp_path / "skating.bvh", lock_contacts=False)
    assert _slides_mm(raw).mean() > 20.0  # the clip does skate
    truth = motion_from_bvh(tmp_path / "skating.bvh")
    slides = _slides_mm(truth)
    assert len(slides) >= 0.8 * len(_slides_mm(walk))  # the steps are still found
    assert slides.mean() < 3.0 and slides.max() < 8.0, (slides.mean(), slides.max())
    # the walk's own distance is recovered (within 2 % of the 10 % it was stretched by)
    travelled = np.linalg.norm(truth.q[-1, :2] - truth.q[0, :2])
    assert travelled == pytest.approx(np.linalg.norm(walk.q[-1, :2] - walk.q[0, :2]), rel=0.02)
    # orientations, joint angles and heights are the file's
    np.testing.assert_allclose(truth.q[:, 2:], raw.q[:, 2:], atol=1e-12)


def test_a_clean_clip_is_unchanged(walk: TruthMotion, tmp_path: Path) -> None:
    write_motion_bvh(tmp_path / "clean.bvh", walk.model, walk.q, 1.0 / 60.0)
    locked = motion_from_bvh(tmp_path / "clean.bvh")
    raw = motion_from_bvh(tmp_path / "clean.bvh", lock_contacts=False)
    P0 = site_positions(raw.model, raw.q, raw.model.site_names)
    P1 = site_positions(locked.model, locked.q, locked.model.site_names)
    assert np.linalg.norm(P1 - P0, axis=2).max() < 1e-3


def test_a_motion_without_stance_is_not_moved(walk: TruthMotion) -> None:
    """Nothing planted (the walk lifted 20 cm off the floor, a flight): no correction."""
    q = walk.q.copy()
    q[:, 2] += 0.2
    locked, offset = lock_planted_points(walk.model, q, walk.time, walk.contact_names)
    assert np.abs(offset).max() == 0.0
    np.testing.assert_array_equal(locked, q)


def test_the_correction_fades_in_flight(walk: TruthMotion) -> None:
    """Feet that skate forward at 0.1 m/s for 1 s, then 1 s of flight: the correction holds
    them, and during the flight it fades to nothing within 0.3 s (the flight stays as
    captured instead of carrying the correction's velocity)."""
    model, names = walk.model, walk.contact_names
    n = 120
    time = np.arange(n) / 60.0
    q = np.repeat(walk.q[:1], n, axis=0)
    q[:, 0] += 0.1 * np.minimum(time, 1.0)
    q[60:, 2] += 0.2  # lifted: nothing near the floor
    locked, offset = lock_planted_points(model, q, time, names)
    P = site_positions(model, locked, names)
    assert np.ptp(P[:55, :, 0], axis=0).max() < 0.003  # held while standing
    drift = np.diff(offset[:, 0]) * 60.0  # the correction's velocity [m/s]
    assert np.abs(drift[60 + 18:]).max() < 0.005
