"""Planted heels carry their anchors along at the velocity their foot IMU gives (IMU only).

Issue #19: in brisk mocap walks the landing heel still travels 1.5-2 cm after it touches down;
the solver held it where it touched down, so the body fell back by that much at every step
(cmu-02-02-walk drifted 5.6 % of the distance walked, 4.4 % now).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from motions import frames_from

from ikfusion.ik import Motion, Solver
from ikfusion.ik.contact_tracker import ContactTracker
from ikfusion.ik.contacts import ContactState
from ikfusion.ik.frame import Frame
from ikfusion.ik.settings import SolverSettings
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology

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
    ball's. A ball sliding 0.2 m/s forward along the floor drags the tips on the floor as fast
    (the toe cannot shorten, and the tips stay on the floor): the body goes that far. Held
    where they touched down the toes kept the body back: the push-off toes of the CMU walks'
    truth slide 2-3 cm at every step (cmu-02-02-walk drifted 4.0 % with perfect sensors).
    Carried by the ball's velocity along the toe only (the tips' least velocity, not one on
    the floor), the body went 0.93 of it."""
    v_ball = np.array([0.2, 0.0, 0.0])
    motion = _glide(human, dict.fromkeys(FOOT_POINTS, v_ball), on_heels=False, on_toes=True)
    np.testing.assert_allclose(motion.q[-1, :2] - motion.q[0, :2], 0.5 * v_ball[:2], atol=0.002)
    toes = [motion.contact_names.index(n) for n in ("LeftToe", "RightToe")]
    assert motion.contacts[-1, toes].all()


def test_a_body_spinning_on_its_toes_holds_them(human: HumanModel) -> None:
    """Issue #19: a ball moving more across the toe than along it (the feet turning on their
    forefeet, as in amp-dance-spins' whirls) says nothing about the tips: the body stays. The
    part of such a velocity along the toe was carried, and the dance's head drifted 5.9 ->
    6.9 cm RMS IMU only."""
    oblique = dict.fromkeys(FOOT_POINTS, np.array([0.2, 0.34, 0.0]))
    motion = _glide(human, oblique, on_heels=False, on_toes=True)
    assert np.linalg.norm(motion.q[-1, :2] - motion.q[0, :2]) <= 1e-3


def _decelerating(t: float) -> dict[str, np.ndarray]:
    """Heel velocities [m/s] of a landing glide: 0.6 m/s forward at 0.5 s, to rest at 0.8 s.

    Known in every frame (at rest outside the glide), as the pipeline gives them: the first
    frame's glide is its mean velocity, half of 0.6 m/s.
    """
    speed = 0.6 * (0.8 - t) / 0.3 if 0.5 <= t <= 0.8 else 0.0
    return dict.fromkeys(FOOT_POINTS, np.array([speed, 0.0, 0.0]))


def test_a_landing_glide_carries_the_body_as_far_as_the_heels_go(human: HumanModel) -> None:
    """Issue #19: heels landing while they still travel decelerate to rest within a few
    frames (cmu-02-02-walk: 1.3 m/s to 0.1 m/s in 0.15 s). The body goes with them the whole
    glide, 0.6 * 0.3 / 2 = 9 cm here plus the first frame's mean velocity (0.3 m/s, 5 mm): the
    velocity averaged over each frame (not its end's, short by half the speed lost per frame)
    and the slow end of the glide carried too (below ``release_speed`` a heel did not start to
    slide, but one sliding goes on to rest). Carried by each frame's velocity while above
    ``release_speed``, the body went 8.3 cm. And the pelvis goes as far as the heels: the
    support took each frame's glide for a hand-over's disagreement and lagged the pelvis behind
    by it, and the legs kept the last 1 cm of that lag as a bend (heels 9.5 cm, pelvis 8.5)."""
    hints = {"LeftToe": False, "RightToe": False}
    frames = [replace(f, points_velocity=_decelerating(f.time), contacts=hints)
              for f in frames_from(human, _standing(human, 1.5), RATE, stance=True)]
    motion = Solver(human).solve(frames)
    glide = 0.09 + 0.5 * 0.6 / RATE  # [m]
    for name in ("LeftHeel", "RightHeel"):
        moved = human.site_position(motion.q[-1], name) - human.site_position(motion.q[0], name)
        np.testing.assert_allclose(moved[:2], [glide, 0.0], atol=0.002)
    np.testing.assert_allclose(motion.q[-1, :2] - motion.q[0, :2], [glide, 0.0], atol=0.002)


def test_a_gliding_landing_heel_takes_the_body_from_the_lifting_toe(human: HumanModel) -> None:
    """Issue #19: the trailing toe of a walk, held alone, lifts off at 0.5-1.5 m/s where its
    carry along the toe can no longer follow it, while the other foot's heel has landed and
    still glides. The heel, carried with its IMU velocity, moves with its anchor: it holds the
    body as well as a still point, so the toe lets go (it was held until the heel stopped,
    50-100 ms: cmu-02-02-walk lost 4.7 cm so with perfect sensors). Not a heel planted before
    the toe: at the start of a walk the heel beginning to lift slides forward by its IMU."""
    model = HumanModel.default()
    names = list(FOOT_POINTS)
    tracker = ContactTracker(model, BodyTopology.of(model), names, SolverSettings.load())
    p = np.array([[0.3, 0.1, 0.0], [0.5, 0.1, 0.04], [-0.45, -0.1, 0.08], [-0.25, -0.1, 0.0]])
    pitch = np.array([-0.1, -0.1, 0.6, 0.6])  # landing foot toe up, trailing foot toe down
    moving = {"LeftHeel": True, "LeftToe": True, "RightHeel": True, "RightToe": True}
    velocity = {"LeftHeel": np.array([0.3, 0.0, 0.0]), "LeftToe": np.array([0.3, 0.0, 0.0]),
                "RightHeel": np.array([1.0, 0.0, 0.6]), "RightToe": np.array([0.8, 0.0, 0.3])}
    for heel_age, toe_lets_go in ((0.05, True), (2.0, False)):
        tracker.reset()
        tracker.start(p, pitch)
        tracker.touch_down(Frame(time=0.0), p, np.zeros(3))
        tracker.state = ContactState(names, np.array([True, False, False, True]), p.copy(),
                                     np.array([heel_age, 0.0, 0.0, 0.4]))
        frame = Frame(time=1 / RATE, points_moving=moving, points_velocity=velocity)
        tracker.carry(frame, 1 / RATE, None, np.array([1.3, 0.0, 0.0]))
        assert tracker.state.anchors[0, 0] == pytest.approx(0.3 + 0.3 / RATE)  # carried
        tracker.release(frame, p, pitch)
        assert tracker.state.active[0]
        assert tracker.state.active[3] == (not toe_lets_go)


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
