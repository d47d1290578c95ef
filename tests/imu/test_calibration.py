"""N-pose / T-pose calibration on simulated sensors (random mountings), heading from the data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from body_sim import SEGMENTS17, simulate

from ikfusion.errors import InputError
from ikfusion.imu import calibrate, calibrate_recording, pose_rotation
from ikfusion.io import load_sensor_map, read_mtmanager, write_mtmanager
from ikfusion.paths import configs_dir
from ikfusion.rotations import angle_between, axis_rotation, log_so3, random_rotations


def mounting_errors_deg(cal, sim) -> np.ndarray:
    """Angle between each R_sensor_segment found and the truth (R_segment_sensor^T) [deg]."""
    return np.array([np.degrees(angle_between(cal.R_sensor_segment[s],
                                              sim.R_segment_sensor[s].T))
                     for s in sim.R_segment_sensor])


def knee_flexion_deg(R_thigh: np.ndarray, R_shank: np.ndarray) -> np.ndarray:
    """Rotation of the shank about the thigh's left (Y) axis [deg]: > 0 bends backwards."""
    return np.degrees(log_so3(np.swapaxes(R_thigh, 1, 2) @ R_shank)[:, 1])


@pytest.mark.parametrize("heading_deg", [70.0, -150.0])
def test_noise_free_recovers_every_mounting(rng, heading_deg: float) -> None:
    sim = simulate(rng, heading_deg=heading_deg)
    cal = calibrate(sim.R_world_sensor, sim.rate, gyr=sim.gyr, acc=sim.acc)
    assert cal.method.startswith("knee flexion axis")
    assert cal.heading_deg == pytest.approx(heading_deg, abs=0.5)
    assert mounting_errors_deg(cal, sim).max() <= 0.5
    assert cal.window[1] <= int(2.5 * sim.rate) and cal.window[1] - cal.window[0] == 120
    assert cal.estimate is not None and cal.estimate.walk_heading is not None
    assert np.degrees(abs(cal.estimate.walk_heading - cal.heading)) < 10.0
    assert not cal.warnings


def test_one_degree_noise_within_two_degrees(rng) -> None:
    for _ in range(3):
        sim = simulate(rng, noise_deg=1.0, heading_deg=float(rng.uniform(-180, 180)))
        cal = calibrate(sim.R_world_sensor, sim.rate, gyr=sim.gyr)
        errors = mounting_errors_deg(cal, sim)
        assert errors.max() <= 2.0, errors


def test_pelvis_strapped_the_other_way_round_still_faces_forward(rng) -> None:
    mounting = {"Pelvis": random_rotations(1, rng)[0]}
    normal = simulate(np.random.default_rng(5), mounting=mounting)
    flipped = simulate(np.random.default_rng(5),
                       mounting={"Pelvis": mounting["Pelvis"] @ axis_rotation("z", np.pi)})
    for sim in (normal, flipped):
        cal = calibrate(sim.R_world_sensor, sim.rate)
        R_segment = cal.segment_orientations(sim.R_world_sensor)
        forward = R_segment["Pelvis"][:, :, 0]  # the pelvis X axis in the world
        walked = sim.p_world_pelvis[-1] - sim.p_world_pelvis[0]
        assert forward[-1] @ walked / np.linalg.norm(walked) > 0.95  # facing where it walks
        for side in ("Right", "Left"):
            flex = knee_flexion_deg(R_segment[f"{side}UpperLeg"], R_segment[f"{side}LowerLeg"])
            assert flex.max() > 50.0 and flex.min() > -1.0  # bends backwards only
        assert np.degrees(angle_between(R_segment["Pelvis"], sim.R_world_segment["Pelvis"])
                          ).max() < 0.5


def test_heading_from_hips_when_no_shank_sensor(rng) -> None:
    segments = ("Pelvis", "T8", "RightUpperLeg", "LeftUpperLeg")
    sim = simulate(rng, segments=segments, heading_deg=20.0)
    cal = calibrate(sim.R_world_sensor, sim.rate)
    assert cal.method.startswith("hip flexion axis")
    assert cal.heading_deg == pytest.approx(20.0, abs=2.0)


def test_heading_from_the_direction_walked_without_legs(rng) -> None:
    segments = ("Pelvis", "T8", "Head", "RightUpperArm", "LeftUpperArm")
    sim = simulate(rng, segments=segments, heading_deg=-40.0)
    cal = calibrate(sim.R_world_sensor, sim.rate, acc=sim.acc)
    assert cal.method.startswith("direction walked")
    assert cal.heading_deg == pytest.approx(-40.0, abs=3.0)


def test_too_little_movement_falls_back_and_says_so(rng) -> None:
    back = np.column_stack([[0, 0, 1.0], [0, 1.0, 0], [-1.0, 0, 0]])  # z out of the back
    sim = simulate(rng, walk=False, seconds=4.0, mounting={"Pelvis": back})
    cal = calibrate(sim.R_world_sensor, sim.rate, acc=sim.acc)
    assert cal.method == "fallback: Pelvis sensor -z axis forward"
    assert len(cal.warnings) == 1 and "--forward" in cal.warnings[0]
    expected = -sim.R_world_sensor["Pelvis"][0][:, 2]
    assert cal.heading == pytest.approx(np.arctan2(expected[1], expected[0]))
    given = calibrate(sim.R_world_sensor, sim.rate, default_forward={"T8": "x"})
    x = sim.R_world_sensor["T8"][0][:, 0]
    assert given.heading == pytest.approx(np.arctan2(x[1], x[0]))
    assert "T8 sensor x axis" in given.method
    with pytest.raises(InputError, match="too little .* cannot give it: the sensor axis x is"):
        calibrate(sim.R_world_sensor, sim.rate, default_forward={"Pelvis": "x"})  # x is up


def test_forward_override(rng) -> None:
    sim = simulate(rng, heading_deg=30.0,
                   mounting={"Pelvis": np.column_stack([[0, 0, 1.0], [0, 1.0, 0], [-1.0, 0, 0]])})
    cal = calibrate(sim.R_world_sensor, sim.rate, forward={"Pelvis": "-z"})
    assert cal.method == "forward Pelvis:-z"
    assert cal.heading_deg == pytest.approx(30.0, abs=1e-6)
    assert not cal.warnings
    wrong = calibrate(sim.R_world_sensor, sim.rate, forward={"Pelvis": "z"})
    assert wrong.heading_deg == pytest.approx(-150.0, abs=1e-6)
    assert any("off the knee/hip flexion axis" in w for w in wrong.warnings)
    with pytest.raises(InputError, match="vertical"):
        calibrate(sim.R_world_sensor, sim.rate, forward={"Pelvis": "x"})
    with pytest.raises(InputError, match="has no sensor"):
        calibrate(sim.R_world_sensor, sim.rate, forward={"Neck": "x"})


def test_moving_window_names_the_sensors_that_moved(rng) -> None:
    sim = simulate(rng)
    with pytest.raises(InputError) as err:
        calibrate(sim.R_world_sensor, sim.rate, window=(300, 360), gyr=sim.gyr)
    message = str(err.value)
    assert "RightLowerLeg (" in message and "LeftLowerLeg (" in message
    assert "window 5.00-6.00 s is not still" in message
    still = {s: np.repeat(R[:1], len(R), axis=0) for s, R in sim.R_world_sensor.items()}
    still["RightFoot"] = sim.R_world_sensor["RightFoot"]
    with pytest.raises(InputError) as err:
        calibrate(still, sim.rate, window=(300, 360))
    assert str(err.value).split("still: ")[1].startswith("RightFoot (")
    assert "LeftFoot" not in str(err.value)
    assert err.value.field == "calibrate"
    with pytest.raises(InputError, match="no still window"):
        calibrate({s: R[200:] for s, R in sim.R_world_sensor.items()}, sim.rate, search=3.0)


def test_tpose_calibration(rng) -> None:
    """A still T-pose: arm segments rotated +-90 deg about the body X axis (palms down)."""
    heading = np.radians(-35.0)
    segments = list(SEGMENTS17)
    mounting = dict(zip(segments, random_rotations(len(segments), rng)))
    mounting["Pelvis"] = axis_rotation("x", np.radians(37.0))  # its x axis points forward
    R = {s: np.repeat((pose_rotation(s, heading, "tpose") @ mounting[s])[None], 150, axis=0)
         for s in segments}
    right_arm_down = pose_rotation("RightUpperArm", heading, "tpose") @ [0, 0, -1.0]
    body_right = axis_rotation("z", heading) @ [0, -1.0, 0]
    np.testing.assert_allclose(right_arm_down, body_right, atol=1e-12)  # arms out sideways
    palm = pose_rotation("LeftHand", heading, "tpose") @ [0, -1.0, 0]  # left palm: -Y in N-pose
    np.testing.assert_allclose(palm, [0, 0, -1.0], atol=1e-12)  # faces down
    cal = calibrate(R, 60.0, pose="tpose", forward={"Pelvis": "x"})
    assert cal.heading == pytest.approx(heading)  # the pelvis sensor's x points forward
    for s in segments:
        assert np.degrees(angle_between(cal.R_sensor_segment[s], mounting[s].T)) < 1e-6
    npose = calibrate(R, 60.0, pose="npose", forward={"Pelvis": "x"})
    assert np.degrees(angle_between(npose.R_sensor_segment["RightUpperArm"],
                                    cal.R_sensor_segment["RightUpperArm"])) == pytest.approx(90)
    with pytest.raises(InputError, match="npose or tpose"):
        calibrate(R, 60.0, pose="apose")


def test_calibrate_a_recording_written_to_files(tmp_path: Path, rng) -> None:
    """Through MT Manager files and a sensor map, with the window given in seconds."""
    sim = simulate(rng, heading_deg=110.0)
    ids = {s: f"00B4{k + 1:04X}" for k, s in enumerate(SEGMENTS17)}
    counter = 64000 + np.arange(len(sim.time))  # wraps during the walk
    for s in SEGMENTS17:
        write_mtmanager(tmp_path / "imu", "C_", ids[s], counter, sim.R_world_sensor[s],
                        sim.rate, gyr=sim.gyr[s], acc=sim.acc.get(s))
    (tmp_path / "map.yaml").write_text(
        "sensors:\n" + "".join(f"  {ids[s]}: {s}\n" for s in SEGMENTS17))
    rec = read_mtmanager(tmp_path / "imu")
    smap = load_sensor_map(tmp_path / "map.yaml")
    cal = calibrate_recording(rec, smap, window_s=(0.5, 2.0))
    assert cal.window == (30, 120) and cal.window_s == (0.5, 2.0)
    assert cal.heading_deg == pytest.approx(110.0, abs=0.5)
    assert mounting_errors_deg(cal, sim).max() <= 0.5
    assert set(cal.R_sensor_segment_by_sensor) == set(ids.values())
    auto = calibrate_recording(rec, smap)
    assert auto.window[1] <= 2.5 * sim.rate


def test_real_walk_knees_bend_backwards(shared_data: Path) -> None:
    """OpenSense walk: the heading from the knees makes both knees flex backwards, and the
    thighs swing further forward than backward, as in gait."""
    rec = read_mtmanager(shared_data / "xsens/opensense_walk")
    smap = load_sensor_map(configs_dir() / "sensors/lower8.yaml")
    cal = calibrate_recording(rec, smap)
    assert cal.method.startswith("knee flexion axis") and not cal.warnings
    assert cal.window_s[0] < 3.0
    R = cal.segment_orientations(rec.R_world_sensor_by_segment(smap))
    walking = slice(cal.window[1] + 300, cal.window[1] + 2000)
    for side in ("Right", "Left"):
        flex = knee_flexion_deg(R[f"{side}UpperLeg"][walking], R[f"{side}LowerLeg"][walking])
        assert np.nanpercentile(flex, 95) > 45.0 and np.nanpercentile(flex, 5) > -10.0
        hip = -np.degrees(log_so3(np.swapaxes(R["Pelvis"][walking], 1, 2)
                                  @ R[f"{side}UpperLeg"][walking])[:, 1])
        assert np.nanmax(hip) > abs(np.nanmin(hip))
