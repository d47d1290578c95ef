"""A hand or knee rests while its sensor barely accelerates, however its segment turns."""

from __future__ import annotations

import numpy as np

from ikfusion.imu.resting import RestThresholds, segment_resting
from ikfusion.imu.resting_stream import SegmentRestingStream

RATE = 60.0


def _sensor_acceleration(p_world_sensor: np.ndarray) -> np.ndarray:
    """(N, 3) world acceleration [m/s^2] of a sensor track (N, 3) [m], by central differences."""
    a = np.zeros_like(p_world_sensor)
    a[1:-1] = (p_world_sensor[2:] - 2 * p_world_sensor[1:-1] + p_world_sensor[:-2]) * RATE**2
    a[0], a[-1] = a[1], a[-2]
    return a


def test_pivot_rests_and_swing_moves() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(int(4 * RATE)) / RATE
    # a shin turning about its knee on the floor by +-40 deg at 0.5 Hz (up to 2.2 rad/s), the
    # sensor 12 cm from the knee
    angle = np.radians(40.0) * np.sin(2 * np.pi * 0.5 * t)
    pivot = 0.12 * np.stack([np.cos(angle), np.zeros_like(t), np.sin(angle)], axis=1)
    # a hand swinging by +-30 cm at 1 Hz
    swing = np.stack([0.3 * np.sin(2 * np.pi * t), np.zeros_like(t), 0.8 + 0 * t], axis=1)
    for track, expected in ((pivot, 1.0), (swing, 0.0)):
        a = _sensor_acceleration(track) + rng.normal(0.0, 0.05, (len(t), 3))
        np.testing.assert_array_equal(segment_resting(a, RATE), expected)


def test_lost_samples_are_unknown_and_do_not_cut_a_rest() -> None:
    a = np.full((120, 3), 0.1)
    a[50:53] = np.nan  # three lost samples (< min_duration)
    a[90:] = [3.0, 0.0, 0.0]  # the hand lifts off
    out = segment_resting(a, RATE, RestThresholds())
    assert np.isnan(out[50:53]).all()
    assert (out[:50] == 1.0).all() and (out[53:88] == 1.0).all()
    assert (out[91:] == 0.0).all()


def test_stream_agrees_with_offline_after_its_lag() -> None:
    # a hand at rest (its sensor tilted, gravity in its specific force), then lifted off
    n = 120
    R = np.tile(np.eye(3), (n, 1, 1))
    R[:] = [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]  # turned 90 deg about x
    a_world = np.zeros((n, 3))
    a_world[80:, 2] = 4.0
    f_sensor = np.einsum("nji,nj->ni", R, a_world + [0.0, 0.0, 9.81])  # R^T (a - g)
    offline = segment_resting(a_world, RATE)
    stream = SegmentRestingStream(RATE)
    causal = np.array([stream.update(k / RATE, R[k], f_sensor[k]) for k in range(n)])
    lag = int(round(RestThresholds().min_duration * RATE))
    assert (causal[lag:79] == 1.0).all() and (causal[:lag - 1] == 0.0).all()
    assert (causal[80:] == 0.0).all() and (offline[82:] == 0.0).all()
