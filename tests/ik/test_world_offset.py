"""The drift correction moves the solved body through one object, WorldOffset.

Independent truth: the solve is invariant to a horizontal translation of the world (the floor
is horizontal), so a translation of the whole solved state between two frames moves every
later frame by exactly that much and changes nothing else.
"""

from __future__ import annotations

import numpy as np
import pytest
from motions import frames_from

from ikfusion.ik import Solver
from ikfusion.model import HumanModel
from ikfusion.sim.gait import GaitParameters, generate_gait


@pytest.fixture(scope="module")
def walk_frames(human: HumanModel) -> list:
    truth = generate_gait(human, GaitParameters(path="straight", duration=2.5, stand=0.5),
                          rate=60.0)
    return frames_from(human, truth.q, stance=True)


def _solve(human: HumanModel, frames: list, move: str | None, at: int,
           delta: np.ndarray) -> np.ndarray:
    solver = Solver(human)

    def after(solver: Solver, pose, k: int, dt: float) -> None:
        if k == at and move == "translate":
            solver.world.translate(delta)
        elif k == at and move == "slide":
            solver.world.slide(delta)

    return solver.solve(frames, after_step=after).q


def test_a_translation_moves_every_later_frame_by_it(human: HumanModel, walk_frames) -> None:
    delta = np.array([0.7, -0.4, 5.0])  # the vertical part is ignored: heights come from the floor
    at = 40
    plain = _solve(human, walk_frames, None, at, delta)
    moved = _solve(human, walk_frames, "translate", at, delta)
    np.testing.assert_array_equal(moved[:at + 1], plain[:at + 1])
    np.testing.assert_allclose(moved[at + 1:, :2] - plain[at + 1:, :2],
                               np.broadcast_to(delta[:2], (len(plain) - at - 1, 2)), atol=1e-6)
    np.testing.assert_allclose(moved[at + 1:, 2:], plain[at + 1:, 2:], atol=1e-6)


def test_a_slide_carries_the_body_with_its_planted_feet(human: HumanModel,
                                                        walk_frames) -> None:
    delta = np.array([0.05, 0.02, 0.0])
    at = 40
    plain = _solve(human, walk_frames, None, at, delta)
    slid = _solve(human, walk_frames, "slide", at, delta)
    np.testing.assert_array_equal(slid[:at + 1], plain[:at + 1])
    # the next frame stands on the moved anchors: the pelvis moved with them
    np.testing.assert_allclose(slid[at + 1, :2] - plain[at + 1, :2], delta[:2], atol=2e-3)


def test_the_offset_reports_its_moves_and_turn(human: HumanModel) -> None:
    solver = Solver(human)
    world = solver.world
    world.translate(np.array([0.3, 0.1, 2.0]))
    world.turn(0.2)
    world.turn(-0.05)
    np.testing.assert_allclose(world.shifted, [0.3, 0.1, 0.0])
    assert world.heading == pytest.approx(0.15)
    solver.reset()
    np.testing.assert_allclose(world.shifted, 0.0)
    assert world.heading == 0.0 and world.R_heading is None
