"""The one YAML reader of user files: encodings, repeated keys, alias bombs, stray values."""

from __future__ import annotations

import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from ikfusion.app.session import load_session
from ikfusion.cli import main
from ikfusion.errors import ConfigError
from ikfusion.ik.settings import SolverSettings
from ikfusion.io import load_sensor_map
from ikfusion.model.body import Body
from ikfusion.uwb import load_constellation, load_heights, load_tags
from ikfusion.yaml_files import read_yaml, read_yaml_document

# One valid file of each kind a user writes, with a non-ASCII character in a comment on line 2
# (a name, as people write them), and what its loader returns.
KINDS: dict[str, tuple[Callable[[Path], Any], str]] = {
    "sensor map": (load_sensor_map, "sensors:\n  # capteur de la hanche, José\n"
                                    "  00B42279: Pelvis\n"),
    "body": (Body.from_yaml, "height: 1.75\n# mesuré par José\nupper_leg: 0.43\n"),
    "readers": (load_constellation, "readers:\n  # près de la porte, José\n"
                                    "  - {id: R1, position: [0, 0, 2]}\n"
                                    "  - {id: R2, position: [5, 0, 2]}\n"
                                    "  - {id: R3, position: [0, 5, 2]}\n"),
    "tags": (load_tags, "tags:\n  # casque de José\n  T1: {actor: jose, site: HeadTop}\n"),
    "heights": (load_heights, "heights:\n  # mesuré par José\n  R1: 2.0\n"),
}


def _write(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("encoding", ["utf-8", "utf-8-sig", "utf-16", "utf-16-le-bom",
                                      "utf-16-be-bom"])
def test_windows_unicode_files_read_like_utf8(tmp_path: Path, kind: str, encoding: str) -> None:
    load, text = KINDS[kind]
    (tmp_path / "utf8").mkdir()
    (tmp_path / "other").mkdir()
    plain = _write(tmp_path / "utf8/file.yaml", text.encode("utf-8"))
    if encoding.endswith("-bom"):  # explicit byte order after its mark
        codec = encoding.removesuffix("-bom")
        bom = b"\xff\xfe" if codec.endswith("le") else b"\xfe\xff"
        data = bom + text.encode(codec)
    else:
        data = text.encode(encoding)
    other = _write(tmp_path / "other/file.yaml", data)
    assert repr(load(other)).replace("/other/", "/utf8/") == repr(load(plain))


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_latin1_byte_is_a_config_error_with_line_and_byte(tmp_path: Path, kind: str) -> None:
    load, text = KINDS[kind]
    path = _write(tmp_path / "latin1.yaml", text.encode("latin-1"))
    offset = next(i for i, c in enumerate(text) if ord(c) > 127)  # one byte per character
    column = offset - text.index("\n")
    with pytest.raises(ConfigError) as err:
        load(path)
    assert err.value.path == path and err.value.line == 2
    assert f"column {column}" in str(err.value) and f"byte offset {offset}" in str(err.value)
    assert f"{ord(text[offset]):02X}" in str(err.value) and "UTF-8" in str(err.value)


def test_utf16_without_mark_names_the_line(tmp_path: Path) -> None:
    path = _write(tmp_path / "map.yaml", "sensors:\n  00B42279: Pelvis\n".encode("utf-16-le"))
    with pytest.raises(ConfigError) as err:
        load_sensor_map(path)
    assert err.value.line == 1 and "U+0000" in str(err.value)


def _one_sensor_export(folder: Path) -> Path:
    export = folder / "T_00B40001.txt"
    export.write_text("// Update Rate: 60.0Hz\nPacketCounter\tQuat_q0\tQuat_q1\tQuat_q2\tQuat_q3\n"
                      "1\t1\t0\t0\t0\n")
    return export


def test_cli_exit_2_for_a_latin1_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    export = _one_sensor_export(tmp_path)
    text = "sensors:\n  00B40001: Pelvis  # hanche\xe9\n"
    bad = _write(tmp_path / "map.yaml", text.encode("latin-1"))
    assert main(["solve", "--imu", str(export), "--map", str(bad), "--out",
                 str(tmp_path / "r"), "--quiet"]) == 2
    message = capsys.readouterr().err
    offset = text.index("\xe9")
    assert "map.yaml, line 2" in message and f"byte offset {offset}" in message
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize(
    ("load", "text", "line", "field"),
    [
        (Body.from_yaml, "height: 1.75\nupper_leg: 0.43\nheight: 1.60\n", 3, "height"),
        (load_tags, "tags:\n  T1: {actor: ann, site: HeadTop}\n"
                    "  T1: {actor: bob, site: LeftFootTop}\n", 3, "tags.T1"),
        (load_sensor_map, "sensors:\n  00B42279: Pelvis\n  00B42279: T8\n", 3,
         "sensors.00B42279"),
        (load_heights, "heights:\n  R1: 2.0\n  R2: 2.1\n  R1: 2.5\n", 4, "heights.R1"),
        (load_constellation, "readers:\n  - {id: R1, position: [0, 0, 2], position: [1, 0, 2]}\n"
                             "  - {id: R2, position: [5, 0, 2]}\n", 2, "readers.0.position"),
        (SolverSettings.load, "weights:\n  posture: 1.0\nweights:\n  posture: 2.0\n", 3,
         "weights"),
    ],
)
def test_repeated_key_is_refused(tmp_path: Path, load: Callable[[Path], Any], text: str,
                                 line: int, field: str) -> None:
    path = tmp_path / "file.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load(path)
    assert (err.value.path, err.value.line, err.value.field) == (path, line, field)
    assert "twice" in str(err.value)


def test_repeated_height_in_a_body_no_longer_takes_the_last(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    body = tmp_path / "body.yaml"
    body.write_text("height: 1.80\nmass: 70\nheight: 1.50\n")
    smap = tmp_path / "map.yaml"
    smap.write_text("sensors:\n  00B40001: Pelvis\n")
    assert main(["solve", "--imu", str(_one_sensor_export(tmp_path)), "--map", str(smap),
                 "--body", str(body), "--out", str(tmp_path / "r"), "--quiet"]) == 2
    assert "body.yaml, line 3, field 'height'" in capsys.readouterr().err


def _alias_bomb(levels: int) -> str:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, levels)]
    return "\n".join(lines) + f"\nsensors: {{00B42279: *a{levels - 1}}}\n"


def test_billion_laughs_is_refused_before_building_anything(tmp_path: Path) -> None:
    path = tmp_path / "bomb.yaml"
    path.write_text(_alias_bomb(9))  # 10^9 values from 10 lines
    with pytest.raises(ConfigError) as err:
        read_yaml(path)
    assert "alias" in str(err.value) and err.value.path == path
    # As a sensor map: the old reader spent its memory writing the values into the message.
    path.write_text(_alias_bomb(7))
    tracemalloc.start()
    try:
        with pytest.raises(ConfigError) as err:
            load_sensor_map(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert "alias" in str(err.value)
    assert peak < 5e6, f"{peak / 1e6:.0f} MB to refuse a 10-line file"


def test_recursive_alias_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "loop.yaml"
    path.write_text("sensors: &s\n  00B42279: Pelvis\n  more: *s\n")
    with pytest.raises(ConfigError) as err:
        read_yaml(path)
    assert err.value.line == 3 and "recursive" in str(err.value)


def test_modest_alias_reuse_still_reads(tmp_path: Path) -> None:
    block = "{" + ", ".join(f"k{i}: {i}" for i in range(100)) + "}"
    path = tmp_path / "reuse.yaml"
    path.write_text(f"base: &b {block}\nitems:\n" + "  - *b\n" * 400
                    + "override: {<<: *b, k0: -1}\n")
    data = read_yaml(path)
    assert len(data["items"]) == 400 and data["items"][-1]["k99"] == 99
    assert data["override"]["k0"] == -1 and data["override"]["k1"] == 1


def test_key_lines_are_recorded(tmp_path: Path) -> None:
    path = tmp_path / "r.yaml"
    path.write_text("# header\nreaders:\n  - id: R1\n    position: [0, 0, 2]\n")
    doc = read_yaml_document(path)
    assert doc.line_of("readers") == 2 and doc.line_of("readers", 0) == 3
    assert doc.line_of("readers", 0, "position") == 4 and doc.line_of("absent") is None


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("height: 1" + "0" * 5000 + "\n", "height"),  # more digits than Python converts
        ("height: 1.75\nmass: 2001-13-45\n", "mass"),  # not a date
    ],
)
def test_values_python_cannot_hold_are_config_errors(tmp_path: Path, text: str,
                                                     field: str) -> None:
    path = tmp_path / "body.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        Body.from_yaml(path)
    assert err.value.field == field and err.value.line == text.count("\n")


def test_nesting_too_deep_is_a_config_error(tmp_path: Path) -> None:
    path = tmp_path / "deep.yaml"
    path.write_text("a: " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(ConfigError, match="nested too deeply"):
        read_yaml(path)


def test_session_file_goes_through_the_reader(tmp_path: Path) -> None:
    path = tmp_path / "session.yaml"
    path.write_bytes("actors:\n  josé: {imu: x}\n".encode("latin-1"))
    with pytest.raises(ConfigError) as err:
        load_session(path)
    assert err.value.line == 2


def test_a_file_read_again_is_a_fresh_copy_and_a_changed_file_is_parsed_again(
        tmp_path: Path) -> None:
    path = tmp_path / "config.yaml"
    path.write_text("weights: {a: 1.0}\n", encoding="utf-8")
    first = read_yaml(path)
    first["weights"]["a"] = 99.0  # a caller changing what it got
    assert read_yaml(path) == {"weights": {"a": 1.0}}
    path.write_text("weights: {a: 2.0, b: 3.0}\n", encoding="utf-8")
    assert read_yaml(path) == {"weights": {"a": 2.0, "b": 3.0}}
    assert read_yaml_document(path).line_of("weights", "b") == 1
