"""Hands on the floor: a cartwheel is carried by its palms, never by a foot swung overhead."""

from __future__ import annotations

import numpy as np
from motions import frames_from

from ikfusion.app.evaluate import phase_slides
from ikfusion.ik import Solver
from ikfusion.ik.contacts import ContactState, ContactThresholds, release_contacts
from ikfusion.mocap.model_motion import TruthMotion, contact_phases, site_positions
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology, FootLayout


def test_cartwheel_holds_no_point_off_the_floor(cartwheels: TruthMotion) -> None:
    model, q = cartwheels.model, cartwheels.q
    names = model.sites_of_kind("contact")
    motion = Solver(model).solve(frames_from(model, q, stance=True))
    p_true = site_positions(model, q, names)
    held = motion.contacts
    # a point is held only where the true one is on the floor (the old code held a heel that
    # rose to 1.7 m while the body turned over the hands)
    assert not (held & (p_true[..., 2] > 0.2)).any()
    # the true points barely move while they are held (old: 1.1 m)
    assert max(phase_slides(p_true, held)) < 0.3
    # the palms carry the body while the feet are up
    truth = contact_phases(model, q, cartwheels.time, names)
    palms = [names.index("LeftPalm"), names.index("RightPalm")]
    on_hands = truth[:, palms].any(axis=1)
    assert held[on_hands][:, palms].any(axis=1).mean() > 0.5
    # the pelvis follows: old 2.8 m off at the end
    err = motion.q[:, :2] - q[:, :2]
    assert np.linalg.norm(err[-1] - err[0]) < 0.5


def _contact_setup(human: HumanModel) -> tuple[list[str], FootLayout, ContactThresholds]:
    """The model's contact point names, their foot layout and flat-floor thresholds."""
    names = list(human.sites_of_kind("contact"))
    th = ContactThresholds(floor_z=0.0, enter_height=0.03, enter_speed=0.5,
                           enter_relative=0.03, leave_relative=0.025, leave_distance=0.02,
                           settle_speed=0.2, tilt_deg=2.0, still_relative=0.06,
                           reenter_delay=0.2)
    return names, BodyTopology.of(human).foot_layout(names), th


def test_body_handed_to_the_lowest_palm_when_the_planted_toe_swings_up(
        human: HumanModel) -> None:
    names, layout, th = _contact_setup(human)
    toe, palm = names.index("RightToe"), names.index("LeftPalm")
    state = ContactState.empty(names)
    state.active[toe] = True
    state.anchors[toe] = [1.0, 2.0, 0.0]
    # sensed pose (any translation): the palm lowest, the toe 1.2 m above it, the rest between
    p_sensed = np.tile([0.0, 0.0, 0.8], (len(names), 1))
    p_sensed[palm] = [0.3, -0.2, 0.1]
    p_sensed[toe] = [0.5, 0.4, 1.3]
    out = release_contacts(state, p_sensed, th, layout=layout)
    assert not out.active[toe]
    assert out.active[palm] and out.active.sum() == 1
    # anchored where the sensed pose puts it relative to the toe's anchor, on the floor
    np.testing.assert_allclose(out.anchors[palm], [0.8, 1.4, 0.0], atol=1e-9)
    # a heel slightly below a lifting toe of the other foot is not taken over (walking)
    heel = names.index("LeftHeel")
    p_sensed[toe, 2], p_sensed[heel, 2], p_sensed[palm, 2] = 0.14, 0.1, 0.5
    out = release_contacts(state, p_sensed, th, layout=layout)
    assert out.active[toe] and out.active.sum() == 1


def test_point_taking_the_body_is_anchored_where_it_was_solved(human: HumanModel) -> None:
    """Issue #19 (dm-getup-facedown, causal no-slide): the body kneeling down from a toe onto
    its knee. The solve holds the toe with its legs bent a little away from their sensors (the
    drift correction's pulls and lean); the knee that takes the body was anchored where the
    unbent sensed pose puts it, 5 cm from where it was solved, and the hips, knees and ankles
    jumped by 4-5 deg in that frame (and by 7 deg when the knee let go again)."""
    names, layout, th = _contact_setup(human)
    toe, knee = names.index("RightToe"), names.index("RightKnee")
    state = ContactState.empty(names)
    state.active[toe] = True
    state.anchors[toe] = [3.216, 3.655, 0.0]
    # sensed pose (any translation): the knee lowest, the toe rising off the floor behind it
    p_sensed = np.tile([0.0, 0.0, 0.5], (len(names), 1))
    p_sensed[toe] = [0.1, -0.2, 0.043]
    p_sensed[knee] = [0.0, 0.147, 0.0]
    # the last solve: the toe on its anchor, the knee on the floor 5.3 cm beside where the
    # sensed pose aligned on the toe's anchor puts it (3.116, 4.002)
    p_solved = np.tile([3.0, 4.0, 0.5], (len(names), 1))
    p_solved[toe] = state.anchors[toe]
    p_solved[knee] = [3.132, 4.055, 0.0]
    out = release_contacts(state, p_sensed, th, p_solved=p_solved, layout=layout)
    assert out.active[knee] and out.active.sum() == 1
    # it stays where it was solved: nothing jumps (old: anchored at [3.116, 4.002])
    np.testing.assert_allclose(out.anchors[knee], [3.132, 4.055, 0.0], atol=1e-9)
