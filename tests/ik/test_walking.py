"""IMU-only solving of a simulated walk: planted points do not slide, distance is kept."""

from __future__ import annotations

import numpy as np
import pytest
from motions import frames_from

from ikfusion.app.evaluate import phase_slides
from ikfusion.ik import Solver
from ikfusion.mocap.model_motion import site_positions
from ikfusion.model import HumanModel
from ikfusion.sim.gait import GaitParameters, generate_gait


def stride_path_length(q: np.ndarray, every: int) -> float:
    """Pelvis path length sampled once per stride (removes the side-to-side sway)."""
    xy = q[::every, :2]
    return float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))


@pytest.fixture(scope="module", params=["straight", "circle"])
def walk(request, human: HumanModel):
    params = GaitParameters(path=request.param, duration=9.0, stand=1.0)
    truth = generate_gait(human, params, rate=60.0)
    motion = Solver(human).solve(frames_from(human, truth.q, stance=True))
    return truth, motion


def test_truth_walk_is_exact(walk, human: HumanModel) -> None:
    truth, _ = walk
    P = site_positions(human, truth.q, truth.contact_names)
    assert max(phase_slides(P, truth.contacts)) <= 1e-4
    assert P[..., 2].min() >= -1e-3


def test_planted_points_do_not_slide(walk, human: HumanModel) -> None:
    truth, motion = walk
    P = site_positions(human, motion.q, motion.contact_names)
    slides = np.array(phase_slides(P, motion.contacts))
    assert len(slides) >= 20
    assert slides.max() <= 1e-3


def test_walked_distance_matches_truth(walk) -> None:
    truth, motion = walk
    every = int(round(truth.info['parameters'].cycle * 60.0))
    walked = stride_path_length(motion.q, every)
    expected = stride_path_length(truth.q, every)
    assert expected > 5.0
    assert abs(walked / expected - 1.0) <= 0.02


def test_knees_and_palms_are_never_planted_in_walking(walk) -> None:
    """They are far above the floor: only heels and toes carry a walk."""
    _, motion = walk
    body = [k for k, n in enumerate(motion.contact_names) if "Knee" in n or "Palm" in n]
    assert len(body) == 4
    assert not motion.contacts[:, body].any()
    assert motion.contacts.any()
