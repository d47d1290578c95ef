"""Unit tests of the IMU + UWB EKF pieces: propagation (closed forms), Jacobians (finite
differences), the tags file, sequence unwrapping, and a synthetic unit with gaps."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ikfusion.errors import ConfigError
from ikfusion.rotations import exp_so3, log_so3
from ikfusion.uwb import make_constellation
from ikfusion.uwb.ekf import EkfOptions, ImuSamples, UnitStart, UnitTransmissions, run_unit_filter
from ikfusion.uwb.ekf_model import (
    ATT,
    CLOCK,
    GRAVITY_WORLD,
    N_ERROR,
    NominalState,
    fill_transition,
    inject_error,
    matrix_to_quat,
    new_transition,
    predict_toa_unit,
    propagate_nominal,
    tag_position,
    tag_position_jacobian,
)
from ikfusion.uwb.tracking import TagInfo, load_tags, save_tags, unwrap_sequence


def _state(rng: np.random.Generator) -> NominalState:
    R = exp_so3(rng.normal(size=3))
    return NominalState(rng.uniform(1, 4, 3), rng.normal(size=3), matrix_to_quat(R),
                        0.05 * rng.normal(size=3), 0.01 * rng.normal(size=3), 123.4, 5.6)


def _difference(a: NominalState, b: NominalState) -> np.ndarray:
    """Error state taking ``a`` to ``b`` (inverse of inject_error)."""
    d = np.zeros(N_ERROR)
    d[0:3] = b.p_world_sensor - a.p_world_sensor
    d[3:6] = b.v_world_sensor - a.v_world_sensor
    d[ATT] = log_so3(a.R_world_sensor.T @ b.R_world_sensor)
    d[9:12] = b.b_acc - a.b_acc
    d[12:15] = b.b_gyr - a.b_gyr
    d[CLOCK] = b.clock - a.clock
    d[16] = b.clock_rate - a.clock_rate
    return d


def test_propagation_constant_acceleration_is_exact() -> None:
    a_world = np.array([0.3, -0.2, 0.5])
    x = NominalState(np.array([1.0, 2.0, 1.5]), np.array([0.5, 0.1, 0.0]), np.array([1.0, 0, 0, 0]),
                     np.zeros(3), np.zeros(3), 10.0, 2.0)
    f = a_world - GRAVITY_WORLD  # specific force, sensor frame = world frame here
    dt, steps = 0.01, 250
    for _ in range(steps):
        propagate_nominal(x, f, np.zeros(3), dt)
    t = dt * steps
    np.testing.assert_allclose(x.p_world_sensor, [1.0, 2.0, 1.5] + np.array([0.5, 0.1, 0.0]) * t
                               + 0.5 * a_world * t**2, atol=1e-10)
    np.testing.assert_allclose(x.v_world_sensor, [0.5, 0.1, 0.0] + a_world * t, atol=1e-10)
    assert x.clock == pytest.approx(10.0 + 2.0 * t)


def test_propagation_constant_rotation_is_exact() -> None:
    w = np.array([0.4, -1.1, 2.0])  # rad/s, sensor frame
    R0 = exp_so3([0.2, 0.3, -0.1])
    x = NominalState(np.zeros(3), np.zeros(3), matrix_to_quat(R0), np.zeros(3), np.zeros(3))
    dt, steps = 1.0 / 60.0, 300
    for _ in range(steps):  # free fall: zero specific force
        propagate_nominal(x, np.zeros(3), w, dt)
    t = dt * steps
    np.testing.assert_allclose(x.R_world_sensor, R0 @ exp_so3(w * t), atol=1e-10)
    np.testing.assert_allclose(x.p_world_sensor, 0.5 * GRAVITY_WORLD * t**2, atol=1e-10)


def test_toa_jacobian_matches_finite_differences(rng: np.random.Generator) -> None:
    readers = rng.uniform(-5, 5, (6, 3))
    offsets = rng.normal(size=6)
    lever = np.array([0.1, -0.05, 0.12])
    for _ in range(5):
        x = _state(rng)
        h0, H = predict_toa_unit(x, lever, readers, offsets, 0.0)
        numeric = np.zeros_like(H)
        eps = 1e-6
        for i in range(N_ERROR):
            d = np.zeros(N_ERROR)
            d[i] = eps
            xp, xm = x.copy(), x.copy()
            inject_error(xp, d)
            inject_error(xm, -d)
            numeric[:, i] = (predict_toa_unit(xp, lever, readers, offsets, 0.0)[0]
                             - predict_toa_unit(xm, lever, readers, offsets, 0.0)[0]) / (2 * eps)
        np.testing.assert_allclose(H, numeric, atol=1e-6)
        J = tag_position_jacobian(x, lever)
        d = 1e-6 * rng.normal(size=N_ERROR)
        xp = x.copy()
        inject_error(xp, d)
        np.testing.assert_allclose(tag_position(xp, lever) - tag_position(x, lever), J @ d,
                                   atol=1e-11)


def test_transition_matches_perturbed_propagation(rng: np.random.Generator) -> None:
    dt = 0.005
    f, w = np.array([0.5, -0.3, 9.9]), np.array([0.7, -0.4, 1.2])
    for _ in range(3):
        x = _state(rng)
        d = 1e-5 * rng.normal(size=N_ERROR)
        xp = x.copy()
        inject_error(xp, d)
        x1, xp1 = x.copy(), xp.copy()
        R_mid = propagate_nominal(x1, f, w, dt)
        propagate_nominal(xp1, f, w, dt)
        F = new_transition()
        fill_transition(F, R_mid, f - x.b_acc, w - x.b_gyr, dt)
        # First order in dt: the residual is O(dt^2 |d|) plus O(|d|^2).
        np.testing.assert_allclose(_difference(x1, xp1), F @ d, atol=2e-3 * np.abs(d).max())


def test_tags_file_round_trip(tmp_path: Path) -> None:
    tags = {"T1": TagInfo("T1", "A", "HeadTop"), "T2": TagInfo("T2", "A", "LeftFootTop")}
    path = save_tags(tags, tmp_path / "tags.yaml")
    assert load_tags(path) == tags
    bad = tmp_path / "bad.yaml"
    bad.write_text("tags:\n  T1: {actor: A, site: Nose}\n")
    with pytest.raises(ConfigError, match="tags.T1.site"):
        load_tags(bad)


def test_unwrap_sequence_follows_time() -> None:
    time = np.arange(600) * 0.1
    seq = (np.arange(600) + 200) % 256
    keep = np.ones(600, dtype=bool)
    keep[300:340] = False  # a gap longer than a few transmissions
    out = unwrap_sequence(time[keep], seq[keep], 10.0)
    np.testing.assert_array_equal(out - out[0], (np.arange(600) + 200)[keep] - 200)


def _synthetic_unit(rng: np.random.Generator) -> tuple[ImuSamples, UnitTransmissions, np.ndarray,
                                                        np.ndarray, np.ndarray]:
    """A unit circling at 1 m/s (yawing with the path), perfect IMU, 10 Hz TOAs."""
    rate, radius, speed = 100.0, 1.5, 1.0
    time = np.arange(0.0, 20.0, 1.0 / rate)
    omega = speed / radius
    ang = omega * time
    p = np.stack([3 + radius * np.sin(ang), 4 - radius * np.cos(ang), 1.6 + 0 * ang], axis=1)
    a_world = np.stack([-radius * omega**2 * np.sin(ang), radius * omega**2 * np.cos(ang),
                        0 * ang], axis=1)
    R = np.stack([exp_so3([0.0, 0.0, a]) for a in ang])
    acc = np.einsum("nji,nj->ni", R, a_world - GRAVITY_WORLD)
    gyr = np.tile([0.0, 0.0, omega], (time.shape[0], 1))
    readers = np.array([[0, 0, 2.6], [6, 0, 0.3], [6, 8, 2.6], [0, 8, 0.3], [3, 0, 2.0],
                        [3, 8, 0.5]], dtype=float)
    c = make_constellation(readers, sigma=0.03)
    seq = np.arange(7, 7 + 200)
    t_tx = 0.031 + (seq - 7) * 0.1
    p_tx = np.stack([np.interp(t_tx, time, p[:, i]) for i in range(3)], axis=1)
    tau_nominal = seq * 299_792_458.0 / 10.0
    clock = 55.0 + 3.0 * t_tx
    dist = np.linalg.norm(readers[None] - p_tx[:, None], axis=2)
    toa = tau_nominal[:, None] + clock[:, None] + dist + rng.normal(0, 0.03, dist.shape)
    toa[rng.random(toa.shape) < 0.2] = np.nan  # missing readers
    acc[500:530] = np.nan  # missing IMU samples
    gyr[500:530] = np.nan
    imu = ImuSamples(time, acc, gyr, R, None)
    tx = UnitTransmissions(t_tx, seq, tau_nominal, toa)
    return imu, tx, c.positions, p, clock


def test_synthetic_unit_tracks_with_missing_samples_and_readers(rng: np.random.Generator) -> None:
    imu, tx, readers, p_true, clock = _synthetic_unit(rng)
    start = UnitStart(float(tx.time[0]), p_true[3] + [0.05, -0.03, 0.04], np.eye(3) * 0.01,
                      float(clock[0]) + 0.1, 2.5, 0.5, 2.0)
    track = run_unit_filter(imu, tx, readers, np.zeros(6), start, np.zeros(3), 0.03,
                            EkfOptions(attitude_sigma_deg=None))
    err = np.linalg.norm(track.p_world_tag - p_true, axis=1)
    settled = imu.time > 3.0
    assert np.sqrt(np.nanmean(err[settled] ** 2)) < 0.05  # 6 readers, 20 % missed
    assert track.totals.toas_rejected <= 0.02 * track.totals.toas
    assert track.totals.transmissions == len(tx)
    assert np.isfinite(track.cov[settled]).all()
    assert math.isnan(track.p_world_tag[0, 0]) or track.time[0] >= 0.0


def test_imu_units_from_recording_match_simulation() -> None:
    from ikfusion.io.recording import ImuRecording, SensorStream
    from ikfusion.mocap.model_motion import TruthMotion
    from ikfusion.model import HumanModel
    from ikfusion.sim.imu import simulate_imus
    from ikfusion.sim.uwb_capture import imu_units_from_simulation
    from ikfusion.uwb.imu_units import imu_units_from_recording

    model = HumanModel.default()
    n = 20
    time = np.arange(n) / 60.0
    q = np.tile(model.neutral(), (n, 1))
    truth = TruthMotion(model, time, q, [], np.zeros((n, 0), dtype=bool))
    segments = ["Head", "LeftFoot", "RightFoot"]
    imus = simulate_imus(model, time, q, segments, np.random.default_rng(3))
    tags = {"T1": TagInfo("T1", "A", "HeadTop"), "T2": TagInfo("T2", "A", "RightFootTop")}
    simulated = imu_units_from_simulation(truth, imus, tags)
    streams = {f"S{i}": SensorStream(f"S{i}", imus.R_world_sensor[i], np.ones(n, dtype=bool),
                                     np.ones(n, dtype=bool), acc=imus.acc[i], gyr=imus.gyr[i])
               for i in range(3)}
    recording = ImuRecording(time, 60.0, streams)
    sensor_map = {f"S{i}": s for i, s in enumerate(segments)}
    mounting = dict(zip(segments, imus.R_segment_sensor))
    real = imu_units_from_recording(recording, sensor_map, tags, model, mounting)
    for tag_id in tags:
        np.testing.assert_allclose(real[tag_id].lever_sensor_tag,
                                   simulated[tag_id].lever_sensor_tag, atol=1e-9)
        np.testing.assert_allclose(real[tag_id].acc, simulated[tag_id].acc)
    assert 0.05 < np.linalg.norm(simulated["T1"].lever_sensor_tag) < 0.3
