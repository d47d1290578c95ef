"""A leg that lets go of the floor eases back to its sensed orientations at a bounded rate."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.ik.release import ReleaseEasing
from ikfusion.rotations import angle_between, exp_so3

DT = 1.0 / 60.0
SPEED = np.radians(20.0)


def test_a_released_leg_keeps_its_bend_and_eases_back() -> None:
    # segments 0 (pelvis), 1-2 (left leg), 3-4 (right leg); points: left heel, right heel
    easing = ReleaseEasing([np.array([1, 2]), np.array([3, 4])], 5, SPEED)
    sensed = exp_so3(np.random.default_rng(1).normal(size=(5, 3)))
    bend = np.radians(3.0) * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 0]])
    solved = sensed @ exp_so3(bend)
    asked = []

    def bend_of(segments: np.ndarray) -> np.ndarray:
        asked.append(segments.tolist())
        return bend[segments]

    easing.release(np.array([False, False]), bend_of)
    assert easing.apply(sensed, DT) is None and not asked  # nothing let go: sensors stand
    easing.release(np.array([True, False]), bend_of)
    assert asked == [[1, 2]]
    targets = easing.apply(sensed, 0.0)
    assert targets is not None
    # the left leg starts where it was solved, the pelvis and the right leg at their sensors
    assert np.degrees(angle_between(targets[1:3], solved[1:3])).max() < 1e-9
    assert np.degrees(angle_between(targets[[0, 3, 4]], sensed[[0, 3, 4]])).max() < 1e-9
    # ... and each left segment turns back at 20 deg/s: 3 deg in 0.15 s
    previous = targets
    for k in range(1, 9):
        targets = easing.apply(sensed, DT)
        step = np.degrees(angle_between(targets[1:3], previous[1:3]))
        assert step.max() <= 20.0 * DT + 1e-9
        left = np.degrees(angle_between(targets[1:3], sensed[1:3]))
        assert left == pytest.approx(max(0.0, 3.0 - 20.0 * DT * k), abs=1e-6)
        previous = targets
    assert easing.apply(sensed, DT) is None  # all the way back


def test_a_new_release_restarts_from_the_latest_bend() -> None:
    easing = ReleaseEasing([np.array([1])], 2, SPEED)
    sensed = np.tile(np.eye(3), (2, 1, 1))
    easing.release(np.array([True]), lambda legs: np.radians([[2.0, 0, 0]]))
    easing.apply(sensed, 5 * DT)
    easing.release(np.array([True]), lambda legs: np.radians([[0, 4.0, 0]]))
    targets = easing.apply(sensed, 0.0)
    assert np.degrees(angle_between(targets[1], exp_so3(np.radians([0, 4.0, 0])))) < 1e-9


def test_zero_speed_switches_it_off() -> None:
    easing = ReleaseEasing([np.array([1])], 2, 0.0)
    sensed = np.tile(np.eye(3), (2, 1, 1))
    easing.release(np.array([True]), lambda legs: np.radians([[2.0, 0, 0]]))
    assert easing.apply(sensed, DT) is None


def _numpy_apply(offsets: np.ndarray, R: np.ndarray, by: float) -> tuple[np.ndarray, object]:
    """The easing's step by NumPy on every row (its formula before rows were kept as floats)."""
    norm = np.sqrt(np.add.reduce(offsets * offsets, axis=1))
    positive = norm > 0
    keep = np.maximum(0.0, 1.0 - by / np.where(positive, norm, 1.0))
    offsets = offsets * np.where(positive, keep, 0.0)[:, None]
    moving = np.flatnonzero(np.logical_or.reduce(offsets != 0.0, axis=1))
    if len(moving) == 0:
        return offsets, None
    out = R.copy()
    out[moving] = out[moving] @ exp_so3(offsets[moving])
    return offsets, out


def test_easing_steps_are_numpys_numbers() -> None:
    """Released legs of every size, zeros of either sign, a NaN: NumPy's offsets and targets,
    to the bit, frame after frame until they are all zero."""
    rng = np.random.default_rng(5)
    legs = [np.array([1, 2, 3]), np.array([4, 5]), np.array([2, 6])]
    for trial in range(20):
        easing = ReleaseEasing(legs, 8, SPEED)
        sensed = exp_so3(rng.normal(size=(8, 3)))
        bend = rng.normal(size=(8, 3)) * 10.0 ** rng.uniform(-6, -1, size=(8, 1))
        bend[2, 1], bend[5] = -0.0, [0.0, -0.0, 0.0]
        if trial == 0:
            bend[6, 0] = np.nan
        expected = np.zeros((8, 3))
        for frame in range(40):
            if frame in (0, 3, 11):
                released = rng.random(3) < 0.6
                easing.release(released, lambda s, b=bend: b[s])
                for k in np.flatnonzero(released):
                    expected[legs[k]] = bend[legs[k]]
            got = easing.apply(sensed, DT)
            expected, want = _numpy_apply(expected, sensed, SPEED * DT)
            assert easing.offsets.tobytes() == expected.tobytes()
            assert (got is None) == (want is None)
            if got is not None:
                assert np.asarray(got).tobytes() == np.asarray(want).tobytes()
