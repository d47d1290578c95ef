"""MT Manager exports of ../shared/data/xsens: the reader returns the files' own numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mt_raw import counters, orientation, raw_table, row_dict

from ikfusion.io import read_mtmanager, read_mtmanager_file, trial_files

VECTORS = {"acc": "Acc_", "gyr": "Gyr_", "mag": "Mag_"}


def exports(root: Path) -> list[Path]:
    return sorted(p for p in (root / "xsens").rglob("*.txt")
                  if p.stem[-8:].upper() == p.stem[-8:] and len(p.stem) > 8
                  and all(c in "0123456789ABCDEF" for c in p.stem[-8:]))


def test_every_export_reads_with_its_first_and_last_numbers(shared_data: Path) -> None:
    files = exports(shared_data)
    assert len(files) == 31  # 7 formats + 8 opensense + 5 movingreality + 11 static
    for path in files:
        recording = read_mtmanager(path, rate=100.0)
        (stream,) = recording.sensors.values()
        names, rows, _ = raw_table(path)
        assert stream.rows == len(rows), path
        index = counters(names, rows) - counters(names, rows)[0]
        assert len(recording.time) == index[-1] + 1
        for k in (0, len(rows) - 1):
            raw = row_dict(names, rows[k])
            i = int(index[k])
            for attr, prefix in VECTORS.items():
                if prefix + "X" in raw:
                    expected = [raw[prefix + a] for a in "XYZ"]
                    np.testing.assert_array_equal(getattr(stream, attr)[i], expected,
                                                  err_msg=f"{path.name} {attr} row {k}")
            R = orientation(raw)
            if R is None:
                assert stream.orientation_source == ""
                assert np.isnan(stream.R_world_sensor[i]).all()
            else:
                np.testing.assert_allclose(stream.R_world_sensor[i], R, atol=1e-6,
                                           err_msg=f"{path.name} orientation row {k}")


def test_readme_values_of_the_old_export(shared_data: Path) -> None:
    rec = read_mtmanager(shared_data / "xsens/formats/MT_012005D6_031-000_00B421AF.txt")
    s = rec.sensors["00B421AF"]
    assert rec.rate == 100.0 and rec.source_coordinate_system == "ENU"
    assert s.orientation_source == "Mat" and s.rows == 3369 and s.lost == 0
    np.testing.assert_array_equal(s.acc[0], [3.030769, 5.254238, -7.714005])
    np.testing.assert_array_equal(s.gyr[0], [0.005991, -0.032133, 0.022713])
    np.testing.assert_array_equal(s.mag[0], [-0.045410, -0.266113, 0.897217])
    np.testing.assert_array_equal(s.acc[-1], [2.657654, 5.012634, -7.581414])
    assert s.valid.all()


def test_nan_time_fields_keep_the_data(shared_data: Path) -> None:
    """MT Manager 2022 writes NaN in its empty time columns: the data of the row are kept."""
    path = shared_data / "xsens/formats/MT2022_ACC_GYRO_ROT_EULER_TAB_00B42D4F.txt"
    parsed = read_mtmanager_file(path)
    assert np.isnan(parsed.column("SampleTimeFine")).all()
    assert np.isnan(parsed.column("Year")).all()
    s = read_mtmanager(path, rate=100.0).sensors["00B42D4F"]
    np.testing.assert_array_equal(s.acc[0], [0.069663, -0.012828, 9.978389])
    assert s.valid.all() and s.orientation_source == "Euler"
    acc_only = read_mtmanager(shared_data / "xsens/formats/MT2022_ACC_00B42D4B.txt", rate=100.0)
    s = acc_only.sensors["00B42D4B"]
    np.testing.assert_array_equal(s.acc[-1], [0.061840, -0.013683, 9.956912])
    assert not s.valid.any() and s.received.all()  # no orientation at all
    assert any("no orientation columns" in w for w in acc_only.warnings)


def test_gravity_points_up_in_every_orientation_convention(shared_data: Path) -> None:
    """Physics check of the orientation reading: at rest ``R_world_sensor @ acc = (0, 0, g)``."""
    checked = 0
    for path in exports(shared_data):
        s = next(iter(read_mtmanager(path, rate=100.0).sensors.values()))
        if s.orientation_source == "" or s.acc is None:
            continue
        quiet = s.valid & (np.abs(np.linalg.norm(s.acc, axis=1) - 9.81) < 0.25)
        if s.gyr is not None:
            quiet &= np.linalg.norm(s.gyr, axis=1) < 0.15
        k = np.flatnonzero(quiet)[:20]
        assert len(k) >= 3, path.name
        f_world = np.einsum("nij,nj->ni", s.R_world_sensor[k], s.acc[k]).mean(axis=0)
        assert np.hypot(f_world[0], f_world[1]) < 0.5, path.name  # a transposed matrix: metres
        assert 9.5 < f_world[2] < 10.2, path.name
        checked += 1
    assert checked == 30


def test_quaternion_and_euler_columns_agree(shared_data: Path) -> None:
    """movingreality files hold both; the quaternion is used and the Euler angles agree."""
    trial = shared_data / "xsens/movingreality_trial007/MT_012000E0_007-000_"
    rec = read_mtmanager(trial, rate=100.0)
    assert len(rec.sensors) == 5 and len(rec.time) == 13439
    assert not any("disagree" in w for w in rec.warnings)
    names, rows, _ = raw_table(Path(str(trial) + "00B47786.txt"))
    raw = row_dict(names, rows[5000])
    from ikfusion.rotations import angle_between, xsens_euler_to_matrix

    R_euler = xsens_euler_to_matrix(raw["Roll"], raw["Pitch"], raw["Yaw"])
    s = rec.sensors["00B47786"]
    assert s.orientation_source == "Quat"
    assert np.degrees(angle_between(s.R_world_sensor[5000], R_euler)) < 0.01
    np.testing.assert_array_equal(s.free_acc[5000], [raw[f"FreeAcc_{a}"] for a in "ENU"])


def test_opensense_trial_on_one_time_base(shared_data: Path) -> None:
    folder = shared_data / "xsens/opensense_walk"
    by_folder = read_mtmanager(folder)
    by_prefix = read_mtmanager(folder / "MT_012005D6_009-001_")
    assert by_folder.sensor_ids == by_prefix.sensor_ids
    assert len(by_folder.sensors) == 8 and by_folder.rate == 100.0
    last = {}
    for sid in by_folder.sensors:
        names, rows, _ = raw_table(folder / f"MT_012005D6_009-001_{sid}.txt")
        c = counters(names, rows)
        assert c[0] == 472
        last[sid] = int(c[-1])
    assert len(by_folder.time) == max(last.values()) - 472 + 1
    np.testing.assert_allclose(np.diff(by_folder.time), 0.01)
    for sid, s in by_folder.sensors.items():
        assert s.span == (0, last[sid] - 472 + 1)
        assert s.lost == 0 and s.valid[:s.span[1]].all() and not s.valid[s.span[1]:].any()
        assert np.isnan(s.R_world_sensor[s.span[1]:]).all()
        np.testing.assert_array_equal(s.packet_counter, 472 + np.arange(len(by_folder.time)))
    early = [w for w in by_folder.warnings if "stops" in w]
    assert len(early) == sum(1 for v in last.values() if v < max(last.values()))


def test_static_trial_comma_separated(shared_data: Path) -> None:
    rec = read_mtmanager(shared_data / "xsens/static11")
    assert len(rec.sensors) == 11 and len(rec.time) == 366
    assert all(s.valid.all() and s.orientation_source == "Quat" for s in rec.sensors.values())
    assert len(trial_files(shared_data / "xsens/static11")) == 11


def test_formats_folder_holds_several_trials(shared_data: Path) -> None:
    from ikfusion.errors import InputError

    with pytest.raises(InputError, match="5 trials") as err:
        read_mtmanager(shared_data / "xsens/formats", rate=100.0)
    assert "MT46_01-000_ (2 files)" in str(err.value)
    two = read_mtmanager(shared_data / "xsens/formats/MT46_01-000_")
    assert two.sensor_ids == ["00B42D4D", "00B42D4E"]
