"""Sensor maps: which sensor id sits on which body segment (SPEC section 3).

A sensor map is YAML::

    sensors:
      00B42279: Pelvis
      00B4227C: RightUpperLeg
    forward:            # optional: the sensor axis that points forward in the N-pose,
      Pelvis: -z        # used only when a recording has too little movement to find it

Every scalar is read as text, so an id such as ``00421234`` is never turned into a number.
Segment names are the 23 MVN names of SPEC section 2. OpenSense's mapping XML (OpenSim body
names, see :mod:`ikfusion.io.opensense_map`) is read as well.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from ..errors import ConfigError
from ..model.joints import SEGMENTS
from ..yaml_files import read_yaml, with_line
from .opensense_map import is_xml_file, read_opensense_mapping
from .recording import check_sensor_ids, normalize_sensor_id

__all__ = ["SensorMap", "check_sensors", "load_sensor_map", "parse_axis"]


class SensorMap(dict[str, str]):
    """Sensor id -> segment, with the optional default mounting of the map.

    Attributes:
        path: The YAML file, when read from one.
        forward: Segment -> the sensor axis pointing forward in the N-pose (``"x"``, ``"-z"``
            ...); the default mounting used when the heading cannot be found from the data.
    """

    def __init__(self, sensors: Mapping[str, str], path: Path | None = None,
                 forward: Mapping[str, str] | None = None) -> None:
        super().__init__(sensors)
        self.path = path
        self.forward: dict[str, str] = dict(forward or {})

    @property
    def segments(self) -> list[str]:
        """The mapped segments."""
        return list(self.values())

    def sensor_of(self, segment: str) -> str | None:
        """The sensor id mapped to a segment, or None."""
        return next((s for s, seg in self.items() if seg == segment), None)


def _text_loader() -> type[yaml.SafeLoader]:
    """A YAML loader that keeps every plain scalar as text (no ints, floats, bools)."""

    class TextLoader(yaml.SafeLoader):
        pass

    TextLoader.yaml_implicit_resolvers = {
        key: [(tag, regex) for tag, regex in resolvers
              if tag in ("tag:yaml.org,2002:null", "tag:yaml.org,2002:merge")]
        for key, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
    }
    return TextLoader


def parse_axis(text: str) -> tuple[int, float]:
    """``"x"``, ``"+y"``, ``"-z"`` -> (axis index, sign).

    Raises:
        ValueError: Anything else.
    """
    t = str(text).strip().lower()
    sign = -1.0 if t.startswith("-") else 1.0
    letter = t.lstrip("+-")
    if letter not in ("x", "y", "z") or len(t) - len(letter) > 1:
        raise ValueError(f"an axis is x, y or z with an optional sign (e.g. -z), not {text!r}")
    return "xyz".index(letter), sign


def sensor_map_from_dict(doc: Any, path: Path | None = None) -> SensorMap:
    """Validate a parsed sensor-map document.

    Raises:
        ConfigError: No ``sensors`` mapping, an unknown segment (naming the key and listing the
            valid names), a segment with two sensors, a bad ``forward`` entry.
    """
    sensors = doc.get("sensors") if isinstance(doc, dict) else None
    if not isinstance(sensors, dict) or not sensors:
        raise ConfigError("expected a mapping `sensors: {<sensor id>: <segment>}`", path=path,
                          field="sensors")
    out: dict[str, str] = {}
    for sensor, segment in sensors.items():
        key = normalize_sensor_id(sensor)
        if not isinstance(segment, str) or segment not in SEGMENTS:
            raise ConfigError(f"unknown segment {segment!r} for sensor {sensor}; valid segments: "
                              f"{', '.join(SEGMENTS)}", path=path, field=f"sensors.{sensor}")
        if key in out:
            raise ConfigError(f"sensor {key} is mapped twice", path=path,
                              field=f"sensors.{sensor}")
        if segment in out.values():
            other = next(s for s, seg in out.items() if seg == segment)
            raise ConfigError(f"segment {segment} has two sensors ({other} and {key})",
                              path=path, field=f"sensors.{sensor}")
        out[key] = segment
    forward = doc.get("forward") or {}
    if not isinstance(forward, dict):
        raise ConfigError("`forward` must map segments to axes, e.g. `forward: {Pelvis: -z}`",
                          path=path, field="forward")
    for segment, axis in forward.items():
        if segment not in out.values():
            raise ConfigError(f"`forward` names {segment!r}, which has no sensor in the map "
                              f"(mapped: {', '.join(out.values())})", path=path,
                              field=f"forward.{segment}")
        try:
            parse_axis(axis)
        except ValueError as err:
            raise ConfigError(str(err), path=path, field=f"forward.{segment}") from None
    unknown = sorted(set(doc) - {"sensors", "forward"})
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(unknown)}; a sensor map has `sensors` and "
                          "optionally `forward`", path=path, field=unknown[0])
    return SensorMap(out, path, {str(k): str(v) for k, v in forward.items()})


def load_sensor_map(path: str | Path) -> SensorMap:
    """Read a sensor map: the YAML of SPEC section 3 or OpenSense's mapping XML.

    Args:
        path: The YAML file (e.g. ``configs/sensors/lower8.yaml``), or an OpenSense XML
            (``myIMUMappings.xml``: ``.xml`` name or text starting with ``<``), whose OpenSim
            bodies become segments by :data:`~ikfusion.io.opensense_map.OPENSIM_BODY_SEGMENTS`.

    Returns:
        The :class:`SensorMap` (a dict sensor id -> segment; no ``forward`` from an XML).

    Raises:
        ConfigError: Unreadable, not YAML/XML, or an invalid map (see
            :func:`sensor_map_from_dict`); the message names the file, the line and the key.
    """
    file = Path(path)
    if is_xml_file(file):
        sensors = read_opensense_mapping(file)
        try:
            return sensor_map_from_dict(
                {"sensors": {sid: segment for sid, (segment, _) in sensors.items()}}, file)
        except ConfigError as err:
            sid = (err.field or "").removeprefix("sensors.")
            raise with_line(err, sensors[sid][1] if sid in sensors else None) from None
    doc = read_yaml(file, "the sensor map", loader=_text_loader())
    return sensor_map_from_dict(doc, file)


def check_sensors(sensor_map: Mapping[str, str], found: Iterable[str],
                  source: str | Path | None = None) -> list[str]:
    """Check that every mapped sensor was recorded.

    Returns:
        Warnings about recorded sensors that the map does not use.

    Raises:
        InputError: Listing the missing ids and the ids found.
    """
    return check_sensor_ids(sensor_map, found, source)
