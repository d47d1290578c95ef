"""Simulated IMUs against closed forms: still sensors feel gravity, a steady turn its rate."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.model import SENSOR_SEGMENTS, HumanModel
from ikfusion.rotations import angle_between, axis_rotation, log_so3
from ikfusion.sim.imu import ImuNoise, simulate_imus


@pytest.fixture(scope="module")
def human() -> HumanModel:
    return HumanModel.default()


def turning(model: HumanModel, rate: float, n: int, hz: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) / hz
    q = np.array([model.configuration({"jRightElbow_flex": 30.0},
                                      R_world_pelvis=axis_rotation("z", rate * tk)) for tk in t])
    return t, q


def test_perfect_sensors_report_the_truth(human: HumanModel, rng) -> None:
    t, q = turning(human, 0.0, 20, 60.0)
    imus = simulate_imus(human, t, q, SENSOR_SEGMENTS, rng, ImuNoise.none())
    for i, segment in enumerate(SENSOR_SEGMENTS):
        R = human.segment_rotation(q[5], segment) @ imus.R_segment_sensor[i]
        np.testing.assert_allclose(imus.R_world_sensor[i, 5], R, atol=1e-12)
        # Standing still: the specific force is gravity's reaction, up, in the sensor frame.
        np.testing.assert_allclose(imus.acc[i, 5], R.T @ [0.0, 0.0, 9.81], atol=1e-9)
        np.testing.assert_allclose(imus.gyr[i, 5], 0.0, atol=1e-9)


def test_steady_turn_gives_its_rate_in_the_sensor_frame(human: HumanModel, rng) -> None:
    rate = 1.2  # rad/s about the vertical
    t, q = turning(human, rate, 60, 100.0)
    imus = simulate_imus(human, t, q, ["Pelvis", "T8"], rng, ImuNoise.none())
    for i in range(2):
        for k in (10, 30, 50):
            expected = imus.R_world_sensor[i, k].T @ [0.0, 0.0, rate]
            np.testing.assert_allclose(imus.gyr[i, k], expected, atol=1e-3)
    # The pelvis sensor circles the vertical axis: centripetal acceleration toward it.
    k = 30
    R = imus.R_world_sensor[0, k]
    p = human.site_position(q[k], "Pelvis")
    centripetal = -rate**2 * np.array([p[0], p[1], 0.0])
    np.testing.assert_allclose(imus.acc[0, k], R.T @ (centripetal + [0, 0, 9.81]), atol=2e-3)


def test_default_noise_has_the_documented_size(human: HumanModel, rng) -> None:
    # many short series: the errors start stationary, so 2 s of each tell their size
    t, q = turning(human, 0.0, 120, 60.0)
    noise = ImuNoise(heading_walk_deg_per_sqrt_s=0.0)
    imus = simulate_imus(human, t, q, ["Pelvis"] * 1000, rng, noise, random_mounting=False)
    truth = human.segment_rotation(q[0], "Pelvis")
    errors = np.degrees(angle_between(imus.R_world_sensor, truth))
    expected = np.sqrt(noise.tilt_deg**2 + noise.heading_deg**2 + 3 * noise.white_deg**2)
    assert np.sqrt(np.mean(errors**2)) == pytest.approx(expected, rel=0.1)
    # ... and varies slowly and smoothly, as a fusion filter's output does: white noise through
    # two lags of time constant tau moves by (its size) * dt / tau from one sample to the next
    steps = np.degrees(angle_between(imus.R_world_sensor[:, 1:], imus.R_world_sensor[:, :-1]))
    dt = 1 / 60.0
    per_axis = [(noise.tilt_deg**2 / 2, noise.tilt_correlation_s)] * 2 + [
        (noise.heading_deg**2, noise.heading_correlation_s)]
    expected_steps = np.sqrt(sum(var * (dt / tau) ** 2 for var, tau in per_axis)
                             + 6 * noise.white_deg**2)
    assert np.sqrt(np.mean(steps**2)) == pytest.approx(expected_steps, rel=0.1)
    assert expected_steps < 0.05 * expected  # far from white noise of the same size


def test_zero_time_constants_give_white_errors(human: HumanModel, rng) -> None:
    t, q = turning(human, 0.0, 300, 60.0)
    noise = ImuNoise(tilt_correlation_s=0.0, heading_correlation_s=0.0, white_deg=0.0,
                     heading_walk_deg_per_sqrt_s=0.0)
    imus = simulate_imus(human, t, q, ["Pelvis"] * 50, rng, noise, random_mounting=False)
    truth = human.segment_rotation(q[0], "Pelvis")
    errors = log_so3(imus.R_world_sensor @ truth.T)  # world-frame error vectors [rad]
    np.testing.assert_allclose(np.degrees(errors.reshape(-1, 3).std(axis=0)),
                               [noise.tilt_deg / np.sqrt(2)] * 2 + [noise.heading_deg], rtol=0.1)
    lag1 = np.mean(errors[:, 1:] * errors[:, :-1]) / np.mean(errors**2)
    assert abs(lag1) < 0.05  # no correlation from one sample to the next
