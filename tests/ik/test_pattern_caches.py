"""The frame loop's kept results: what is worked out once per pattern of planted points or feet
stance must equal the plain computation whichever pattern comes back, and must not be mutable."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ikfusion.ik.contact_tracker import ContactTracker
from ikfusion.ik.fast_math import any_true
from ikfusion.ik.frame import Frame
from ikfusion.ik.settings import SolverSettings
from ikfusion.ik.support import SupportFollower
from ikfusion.model import HumanModel
from ikfusion.model.topology import BodyTopology


@pytest.mark.parametrize("values", [
    np.zeros(0, dtype=bool), np.zeros(14, dtype=bool), np.eye(1, 14, 13, dtype=bool)[0],
    np.array([0.0, np.nan]), np.array([0.0, -0.0]), np.array([[0, 0], [0, 3]]),
    np.zeros((3, 3)), np.array([np.inf])])
def test_any_true_is_numpys_any(values: np.ndarray) -> None:
    assert any_true(values) is bool(np.any(values))


def _bits_of(mask: np.ndarray) -> int:
    """The int with bit i set where ``mask[i]`` (plain arithmetic)."""
    return sum(2 ** int(i) for i in np.flatnonzero(mask))


def _tracker(human: HumanModel) -> ContactTracker:
    names = human.sites_of_kind("contact")
    return ContactTracker(human, BodyTopology.of(human), names, SolverSettings.load())


def test_planted_groups_follow_every_pattern_back_and_forth(human: HumanModel,
                                                            rng: np.random.Generator) -> None:
    support: SupportFollower = _tracker(human).support
    k = len(support._led)
    groups = np.array(support._feet)
    patterns = [rng.random(k) < p for p in (0.1, 0.3, 0.6) for _ in range(20)]
    for points in patterns + patterns[::-1]:  # each pattern again after the others
        planted = support._planted(support._bits.of(points))  # groups, as bits
        assert planted == _bits_of((groups & points).any(axis=1))


def test_feet_stance_follows_every_pattern_back_and_forth(human: HumanModel) -> None:
    tracker = _tracker(human)
    feet = ["LeftFoot", "RightFoot", "LeftLowerLeg", "Pelvis"]
    stances = [dict(zip(feet, flags)) for flags in itertools.product([True, False], repeat=4)]
    stances += [{"RightFoot": True}, {"LeftFoot": False, "T8": True}]
    for stance in stances + stances[::-1]:
        still = tracker._stance.feet_still(Frame(0.0, feet_still=stance))[0]
        assert still is not None
        expected = [np.nan if f is None or f not in stance else float(stance[f])
                    for f in tracker._foot_names]
        np.testing.assert_array_equal(still, expected)
        assert not still.flags.writeable
    assert tracker._stance.feet_still(Frame(0.0))[0] is None


def test_stance_like_the_last_frames_is_safe_against_a_dict_written_in_place(
        human: HumanModel) -> None:
    """The usual frame's shortcut (the last frame's stance, equal) follows a caller's dict that
    it writes to in place between frames, and equal dicts in another order."""
    stance, fresh = _tracker(human)._stance, _tracker(human)._stance
    known = {"LeftFoot": True, "RightFoot": False}
    moving = {"LeftHeel": True}
    for flags in [(True, False), (True, False), (False, False), (False, True), (False, True)]:
        known["LeftFoot"], known["RightFoot"] = flags
        moving["LeftHeel"] = flags[1]
        frame = Frame(0.0, feet_still=known, points_moving=moving)
        copied = Frame(0.0, feet_still=dict(reversed(known.items())), points_moving=dict(moving))
        for got in (stance.feet_still(frame), stance.feet_still(copied)):
            want = fresh.feet_still(Frame(0.0, feet_still=dict(known)))
            assert got[1] == want[1] and got[0] is not None and want[0] is not None
            np.testing.assert_array_equal(got[0], want[0])
        for moved in (stance.points_moving(frame), stance.points_moving(copied)):
            expected = fresh.points_moving(Frame(0.0, points_moving=dict(moving)))
            assert moved is not None and expected is not None
            np.testing.assert_array_equal(moved, expected)


def test_foot_pitch_is_nan_without_a_foot_and_fresh_each_frame(human: HumanModel,
                                                               rng: np.random.Generator) -> None:
    from ikfusion.rotations import exp_so3

    tracker = _tracker(human)
    n = len(human.segment_names)
    tracked = np.ones(n, dtype=bool)
    tracked.setflags(write=False)
    q = human.neutral()
    for _ in range(5):
        R = exp_so3(rng.normal(scale=0.5, size=(n, 3)))
        pitch = tracker.foot_pitch(q, R, tracked)
        for i, f in enumerate(tracker._foot_names):
            if tracker._feet[i] < 0:
                assert np.isnan(pitch[i]), f
                continue
            x = R[tracker._feet[i], :, 0]
            assert pitch[i] == np.arctan2(-x[2], np.hypot(x[0], x[1]))
        pitch[:] = 0.0  # the caller's own array: the next frame starts from NaN again


@pytest.mark.parametrize("feet", [None, [-1, 3, 3, -1, 7, 1, 1, -1], [2, 2, 5, 5, -1], [-1, -1]])
def test_foot_pitch_is_its_references_bytes(human: HumanModel, rng: np.random.Generator,
                                            feet: list[int] | None) -> None:
    """The flat ``take`` and the slice give the strided columns' pitches, bit for bit.

    On the default points' feet (consecutive: a slice) and on scattered ones (an index array),
    targets near pitch zero and +-90 deg, untracked feet from ``q``, NaN in the targets.
    """
    from ikfusion.ik.foot_pitch import FootPitch
    from ikfusion.rotations import exp_so3

    pitch_of = (_tracker(human)._pitch_of if feet is None
                else FootPitch(human, np.array(feet, dtype=int)))
    n = len(human.segment_names)
    q = human.neutral()
    for frame in range(200):
        R = exp_so3(rng.normal(scale=[0.5, 2.0, 0.5][frame % 3], size=(n, 3)))
        if frame % 7 == 0:
            R[rng.integers(n), :, 0] = [0.0, 0.0, 1.0]  # straight up: pitch -90 deg
        if frame % 13 == 0:
            R[rng.integers(n)] = np.nan
        tracked = rng.random(n) < (0.9 if frame % 2 else 1.0)
        new, old = pitch_of(q, R, tracked), pitch_of.reference(q, R, tracked)
        assert new.tobytes() == old.tobytes()
        assert new.flags.writeable and new is not pitch_of(q, R, tracked)


def test_reference_points_are_the_oldest_groups_whatever_the_ages(human: HumanModel,
                                                                   rng: np.random.Generator
                                                                   ) -> None:
    support: SupportFollower = _tracker(human).support
    groups = np.array(support._feet)
    for _ in range(200):
        active = rng.random(groups.shape[1]) < 0.4
        planted = (groups & active).any(axis=1)
        if not planted.any():
            continue
        support._planted_for = rng.choice([0.0, 0.01, 0.5], size=len(groups))  # ties too
        oldest = planted & (support._planted_for == support._planted_for[planted].max())
        expected = (groups & oldest[:, None]).any(axis=0) & active
        reference = support._reference(support._bits.of(active), _bits_of(planted))
        np.testing.assert_array_equal(support._bits.mask(reference), expected)


def test_drifting_points_are_the_drifts_bits(human: HumanModel,
                                             rng: np.random.Generator) -> None:
    """Python floats on the asked rows give ``bits.of(drift > limit)``'s bits, bit for bit.

    Every pattern of planted points (one foot, two, none), limits below, at and above the
    drifts (negative and zero too), NaN and inf in the sensed points and anchors, scales from
    tenths of a millimetre to overflow.
    """
    from ikfusion.ik.foot_pairs import drift_from_other_foot, drifting_points
    from ikfusion.ik.point_bits import indices

    tracker = _tracker(human)
    layout, bits, k = tracker.layout, tracker._bits, len(tracker.names)
    for case in range(3000):
        active = bits.mask(bits.of(rng.random(k) < [0.1, 0.3, 0.6][case % 3]))
        scale = [1e-4, 0.05, 1.0, 1e155][case % 4]
        anchors, p_sensed = (rng.normal(scale=scale, size=(k, 3)) for _ in range(2))
        if case % 5 == 0:
            p_sensed[rng.integers(k), rng.integers(3)] = [np.nan, np.inf, -np.inf][case % 3]
        if case % 7 == 0:
            anchors[rng.integers(k), rng.integers(3)] = np.nan
        with np.errstate(all="ignore"):  # (NaN, inf and overflow on purpose)
            drift = drift_from_other_foot(layout, active, anchors, p_sensed)
            limit = float(rng.choice([-0.01, 0.0, 0.05 * scale, drift[rng.integers(k)]]))
            rows = bits.of(rng.random(k) < 0.7) if case % 2 else bits.of(active)
            assert (drifting_points(layout, active, anchors, p_sensed, limit, indices(rows))
                    == bits.of(drift > limit) & rows)


def test_other_foot_and_drift_follow_every_pattern_back_and_forth(
        human: HumanModel, rng: np.random.Generator) -> None:
    from ikfusion.ik.foot_pairs import drift_from_other_foot, other_foot, other_foot_age

    layout = _tracker(human).layout
    k = len(layout.on_foot)
    other = ~layout.same_foot
    patterns = [rng.random(k) < p for p in (0.1, 0.3, 0.6) for _ in range(20)]
    for active in patterns + patterns[::-1]:
        np.testing.assert_array_equal(other_foot(layout, active),
                                      (other & active[None, :]).any(axis=1))
        assert not other_foot(layout, active).flags.writeable
        anchors, p_sensed, age = rng.normal(size=(k, 3)), rng.normal(size=(k, 3)), rng.random(k)
        drift = drift_from_other_foot(layout, active, anchors, p_sensed)
        other_age = other_foot_age(layout, active, age)
        for i in range(k):  # plain: align on the other foot's planted points, per point
            others = active & other[i] & active[i]
            if not others.any():
                assert drift[i] == 0.0 and other_age[i] == np.inf
                continue
            offset = (anchors[others] - p_sensed[others]).mean(axis=0)
            assert drift[i] == pytest.approx(np.hypot(*(p_sensed[i] + offset - anchors[i])[:2]))
            assert other_age[i] == age[others].max()


def test_last_input_is_kept_only_for_the_same_read_only_array() -> None:
    from ikfusion.ik.point_masks import LastInput

    calls: list[int] = []

    def lowest_above(p: np.ndarray, margin: float) -> np.ndarray:
        calls.append(1)
        return p[:, 2] - p[:, 2].min() + margin

    memo = LastInput(lowest_above)
    p = np.arange(12.0).reshape(4, 3)
    np.testing.assert_array_equal(memo(p, 0.5), [0.5, 3.5, 6.5, 9.5])
    p[0, 2] = 20.0  # a writable array is never kept: the change is seen
    np.testing.assert_array_equal(memo(p, 0.5), [15.5, 0.5, 3.5, 6.5])
    p.setflags(write=False)
    first = memo(p, 0.5)
    assert memo(p, 0.5) is first and not first.flags.writeable and len(calls) == 3
    np.testing.assert_array_equal(memo(p, 1.5), first + 1.0)  # other arguments: computed
    np.testing.assert_array_equal(memo(p.copy(), 0.5), first)  # another array: computed
    assert len(calls) == 5
