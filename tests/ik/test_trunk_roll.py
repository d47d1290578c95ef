"""A body sitting up rolls on its back: the contact passes along the trunk (issue #19).

Issue #19 (dm-getup-faceup, perfect sensors, no UWB): sitting up, every IMU says its segment
moves. When the shoulder blade let go, the moving sacrum below it could not take the body, a
palm 5-6 cm higher took it and dragged the body along; a held trunk point stayed held while
its segment rolled onto another of its points; and a palm touching down beside the seat pulled
the (older) buttock off the floor.
"""

from __future__ import annotations

import numpy as np

from ikfusion.ik.contacts import ContactState, ContactThresholds, release_contacts
from ikfusion.ik.settings import SolverSettings
from ikfusion.model import HumanModel
from ikfusion.model.layout import TRUNK_CONTACT_SITES
from ikfusion.model.topology import BodyTopology

NAMES = ["LeftHeel", "LeftToe", "RightHeel", "RightToe", "LeftPalm", "RightPalm", "Sacrum",
         "LeftButtock", "RightButtock", "LeftShoulderBlade"]
LAYOUT = BodyTopology.of(HumanModel.default()).foot_layout(NAMES)
NEEDS_REST = np.array([n in TRUNK_CONTACT_SITES for n in NAMES])
TH = ContactThresholds.from_settings(SolverSettings.load())
MOVING = np.zeros(len(NAMES))  # every IMU says its segment moves (a body sitting up)


def _pose(z: dict[str, float]) -> np.ndarray:
    """(k, 3) points spread 0.2 m apart along x, at the given heights (others 0.4 m) [m]."""
    return np.array([[0.2 * i, 0.05 * i, z.get(n, 0.4)] for i, n in enumerate(NAMES)])


def _holding(p: np.ndarray, ages: dict[str, float]) -> ContactState:
    """The named points planted where ``p`` puts them, with the given contact ages [s]."""
    state = ContactState.empty(NAMES)
    state.anchors[:] = p
    for name, age in ages.items():
        state.active[NAMES.index(name)], state.age[NAMES.index(name)] = True, age
    return state


def _released(state: ContactState, p: np.ndarray) -> ContactState:
    return release_contacts(state, p, TH, foot_still=MOVING, p_solved=p, layout=LAYOUT,
                            needs_rest=NEEDS_REST)


def _held(state: ContactState) -> list[str]:
    return [n for n, a in zip(NAMES, state.active) if a]


def test_the_sacrum_takes_the_body_from_a_shoulder_blade_that_lets_go() -> None:
    # the shoulder blade lifts 4 cm; the sacrum is lowest, a palm 5 cm above it
    p = _pose({"LeftShoulderBlade": 0.04, "Sacrum": 0.0, "LeftPalm": 0.05, "RightPalm": 0.12})
    out = _released(_holding(_pose({"LeftShoulderBlade": 0.0}), {"LeftShoulderBlade": 1.0}), p)
    assert _held(out) == ["Sacrum"]  # before: ["LeftPalm"] (a moving trunk point took nothing)
    # a body rising off its feet is not put on a moving trunk point swung low: as before, the
    # lifted toe keeps it (the other foot is within still_relative of the floor)
    p = _pose({"LeftToe": 0.04, "Sacrum": 0.0, "RightHeel": 0.01})
    out = _released(_holding(_pose({"LeftToe": 0.0}), {"LeftToe": 1.0}), p)
    assert _held(out) == ["LeftToe"]


def test_a_held_sacrum_rolls_onto_the_buttock_its_pelvis_turns_lower() -> None:
    held = _pose({"Sacrum": 0.0, "RightButtock": 0.01})
    state = _holding(held, {"Sacrum": 0.3})
    # the pelvis rolls: the right buttock now 1 cm below the sacrum (less than leave_relative)
    p = held + [0.3, -0.2, 0.0]  # any translation of the sensed pose
    p[NAMES.index("Sacrum"), 2] = 0.01
    p[NAMES.index("RightButtock"), :2] += [0.02, -0.01]
    p[NAMES.index("RightButtock"), 2] = 0.0
    out = _released(state, p)
    assert _held(out) == ["RightButtock"]  # before: ["Sacrum"] held while the seat rolls
    i, j = NAMES.index("Sacrum"), NAMES.index("RightButtock")
    # anchored where the sensed pelvis puts it relative to the sacrum's anchor, on the floor
    np.testing.assert_allclose(out.anchors[j, :2], held[i, :2] + p[j, :2] - p[i, :2],
                               atol=1e-12)
    assert out.anchors[j, 2] == TH.floor_z
    assert out.age[j] == 0.3 and out.released[i] == 0.0
    # a level pelvis (within the margin) keeps its point
    level = held.copy()
    level[j, 2] = 0.001
    level[i, 2] = 0.0
    assert _held(_released(_holding(held, {"Sacrum": 0.3}), level)) == ["Sacrum"]


def test_a_palm_that_disagrees_with_the_seat_lets_go_not_the_seat() -> None:
    # the body sits on its right buttock; a palm touched down just now beside it
    held = _pose({"RightButtock": 0.0, "RightPalm": 0.0})
    state = _holding(held, {"RightButtock": 0.5, "RightPalm": 0.0})
    p = held.copy()
    p[NAMES.index("RightPalm"), 0] += 0.04  # the sensed pose pulls them 4 cm apart
    out = _released(state, p)
    assert _held(out) == ["RightButtock"]  # before: ["RightPalm"] (the older point let go)
    # two feet that disagree: the one planted earlier lets go (toe-off), as before
    held = _pose({"LeftToe": 0.0, "RightHeel": 0.0})
    feet = _holding(held, {"LeftToe": 0.5, "RightHeel": 0.0})
    p = held.copy()
    p[NAMES.index("RightHeel"), 0] += 0.04
    out = release_contacts(feet, p, TH, p_solved=p, layout=LAYOUT, needs_rest=NEEDS_REST)
    assert _held(out) == ["RightHeel"]
