"""Sensor maps: the shipped maps, validation, ids kept as text, the default mounting."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from ikfusion.cli import main
from ikfusion.errors import ConfigError
from ikfusion.io import SensorMap, load_sensor_map, read_mtmanager
from ikfusion.io.opensense_map import OPENSIM_BODY_SEGMENTS
from ikfusion.model import SEGMENTS
from ikfusion.paths import configs_dir

AWINDA16 = dict(zip(
    ["00B458EE", "00B458F1", "00B458F8", "00B458F4", "00B457D7", "00B458EB", "00B458EF",
     "00B458EA", "00B458F3", "00B458F0", "00B458EC", "00B458F6", "00B457DC", "00B457D9",
     "00B458F5", "00B458ED"],
    ["Pelvis", "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "RightUpperLeg", "RightLowerLeg",
     "RightFoot", "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand", "RightShoulder",
     "RightUpperArm", "RightForeArm", "RightHand", "Head"]))
MVN17 = {"Pelvis", "T8", "Head", "RightShoulder", "RightUpperArm", "RightForeArm", "RightHand",
         "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand", "RightUpperLeg",
         "RightLowerLeg", "RightFoot", "LeftUpperLeg", "LeftLowerLeg", "LeftFoot"}
OPENSIM_TO_MVN = {"pelvis": "Pelvis", "torso": "T8", "femur_r": "RightUpperLeg",
                  "tibia_r": "RightLowerLeg", "calcn_r": "RightFoot", "femur_l": "LeftUpperLeg",
                  "tibia_l": "LeftLowerLeg", "calcn_l": "LeftFoot"}


def test_shipped_maps() -> None:
    folder = configs_dir() / "sensors"
    mvn17 = load_sensor_map(folder / "mvn17.yaml")
    assert set(mvn17.values()) == MVN17 and len(mvn17) == 17
    assert all(s.startswith("00B4") and len(s) == 8 for s in mvn17)
    assert "placeholder" in (folder / "mvn17.yaml").read_text().lower()
    assert dict(load_sensor_map(folder / "awinda16.yaml")) == AWINDA16
    lower8 = load_sensor_map(folder / "lower8.yaml")
    assert set(lower8.values()) == set(OPENSIM_TO_MVN.values())
    for smap in (mvn17, lower8):
        assert set(smap.values()) <= set(SEGMENTS)
        assert set(smap.forward) <= set(smap.values())


def test_lower8_matches_the_opensense_trial(shared_data: Path) -> None:
    folder = shared_data / "xsens/opensense_walk"
    root = ET.parse(folder / "myIMUMappings.xml").getroot()
    expected = {}
    for element in root.iter():
        name, body = element.findtext("name_in_model"), element.get("name")
        if name and body and body.startswith("MT_"):
            expected[body[-8:].upper()] = OPENSIM_TO_MVN[name.replace("_imu", "")]
    if not expected:  # the mapping file's layout: <ExperimentalSensor name="_00B42268">
        for element in root.iter("ExperimentalSensor"):
            sid = element.get("name", "").lstrip("_").upper()
            expected[sid] = OPENSIM_TO_MVN[element.findtext("name_in_model").replace("_imu", "")]
    lower8 = load_sensor_map(configs_dir() / "sensors/lower8.yaml")
    assert dict(lower8) == expected
    rec = read_mtmanager(folder, sensor_map=lower8)
    assert not any("not in the sensor map" in w for w in rec.warnings)


@pytest.mark.parametrize(
    ("text", "field", "words"),
    [
        ("sensors:\n  00B40001: Pelvis\n  00B40002: Knee\n", "sensors.00B40002",
         "unknown segment 'Knee' for sensor 00B40002; valid segments: Pelvis, L5"),
        ("sensors:\n  00B40001: Pelvis\n  00B40002: Pelvis\n", "sensors.00B40002",
         "segment Pelvis has two sensors (00B40001 and 00B40002)"),
        ("sensors: []\n", "sensors", "expected a mapping"),
        ("sensor:\n  00B40001: Pelvis\n", "sensors", "expected a mapping"),
        ("sensors:\n  00B40001: Pelvis\nforward:\n  Head: z\n", "forward.Head", "no sensor"),
        ("sensors:\n  00B40001: Pelvis\nforward:\n  Pelvis: w\n", "forward.Pelvis",
         "x, y or z"),
        ("sensors:\n  00B40001: Pelvis\nextra: 1\n", "extra", "unknown key"),
    ],
)
def test_bad_maps_name_file_and_key(tmp_path: Path, text: str, field: str, words: str) -> None:
    path = tmp_path / "map.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_sensor_map(path)
    assert err.value.path == path and err.value.field == field
    assert words in str(err.value)


def test_ids_that_look_like_numbers_stay_text(tmp_path: Path) -> None:
    path = tmp_path / "map.yaml"
    path.write_text("sensors:\n  00421234: Pelvis\n  1E400000: Head\n  00b4abcd: T8\n"
                    "forward:\n  Pelvis: -z\n")
    smap = load_sensor_map(path)
    assert isinstance(smap, SensorMap) and smap.path == path
    assert list(smap) == ["00421234", "1E400000", "00B4ABCD"]
    assert smap.forward == {"Pelvis": "-z"} and smap.sensor_of("T8") == "00B4ABCD"


def test_not_yaml(tmp_path: Path) -> None:
    path = tmp_path / "map.yaml"
    path.write_text("sensors: {00B40001: Pelvis\n")
    with pytest.raises(ConfigError, match="not valid YAML") as err:
        load_sensor_map(path)
    assert err.value.path == path


def test_opensim_body_table_names_our_segments() -> None:
    assert set(OPENSIM_BODY_SEGMENTS.values()) <= set(SEGMENTS)
    for body, segment in OPENSIM_TO_MVN.items():
        assert OPENSIM_BODY_SEGMENTS[body] == segment
    sides = {"_r": "Right", "_l": "Left"}
    for body, segment in OPENSIM_BODY_SEGMENTS.items():
        if body[-2:] in sides:
            assert segment.startswith(sides[body[-2:]])
            assert OPENSIM_BODY_SEGMENTS[body[:-1] + ("l" if body[-1] == "r" else "r")] == \
                segment.replace(sides[body[-2:]], sides["_l" if body[-1] == "r" else "_r"])


def test_opensense_xml_map_solves_like_lower8(shared_data: Path, tmp_path: Path) -> None:
    folder = shared_data / "xsens/opensense_walk"
    xml = folder / "myIMUMappings.xml"
    lower8 = configs_dir() / "sensors/lower8.yaml"
    smap = load_sensor_map(xml)
    assert dict(smap) == dict(load_sensor_map(lower8)) and smap.path == xml
    for name, map_file in (("xml", xml), ("yaml", lower8)):
        assert main(["solve", "--imu", str(folder), "--map", str(map_file), "--out",
                     str(tmp_path / name), "--quiet"]) == 0
    for result in ("joint_angles.csv", "segments.csv", "contacts.csv"):
        assert (tmp_path / "xml" / result).read_bytes() == (tmp_path / "yaml" / result).read_bytes()


def _opensense(entries: str) -> str:
    return ('<?xml version="1.0" encoding="UTF-8" ?>\n<OpenSimDocument Version="40000">\n'
            "<XsensDataReaderSettings>\n<ExperimentalSensors>\n" + entries
            + "</ExperimentalSensors>\n</XsensDataReaderSettings>\n</OpenSimDocument>\n")


def _sensor(sid: str, frame: str) -> str:
    return (f'<ExperimentalSensor name="_{sid}">\n'
            f"  <name_in_model>{frame}</name_in_model>\n</ExperimentalSensor>\n")


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        (_opensense(_sensor("00B40001", "pelvis_imu") + _sensor("00B40002", "spine_imu")), 8,
         "unknown OpenSim body 'spine' for sensor 00B40002"),
        (_opensense(_sensor("00B40001", "pelvis_imu") + _sensor("00B40002", "pelvis")), 8,
         "segment Pelvis has two sensors (00B40001 and 00B40002)"),
        (_opensense(_sensor("00B40001", "pelvis_imu") + _sensor("00B40001", "torso_imu")), 8,
         "sensor 00B40001 is listed twice (lines 5 and 8)"),
        (_opensense('<ExperimentalSensor name="_00B40001">\n</ExperimentalSensor>\n'), 5,
         "no <name_in_model>"),
        (_opensense(_sensor("00B40001", "pelvis_imu")).replace("</ExperimentalSensors>", ""), 9,
         "not valid XML: mismatched tag"),
        ('<?xml version="1.0"?>\n<!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 '
         '"&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">]>\n'
         + _opensense(_sensor("00B40001", "pelvis_imu")).split("\n", 1)[1], 2, "DOCTYPE"),
        (_opensense(""), None, "no <ExperimentalSensor"),
    ],
)
def test_bad_opensense_xml_names_file_and_line(tmp_path: Path, text: str, line: int | None,
                                               words: str) -> None:
    path = tmp_path / "myIMUMappings.xml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_sensor_map(path)
    assert err.value.path == path and err.value.line == line
    assert words in str(err.value)


def test_xml_map_under_any_name_and_bad_xml_exits_2(tmp_path: Path, capsys) -> None:
    path = tmp_path / "map.yaml"  # XML content, whatever the name says
    path.write_text(_opensense(_sensor("00B40001", "pelvis_imu") + _sensor("00B40002", "head")
                               + _sensor("00B40003", "radius_l_imu")))
    assert dict(load_sensor_map(path)) == {"00B40001": "Pelvis", "00B40002": "Head",
                                           "00B40003": "LeftForeArm"}
    path.write_text(_opensense(_sensor("00B40001", "pelvis_imu <")))
    export = tmp_path / "T_00B40001.txt"
    export.write_text("// Update Rate: 60.0Hz\nPacketCounter\tQuat_q0\tQuat_q1\tQuat_q2\tQuat_q3\n"
                      "1\t1\t0\t0\t0\n")
    assert main(["solve", "--imu", str(export), "--map", str(path), "--out",
                 str(tmp_path / "r"), "--quiet"]) == 2
    assert "map.yaml, line 6: not valid XML" in capsys.readouterr().err


def test_opensense_xml_with_an_unknown_encoding_is_bad_input(tmp_path: Path) -> None:
    from ikfusion.errors import ConfigError
    from ikfusion.io.sensor_map import load_sensor_map

    xml = tmp_path / "map.xml"
    xml.write_text('<?xml version="1.0" encoding="UTF-1e30"?>\n<OpenSimDocument/>\n')
    with pytest.raises(ConfigError, match="map.xml"):
        load_sensor_map(xml)


def test_a_map_naming_sensors_not_recorded_names_the_map(tmp_path: Path, capsys) -> None:
    """Found by the fuzz campaign: the message named only the recording, not the map at fault."""
    export = tmp_path / "T_00B40001.txt"
    export.write_text("// Update Rate: 60.0Hz\nPacketCounter\tQuat_q0\tQuat_q1\tQuat_q2\tQuat_q3\n"
                      "1\t1\t0\t0\t0\n2\t1\t0\t0\t0\n")
    sensor_map = tmp_path / "map.yaml"
    sensor_map.write_text("sensors:\n  00B40001: Pelvis\n  00B4XX09: Head\n")
    assert main(["inspect", str(export), "--map", str(sensor_map)]) == 2
    err = capsys.readouterr().err
    assert str(sensor_map) in err and "00B4XX09" in err
