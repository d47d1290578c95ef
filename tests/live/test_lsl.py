"""Lab Streaming Layer out (one outlet per actor) and in (inlets mapped by a YAML file)."""

from __future__ import annotations

import time
import uuid
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from ikfusion.errors import ConfigError, InputError
from ikfusion.live.lsl_source import LslSource, load_lsl_map

pylsl = pytest.importorskip("pylsl", reason="the live extra (pylsl with liblsl) is not installed")

from ikfusion.live.lsl_outlet import LslOutletSink  # noqa: E402


def pull(inlet, n: int) -> tuple[list, list]:
    rows: list = []
    while len(rows) < n:
        sample, stamp = inlet.pull_sample(timeout=5.0)
        assert sample is not None, f"only {len(rows)} of {n} samples arrived"
        rows.append(sample)
    return rows, []


def test_outlet_streams_every_actor_with_labelled_channels(result_poses) -> None:
    prefix = f"ikf-test-{uuid.uuid4().hex[:8]}"
    sink = LslOutletSink(rate_hz=30.0, name_prefix=prefix)
    sink.send([result_poses[0]])  # creates the outlet
    (info,) = pylsl.resolve_byprop("name", f"{prefix} A", timeout=5.0)
    inlet = pylsl.StreamInlet(info)
    inlet.open_stream(timeout=5.0)
    full = inlet.info(timeout=5.0)
    assert full.nominal_srate() == 30.0 and full.type() == "MoCap"
    root = ET.fromstring(full.as_xml())
    channels = root.find("desc/channels")
    labels = [c.findtext("label") for c in channels]
    units = {c.findtext("label"): c.findtext("unit") for c in channels}
    pose = result_poses[0]
    assert len(labels) == full.channel_count() == 1 + 7 * len(pose.segments) + len(pose.joint_names)
    assert units["Pelvis_px"] == "meters" and units["jRightKnee_flex"] == "degrees"
    assert [s.findtext("parent") for s in root.find("desc/skeleton")][:2] == ["", "Pelvis"]
    time.sleep(0.2)
    for p in result_poses[1:]:
        sink.send([p])
    rows, _ = pull(inlet, len(result_poses) - 1)
    column = {label: k for k, label in enumerate(labels)}
    for p, row in zip(result_poses[1:], rows):
        assert abs(row[column["time"]] - p.time_s) < 1e-9
        for i, name in enumerate(p.segments):
            xyz = [row[column[f"{name}_p{a}"]] for a in "xyz"]
            np.testing.assert_allclose(xyz, p.p_world_segment[i], atol=1e-4)
            w, x, y, z = (row[column[f"{name}_q{a}"]] for a in "wxyz")
            R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                          [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                          [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
            np.testing.assert_allclose(R, p.R_world_segment[i], atol=1e-4)
        np.testing.assert_allclose([row[column[n]] for n in p.joint_names], p.joint_angles_deg,
                                   atol=1e-4)
    inlet.close_stream()
    sink.close()


def write_map(tmp_path: Path, name: str) -> Path:
    path = tmp_path / "lsl.yaml"
    path.write_text(f"""streams:
  - name: {name}
    timeout: 5
    sensors:
      00421234:
        quat: [0, 1, 2, 3]
        gyr: [4, 5, 6]
        counter: 10
      LeftFoot:
        quat: [7, 8, 9, 0]
""")
    return path


def test_inlet_samples_become_sensor_samples(tmp_path: Path) -> None:
    name = f"ikf-imu-{uuid.uuid4().hex[:8]}"
    outlet = pylsl.StreamOutlet(pylsl.StreamInfo(name, "IMU", 11, 100.0, "double64", name))
    source = LslSource(write_map(tmp_path, name), idle_timeout_s=3.0)
    time.sleep(0.2)
    sent = []
    for k in range(20):
        row = [float(k + c) for c in range(11)]
        row[10] = float(65534 + k)
        outlet.push_sample(row, 1000.0 + 0.01 * k)
        sent.append(row)
    got = []
    for s in source.samples():
        got.append(s)
        if len(got) == 40:
            break
    source.close()
    ids = [s for s in got if s.sensor == "00421234"]  # the id keeps its leading zeros
    feet = [s for s in got if s.sensor == "LeftFoot"]
    assert len(ids) == len(feet) == 20
    for k, (a, b) in enumerate(zip(ids, feet)):
        np.testing.assert_allclose(a.q_world_sensor, sent[k][0:4])
        np.testing.assert_allclose(a.gyr, sent[k][4:7])
        assert a.acc is None and a.counter == (65534 + k) & 0xFFFF
        np.testing.assert_allclose(b.q_world_sensor, [sent[k][7], sent[k][8], sent[k][9],
                                                      sent[k][0]])
        assert a.time_s == b.time_s
    np.testing.assert_allclose([s.time_s for s in ids], 0.01 * np.arange(20), atol=1e-6)


def test_missing_stream_names_file_and_field(tmp_path: Path) -> None:
    path = write_map(tmp_path, f"absent-{uuid.uuid4().hex[:8]}")
    path.write_text(path.read_text().replace("timeout: 5", "timeout: 0.5"))
    with pytest.raises(InputError) as err:
        LslSource(path)
    assert str(path) in str(err.value) and "streams[0]" in str(err.value)
    assert err.value.line == 2


@pytest.mark.parametrize(("text", "field", "line"), [
    ("streams: []\n", "streams", 1),
    ("streams:\n  - sensors: {S1: {quat: [0, 1, 2, 3]}}\n", "streams[0]", 2),
    ("streams:\n  - name: X\n    sensors:\n      S1: {quat: [0, 1, 2]}\n",
     "streams[0].sensors.S1.quat", 4),
    ("streams:\n  - name: X\n    sensors:\n      S1:\n        quat: [0, 1, 2, -1]\n",
     "streams[0].sensors.S1.quat", 5),
    ("streams:\n  - name: X\n    sensors:\n      S1: {quat: [0, 1, 2, 3], mag: [4, 5, 6]}\n",
     "streams[0].sensors.S1", 4),
])
def test_bad_map_names_file_line_and_field(tmp_path: Path, text: str, field: str,
                                           line: int) -> None:
    path = tmp_path / "lsl.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_lsl_map(path)
    assert err.value.field == field and err.value.path == path and err.value.line == line


def test_missing_pylsl_is_a_clear_error(monkeypatch) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "pylsl", None)  # import pylsl now raises ImportError
    with pytest.raises(InputError, match="pylsl") as err:
        LslOutletSink(rate_hz=60.0)
    assert err.value.field == "--lsl-out"
