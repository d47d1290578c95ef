"""N-pose calibration on simulated sensors with random mounting; heading from the data."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.errors import InputError
from ikfusion.imu import calibrate
from ikfusion.model import SENSOR_SEGMENTS, HumanModel
from ikfusion.rotations import angle_between
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.imu import ImuNoise, simulate_imus


@pytest.fixture(scope="module")
def walk():
    model = HumanModel.default()
    return generate_gait(model, GaitParameters(duration=5.5, stand=2.0, start_heading_deg=70.0))


def streams(walk, noise: ImuNoise, seed: int):
    imus = simulate_imus(walk.model, walk.time, walk.q, list(SENSOR_SEGMENTS),
                         np.random.default_rng(seed), noise)
    return imus, {s: imus.R_world_sensor[i] for i, s in enumerate(SENSOR_SEGMENTS)}


def mounting_errors_deg(cal, imus) -> np.ndarray:
    return np.array([np.degrees(angle_between(cal.R_sensor_segment[s], imus.R_segment_sensor[i].T))
                     for i, s in enumerate(SENSOR_SEGMENTS)])


def test_noise_free_recovers_every_mounting(walk) -> None:
    imus, R = streams(walk, ImuNoise.none(), 1)
    cal = calibrate(R, 60.0)
    assert "knee flexion" in cal.method
    assert np.degrees(cal.heading) == pytest.approx(70.0, abs=0.5)
    assert mounting_errors_deg(cal, imus).max() <= 0.5


def test_one_degree_noise_within_two_degrees(walk) -> None:
    noise = ImuNoise(tilt_deg=1.0, heading_deg=1.0, heading_walk_deg_per_sqrt_s=0.0)
    for seed in (2, 3):
        imus, R = streams(walk, noise, seed)
        assert mounting_errors_deg(calibrate(R, 60.0), imus).max() <= 2.0


def test_pelvis_strapped_the_other_way_still_faces_forward(walk) -> None:
    """Mountings are random already; flip the pelvis sensor by 180 deg on top."""
    imus, R = streams(walk, ImuNoise.none(), 4)
    flip = np.diag([-1.0, -1.0, 1.0])
    R["Pelvis"] = R["Pelvis"] @ flip
    cal = calibrate(R, 60.0)
    assert np.degrees(cal.heading) == pytest.approx(70.0, abs=0.5)
    R_pelvis = R["Pelvis"][0] @ cal.R_sensor_segment["Pelvis"]
    assert np.degrees(angle_between(R_pelvis, walk.model.segment_rotation(walk.q[0], "Pelvis"))) \
        < 0.5


def test_too_little_movement_falls_back_and_says_so(walk) -> None:
    _, R = streams(walk, ImuNoise.none(), 5)
    still = {s: v[:100] for s, v in R.items()}  # only the standing part
    cal = calibrate(still, 60.0)
    assert cal.method.startswith("fallback")
    assert cal.warnings and "--forward" in cal.warnings[0]


def test_forward_override(walk) -> None:
    imus, R = streams(walk, ImuNoise.none(), 6)
    i = list(SENSOR_SEGMENTS).index("Pelvis")
    # the pelvis sensor axis that points forward in the N-pose, in the sensor frame
    forward_in_sensor = imus.R_segment_sensor[i].T @ [1.0, 0.0, 0.0]
    k = int(np.argmax(np.abs(forward_in_sensor)))
    axis = ("-" if forward_in_sensor[k] < 0 else "") + "xyz"[k]
    cal = calibrate(R, 60.0, forward={"Pelvis": axis})
    assert cal.method == f"forward Pelvis:{axis}"
    assert abs(np.degrees(cal.heading) - 70.0) < 60.0


def test_moving_window_names_the_sensors(walk) -> None:
    _, R = streams(walk, ImuNoise.none(), 7)
    with pytest.raises(InputError) as err:
        calibrate(R, 60.0, window=(200, 260))
    assert "LowerLeg" in str(err.value)


def test_tpose_calibration() -> None:
    """A still T-pose: arm segments abducted 90 deg (palms down), the rest upright."""
    from ikfusion.rotations import axis_rotation, random_rotations

    rng = np.random.default_rng(11)
    heading = np.radians(-35.0)
    body = axis_rotation("z", heading)
    segments = ["Pelvis", "T8", "RightUpperArm", "RightForeArm", "LeftUpperArm", "LeftHand"]
    mounting = dict(zip(segments, random_rotations(len(segments), rng)))  # R_segment_sensor
    # the pelvis sensor strapped on the back: x up, z backward (its -z axis points forward)
    mounting["Pelvis"] = np.column_stack([[0, 0, 1.0], [0, 1.0, 0], [-1.0, 0, 0]])
    R = {}
    for s in segments:
        R_segment = body
        if s in ("RightUpperArm", "RightForeArm"):
            R_segment = body @ axis_rotation("x", np.radians(-90.0))
        elif s in ("LeftUpperArm", "LeftHand"):
            R_segment = body @ axis_rotation("x", np.radians(90.0))
        R[s] = np.repeat((R_segment @ mounting[s])[None], 120, axis=0)
    cal = calibrate(R, 60.0, pose="tpose")
    assert cal.method.startswith("fallback")
    assert np.degrees(cal.heading) == pytest.approx(-35.0, abs=1e-6)
    for s in segments:
        assert np.degrees(angle_between(cal.R_sensor_segment[s], mounting[s].T)) < 1e-6
