"""MVNX (Xsens MVN XML): the file's numbers, its conventions, subject dimensions, bad files."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from ikfusion.errors import InputError
from ikfusion.io import read_imu, read_mvnx
from ikfusion.rotations import angle_between, quat_wxyz_to_matrix


def frames_of(text: str, kind: str = "normal") -> list[tuple[dict[str, str], str]]:
    found = re.findall(r"<frame ([^>]*)>(.*?)</frame>", text, flags=re.S)
    out = []
    for attrs, body in found:
        a = dict(re.findall(r'(\w+)="([^"]*)"', attrs))
        if a.get("type") == kind:
            out.append((a, body))
    return out


def numbers(body: str, tag: str) -> np.ndarray:
    return np.array(re.search(f"<{tag}>(.*?)</{tag}>", body, flags=re.S).group(1).split(),
                    dtype=float)


@pytest.fixture
def mvnx_path(shared_data: Path) -> Path:
    return shared_data / "mvnx" / "test_mocap.mvnx"


def test_mvnx_holds_the_file_numbers(mvnx_path: Path) -> None:
    mvnx = read_mvnx(mvnx_path)
    text = mvnx_path.read_text()
    frames = frames_of(text)
    assert len(mvnx) == len(frames) == 112
    assert mvnx.frame_rate == 60.0 and mvnx.version == "4"
    assert len(mvnx.segments) == 23 and len(mvnx.sensors) == 11 and len(mvnx.joints) == 22
    assert mvnx.subject["configuration"] == "UpperBody"
    for k in (0, len(frames) - 1):
        attrs, body = frames[k]
        assert mvnx.frame_index[k] == int(attrs["index"])
        np.testing.assert_array_equal(mvnx.quat_wxyz_world_segment[k].ravel(),
                                      numbers(body, "orientation"))
        np.testing.assert_array_equal(mvnx.p_world_segment[k].ravel(), numbers(body, "position"))
        np.testing.assert_array_equal(mvnx.quat_wxyz_world_sensor[k].ravel(),
                                      numbers(body, "sensorOrientation"))
        np.testing.assert_array_equal(mvnx.free_acc_world_sensor[k].ravel(),
                                      numbers(body, "sensorFreeAcceleration"))
        np.testing.assert_array_equal(mvnx.mag_sensor[k].ravel(),
                                      numbers(body, "sensorMagneticField"))
        np.testing.assert_array_equal(mvnx.joint_angles_deg[k].ravel(),
                                      numbers(body, "jointAngle"))
        np.testing.assert_array_equal(mvnx.foot_contacts[k], numbers(body, "footContacts") > 0.5)
    np.testing.assert_allclose(mvnx.time[-1], 111 / 60.0)
    assert mvnx.contacts == ["LeftFoot_Heel", "LeftFoot_Toe", "RightFoot_Heel", "RightFoot_Toe"]
    assert set(mvnx.reference_poses) == {"identity", "tpose", "tpose-isb"}
    assert mvnx.joint_angles()["jRightElbow"].shape == (112, 3)


def kinematic_error(mvnx, quats: np.ndarray) -> float:
    """Largest |p_child - (p_parent + R_parent @ joint point)| over frames and joints [m]."""
    worst = 0.0
    for k, segment in enumerate(mvnx.segments):
        R = quat_wxyz_to_matrix(quats[:, k])
        for label, point in mvnx.segment_points[segment].items():
            child = next((j for j, s in enumerate(mvnx.segments) if j != k
                          and np.linalg.norm(mvnx.segment_points[s].get(label, [1.0])) < 1e-9
                          and label.startswith("j")), None)
            if child is None or np.linalg.norm(point) < 1e-9:
                continue
            predicted = mvnx.p_world_segment[:, k] + R @ point
            worst = max(worst, float(np.abs(predicted - mvnx.p_world_segment[:, child]).max()))
    return worst


def test_quaternions_are_scalar_first_and_the_world_z_up(mvnx_path: Path) -> None:
    """Read as (w, x, y, z), every joint point lands on its child segment's origin, the pelvis
    stays upright and the head above it; read as (x, y, z, w) the joints fall apart."""
    mvnx = read_mvnx(mvnx_path)
    assert kinematic_error(mvnx, mvnx.quat_wxyz_world_segment) < 2e-3
    assert kinematic_error(mvnx, np.roll(mvnx.quat_wxyz_world_segment, -1, axis=-1)) > 0.05
    R_pelvis = mvnx.R_world_segment("Pelvis")
    assert np.degrees(np.arccos(R_pelvis[:, 2, 2])).max() < 30.0
    head = mvnx.p_world_segment[:, mvnx.segments.index("Head")]
    pelvis = mvnx.p_world_segment[:, mvnx.segments.index("Pelvis")]
    assert ((head - pelvis)[:, 2] > 0.4).all()


def test_arms_follow_our_npose_convention(mvnx_path: Path) -> None:
    """MVN's arm frames are T-pose aligned (its identity pose has the arms out sideways); after
    conversion an upper arm's -Z points from the shoulder to the elbow, as in our N-pose."""
    mvnx = read_mvnx(mvnx_path)
    identity = mvnx.reference_poses["identity"][1]
    right = mvnx.segments.index("RightUpperArm")
    assert identity[right + 1, 1] - identity[right, 1] < -0.2  # sideways in MVN's identity
    for side in ("Left", "Right"):
        R = mvnx.R_world_segment(f"{side}UpperArm")
        shoulder = mvnx.p_world_segment[:, mvnx.segments.index(f"{side}UpperArm")]
        elbow = mvnx.p_world_segment[:, mvnx.segments.index(f"{side}ForeArm")]
        d = (elbow - shoulder) / np.linalg.norm(elbow - shoulder, axis=1, keepdims=True)
        cos = np.einsum("ni,ni->n", -R[:, :, 2], d)
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 5.0
    legs = mvnx.R_world_segment("RightUpperLeg")
    np.testing.assert_allclose(legs, quat_wxyz_to_matrix(
        mvnx.quat_wxyz_world_segment[:, mvnx.segments.index("RightUpperLeg")]))
    with pytest.raises(InputError, match="no segment 'Knee'"):
        mvnx.R_world_segment("Knee")


def test_body_dimensions_match_the_identity_pose(mvnx_path: Path) -> None:
    mvnx = read_mvnx(mvnx_path)
    dims = mvnx.body_dimensions()
    pose = mvnx.reference_poses["identity"][1]
    p = {s: pose[k] for k, s in enumerate(mvnx.segments)}
    np.testing.assert_allclose(dims["upper_leg"], np.linalg.norm(p["RightLowerLeg"]
                                                                 - p["RightUpperLeg"]), atol=2e-3)
    np.testing.assert_allclose(dims["lower_leg"], np.linalg.norm(p["RightFoot"]
                                                                 - p["RightLowerLeg"]), atol=2e-3)
    np.testing.assert_allclose(dims["upper_arm"], np.linalg.norm(p["RightForeArm"]
                                                                 - p["RightUpperArm"]), atol=2e-3)
    np.testing.assert_allclose(dims["shoulder_width"], np.linalg.norm(p["RightUpperArm"]
                                                                      - p["LeftUpperArm"]),
                               atol=2e-3)
    np.testing.assert_allclose(dims["hip_width"], np.linalg.norm(p["RightUpperLeg"]
                                                                 - p["LeftUpperLeg"]), atol=2e-3)
    floor = p["RightFoot"][2] - dims["ankle_height"]  # under the heel, in the identity pose
    np.testing.assert_allclose(dims["hip_height"], p["RightUpperLeg"][2] - floor, atol=2e-3)
    top = p["Head"][2] + mvnx.segment_points["Head"]["pTopOfHead"][2]
    np.testing.assert_allclose(dims["height"], top - floor, atol=2e-3)
    assert 1.5 < dims["height"] < 1.9 and 0.2 < dims["foot_length"] < 0.3


def test_mvnx_as_an_imu_recording(mvnx_path: Path) -> None:
    mvnx = read_mvnx(mvnx_path)
    rec = read_imu(mvnx_path, sensor_map=mvnx.sensor_map())
    assert rec.rate == 60.0 and len(rec) == 112 and rec.sensor_ids == mvnx.sensors
    s = rec.sensors["RightForeArm"]
    k = mvnx.sensors.index("RightForeArm")
    assert np.degrees(angle_between(s.R_world_sensor, quat_wxyz_to_matrix(
        mvnx.quat_wxyz_world_sensor[:, k]))).max() < 1e-6
    np.testing.assert_array_equal(s.free_acc, mvnx.free_acc_world_sensor[:, k])
    assert s.valid.all() and s.lost == 0


def small_mvnx(frames: str, up: str = "z") -> str:
    head = "0 0 1.5" if up == "z" else "0 1.5 0"
    return f"""<?xml version="1.0"?>
<mvnx version="4"><subject label="s" frameRate="100" segmentCount="2">
<segments><segment label="Pelvis"/><segment label="Head"/></segments>
<sensors><sensor label="Pelvis"/></sensors>
<frames>
<frame type="identity" time="0"><orientation>1 0 0 0 1 0 0 0</orientation>
<position>0 0 0 {head}</position></frame>
{frames}
</frames></subject></mvnx>"""


def frame(index: int, q: str = "1 0 0 0", pos: str = "0 0 1") -> str:
    return (f'<frame type="normal" index="{index}" time="{index * 10}"><orientation>{q} {q}'
            f"</orientation><position>{pos} {pos}</position><sensorOrientation>{q}"
            "</sensorOrientation></frame>")


def test_missing_frames_become_gaps_and_y_up_is_turned(tmp_path: Path) -> None:
    path = tmp_path / "take.mvnx"
    path.write_text(small_mvnx(frame(0) + frame(1) + frame(4), up="y"))
    mvnx = read_mvnx(path)
    assert any("Y-up" in w for w in mvnx.warnings)
    np.testing.assert_allclose(mvnx.p_world_segment[0, 0], [0, -1, 0], atol=1e-12)
    rec = mvnx.imu_recording()
    s = rec.sensors["Pelvis"]
    assert len(rec) == 5 and s.lost == 2 and s.received.tolist() == [1, 1, 0, 0, 1]
    np.testing.assert_allclose(mvnx.time, [0.0, 0.01, 0.04])


@pytest.mark.parametrize(
    ("body", "words"),
    [
        ("<mvnx><subject frameRate='60'><frame type='normal' index='0'>"
         "<orientation>1 0 0 x</orientation></frame></subject></mvnx>", "'x', not a number"),
        ("<mvnx><subject frameRate='60'></subject></mvnx>", "no normal frames"),
        ("<mvnx><comment/></mvnx>", "no <subject>"),
        ("<mvnx><subject>", "not a readable MVNX"),
    ],
)
def test_bad_mvnx(tmp_path: Path, body: str, words: str) -> None:
    path = tmp_path / "bad.mvnx"
    path.write_text(body)
    with pytest.raises(InputError, match=re.escape(words)) as err:
        read_mvnx(path)
    assert err.value.path == path


def test_mvnx_frame_with_the_wrong_count(tmp_path: Path) -> None:
    path = tmp_path / "count.mvnx"
    path.write_text(small_mvnx(frame(0) + frame(1, q="1 0 0")))
    with pytest.raises(InputError, match="frame 1: <orientation> has 6 numbers, expected 8"):
        read_mvnx(path)
