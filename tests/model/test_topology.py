"""Body topology from the model's tree and the sites' segments, never from names."""

from __future__ import annotations

import numpy as np

from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology, segment_parents


def test_feet_legs_and_toe_joints_of_the_default_model() -> None:
    model = HumanModel.default()
    topology = BodyTopology.of(model)
    points = model.sites_of_kind("contact")
    assert {p: topology.foot_of(p) for p in points} == {
        "LeftHeel": "LeftFoot", "LeftToe": "LeftFoot",
        "RightHeel": "RightFoot", "RightToe": "RightFoot",
        "LeftKnee": "LeftLowerLeg", "RightKnee": "RightLowerLeg",
        "LeftPalm": "LeftHand", "RightPalm": "RightHand",
        "Sacrum": "Pelvis", "LeftButtock": "Pelvis", "RightButtock": "Pelvis",
        "LeftShoulderBlade": "T8", "RightShoulderBlade": "T8", "Chest": "T8"}
    assert topology.chain("LeftFoot") == ["LeftFoot", "LeftLowerLeg", "LeftUpperLeg"]
    assert topology.foot_of("HeadTop") is None and topology.foot_of("LeftFootTop") == "LeftFoot"
    toes = [j.name for j in model.ball_joints.values()
            if topology.is_toe_joint(j.spec.parent, j.spec.child)]
    assert sorted(toes) == ["jLeftBallFoot", "jRightBallFoot"]
    layout = topology.foot_layout(points)
    assert layout.on_foot.tolist() == ["Toe" not in p for p in points]
    assert layout.below_foot.tolist() == ["Toe" in p for p in points]
    assert layout.stepping.tolist() == ["Heel" in p or "Toe" in p for p in points]


def test_segment_parents_of_the_default_model() -> None:
    """Every segment once, in the model's order; the root has no parent, the rest lead to it."""
    model = HumanModel.default()
    parents = segment_parents(model)
    assert list(parents) == list(model.segment_names)
    assert [s for s, p in parents.items() if p is None] == ["Pelvis"]
    assert parents["LeftToe"] == "LeftFoot" and parents["RightFoot"] == "RightLowerLeg"
    assert parents["Head"] == "Neck" and parents["LeftShoulder"] == "T8"
    for segment in parents:
        chain = [segment]
        while parents[chain[-1]] is not None:
            chain.append(str(parents[chain[-1]]))
            assert len(chain) <= len(parents)
        assert chain[-1] == "Pelvis"


def test_knees_and_palms_are_contact_groups_of_their_own() -> None:
    """A knee on the lower leg does not swallow the foot below it; a hand's limb ends at the
    shoulder, a leg's at the hip."""
    model = HumanModel.default()
    topology = BodyTopology.of(model)
    points = model.sites_of_kind("contact")
    assert points[:8] == ["LeftHeel", "LeftToe", "RightHeel", "RightToe",
                          "LeftKnee", "RightKnee", "LeftPalm", "RightPalm"]
    layout = topology.foot_layout(points)
    # then the pelvis (sacrum, buttocks) and the upper trunk (shoulder blades, chest)
    assert layout.feet.sum(axis=1).tolist() == [2, 2, 1, 1, 1, 1, 3, 3]
    assert topology.limb("LeftFoot") == topology.chain("LeftFoot")
    assert topology.limb("LeftLowerLeg") == ["LeftLowerLeg", "LeftUpperLeg"]
    assert topology.limb("RightHand") == ["RightHand", "RightForeArm", "RightUpperArm",
                                          "RightShoulder"]
    q = model.neutral()
    # the N-pose stands on heels and toes; knees and palms are far above the floor
    for name in ("LeftKnee", "RightKnee", "LeftPalm", "RightPalm"):
        assert model.site_position(q, name)[2] > 0.3


def test_a_lying_body_rests_on_trunk_groups_that_swallow_no_other_segment() -> None:
    """The pelvis (the root) and the upper trunk carry contact groups of their own; the head
    under the trunk stays on no foot (its tag is a body tag), and a hand is its own."""
    model = HumanModel.default()
    topology = BodyTopology.of(model)
    assert topology.foot_of("HeadTop") is None
    assert topology.foot_of_segment("Head") is None and topology.foot_of_segment("T12") is None
    assert topology.foot_of("LeftPalm") == "LeftHand"
    assert topology.feet(["Sacrum", "Chest", "RightPalm"]) == ["Pelvis", "T8", "RightHand"]
    assert topology.limb("Pelvis") == [] and topology.limb("T8")[0] == "T8"
    assert not any(topology.is_toe_joint(j.spec.parent, j.spec.child)
                   for j in model.ball_joints.values() if "Toe" not in j.spec.child)
    layout = topology.foot_layout(model.sites_of_kind("contact"))
    trunk = [model.sites_of_kind("contact").index(n) for n in ("Sacrum", "Chest", "LeftButtock")]
    assert not layout.stepping[trunk].any()
    q = model.neutral()
    # standing in the N-pose, the trunk's points are far above the floor
    for name in ("Sacrum", "LeftButtock", "RightShoulderBlade", "Chest"):
        assert model.site_position(q, name)[2] > 0.7


def test_the_topology_does_not_read_names() -> None:
    """Segments and sites named in another language: the same feet, heels and legs."""
    parent = {"tronc": "bassin", "cuisse_a": "bassin", "jambe_a": "cuisse_a",
              "pied_a": "jambe_a", "orteils_a": "pied_a", "cuisse_b": "bassin",
              "jambe_b": "cuisse_b", "pied_b": "jambe_b", "orteils_b": "pied_b"}
    sites = {"talon_b": "pied_b", "bout_b": "orteils_b", "talon_a": "pied_a",
             "bout_a": "orteils_a", "tete": "tronc"}
    points = ("talon_b", "bout_b", "talon_a", "bout_a")
    topology = BodyTopology(("bassin", *parent), parent, sites, points)
    assert [topology.foot_of(p) for p in points] == ["pied_b", "pied_b", "pied_a", "pied_a"]
    assert topology.foot_of("tete") is None
    assert topology.chain("pied_a") == ["pied_a", "jambe_a", "cuisse_a"]
    assert topology.is_toe_joint("pied_b", "orteils_b")
    assert not topology.is_toe_joint("jambe_b", "pied_b")
    layout = topology.foot_layout(points)
    assert layout.on_foot.tolist() == [True, False, True, False]
    np.testing.assert_array_equal(layout.same_foot, [[1, 1, 0, 0], [1, 1, 0, 0],
                                                     [0, 0, 1, 1], [0, 0, 1, 1]])
    np.testing.assert_array_equal(layout.feet, [[1, 1, 0, 0], [0, 0, 1, 1]])
    assert topology.foot_layout([]).feet.shape == (0, 0)
