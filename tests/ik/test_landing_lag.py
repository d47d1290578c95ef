"""A heel that lands while the pelvis lags is anchored where the body without the lag puts it
(issue #19, cmu-02-02-walk: the lag of each push-off was lost at every step)."""

from __future__ import annotations

import numpy as np

from ikfusion.ik.contact_tracker import ContactTracker
from ikfusion.ik.contacts import ContactState
from ikfusion.ik.frame import Frame
from ikfusion.ik.landing_lag import unlagged_landings
from ikfusion.ik.settings import SolverSettings
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology

NAMES = ["LeftHeel", "LeftToe", "RightHeel", "RightToe"]
LAYOUT = BodyTopology.of(HumanModel.default()).foot_layout(NAMES)
# the true footprints: the right toe pushing off, the left heel landing 0.6 m ahead
TRUE = np.array([[0.6, 0.1, 0.0], [0.8, 0.1, 0.0], [0.0, -0.1, 0.0], [0.2, -0.1, 0.0]])
LAG = np.array([-0.01, 0.002, 0.0])  # the pelvis 1 cm behind where the right toe puts it
IMU_ONLY = Frame(1.0, {}, points_velocity={"RightToe": np.zeros(3)})


def _landing(before: list[bool], after: list[bool]) -> tuple[ContactState, np.ndarray]:
    """The state after a touch-down (every point solved where the lagging body put it), and
    the points planted before."""
    solved = TRUE.copy()
    solved[:2, :2] += LAG[:2]  # the swing leg hangs from the lagging pelvis
    return ContactState(NAMES, np.array(after), solved, np.zeros(4)), np.array(before)


def test_a_foot_landing_is_anchored_where_the_body_without_the_lag_puts_it() -> None:
    state, before = _landing([False, False, False, True], [True, False, False, True])
    out = unlagged_landings(before, state, LAYOUT, LAG, IMU_ONLY)
    np.testing.assert_allclose(out.anchors[0], TRUE[0], atol=1e-12)
    np.testing.assert_array_equal(out.anchors[1:], state.anchors[1:])  # the others stay


def test_other_landings_and_landings_with_a_correction_stay() -> None:
    """A toe coming down on a foot whose heel holds keeps the foot's shape; a foot landing flat
    or on its toes (a skip, a crouch) lands after lags of other origins; with a correction (no
    point velocities) the swing foot was led where the corrected body wants it."""
    t, f = True, False
    for before, after, frame in (([t, f, f, t], [t, t, f, t], IMU_ONLY),  # toe onto a heel
                                 ([f, f, f, t], [t, t, f, t], IMU_ONLY),  # flat
                                 ([f, f, f, t], [f, t, f, t], IMU_ONLY),  # on its toes
                                 ([f, f, t, t], [t, f, t, t], IMU_ONLY),  # other foot flat
                                 ([f, f, f, t], [t, f, f, t], Frame(1.0, {}))):  # a correction
        state, planted = _landing(before, after)
        out = unlagged_landings(planted, state, LAYOUT, LAG, frame)
        np.testing.assert_array_equal(out.anchors, state.anchors)
    # a lag with height is a hand-over's disagreement, not the carried toe's
    state, planted = _landing([f, f, f, t], [t, f, f, t])
    out = unlagged_landings(planted, state, LAYOUT, LAG + [0.0, 0.0, 0.002], IMU_ONLY)
    np.testing.assert_array_equal(out.anchors, state.anchors)


def test_a_heel_landing_after_a_lone_toe_took_off_is_anchored_less_the_take_off_lag() -> None:
    """Through the tracker: the body stands on its right toe alone with the pelvis lagging, the
    toe lets go (a few frames of flight: the support forgets its lag) and the left heel lands.
    The tracker kept the take-off's points and lag: the heel is anchored less that lag; a heel
    landing after a take-off from a flat foot (a lag of another origin) stays where it was
    solved."""
    model = HumanModel.default()
    q = model.neutral()
    q[2] -= min(model.site_position(q, n)[2] for n in NAMES)
    p = np.array([model.site_position(q, n) for n in NAMES])
    settings = SolverSettings.load()
    tracker = ContactTracker(model, BodyTopology.of(model), NAMES, settings)
    velocity = dict.fromkeys(NAMES, np.zeros(3))  # IMU only: the feet's point velocities
    for took_off_from, moved in (([False, False, False, True], True),
                                 ([False, False, True, True], False)):
        tracker.reset()
        tracker.start(p, np.zeros(4))
        tracker.state = ContactState(NAMES, np.array(took_off_from), p.copy(), np.full(4, 0.4))
        tracker.follow(p, 1 / 60)  # the body stands on those points
        tracker.support.lag = LAG.copy()
        tracker.state = ContactState.empty(NAMES)
        for _ in range(3):  # the flight: nothing planted, the support forgets its lag
            assert tracker.follow(p, 1 / 60) is None
        assert not tracker.support.lag.any()
        hints = {"LeftHeel": True, "LeftToe": False, "RightHeel": False, "RightToe": False}
        frame = Frame(time=1.0, contacts=hints, points_velocity=velocity)
        tracker.touch_down(frame, p, q[:3])
        assert tracker.state.active.tolist() == [True, False, False, False]
        expected = p[0] - LAG if moved else p[0]
        np.testing.assert_allclose(tracker.state.anchors[0], expected, atol=1e-12)
