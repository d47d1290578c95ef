"""MVNX and the generic IMU CSV; a property test of the MT Manager parser."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ikfusion.errors import InputError
from ikfusion.io import read_imu_csv, read_mtmanager, read_mvnx, write_mtmanager
from ikfusion.rotations import angle_between, matrix_to_quat_wxyz, random_rotations


def normal_frames(text: str) -> list[str]:
    return re.findall(r'<frame [^>]*type="normal">(.*?)</frame>', text, flags=re.S)


def element(frame: str, tag: str) -> np.ndarray:
    return np.array(re.search(f"<{tag}>(.*?)</{tag}>", frame, flags=re.S).group(1).split(),
                    dtype=float)


def test_mvnx_reads_the_file_numbers(shared_data: Path) -> None:
    path = shared_data / "mvnx" / "test_mocap.mvnx"
    mvnx = read_mvnx(path)
    frames = normal_frames(path.read_text())
    assert len(mvnx.time) == len(frames) == 112
    assert mvnx.frame_rate == 60.0
    assert len(mvnx.segments) == 23 and len(mvnx.sensors) == 11
    for k in (0, len(frames) - 1):
        np.testing.assert_allclose(mvnx.quat_wxyz_world_segment[k].ravel(),
                                   element(frames[k], "orientation"))
        np.testing.assert_allclose(mvnx.p_world_segment[k].ravel(), element(frames[k], "position"))
        np.testing.assert_allclose(mvnx.quat_wxyz_world_sensor[k].ravel(),
                                   element(frames[k], "sensorOrientation"))
        np.testing.assert_allclose(mvnx.joint_angles_deg[k].ravel(),
                                   element(frames[k], "jointAngle"))
        np.testing.assert_array_equal(mvnx.foot_contacts[k],
                                      element(frames[k], "footContacts") > 0.5)
    assert mvnx.contacts == ["LeftFoot_Heel", "LeftFoot_Toe", "RightFoot_Heel", "RightFoot_Toe"]
    recording = mvnx.imu_recording()
    assert set(recording.sensors) == set(mvnx.sensors)


def test_mvnx_arms_follow_our_npose_convention(shared_data: Path) -> None:
    """MVN's arm frames are T-pose aligned: after conversion, an arm hanging down in MVN's
    first frame has its segment -Z pointing from shoulder to elbow, like ours."""
    mvnx = read_mvnx(shared_data / "mvnx" / "test_mocap.mvnx")
    for side in ("Left", "Right"):
        R = mvnx.R_world_segment(f"{side}UpperArm")[0]
        shoulder = mvnx.p_world_segment[0, mvnx.segments.index(f"{side}UpperArm")]
        elbow = mvnx.p_world_segment[0, mvnx.segments.index(f"{side}ForeArm")]
        direction = (elbow - shoulder) / np.linalg.norm(elbow - shoulder)
        assert np.degrees(np.arccos(np.clip(-R[:, 2] @ direction, -1, 1))) < 10.0


def test_mvnx_bad_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.mvnx"
    path.write_text("<mvnx><subject frameRate='60'><frame type='normal' time='0'>"
                    "<orientation>1 0 0 x</orientation></frame></subject></mvnx>")
    with pytest.raises(InputError, match="orientation"):
        read_mvnx(path)


def test_generic_csv(tmp_path: Path, rng) -> None:
    R = random_rotations(2, rng)
    lines = ["time,sensor,qw,qx,qy,qz,ax,ay,az,gx,gy,gz"]
    for k in range(10):
        for s in (0, 1):
            if s == 1 and k == 4:
                continue  # a lost sample
            q = matrix_to_quat_wxyz(R[s])
            lines.append(f"{k * 0.01:.2f},S{s}," + ",".join(f"{v:.9f}" for v in q)
                         + ",0,0,9.81,0.1,0,0")
    path = tmp_path / "imu.csv"
    path.write_text("\n".join(lines) + "\n")
    rec = read_imu_csv(path)
    assert rec.rate == pytest.approx(100.0)
    assert rec.sensors["S1"].lost == 1 and not rec.sensors["S1"].valid[4]
    assert np.degrees(angle_between(rec.sensors["S0"].R_world_sensor[3], R[0])) < 1e-6
    np.testing.assert_allclose(rec.sensors["S0"].acc[0], [0, 0, 9.81])
    path.write_text("time,sensor,qw,qx,qy,qz\n0,S0,1,0,0,zero\n")
    with pytest.raises(InputError) as err:
        read_imu_csv(path)
    assert err.value.line == 2 and err.value.field == "qz"


@settings(max_examples=25, deadline=None)
@given(delimiter=st.sampled_from(["\t", ",", ";", " "]),
       orientation=st.sampled_from(["quat", "mat", "euler"]),
       n=st.integers(2, 40), start=st.integers(0, 65535), seed=st.integers(0, 2**16))
def test_writer_reader_round_trip(tmp_path_factory, delimiter: str, orientation: str, n: int,
                                  start: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    folder = tmp_path_factory.mktemp("rt")
    R = random_rotations(n, rng)
    acc = rng.normal(size=(n, 3))
    write_mtmanager(folder, "P_", "00B4ABCD", start + np.arange(n), R, 100.0, acc=acc,
                    delimiter=delimiter, orientation=orientation)
    s = read_mtmanager(folder / "P_").sensors["00B4ABCD"]
    assert s.rows == n and s.lost == 0
    np.testing.assert_allclose(s.acc, acc, atol=1e-6)
    np.testing.assert_allclose(s.R_world_sensor, R, atol=1e-5)
