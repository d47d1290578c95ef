"""The generator's bouncing gaits: ballistic flights, contact phases, no slip in stance."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.mocap.model_motion import TruthMotion, site_positions
from ikfusion.model import HumanModel
from ikfusion.sim.gait import GAIT_PRESETS, gait_preset, generate_gait

RATE = 60.0


def _truth(name: str, seconds: float = 5.0) -> TruthMotion:
    return generate_gait(HumanModel.default(), gait_preset(name, seconds, stand=1.0), rate=RATE)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) index pairs of the True runs of ``mask``."""
    edges = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


@pytest.fixture(scope="module", params=["hop", "skip", "jump"])
def bouncing(request: pytest.FixtureRequest) -> tuple[str, TruthMotion]:
    return request.param, _truth(request.param)


def test_the_pelvis_flies_on_a_parabola_with_gravity(bouncing: tuple[str, TruthMotion]) -> None:
    _, truth = bouncing
    airborne = ~truth.contacts.any(axis=1)
    flights = [(a, b) for a, b in _runs(airborne) if b - a >= 6]
    assert len(flights) >= 5
    for a, b in flights:
        t = truth.time[a:b] - truth.time[a]
        z = np.polyfit(t, truth.q[a:b, 2], 2)
        assert z[0] == pytest.approx(-9.81 / 2, rel=0.01)  # free fall, apex above take-off
        assert z[1] > 0.5
        for axis in (0, 1):  # no horizontal force in the air: constant velocity
            line = np.polyfit(t, truth.q[a:b, axis], 1)
            assert np.abs(np.polyval(line, t) - truth.q[a:b, axis]).max() < 1e-3


def test_planted_points_do_not_slide_and_stand_on_the_floor(
        bouncing: tuple[str, TruthMotion]) -> None:
    _, truth = bouncing
    points = site_positions(truth.model, truth.q, list(truth.contact_names))
    for i in range(len(truth.contact_names)):
        for a, b in _runs(truth.contacts[:, i]):
            assert np.ptp(points[a:b, i], axis=0).max() < 1e-3
            assert np.abs(points[a:b, i, 2]).max() < 1e-3
    assert points[..., 2].min() > -1e-3


def test_each_gait_lands_on_its_own_feet(bouncing: tuple[str, TruthMotion]) -> None:
    name, truth = bouncing
    names = list(truth.contact_names)
    start = int(2.2 * RATE)  # after the lift of a free foot and the first take-off
    right = truth.contacts[start:, names.index("RightHeel")]
    left = truth.contacts[start:, names.index("LeftHeel")]
    landings = [("R" if right[a] else "") + ("L" if left[a] else "")
                for a, _ in _runs(right | left)]
    assert len(landings) >= 5
    expected = {"hop": "R", "jump": "RL"}
    if name in expected:
        assert set(landings) == {expected[name]}
    else:  # skipping: step-hop on each leg, right right left left ...
        assert set(landings) == {"R", "L"}
        pairs = "".join(landings)
        assert "RRLL" in pairs and "RRR" not in pairs and "LLL" not in pairs


def test_bouncing_gaits_are_named_presets() -> None:
    assert {"hop", "skip", "jump"} <= set(GAIT_PRESETS)
    with pytest.raises(ValueError, match="bounce"):
        generate_gait(HumanModel.default(), gait_preset("hop", 3.0).__class__(
            bounce="cartwheel", duration=3.0))
