"""Planted points sharing one rigid segment are held by independent rows (issue #19).

A body lying on its back rests on both shoulder blades (both on T8) and on its sacrum and
buttocks (all three on the pelvis). Held with three rows each, such points give dependent rows
(a rigid segment has six degrees of freedom), and as soon as an anchor is a little off the
segment's shape (an anchor settling toward the floor, a segment that turned since the last
frame) the contact QP was infeasible: dm-getup-faceup needed relaxed constraints in 91-121
frames, and the projection relaxed the same way.
"""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.ik import Configuration, SolverSettings
from ikfusion.ik.limits import ContactConstraint, FloorLimit, JointRangeLimit
from ikfusion.ik.limits.shared_segment import shared_segment_rows
from ikfusion.ik.projection import project_on_contacts
from ikfusion.model import HumanModel

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
