"""Sensor maps: which sensor id sits on which body segment (SPEC section 3)."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import yaml

from ..errors import ConfigError, InputError
from ..model.joints import SEGMENTS


def load_sensor_map(path: str | Path) -> dict[str, str]:
    """Read ``sensors: {<sensor id>: <segment>}``.

    Raises:
        ConfigError: Not YAML, no ``sensors`` mapping, an unknown segment or a segment twice.
    """
    file = Path(path)
    try:
        doc = yaml.safe_load(file.read_text())
    except OSError as err:
        raise ConfigError(f"cannot read sensor map: {err.strerror}", path=file) from err
    except yaml.YAMLError as err:
        raise ConfigError(f"not valid YAML: {err}", path=file) from err
    sensors = doc.get("sensors") if isinstance(doc, dict) else None
    if not isinstance(sensors, dict) or not sensors:
        raise ConfigError("expected a mapping `sensors: {<sensor id>: <segment>}`", path=file,
                          field="sensors")
    out: dict[str, str] = {}
    for sensor, segment in sensors.items():
        key = str(sensor).upper()
        if segment not in SEGMENTS:
            raise ConfigError(f"unknown segment {segment!r}; segments: {', '.join(SEGMENTS)}",
                              path=file, field=f"sensors.{sensor}")
        if segment in out.values():
            raise ConfigError(f"segment {segment} has two sensors", path=file,
                              field=f"sensors.{sensor}")
        out[key] = str(segment)
    return out


def check_sensors(sensor_map: dict[str, str], found: Iterable[str],
                  source: str | Path | None = None) -> list[str]:
    """Check that every mapped sensor was recorded.

    Returns:
        Warnings about recorded sensors that the map does not use.

    Raises:
        InputError: Listing the missing ids and the ids found.
    """
    ids = sorted(str(f).upper() for f in found)
    missing = sorted(set(sensor_map) - set(ids))
    if missing:
        raise InputError(f"mapped sensors not in the recording: {', '.join(missing)}; "
                         f"sensors found: {', '.join(ids)}", path=source, field="sensors")
    return [f"sensor {s} is in the recording but not in the sensor map (ignored)"
            for s in ids if s not in sensor_map]
