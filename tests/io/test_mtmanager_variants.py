"""MT Manager variants written by hand or by the writer: delimiters, formats, loss, wraps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mt_raw import raw_table

from ikfusion.errors import InputError
from ikfusion.io import load_sensor_map, read_mtmanager, write_mtmanager
from ikfusion.rotations import (
    R_ENU_NED,
    R_ENU_NWU,
    angle_between,
    axis_rotation,
    exp_so3,
    matrix_to_quat_wxyz,
    random_rotations,
)


def smooth_rotations(n: int, rng: np.random.Generator) -> np.ndarray:
    """A smooth random orientation track (so slerp across gaps can be checked)."""
    start = random_rotations(1, rng)[0]
    rate = rng.normal(size=3)
    return start @ exp_so3(np.outer(np.arange(n) * 0.01, rate))


def test_five_percent_loss_and_a_wrap_read_back_exactly(tmp_path: Path, rng) -> None:
    n = 3000
    counter = 65536 - 1200 + np.arange(n)  # wraps once, 1200 packets in
    keep = rng.random(n) > 0.05
    keep[[0, -1]] = True
    R = smooth_rotations(n, rng)
    acc = rng.normal(size=(n, 3))
    write_mtmanager(tmp_path, "T_", "00B40001", counter[keep], R[keep], 100.0, acc=acc[keep],
                    gyr=acc[keep] * 0.1)
    names, rows, _ = raw_table(tmp_path / "T_00B40001.txt")
    written = np.array([int(r[0]) for r in rows])
    assert written.max() == 65535 or not keep[1199]
    assert written.max() < 65536 and np.sum(np.diff(written) < 0) == 1  # one wrap in the file
    rec = read_mtmanager(tmp_path / "T_")
    s = rec.sensors["00B40001"]
    assert s.lost == int((~keep).sum()) and s.rows == int(keep.sum())
    assert len(rec.time) == n
    np.testing.assert_allclose(np.diff(rec.time), 0.01)
    np.testing.assert_array_equal(s.received, keep)
    np.testing.assert_array_equal(s.valid, keep)
    np.testing.assert_array_equal(s.packet_counter, counter)
    assert int(s.gaps[:, 1].sum()) == s.lost
    np.testing.assert_array_equal(np.isnan(s.acc).any(axis=1), ~keep)
    np.testing.assert_allclose(s.acc[keep], acc[keep], atol=1e-6)
    assert np.degrees(angle_between(s.R_world_sensor, R)).max() < 0.01  # gaps slerp-filled
    assert any("lost packet" in w and "00B40001" in w for w in rec.warnings)


@pytest.mark.parametrize("delimiter", ["\t", ",", ";", " "])
@pytest.mark.parametrize("orientation", ["quat", "mat", "euler"])
def test_delimiters_and_orientation_formats(tmp_path: Path, rng, delimiter: str,
                                            orientation: str) -> None:
    n = 50
    R = random_rotations(n, rng)
    R[7] = np.nan  # an empty orientation: runs of delimiters
    acc = rng.normal(size=(n, 3))
    acc[3, 1] = np.nan
    write_mtmanager(tmp_path, "D_", "00B4ABCD", np.arange(n), R, 40.0, acc=acc,
                    delimiter=delimiter, orientation=orientation, sample_time_fine=False)
    if delimiter == " ":
        assert "  " in (tmp_path / "D_00B4ABCD.txt").read_text()  # empty fields: runs
    rec = read_mtmanager(tmp_path / "D_00B4ABCD.txt")
    s = rec.sensors["00B4ABCD"]
    assert rec.rate == 40.0 and s.rows == n and s.lost == 0
    good = np.ones(n, dtype=bool)
    good[7] = False
    assert np.degrees(angle_between(s.R_world_sensor[good], R[good])).max() < 1e-4
    assert np.isnan(s.R_world_sensor[7]).all()  # a NaN field stays NaN, no slerp
    np.testing.assert_allclose(s.acc, acc, atol=1e-6, equal_nan=True)
    assert s.valid.tolist() == [k not in (3, 7) for k in range(n)]


@pytest.mark.parametrize("system", ["NED", "NWU"])
def test_ned_and_nwu_exports_are_converted_to_enu(tmp_path: Path, system: str) -> None:
    W = {"NED": R_ENU_NED, "NWU": R_ENU_NWU}[system]
    R_file = axis_rotation("z", np.radians(30.0)) @ axis_rotation("x", np.radians(10.0))
    free_file = np.array([1.0, 2.0, 3.0])
    names = {"NED": ("N", "E", "D"), "NWU": ("N", "W", "U")}[system]
    quat = " ".join(f"{v:.9f}" for v in matrix_to_quat_wxyz(R_file))
    text = ("// Update Rate: 100.0Hz\n"
            f"// Coordinate system: {system}\n"
            "PacketCounter\tAcc_X\tAcc_Y\tAcc_Z\t"
            + "\t".join(f"FreeAcc_{a}" for a in names)
            + "\tQuat_q0\tQuat_q1\tQuat_q2\tQuat_q3\n"
            f"00001\t0.5\t0.6\t9.7\t1.0\t2.0\t3.0\t{quat.replace(' ', chr(9))}\n")
    path = tmp_path / "N_00B40002.txt"
    path.write_text(text)
    rec = read_mtmanager(path)
    s = rec.sensors["00B40002"]
    assert rec.coordinate_system == "ENU" and rec.source_coordinate_system == system
    assert np.degrees(angle_between(s.R_world_sensor[0], W @ R_file)) < 1e-5
    np.testing.assert_allclose(s.free_acc[0], W @ free_file, atol=1e-12)
    np.testing.assert_array_equal(s.acc[0], [0.5, 0.6, 9.7])  # sensor frame: unchanged


def test_ned_writer_round_trip_and_sensor_pointing_north(tmp_path: Path) -> None:
    R_ned_sensor = np.eye(3)[None]  # sensor x North, y East, z Down
    R_enu = R_ENU_NED @ R_ned_sensor
    path = write_mtmanager(tmp_path, "N_", "00B40002", np.arange(1), R_enu, 100.0,
                           free_acc=np.array([[0.0, 1.0, 0.0]]), coordinate_system="NED")
    assert "FreeAcc_N\tFreeAcc_E\tFreeAcc_D" in path.read_text()
    s = read_mtmanager(path).sensors["00B40002"]
    np.testing.assert_allclose(s.R_world_sensor[0] @ [1, 0, 0], [0, 1, 0], atol=1e-6)
    np.testing.assert_allclose(s.R_world_sensor[0] @ [0, 0, 1], [0, 0, -1], atol=1e-6)
    np.testing.assert_allclose(s.free_acc[0], [0.0, 1.0, 0.0], atol=1e-6)


def test_semicolon_file_with_decimal_commas_and_extra_comments(tmp_path: Path) -> None:
    path = tmp_path / "S_00B40005.txt"
    path.write_text("// General information: \n//  MT Manager version: 2022.2.0 \n"
                    "// Device settings: \n//  Update Rate: 40Hz\n// Coordinate system: ENU\n"
                    "// an extra remark\n"
                    "PacketCounter;SampleTimeFine;Acc_X;Acc_Y;Acc_Z;Roll;Pitch;Yaw\n"
                    "100;;9,81;0,0;-0,5;10,0;-5,0;90,0\n"
                    "// operator: walked here\n\n"
                    "101;;NaN;0,1;-0,4;11,0;-5,0;90,0\n")
    rec = read_mtmanager(path)
    s = rec.sensors["00B40005"]
    assert rec.rate == 40.0 and s.rows == 2 and len(rec.time) == 2
    np.testing.assert_array_equal(s.acc, [[9.81, 0.0, -0.5], [np.nan, 0.1, -0.4]])
    from ikfusion.rotations import xsens_euler_to_matrix

    np.testing.assert_allclose(s.R_world_sensor[1], xsens_euler_to_matrix(11.0, -5.0, 90.0))
    assert s.valid.tolist() == [True, False]


def test_space_delimited_runs_of_spaces(tmp_path: Path) -> None:
    path = tmp_path / "P_00B40006.txt"
    path.write_text("// Update Rate: 100.0Hz\n"
                    "PacketCounter SampleTimeFine Year Acc_X Acc_Y Acc_Z Quat_q0 Quat_q1 Quat_q2 "
                    "Quat_q3\n"
                    "00010   1.0 2.0 3.0 1 0 0 0\n"  # SampleTimeFine and Year empty
                    "00011   1.5  3.5 1 0 0 0\n"  # ... and Acc_Y empty
                    "00013   2.0 2.5 4.0    \n")  # no orientation; packet 12 lost
    rec = read_mtmanager(path)
    s = rec.sensors["00B40006"]
    assert s.rows == 3 and s.lost == 1 and len(rec.time) == 4
    np.testing.assert_array_equal(s.acc[[0, 1, 3]], [[1, 2, 3], [1.5, np.nan, 3.5], [2, 2.5, 4]])
    assert s.valid.tolist() == [True, False, False, False]
    np.testing.assert_array_equal(s.R_world_sensor[0], np.eye(3))
    assert np.isnan(s.R_world_sensor[3]).all()


def test_space_delimited_aligned_columns(tmp_path: Path) -> None:
    path = tmp_path / "A_00B40007.txt"
    path.write_text("// Update Rate: 60Hz\nPacketCounter   Acc_X     Acc_Y     Acc_Z\n"
                    "   1          0.100     0.200     9.800\n"
                    "   2          0.110     0.210     9.810\n")
    s = read_mtmanager(path).sensors["00B40007"]
    np.testing.assert_array_equal(s.acc, [[0.1, 0.2, 9.8], [0.11, 0.21, 9.81]])


def test_quaternion_preferred_then_matrix_then_euler_per_row(tmp_path: Path, rng) -> None:
    R = random_rotations(3, rng)
    write_mtmanager(tmp_path, "M_", "00B40008", np.arange(3), R, 100.0,
                    orientation=["euler", "mat", "quat"], sample_time_fine=False)
    path = tmp_path / "M_00B40008.txt"
    lines = path.read_text().splitlines()
    header = lines[-4].split("\t")
    rows = [ln.split("\t") for ln in lines[-3:]]
    for name in ("Quat_q0", "Quat_q1", "Quat_q2", "Quat_q3"):  # row 1: no quaternion
        rows[1][header.index(name)] = "NaN"
    for name in [h for h in header if h.startswith("Mat") or h.startswith("Quat")]:
        rows[2][header.index(name)] = ""  # row 2: Euler only
    rows[0][header.index("Roll")] = str(float(rows[0][header.index("Roll")]) + 20.0)
    path.write_text("\n".join(lines[:-3] + ["\t".join(r) for r in rows]) + "\n")
    rec = read_mtmanager(path)
    s = rec.sensors["00B40008"]
    assert s.orientation_source == "Quat+Mat+Euler"
    errors = np.degrees(angle_between(s.R_world_sensor, R))
    assert errors.max() < 1e-3  # row 0 from the quaternion, not the altered Euler angles
    assert any("Mat and Euler columns used where" in w for w in rec.warnings)


def test_partial_vector_columns_and_missing_orientation_component(tmp_path: Path) -> None:
    path = tmp_path / "C_00B40009.txt"
    path.write_text("// Update Rate: 100Hz\n"
                    "PacketCounter\tAcc_X\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\tQuat_q0\tQuat_q1\tQuat_q2\n"
                    "1\t1.0\t3.0\t0.1\t0.2\t0.3\t1\t0\t0\n")
    rec = read_mtmanager(path)
    s = rec.sensors["00B40009"]
    np.testing.assert_array_equal(s.acc[0], [1.0, np.nan, 3.0])
    np.testing.assert_array_equal(s.gyr[0], [0.1, 0.2, 0.3])
    assert s.orientation_source == "" and not s.valid.any()
    assert any("Acc_Y missing" in w for w in rec.warnings)
    assert any("incomplete quaternion columns (missing Quat_q3)" in w for w in rec.warnings)


def test_sensors_starting_late_and_stopping_early_across_a_wrap(tmp_path: Path, rng) -> None:
    R = random_rotations(1, rng)[0][None].repeat(400, axis=0)
    base = 65400 + np.arange(400)  # the trial wraps after 136 packets
    write_mtmanager(tmp_path, "L_", "00B4000A", base, R, 100.0)
    write_mtmanager(tmp_path, "L_", "00B4000B", base[150:300], R[150:300], 100.0)  # after wrap
    write_mtmanager(tmp_path, "L_", "00B4000C", base[20:100], R[20:100], 100.0)  # before wrap
    rec = read_mtmanager(tmp_path)
    assert len(rec.time) == 400
    assert rec.sensors["00B4000B"].span == (150, 300)
    assert rec.sensors["00B4000C"].span == (20, 100)
    late = rec.sensors["00B4000B"]
    assert not late.valid[:150].any() and late.valid[150:300].all()
    assert np.isnan(late.R_world_sensor[:150]).all() and np.isnan(late.R_world_sensor[300:]).all()
    assert any("00B4000B starts 1.50 s" in w for w in rec.warnings)
    assert any("00B4000C stops 3.00 s" in w for w in rec.warnings)
    assert all(s.lost == 0 for s in rec.sensors.values())


def test_repeated_counter_rows_keep_the_first(tmp_path: Path) -> None:
    path = tmp_path / "R_00B4000D.txt"
    path.write_text("// Update Rate: 100Hz\nPacketCounter,Acc_X,Acc_Y,Acc_Z\n"
                    "5,1,1,1\n6,2,2,2\n6,9,9,9\n7,3,3,3\n")
    rec = read_mtmanager(path)
    s = rec.sensors["00B4000D"]
    assert s.rows == 4 and len(rec.time) == 3
    np.testing.assert_array_equal(s.acc[:, 0], [1, 2, 3])
    assert any("repeat a PacketCounter" in w for w in rec.warnings)


def test_rate_from_sample_time_fine_and_the_rate_option(tmp_path: Path, rng) -> None:
    R = random_rotations(200, rng)
    write_mtmanager(tmp_path, "F_", "00B4000E", np.arange(200), R, None,
                    sample_time_fine=np.arange(200) * 10000.0 / 60.0)
    rec = read_mtmanager(tmp_path / "F_")
    assert rec.rate == pytest.approx(60.0, abs=1e-3)
    assert any("from SampleTimeFine" in w for w in rec.warnings)
    write_mtmanager(tmp_path, "G_", "00B4000F", np.arange(200), R, None, sample_time_fine=False)
    with pytest.raises(InputError, match="--rate HZ") as err:
        read_mtmanager(tmp_path / "G_")
    assert err.value.path == tmp_path / "G_00B4000F.txt"
    assert read_mtmanager(tmp_path / "G_", rate=40.0).rate == 40.0
    write_mtmanager(tmp_path, "H_", "00B40010", np.arange(20), R[:20], 100.0)
    rec = read_mtmanager(tmp_path / "H_", rate=60.0)  # the file's own rate wins, with a word
    assert rec.rate == 100.0 and any("is not used" in w for w in rec.warnings)


def test_sample_time_fine_counts_the_wraps_of_a_long_gap(tmp_path: Path, rng) -> None:
    """A 70 000-packet gap looks like 4 464 packets to a 16-bit counter."""
    counter = np.concatenate([np.arange(100), 70100 + np.arange(100)])
    R = random_rotations(200, rng)
    write_mtmanager(tmp_path, "W_", "00B40011", counter, R, 100.0)
    s = read_mtmanager(tmp_path / "W_").sensors["00B40011"]
    assert s.lost == 70000 and s.span == (0, 70200)
    write_mtmanager(tmp_path, "X_", "00B40012", counter, R, 100.0, sample_time_fine=False)
    assert read_mtmanager(tmp_path / "X_").sensors["00B40012"].lost == 70000 - 65536


def test_sample_time_fine_that_disagrees_is_reported(tmp_path: Path, rng) -> None:
    ticks = np.arange(50) * 100.0
    ticks[30:] += 500.0  # five samples' worth of time without a counter step
    write_mtmanager(tmp_path, "Y_", "00B40013", np.arange(50), random_rotations(50, rng), 100.0,
                    sample_time_fine=ticks)
    rec = read_mtmanager(tmp_path / "Y_")
    assert any("disagree on 1 step" in w for w in rec.warnings)


def test_device_id_from_the_header_when_the_name_has_none(tmp_path: Path) -> None:
    path = tmp_path / "walk.txt"
    path.write_text("// Device information: \n//  DeviceId: 00b4cafe\n// Update Rate: 100Hz\n"
                    "PacketCounter\tAcc_X\tAcc_Y\tAcc_Z\n1\t0\t0\t9.8\n")
    assert read_mtmanager(path).sensor_ids == ["00B4CAFE"]


def test_reading_with_a_sensor_map(tmp_path: Path, rng) -> None:
    R = random_rotations(10, rng)
    for sid in ("00B40021", "00B40022", "00B40023"):
        write_mtmanager(tmp_path, "K_", sid, np.arange(10), R, 100.0)
    sensor_map = tmp_path / "map.yaml"
    sensor_map.write_text("sensors:\n  00b40021: Pelvis\n  00B40022: T8\n")
    smap = load_sensor_map(sensor_map)
    rec = read_mtmanager(tmp_path, sensor_map=smap)
    assert any("00B40023 is in the recording but not in the sensor map" in w
               for w in rec.warnings)
    assert set(rec.segment_streams(smap)) == {"Pelvis", "T8"}
    assert rec.segment_streams(smap)["T8"].sensor_id == "00B40022"
    sensor_map.write_text("sensors:\n  00B40021: Pelvis\n  00B40099: Head\n  00B40098: T8\n")
    with pytest.raises(InputError) as err:
        read_mtmanager(tmp_path, sensor_map=load_sensor_map(sensor_map))
    message = str(err.value)
    assert "00B40099 (Head), 00B40098 (T8)" in message
    assert "sensors found: 00B40021, 00B40022, 00B40023" in message


def test_prefix_selects_only_its_own_files(tmp_path: Path, rng) -> None:
    R = random_rotations(5, rng)
    write_mtmanager(tmp_path, "trial1_", "00B40031", np.arange(5), R, 100.0)
    write_mtmanager(tmp_path, "trial1_", "00B40032", np.arange(5), R, 100.0)
    write_mtmanager(tmp_path, "trial1_extra_", "00B40033", np.arange(5), R, 100.0)
    assert read_mtmanager(tmp_path / "trial1_").sensor_ids == ["00B40031", "00B40032"]
    assert read_mtmanager(tmp_path / "trial1_extra_").sensor_ids == ["00B40033"]
    with pytest.raises(InputError, match="2 trials"):
        read_mtmanager(tmp_path)


@settings(max_examples=30, deadline=None)
@given(delimiter=st.sampled_from(["\t", ",", ";", " "]),
       orientation=st.sampled_from(["quat", "mat", "euler", ("quat", "euler"),
                                    ("mat", "quat")]),
       system=st.sampled_from(["ENU", "NED", "NWU"]), header=st.sampled_from(["old", "new"]),
       empty=st.sampled_from(["", "NaN"]), n=st.integers(2, 60),
       start=st.integers(0, 65535), seed=st.integers(0, 2**16), loss=st.floats(0.0, 0.3))
def test_writer_reader_round_trip(tmp_path_factory, delimiter: str, orientation: object,
                                  system: str, header: str, empty: str, n: int, start: int,
                                  seed: int, loss: float) -> None:
    rng = np.random.default_rng(seed)
    folder = tmp_path_factory.mktemp("rt")
    keep = rng.random(n) >= loss
    keep[[0, -1]] = True
    R = random_rotations(n, rng)
    acc = rng.normal(size=(n, 3))
    free = rng.normal(size=(n, 3))
    acc[rng.random(n) < 0.1, 0] = np.nan
    write_mtmanager(folder, "P_", "00B4ABCD", start + np.arange(n)[keep], R[keep], 60.0,
                    acc=acc[keep], free_acc=free[keep], delimiter=delimiter,
                    orientation=orientation, coordinate_system=system, header=header,
                    empty=empty, comments=["a note"])
    rec = read_mtmanager(folder / "P_")
    s = rec.sensors["00B4ABCD"]
    assert rec.rate == 60.0 and len(rec.time) == n
    assert s.rows == keep.sum() and s.lost == (~keep).sum()
    np.testing.assert_array_equal(s.received, keep)
    np.testing.assert_allclose(s.acc[keep], acc[keep], atol=1e-6, equal_nan=True)
    np.testing.assert_allclose(s.free_acc[keep], free[keep], atol=2e-6)
    assert np.degrees(angle_between(s.R_world_sensor[keep], R[keep])).max() < 1e-3
    # a component empty in every received row is an absent column, not a bad sample
    recorded = np.isfinite(acc[keep]).any(axis=0)
    np.testing.assert_array_equal(s.valid, keep & np.isfinite(acc[:, recorded]).all(axis=1))
