"""Planted heels carry their anchors along at the velocity their foot IMU gives (IMU only).

Issue #19: in brisk mocap walks the landing heel still travels 1.5-2 cm after it touches down;
the solver held it where it touched down, so the body fell back by that much at every step
(cmu-02-02-walk drifted 5.6 % of the distance walked, 4.4 % now).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from motions import frames_from

from ikfusion.ik import Motion, Solver
from ikfusion.model import HumanModel

RATE = 60.0
FOOT_POINTS = ("LeftHeel", "LeftToe", "RightHeel", "RightToe")


def _standing(human: HumanModel, seconds: float) -> np.ndarray:
    """The N-pose standing still on the floor for ``seconds`` [s] (N, nq)."""
    q = human.neutral()
    q[2] -= min(human.site_position(q, n)[2] for n in FOOT_POINTS)
    return np.repeat(q[None], int(seconds * RATE) + 1, axis=0)


def _glide(human: HumanModel, velocities: dict[str, np.ndarray], on_heels: bool = True,
           on_toes: bool = False) -> Motion:
    """2 s standing (on the heels only: the toes hinted off the floor; or ``on_toes`` only)
    solved while the foot IMUs give ``velocities`` [m/s] to the named points from 0.5 to
    1.0 s."""
    hints = ({"LeftHeel": False, "RightHeel": False} if on_toes
             else {"LeftToe": False, "RightToe": False} if on_heels else None)
    frames = [replace(f, points_velocity=velocities if 0.5 <= f.time < 1.0 else {},
                      contacts=hints)
              for f in frames_from(human, _standing(human, 2.0), RATE, stance=True)]
    return Solver(human).solve(frames)


def test_a_body_whose_feet_slide_by_their_imus_moves_with_them(human: HumanModel) -> None:
    """Standing on both heels while the foot IMUs say the feet glide forward at 0.2 m/s for
    0.5 s (heels landing while they still travel, a slide on a slippery floor): the body goes
    10 cm with them and still stands on them; held on their touch-down anchors it stayed where
    it was."""
    motion = _glide(human, dict.fromkeys(FOOT_POINTS, np.array([0.2, 0.0, 0.0])))
    np.testing.assert_allclose(motion.q[-1, :2] - motion.q[0, :2], [0.1, 0.0], atol=0.005)
    heels = [motion.contact_names.index(n) for n in ("LeftHeel", "RightHeel")]
    assert motion.contacts[-1, heels].all()




def test_a_body_on_its_toes_moves_with_what_their_hinge_cannot_take_up(
        human: HumanModel) -> None:
    """Issue #19: standing on the toes only (push-off), the IMU's velocity of a toe is its
    ball's. A ball moving 0.2 m/s forward drags the tips forward by the part of it along the
    toe (the toe cannot shorten): the body goes that far. Held where they touched down the
    toes kept the body back: the push-off toes of the CMU walks' truth slide 2-3 cm at every
    step (cmu-02-02-walk drifted 4.0 % with perfect sensors)."""
    v_ball = np.array([0.2, 0.0, 0.0])
    motion = _glide(human, dict.fromkeys(FOOT_POINTS, v_ball), on_heels=False, on_toes=True)
    q = human.neutral()
    u = human.site_position(q, "LeftToe") - human.segment_position(q, "LeftToe")
    u /= np.linalg.norm(u)
    expected = 0.5 * float(v_ball @ u) * u[:2]  # 0.5 s at the tip's slide along the toe
    np.testing.assert_allclose(motion.q[-1, :2] - motion.q[0, :2], expected, atol=0.005)
    toes = [motion.contact_names.index(n) for n in ("LeftToe", "RightToe")]
    assert motion.contacts[-1, toes].all()


def test_a_body_pivoting_on_its_toes_holds_them(human: HumanModel) -> None:
    """Feet turning on their toe tips (the balls swing sideways about them, as in kneeling
    down or turning on the toes): the IMU's balls move 0.2 m/s, the tips do not."""
    sideways = dict.fromkeys(FOOT_POINTS, np.array([0.0, 0.2, 0.0]))
    motion = _glide(human, sideways, on_heels=False, on_toes=True)
    assert np.linalg.norm(motion.q[-1, :2] - motion.q[0, :2]) <= 1e-3


def test_planted_points_hold_unless_the_heels_slide_along_the_floor(
        human: HumanModel) -> None:
    """No carry without velocities (unknown, or a solve with UWB), nor for a foot standing on
    its heel and toes (a flat foot: a toe's velocity by the IMU is its ball's), nor for points
    that move mostly vertically (still landing: a jump's touchdown sample, integrated across
    the impact, says 0.1 m/s forward and 0.5 m/s down while the true toes stand), nor below
    ``release_speed`` (integration noise)."""
    gliding = dict.fromkeys(FOOT_POINTS, np.array([0.2, 0.0, 0.0]))
    landing = dict.fromkeys(FOOT_POINTS, np.array([0.2, 0.0, -0.5]))
    slow = dict.fromkeys(FOOT_POINTS, np.array([0.05, 0.0, 0.0]))
    for velocities, on_heels in (({}, True), (gliding, False), (landing, True), (slow, True)):
        motion = _glide(human, velocities, on_heels)
        assert np.linalg.norm(motion.q[-1, :2] - motion.q[0, :2]) <= 1e-3
