"""Planted points sharing one rigid segment are held by independent rows (issue #19).

A body lying on its back rests on both shoulder blades (both on T8) and on its sacrum and
buttocks (all three on the pelvis). Held with three rows each, such points give dependent rows
(a rigid segment has six degrees of freedom), and as soon as an anchor is a little off the
segment's shape (an anchor settling toward the floor, a segment that turned since the last
frame) the contact QP was infeasible: dm-getup-faceup needed relaxed constraints in 91-121
frames, and the projection relaxed the same way. Their anchors also settle toward the floor
together: one settling alone, next to another already on the floor, tilted the segment about that
one and its point slid sideways (dm-getup-faceup's shoulder blades: 1.9 mm while held).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from motions import frames_from

from ikfusion.ik import Configuration, Solver, SolverSettings
from ikfusion.ik.contacts import ContactState, ContactThresholds, touch_down
from ikfusion.ik.limits import ContactConstraint, FloorLimit, JointRangeLimit
from ikfusion.ik.limits.shared_segment import shared_segment_rows
from ikfusion.ik.projection import project_on_contacts
from ikfusion.mocap.model_motion import site_positions
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology

BACK = ("LeftShoulderBlade", "RightShoulderBlade", "Sacrum", "LeftButtock", "RightButtock",
        "LeftHeel", "RightHeel")


def constraint(human: HumanModel, names: tuple[str, ...]) -> ContactConstraint:
    """The contact constraint of ``names``, each point on its own segment."""
    return ContactConstraint([human.site_frame_id(n) for n in names], names,
                             [human.sites[n].segment for n in names])


def settled(P: np.ndarray, names: tuple[str, ...], lowered: tuple[str, ...]) -> np.ndarray:
    """Anchors at the points ``P`` (k, 3) [m], those ``lowered`` 1 cm lower (settling)."""
    anchors = P.copy()
    for n in lowered:
        anchors[names.index(n), 2] -= 0.01
    return anchors


@pytest.mark.parametrize(("names", "rows"), [
    (("LeftShoulderBlade", "RightShoulderBlade"), 3 + 2),
    (("Sacrum", "LeftButtock", "RightButtock"), 3 + 2 + 1),
    (BACK, 3 + 2 + 3 + 2 + 1 + 3 + 3),
])
def test_points_on_one_segment_give_independent_rows(human: HumanModel,
                                                     names: tuple[str, ...], rows: int) -> None:
    rng = np.random.default_rng(3)
    conf = Configuration(human.model, human.random_configuration(rng))
    contact = constraint(human, names)
    P = conf.positions(contact.frame_ids)
    contact.set_anchors(np.ones(len(names), dtype=bool), settled(P, names, names[1:2]))
    A = contact.equality(conf).A
    assert A.shape[0] == rows
    assert np.linalg.matrix_rank(A) == rows  # three rows each: rank 5 of 6, 6 of 9


def test_a_body_lying_on_its_back_is_held_without_relaxing(human: HumanModel) -> None:
    """Back, pelvis and heels planted, two anchors settled 1 cm, the body turned a little."""
    settings = SolverSettings.load()
    rng = np.random.default_rng(4)
    q0 = human.random_configuration(rng, margin_deg=20.0)
    conf = Configuration(human.model, q0)
    contact = constraint(human, BACK)
    P = conf.positions(contact.frame_ids)
    lowered = ("RightShoulderBlade", "RightButtock")
    anchors = settled(P, BACK, lowered)
    contact.set_anchors(np.ones(len(BACK), dtype=bool), anchors)
    floor = FloorLimit(contact.frame_ids, float(P[:, 2].min()) - 1.0)  # out of the way
    floor.enabled[:] = False
    conf.update(conf.integrate(rng.normal(scale=0.02, size=human.model.nv)))  # ~1 deg each
    relaxed = project_on_contacts(conf, contact, floor, JointRangeLimit(human.ball_joints, 0.0),
                                  contact.frame_ids, settings.constraint_tolerance,
                                  settings.projection_steps, settings.backend, settings.qp)
    assert not relaxed
    assert (contact.planted_slide_m(conf.positions(contact.frame_ids))
            <= settings.constraint_tolerance).all()
    # the points whose anchors kept their place are exactly on them; the lowered ones within
    # the 1 cm their anchors moved
    off = np.linalg.norm(conf.positions(contact.frame_ids) - anchors, axis=1)
    kept = np.array([n not in lowered for n in BACK])
    assert off[kept].max() < 1e-4
    assert off[~kept].max() < 0.011


def test_points_alone_on_their_segments_keep_the_world_axes() -> None:
    active = np.array([True, True, False])
    assert shared_segment_rows(["LeftFoot", "RightFoot", "T8"], active, np.zeros((3, 3)),
                               np.zeros(3, dtype=bool)) is None


def lying_on_the_back(human: HumanModel, roll_deg: float, seconds: float = 2.0,
                      rate: float = 60.0) -> np.ndarray:
    """A body lying on its back, rolled ``roll_deg`` onto its left side (the right shoulder
    blade ``d sin(roll)`` above the left one), its pelvis turning under the upper trunk.

    The left shoulder blade starts on the floor; every other contact point is above it.
    """
    qs = []
    for k in range(int(seconds * rate)):
        s = np.sin(np.pi * k / rate)
        R = (pin.utils.rotate("z", np.radians(4.0 * s))
             @ pin.utils.rotate("x", np.radians(roll_deg))
             @ pin.utils.rotate("y", -np.pi / 2))  # face up, the head toward -x
        qs.append(human.configuration({"jL5S1_rot": 10.0 * s, "jL5S1_flex": 5.0 * s},
                                      R_world_pelvis=R))
    q = np.array(qs)
    q[:, 2] -= site_positions(human, q[:1], ["LeftShoulderBlade"])[0, 0, 2]
    return q


def test_a_body_held_on_both_shoulder_blades_does_not_slide(human: HumanModel) -> None:
    """Planted on both shoulder blades, the right one 27 mm up: neither moves while held.

    Old code: the right blade's anchor settled straight down to the floor while the left one
    stayed, the segment tilted about the left one, and the right blade slid 2.2 mm sideways.
    """
    names = human.sites_of_kind("contact")
    blades = [names.index("LeftShoulderBlade"), names.index("RightShoulderBlade")]
    q = lying_on_the_back(human, roll_deg=-9.0)
    start = site_positions(human, q[:1], names)[0]
    assert start[:, 2].min() == pytest.approx(start[blades[0], 2], abs=1e-9)
    assert start[blades[1], 2] > 0.02
    hints = {n: i in blades for i, n in enumerate(names)}
    motion = Solver(human).solve([replace(f, contacts=hints) for f in frames_from(human, q)])
    assert motion.contacts[:, blades].all()
    assert not motion.relaxed.any()
    p = site_positions(human, motion.q, names)[:, blades]
    slide = np.linalg.norm(p[..., :2] - p[:1, :, :2], axis=2)
    assert slide.max() < 1e-3  # the limit (old code: 2.2 mm)
    # they stay where they were planted, the right one at its height (no settling alone)
    assert np.abs(p[..., 2] - p[:1, :, 2]).max() < 1e-3


def test_planted_points_of_one_segment_settle_together(human: HumanModel) -> None:
    """Anchors above the floor settle at ``settle_speed``; those of one segment as one."""
    names = ["LeftShoulderBlade", "RightShoulderBlade", "Chest", "Sacrum"]
    layout = BodyTopology.of(human).foot_layout(names)
    np.testing.assert_array_equal(layout.same_segment, [[1, 1, 1, 0], [1, 1, 1, 0],
                                                        [1, 1, 1, 0], [0, 0, 0, 1]])
    th = ContactThresholds.from_settings(SolverSettings.load())
    dt = 1 / 60
    state = ContactState.empty(names)
    state.active[:] = [True, True, False, True]
    state.anchors[:] = [[0.0, 0.1, 0.004], [0.0, -0.1, 0.03], [0.1, 0.0, 0.05],
                        [0.4, 0.0, 0.02]]
    p = state.anchors.copy()
    hints = {n: bool(a) for n, a in zip(names, state.active)}
    frames = 3
    for _ in range(frames):
        state = touch_down(state, p, p, p, dt, th, hints, layout=layout)
    drop = frames * th.settle_speed * dt
    assert 0.004 < drop < 0.02  # the left blade reached the floor, the sacrum not yet
    z = state.anchors[:, 2]
    # both blades went down by the left one's 4 mm: their shape is kept, the right one 26 mm up
    np.testing.assert_allclose(z[:2], [0.0, 0.026], atol=1e-12)
    # the chest (not planted) and the sacrum (alone on the pelvis) settle on their own
    np.testing.assert_allclose(z[2:], [0.05 - drop, 0.02 - drop], atol=1e-12)
    assert np.array_equal(state.anchors[:, :2], p[:, :2])


def test_rows_follow_the_planted_points_from_call_to_call(human: HumanModel) -> None:
    """One constraint set again and again (the solver's, frame after frame; the world-axes
    rows are kept while the same points are planted) holds what a fresh constraint holds:
    the same rows and slides when the points stay, when a heel rises, when a second point of
    a segment is planted (shared rows) and when it lets go (the world axes again)."""
    rng = np.random.default_rng(23)
    conf = Configuration(human.model, human.neutral())
    P = conf.positions([human.site_frame_id(n) for n in BACK])
    k = len(BACK)
    heel = BACK.index("LeftHeel")
    blades = [BACK.index("LeftShoulderBlade"), BACK.index("RightShoulderBlade")]
    steps = [([heel], []), ([heel], []), ([heel], [heel]), ([heel], []),
             ([heel, *blades], []), ([heel, *blades], []), ([heel], []), ([heel], [heel])]
    reused = constraint(human, BACK)
    for planted, rising in steps:
        active, free_z = np.zeros(k, dtype=bool), np.zeros(k, dtype=bool)
        active[planted], free_z[rising] = True, True
        anchors = P + 0.01 * rng.normal(size=P.shape)
        fresh = constraint(human, BACK)
        for c in (reused, fresh):
            c.set_anchors(active, anchors, free_z)
        assert np.array_equal(reused.planted_slide_m(P), fresh.planted_slide_m(P))
        for mine, theirs in zip(reused.equality(conf), fresh.equality(conf)):
            assert np.array_equal(mine, theirs)
        # the second blade on T8 is held across the line from the first only (two rows)
        assert len(reused.equality(conf).b) == 3 * len(planted) - len(rising) - (
            1 if len(planted) == 3 else 0)


def test_the_rows_from_positions_are_the_equality_rows_on_a_shared_segment(
        human: HumanModel) -> None:
    """The projection's QP takes the rows from every point's positions and Jacobians
    (:meth:`ContactConstraint.rows`): on a lying body's shared segments, too, the very numbers
    of :meth:`ContactConstraint.equality`."""
    rng = np.random.default_rng(6)
    conf = Configuration(human.model, human.random_configuration(rng, margin_deg=20.0))
    contact = constraint(human, BACK)
    P = conf.positions(contact.frame_ids)
    planted = rng.random(len(BACK)) < 0.8
    contact.set_anchors(planted, settled(P, BACK, ("RightShoulderBlade",)))
    assert contact._basis is not None  # points sharing a segment: rows along their own axes
    for fresh, given in zip(contact.equality(conf),
                            contact.rows(P, conf.linear_jacobians(contact.frame_ids))):
        assert np.array_equal(fresh, given)
