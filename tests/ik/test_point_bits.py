"""The contact points as int bits: every conversion and group equals the plain NumPy mask rule,
whatever the pattern, met first or again."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.ik.point_bits import first, has, indices, point_bits
from ikfusion.ik.point_evidence import motion_bits, stance_bits, tilted_bits, tilted_of
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology, FootLayout


@pytest.fixture(scope="module")
def layout(human: HumanModel) -> FootLayout:
    return BodyTopology.of(human).foot_layout(human.sites_of_kind("contact"))


def _plain(mask: np.ndarray) -> int:
    """Bit i set where ``mask[i]``: plain arithmetic."""
    return sum(2 ** int(i) for i in np.flatnonzero(mask))


def test_masks_and_bits_convert_both_ways(layout: FootLayout, rng: np.random.Generator) -> None:
    bits = point_bits(layout)
    k = len(layout.on_foot)
    patterns = [rng.random(k) < p for p in (0.0, 0.2, 0.5, 1.0) for _ in range(10)]
    for mask in patterns + patterns[::-1]:
        b = bits.of(mask)
        assert b == _plain(mask) and bits.of(mask.astype(float)) == b
        np.testing.assert_array_equal(bits.mask(b), mask)
        assert not bits.mask(b).flags.writeable and bits.array(b).flags.writeable
        assert indices(b) == tuple(np.flatnonzero(mask).tolist())
        assert all(has(b, i) == mask[i] for i in range(k))
        if mask.any():
            assert first(b) == int(np.argmax(mask))
    assert point_bits(layout) is bits  # kept with the layout


def test_groups_are_the_layouts(layout: FootLayout, rng: np.random.Generator) -> None:
    bits = point_bits(layout)
    assert bits.heels == _plain(layout.on_foot) and bits.toes == _plain(layout.below_foot)
    assert bits.stepping == _plain(layout.stepping)
    assert bits.shares_segment == _plain(layout.shares_segment)
    other = ~layout.same_foot
    for _ in range(60):
        mask = rng.random(len(layout.on_foot)) < rng.random()
        expected = (other & mask[None, :]).any(axis=1)  # row i: the other foot of point i
        assert bits.other_foot(bits.of(mask)) == _plain(expected)


def test_evidence_bits_are_the_masks(layout: FootLayout, rng: np.random.Generator) -> None:
    bits = point_bits(layout)
    k = len(layout.on_foot)
    for _ in range(60):
        pitch = rng.normal(scale=0.4, size=k)
        pitch[rng.random(k) < 0.2] = np.nan  # unknown: not tilted
        tilted = (layout.on_foot & (pitch > 0.3)) | (layout.below_foot & (pitch < -0.3))
        assert tilted_bits(bits, pitch, 0.3) == _plain(tilted)
        # sensed_evidence.python_evidence's call: the rows as plain index lists
        heels, toes = np.flatnonzero(layout.on_foot), np.flatnonzero(layout.below_foot)
        assert tilted_of(pitch.tolist(), 0.3, heels.tolist(), toes.tolist()) == _plain(tilted)
        evidence = rng.choice([0.0, 1.0, np.nan], size=k)
        assert motion_bits(bits, evidence) == (_plain(evidence == 1.0), _plain(evidence == 0.0))
        assert stance_bits(bits, evidence) == (_plain(evidence == 1.0), _plain(evidence == 0.0))
    assert tilted_bits(bits, None, 0.3) == 0 and stance_bits(bits, None) == (0, 0)
