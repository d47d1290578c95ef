"""Input files of a calibration: reader heights and surveyed reader positions (YAML).

- heights (SPEC section 3): ``heights: {<reader id>: <z in metres>, ...}``;
- survey (for the optional alignment to a user frame): ``points: {<reader id>: [x, y, z], ...}``
  in metres, in the user's world frame (Z up).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..yaml_files import read_yaml
from .constellation import MAX_COORDINATE_M, check_coordinates, finite_number


def load_heights(path: str | Path) -> dict[str, float]:
    """Read a heights file ``heights: {<reader id>: <z in metres>, ...}`` (SPEC section 3).

    Raises:
        ConfigError: Naming the file and the key at fault.
    """
    path = Path(path)
    data = read_yaml(path)
    if not isinstance(data, Mapping) or "heights" not in data:
        raise ConfigError(
            "expected a mapping 'heights: {<reader id>: <z in metres>}'",
            path=path,
            field="heights",
        )
    return heights_from_mapping(data["heights"], source=path)


def heights_from_mapping(value: object, *, source: Path | None = None) -> dict[str, float]:
    """Validate ``{reader id: height [m]}``.

    Raises:
        ConfigError: For a non-mapping, an empty id or a height that is not a finite number of
            at most :data:`~ikfusion.uwb.constellation.MAX_COORDINATE_M` metres.
    """
    if not isinstance(value, Mapping) or not value:
        raise ConfigError(
            "expected a non-empty mapping {<reader id>: <z in metres>}",
            path=source,
            field="heights",
        )
    out: dict[str, float] = {}
    for key, raw in value.items():
        rid = str(key).strip()
        if not rid:
            raise ConfigError("empty reader id", path=source, field="heights")
        z = finite_number(raw)
        if z is None or abs(z) > MAX_COORDINATE_M:
            raise ConfigError(
                f"reader {rid}: expected a height in metres (at most {MAX_COORDINATE_M:g} m), "
                f"found {raw!r}",
                path=source,
                field=f"heights.{rid}",
            )
        out[rid] = z
    return out


def load_survey(path: str | Path) -> dict[str, np.ndarray]:
    """Read surveyed reader positions ``points: {<reader id>: [x, y, z], ...}`` [m].

    Raises:
        ConfigError: Naming the file and the key at fault.
    """
    path = Path(path)
    data = read_yaml(path)
    if not isinstance(data, Mapping) or not isinstance(data.get("points"), Mapping):
        raise ConfigError(
            "expected a mapping 'points: {<reader id>: [x, y, z]}'", path=path, field="points"
        )
    return survey_from_mapping(data["points"], source=path)


def survey_from_mapping(value: object, *, source: Path | None = None) -> dict[str, np.ndarray]:
    """Validate ``{reader id: [x, y, z]}`` [m].

    Raises:
        ConfigError: For a malformed point.
    """
    if not isinstance(value, Mapping):
        raise ConfigError(
            "expected a mapping {<reader id>: [x, y, z]}", path=source, field="points"
        )
    out: dict[str, np.ndarray] = {}
    for key, raw in value.items():
        rid = str(key).strip()
        values = raw.tolist() if isinstance(raw, np.ndarray) else raw
        numbers = [finite_number(v) for v in values] if isinstance(values, list | tuple) else []
        if len(numbers) != 3 or any(v is None for v in numbers):
            raise ConfigError(
                f"expected [x, y, z] in metres, found {raw!r}",
                path=source,
                field=f"points.{rid}",
            )
        out[rid] = np.array(numbers, dtype=float)
        check_coordinates(out[rid], source, f"points.{rid}", f"reader {rid}")
    return out
