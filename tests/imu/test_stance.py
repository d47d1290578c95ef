"""Foot stance from the foot IMU against the true contact phases of simulated walks."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.imu.stance import StanceThresholds, angular_speed, foot_still
from ikfusion.model import HumanModel
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.imu import ImuNoise, simulate_imus


@pytest.fixture(scope="module")
def walk():  # type: ignore[no-untyped-def]
    truth = generate_gait(HumanModel.default(), GaitParameters(duration=8.0, path="circle"),
                          rate=60.0)
    imus = simulate_imus(truth.model, truth.time, truth.q, ["LeftFoot", "RightFoot"],
                         np.random.default_rng(5), ImuNoise())
    return truth, imus


def _true_contact(truth, side: str) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    c = truth.contacts[:, [truth.contact_names.index(side + "Heel"),
                           truth.contact_names.index(side + "Toe")]]
    return c.all(axis=1), c.any(axis=1)


@pytest.mark.parametrize("use_gyro", [True, False])
def test_still_feet_are_feet_on_the_floor(walk, use_gyro: bool) -> None:  # type: ignore[no-untyped-def]
    """Still means in contact (precision) and most of every flat-foot phase is found (recall)."""
    truth, imus = walk
    for i, side in enumerate(("Left", "Right")):
        if use_gyro:
            still = foot_still(imus.R_world_sensor[i], truth.rate, imus.gyr[i])
        else:  # orientation differences: only usable with smooth orientations
            R_exact = simulate_imus(truth.model, truth.time, truth.q, [side + "Foot"],
                                    np.random.default_rng(1), ImuNoise.none()).R_world_sensor[0]
            still = foot_still(R_exact, truth.rate, None, StanceThresholds())
        flat, anyc = _true_contact(truth, side)
        found = still == 1.0
        assert found.any()
        precision = anyc[found].mean()
        recall = found[flat].mean()
        assert precision > 0.97, (side, precision)
        assert recall > 0.7, (side, recall)
        # every true flat-foot phase is detected somewhere
        edges = np.diff(np.r_[0, flat.astype(int), 0])
        for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
            if b - a >= 12:
                assert found[a:b].any(), (side, a, b)


def test_missing_samples_are_unknown_and_short_calm_is_not_still() -> None:
    rate = 100.0
    gyr = np.full((300, 3), 3.0)
    gyr[50:55] = 0.0     # 50 ms of calm: a swing foot turning over, not a stance
    gyr[100:200] = 0.01  # 1 s still
    gyr[150:152] = np.nan
    R = np.tile(np.eye(3), (300, 1, 1))
    still = foot_still(R, rate, gyr)
    assert np.all(still[50:55] == 0.0)
    assert np.all(still[110:148] == 1.0) and np.all(np.isnan(still[150:152]))
    assert np.all(still[:45] == 0.0) and np.all(still[210:] == 0.0)


def test_angular_speed_from_orientations_matches_the_rotation_rate() -> None:
    rate, w = 50.0, 2.0
    angles = w * np.arange(100) / rate
    c, s = np.cos(angles), np.sin(angles)
    R = np.zeros((100, 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    R[40] = np.nan
    speed = angular_speed(R, rate)
    good = np.isfinite(speed)
    assert np.allclose(speed[good], w, atol=1e-9)
    assert np.isnan(speed[40]) or speed[40] == pytest.approx(w)


def test_a_lost_sample_does_not_cut_a_short_stance() -> None:
    """A 0.2 s stance with one lost gyroscope sample in its middle stays still (it was cut in
    two pieces shorter than the minimum duration and reported moving: the foot let go)."""
    rate = 60.0
    gyr = np.tile([4.0, 0.0, 0.0], (60, 1))
    gyr[20:32] = 0.0  # 0.2 s flat on the floor
    gyr[26] = np.nan  # a lost packet
    still = foot_still(np.tile(np.eye(3), (60, 1, 1)), rate, gyr)
    assert (still[22:26] == 1.0).all() and (still[27:30] == 1.0).all(), still[18:34]
    assert np.isnan(still[26])  # no sample: unknown
    assert (still[:15] == 0.0).all() and (still[40:] == 0.0).all()


def test_a_long_dropout_stays_unknown() -> None:
    rate = 60.0
    gyr = np.zeros((120, 3))
    gyr[40:80] = np.nan  # 0.67 s without the sensor
    still = foot_still(np.tile(np.eye(3), (120, 1, 1)), rate, gyr)
    assert np.isnan(still[40:80]).all()
    assert (still[:38] == 1.0).all() and (still[82:] == 1.0).all()
