"""The touch-down's landing rules (ikfusion.ik.landing_rules) checked cheap rules first (#20).

:func:`may_land` applies the rules without speeds first and measures the speeds of the
candidates left only; its answer must be the conjunction of every rule over every candidate,
as :func:`_every_rule` writes it, on random frames of every kind.
"""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.ik import SolverSettings
from ikfusion.ik.contact_thresholds import ContactThresholds
from ikfusion.ik.landing_rules import _slow, may_land
from ikfusion.ik.point_bits import PointBits, indices, point_bits
from ikfusion.ik.point_evidence import FrameEvidence, motion_bits
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology

MODEL = HumanModel.default()
LAYOUT = BodyTopology.of(MODEL).foot_layout(MODEL.sites_of_kind("contact"))
K = len(LAYOUT.on_foot)


def _every_rule(bits: PointBits, on: int, enter: int, p_solved: np.ndarray,
                p_solved_previous: np.ndarray, dt: float, ev: FrameEvidence,
                released: np.ndarray, th: ContactThresholds,
                points_moving: np.ndarray | None) -> int:
    """Every landing rule over every candidate, in one conjunction (the reference)."""
    height_rel, rows = ev.height_rel, indices(enter)
    moving_point, settled = motion_bits(bits, points_moving)
    since = released.tolist()
    slow = _slow(rows, p_solved, p_solved_previous, dt, th.enter_speed)
    support_moving = (bits.of(height_rel <= np.min(height_rel[bits.mask(on)], initial=np.inf))
                      if on and not on & ~moving_point else 0)
    ok = ((slow | settled | support_moving) & ~ev.tilted
          & (sum(1 << i for i in rows if since[i] >= th.reenter_delay) | settled))
    if points_moving is not None:
        ok &= ~(moving_point & bits.other_foot(on & ~moving_point))
    return enter & ok & ~(ev.rest & ev.foot_moves)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cheap_rules_first_give_every_rules_answer(seed: int) -> None:
    rng = np.random.default_rng(seed)
    bits, th = point_bits(LAYOUT), ContactThresholds.from_settings(SolverSettings.load())
    landed = 0
    for _ in range(3000):
        def some() -> int:
            return int(rng.integers(1 << K)) & int(rng.integers(1 << K))

        on, enter = some(), some()
        enter &= ~on
        ev = FrameEvidence(rng.random(K) * 0.05, some(), some(), some(), some(), 0, 0)
        p = rng.normal(scale=0.3, size=(K, 3))
        p_before = p + rng.normal(scale=0.004, size=(K, 3)) * rng.integers(1, 4)
        dt = float(rng.choice([0.01, 0.03, 0.0, -0.01]))
        released = rng.choice([0.0, 0.1, 0.25, np.inf], size=K)
        moving = (None if rng.random() < 0.5 else
                  rng.choice([0.0, 1.0, np.nan], size=K))
        args = (bits, on, enter, p, p_before, dt, ev, released, th, moving)
        want = _every_rule(*args)
        assert may_land(*args) == want
        landed += want != 0
    assert landed > 100  # (cases where some point lands, not only refusals)
