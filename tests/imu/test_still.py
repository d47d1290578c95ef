"""Still windows: the spread formula, the window search, the checks."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.errors import InputError
from ikfusion.imu import check_still, find_still_window, mean_rotation
from ikfusion.imu.still import (
    StillThresholds,
    _prefix_quaternions,
    _spread_of_quaternions,
    _window_scores,
    aligned_quaternions,
    spread_per_window,
)
from ikfusion.rotations import (
    angle_between,
    exp_so3,
    log_so3,
    matrix_to_quat_wxyz,
    random_rotations,
)


@pytest.mark.parametrize("sigma_deg", [0.3, 2.0, 8.0])
def test_spread_formula_matches_the_rms_angle(rng, sigma_deg: float) -> None:
    center = random_rotations(1, rng)[0]
    R = center @ exp_so3(rng.normal(scale=np.radians(sigma_deg), size=(200, 3)))
    direct = np.degrees(np.sqrt(np.mean(angle_between(R, mean_rotation(R)) ** 2)))
    assert spread_per_window(R, 200)[0] == pytest.approx(direct, rel=0.02)
    assert direct == pytest.approx(sigma_deg * np.sqrt(3), rel=0.15)


def test_mean_rotation_near_a_half_turn_ignores_quaternion_signs_and_nan(rng) -> None:
    """About a half turn the quaternions of the samples straddle w = 0 with both signs."""
    center = exp_so3(np.pi * np.array([0.0, 0.6, 0.8]))
    R = center @ exp_so3(rng.normal(scale=0.05, size=(50, 3)))
    q = matrix_to_quat_wxyz(R)
    assert (q @ q[0] < 0).any()  # sign flips among the samples
    R[10] = np.nan
    karcher = R[0]
    good = R[~np.isnan(R).any(axis=(1, 2))]
    for _ in range(20):  # the geodesic mean, by fixed-point iteration
        karcher = karcher @ exp_so3(log_so3(karcher.T @ good).mean(axis=0))
    assert np.degrees(angle_between(mean_rotation(R), karcher)) < 0.05
    with pytest.raises(InputError, match="no finite orientation"):
        mean_rotation(np.full((3, 3, 3), np.nan))


def moving_then_still(rng, rate: float = 100.0) -> dict[str, np.ndarray]:
    t = np.arange(int(8 * rate)) / rate
    still = (t >= 2.0) & (t < 4.5)
    angle = np.where(still, 0.0, 0.8 * np.sin(3 * t))[:, None]
    out = {}
    for k in range(3):
        axis = rng.normal(size=3)
        out[f"S{k}"] = random_rotations(1, rng)[0] @ exp_so3(angle * axis / np.linalg.norm(axis))
    return out


def test_window_search_finds_the_still_part(rng) -> None:
    R = moving_then_still(rng)
    start, end = find_still_window(R, 100.0)
    assert end - start == 200 and 200 <= start and end <= 450
    spreads = check_still(R, (start, end), 100.0)
    assert max(spreads.values()) < 1e-4  # deg: float rounding of the formula


def test_gyroscope_says_when_orientations_cannot(rng) -> None:
    R = {"S0": np.repeat(random_rotations(1, rng), 800, axis=0)}
    gyr = {"S0": np.zeros((800, 3))}
    gyr["S0"][:300] = 1.0  # a spinning gyro the orientation filter has not followed
    start, _ = find_still_window(R, 100.0, gyr=gyr)
    assert start >= 300
    with pytest.raises(InputError, match=r"S0 \(99 deg/s\)"):
        check_still(R, (0, 100), 100.0, gyr=gyr)


def test_missing_data_in_the_window(rng) -> None:
    R = moving_then_still(rng)
    R["S1"][250:300] = np.nan
    with pytest.raises(InputError, match=r"S1 \(no data\)"):
        check_still(R, (250, 300), 100.0)
    with pytest.raises(InputError, match="not inside the recording"):
        check_still(R, (700, 900), 100.0)


def test_the_pose_at_the_start_wins_over_a_stiller_pause_later(rng) -> None:
    """Start-stop walking: a pause in a stride later on can be stiller than the N-pose; the
    calibration pose is the first still moment (gen-start-stop picked its 8 s pause before)."""
    rate = 100.0
    t = np.arange(int(10 * rate)) / rate
    pose = t < 2.5                      # the N-pose: still, with small sensor noise
    pause = (t >= 6.0) & (t < 8.5)      # a pause in a stride: perfectly still
    angle = np.where(pose | pause, 0.0, 0.8 * np.sin(3 * t))[:, None]
    R = {}
    for k in range(3):
        axis = rng.normal(size=3)
        noise = exp_so3(np.where(pose[:, None], rng.normal(scale=np.radians(0.3), size=(len(t), 3)),
                                 0.0))
        R[f"S{k}"] = random_rotations(1, rng)[0] @ exp_so3(angle * axis / np.linalg.norm(axis)) \
            @ noise
    start, end = find_still_window(R, rate)
    assert end <= 250


@pytest.mark.parametrize("finite_rows", [None, 10, 30])
def test_prefix_quaternions_are_those_of_the_prefix_to_the_bit(rng, finite_rows) -> None:
    """One conversion serves every window width: a prefix's quaternions and window spreads
    are the first ones of a longer prefix's, bit for bit (NaN samples and prefixes converted
    matrix by matrix included)."""
    R = random_rotations(1, rng)[0] @ exp_so3(rng.normal(scale=0.2, size=(600, 3)))
    R[rng.random(600) < 0.1] = np.nan
    if finite_rows is not None:  # few finite samples: the one-by-one conversion
        R[np.flatnonzero(np.isfinite(R).all(axis=(1, 2)))[finite_rows:400]] = np.nan
    shared = aligned_quaternions(R[:500])
    for needed in (2, 7, 24, 25, 40, 151, 399, 400, 401, 500):
        quats = _prefix_quaternions(R, shared, needed)
        np.testing.assert_array_equal(quats, aligned_quaternions(R[:needed]))
        for width in (2, 5, 20):
            if width <= needed:
                np.testing.assert_array_equal(_spread_of_quaternions(quats, width),
                                              spread_per_window(R[:needed], width))


def test_window_search_as_each_width_on_its_own(rng) -> None:
    """find_still_window's scores are those of each width's own prefix (the code before)."""
    rate = 50.0
    R = {s: random_rotations(1, rng)[0] @ exp_so3(
        np.concatenate([rng.normal(scale=0.01, size=(150, 3)),
                        rng.normal(scale=0.3, size=(450, 3))])) for s in ("A", "B")}
    R["B"][[3, 70]] = np.nan
    limits = StillThresholds()
    window = find_still_window(R, rate, search=5.0)
    for width in (100, 75, 50):
        starts = min(600 - width + 1, int(round(5.0 * rate)) + 1)
        expected = np.zeros(starts)
        for R_sensor in R.values():
            expected = np.maximum(expected, spread_per_window(R_sensor[:starts + width - 1],
                                                              width)[:starts]
                                  / limits.spread_deg)
        shared = {s: aligned_quaternions(R_sensor[:350]) for s, R_sensor in R.items()}
        quats = {s: _prefix_quaternions(R[s], q, starts + width - 1) for s, q in shared.items()}
        np.testing.assert_array_equal(_window_scores(quats, None, width, starts, limits),
                                      expected)
    assert window[1] - window[0] == 100
