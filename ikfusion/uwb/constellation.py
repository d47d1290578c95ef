"""Reader constellations: where the UWB readers are, their clock offsets, coverage and area.

A constellation file (SPEC section 3) is YAML::

    readers:
      - {id: R1, position: [0.0, 0.0, 2.5], clock_offset: 0.0}
      - {id: R2, position: [6.0, 0.0, 0.4], clock_offset: 0.0,
         position_covariance: [[1e-4, 0, 0], [0, 1e-4, 0], [0, 0, 4e-4]]}
    range: 30.0          # optional coverage radius [m]; readers farther away hear nothing
    sigma: 0.03          # optional range noise (1 sigma) [m]
    area: [[0, 0], [6, 0], [6, 8], [0, 8]]   # optional capture-area polygon (x, y) [m]

Positions are ``p_world_reader`` in the world frame (Z up) in metres (at most
:data:`MAX_COORDINATE_M` from the origin per axis); clock offsets are in metres of
light travel (c times the reader clock's offset on the common timeline). ``position_covariance``
(3x3, [m^2]) is the optional uncertainty of a surveyed or calibrated reader position. The keys
``name``, ``description`` and ``metadata`` are accepted and kept; any other key is an error, so a
typo (``postion``) never goes unnoticed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml

from ..atomic import atomic_write_text
from ..errors import ConfigError
from ..yaml_files import read_yaml

#: Range noise used when a file does not give ``sigma`` [m].
DEFAULT_RANGE_SIGMA = 0.03
#: Largest reader (and area) coordinate accepted [m]: no capture hall is a kilometre across,
#: so a larger value is a typo or a unit mix-up (millimetres, a survey's national grid).
MAX_COORDINATE_M = 1000.0
#: Largest clock offset accepted [m of light travel] (about an hour): beyond it a float64
#: TOA no longer resolves a tenth of a millimetre, so such an offset is a unit mix-up.
MAX_CLOCK_OFFSET_M = 1.0e12

_TOP_KEYS = ("readers", "range", "sigma", "area", "name", "description", "metadata")
_READER_KEYS = ("id", "position", "clock_offset", "position_covariance")


@dataclass(frozen=True)
class Reader:
    """One UWB reader (anchor).

    Attributes:
        id: Reader id as written in TOA logs.
        p_world_reader: Antenna position in the world frame, shape (3,) [m].
        clock_offset: Offset of the reader clock on the common timeline, in metres of light
            travel [m]; it adds to every time of arrival the reader reports.
        position_covariance: Uncertainty of ``p_world_reader``, shape (3, 3) [m^2], or None.
    """

    id: str
    p_world_reader: np.ndarray
    clock_offset: float = 0.0
    position_covariance: np.ndarray | None = None


@dataclass(frozen=True)
class Constellation:
    """A set of readers sharing one clock, with optional coverage radius, noise and area.

    Attributes:
        readers: The readers, in file order (this order indexes every per-reader array).
        range: Coverage radius [m]: a tag farther than this from a reader is not heard by it.
            None means unlimited.
        sigma: Range noise, one standard deviation [m].
        area: Capture-area polygon, shape (K, 2) [m] in the world x-y plane, or None.
        name: Free-form name (from the file's ``name`` or its file stem).
        source: File the constellation was read from, when there is one.
        metadata: The file's free ``metadata`` mapping, kept for round trips.
    """

    readers: tuple[Reader, ...]
    range: float | None = None
    sigma: float = DEFAULT_RANGE_SIGMA
    area: np.ndarray | None = None
    name: str = ""
    source: Path | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)

    @property
    def ids(self) -> tuple[str, ...]:
        """Reader ids in order."""
        return tuple(r.id for r in self.readers)

    @property
    def positions(self) -> np.ndarray:
        """Reader positions ``p_world_reader`` stacked, shape (M, 3) [m]."""
        if not self.readers:
            return np.zeros((0, 3))
        return np.stack([r.p_world_reader for r in self.readers])

    @property
    def clock_offsets(self) -> np.ndarray:
        """Reader clock offsets, shape (M,) [m]."""
        return np.array([r.clock_offset for r in self.readers], dtype=float)

    @property
    def position_covariances(self) -> np.ndarray | None:
        """Reader position covariances, shape (M, 3, 3) [m^2] (zeros where a reader has none).

        None when no reader carries a covariance.
        """
        if all(r.position_covariance is None for r in self.readers):
            return None
        return np.stack(
            [
                np.zeros((3, 3)) if r.position_covariance is None else r.position_covariance
                for r in self.readers
            ]
        )

    def index(self, reader_id: str) -> int:
        """Position of a reader in :attr:`readers`.

        Raises:
            ConfigError: When no reader has this id (the message lists the valid ids).
        """
        for i, r in enumerate(self.readers):
            if r.id == reader_id:
                return i
        raise ConfigError(
            f"no reader with id {reader_id!r}; readers are {', '.join(self.ids)}",
            path=self.source,
            field="readers",
        )

    def with_readers(self, readers: Sequence[Reader], name: str | None = None) -> Constellation:
        """A copy with other readers (same range, sigma and area)."""
        return Constellation(
            readers=tuple(readers),
            range=self.range,
            sigma=self.sigma,
            area=self.area,
            name=self.name if name is None else name,
            source=None,
            metadata=dict(self.metadata),
        )

    def to_dict(self) -> dict[str, Any]:
        """The YAML mapping of this constellation (plain Python types)."""
        out: dict[str, Any] = {}
        if self.name:
            out["name"] = self.name
        readers = []
        for r in self.readers:
            entry: dict[str, Any] = {
                "id": r.id,
                "position": [round(float(v), 6) for v in r.p_world_reader],
                "clock_offset": float(r.clock_offset),
            }
            if r.position_covariance is not None:
                entry["position_covariance"] = [
                    [float(v) for v in row] for row in r.position_covariance
                ]
            readers.append(entry)
        out["readers"] = readers
        if self.range is not None:
            out["range"] = float(self.range)
        out["sigma"] = float(self.sigma)
        if self.area is not None:
            out["area"] = [[round(float(x), 6), round(float(y), 6)] for x, y in self.area]
        if self.metadata:
            out["metadata"] = dict(self.metadata)
        return out


def make_constellation(
    p_world_readers: npt.ArrayLike,
    *,
    ids: Sequence[str] | None = None,
    clock_offsets: npt.ArrayLike | None = None,
    coverage: float | None = None,
    sigma: float = DEFAULT_RANGE_SIGMA,
    area: npt.ArrayLike | None = None,
    name: str = "",
) -> Constellation:
    """Build a constellation from arrays (ids default to ``R1``, ``R2``, ...).

    Args:
        p_world_readers: Reader positions, shape (M, 3) [m].
        ids: Reader ids, M of them.
        clock_offsets: Clock offsets, shape (M,) [m]; zeros by default.
        coverage: Coverage radius (the file's ``range``) [m] or None.
        sigma: Range noise [m].
        area: Capture-area polygon, shape (K, 2) [m], or None.
        name: Free-form name.

    Raises:
        ConfigError: On wrong shapes or values.
    """
    p = np.asarray(p_world_readers, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ConfigError(f"reader positions must have shape (M, 3), got {p.shape}")
    m = p.shape[0]
    names = [f"R{i + 1}" for i in range(m)] if ids is None else [str(i) for i in ids]
    offsets = np.zeros(m) if clock_offsets is None else np.asarray(clock_offsets, dtype=float)
    if len(names) != m or offsets.shape != (m,):
        raise ConfigError(f"{m} reader positions need {m} ids and {m} clock offsets")
    data: dict[str, Any] = {
        "readers": [
            {"id": n, "position": list(map(float, pos)), "clock_offset": float(o)}
            for n, pos, o in zip(names, p, offsets)
        ],
        "sigma": sigma,
    }
    if coverage is not None:
        data["range"] = coverage
    if area is not None:
        data["area"] = np.asarray(area, dtype=float).tolist()
    if name:
        data["name"] = name
    return constellation_from_dict(data)


def load_constellation(path: str | Path, *, allow_empty: bool = False) -> Constellation:
    """Read and validate a constellation YAML file.

    Args:
        path: The YAML file.
        allow_empty: Accept a file without readers (a planning area for ``plan --optimize``).

    Raises:
        ConfigError: Naming the file and the key at fault.
    """
    path = Path(path)
    data = read_yaml(path, "constellation file")
    return constellation_from_dict(data, source=path, allow_empty=allow_empty)


def save_constellation(constellation: Constellation, path: str | Path) -> Path:
    """Write a constellation as YAML (atomically: temporary file, then rename).

    Returns:
        The path written.
    """
    text = yaml.safe_dump(constellation.to_dict(), sort_keys=False, default_flow_style=None)
    return atomic_write_text(Path(path), text)


def constellation_from_dict(
    data: object, *, source: Path | None = None, allow_empty: bool = False
) -> Constellation:
    """Validate a parsed constellation mapping (see the module docstring for the keys).

    Args:
        data: The parsed YAML document.
        source: File it came from (named in errors).
        allow_empty: Accept no readers (planning areas).

    Raises:
        ConfigError: Naming the file and the key at fault.
    """
    if not isinstance(data, Mapping):
        raise ConfigError(
            f"expected a mapping with a 'readers' list, found {type(data).__name__}", path=source
        )
    for key in data:
        if key not in _TOP_KEYS:
            raise ConfigError(
                f"unknown key; valid keys are {', '.join(_TOP_KEYS)}", path=source, field=str(key)
            )
    raw_readers = data.get("readers", [])
    if raw_readers is None:
        raw_readers = []
    if not isinstance(raw_readers, list):
        raise ConfigError("expected a list of readers", path=source, field="readers")
    if not raw_readers and not allow_empty:
        raise ConfigError("a constellation needs at least one reader", path=source, field="readers")
    readers = [_parse_reader(entry, i, source) for i, entry in enumerate(raw_readers)]
    seen: set[str] = set()
    for i, r in enumerate(readers):
        if r.id in seen:
            raise ConfigError(
                f"duplicate reader id {r.id!r}", path=source, field=f"readers[{i}].id"
            )
        seen.add(r.id)
    coverage = data.get("range")
    if coverage is not None:
        coverage = _positive(coverage, "range", source)
    sigma = _positive(data.get("sigma", DEFAULT_RANGE_SIGMA), "sigma", source)
    area = None if data.get("area") is None else _parse_area(data["area"], source)
    name = data.get("name")
    if name is None:
        name = source.stem if source is not None else ""
    metadata = data.get("metadata") or {}
    if not isinstance(metadata, Mapping):
        raise ConfigError("expected a mapping", path=source, field="metadata")
    return Constellation(
        readers=tuple(readers),
        range=coverage,
        sigma=sigma,
        area=area,
        name=str(name),
        source=source,
        metadata=dict(metadata),
    )


def _parse_reader(entry: object, i: int, source: Path | None) -> Reader:
    where = f"readers[{i}]"
    if not isinstance(entry, Mapping):
        raise ConfigError(
            "expected a mapping {id, position, clock_offset}", path=source, field=where
        )
    for key in entry:
        if key not in _READER_KEYS:
            raise ConfigError(
                f"unknown key; valid keys are {', '.join(_READER_KEYS)}",
                path=source,
                field=f"{where}.{key}",
            )
    if "id" not in entry or entry["id"] is None or str(entry["id"]).strip() == "":
        raise ConfigError("missing reader id", path=source, field=f"{where}.id")
    rid = str(entry["id"]).strip()
    if "," in rid or ";" in rid:
        raise ConfigError(
            f"reader id {rid!r} must not contain ',' or ';'", path=source, field=f"{where}.id"
        )
    if "position" not in entry:
        raise ConfigError("missing position [x, y, z]", path=source, field=f"{where}.position")
    pos = _vector(entry["position"], 3, f"{where}.position", source)
    check_coordinates(pos, source, f"{where}.position", f"reader {rid}")
    offset = entry.get("clock_offset", 0.0)
    offset_m = finite_number(offset)
    if offset_m is None or abs(offset_m) > MAX_CLOCK_OFFSET_M:
        raise ConfigError(
            f"reader {rid}: expected a finite number of metres of light travel, at most "
            f"{MAX_CLOCK_OFFSET_M:.0e} m, as clock offset, found {offset!r}",
            path=source,
            field=f"{where}.clock_offset",
        )
    cov = None
    if entry.get("position_covariance") is not None:
        cov = _covariance(entry["position_covariance"], f"{where}.position_covariance", source)
    return Reader(id=rid, p_world_reader=pos, clock_offset=offset_m, position_covariance=cov)


def _vector(value: object, n: int, key: str, source: Path | None) -> np.ndarray:
    if not isinstance(value, list | tuple) or len(value) != n:
        raise ConfigError(
            f"expected a list of {n} numbers, found {value!r}", path=source, field=key
        )
    out = []
    for v in value:
        number = finite_number(v)
        if number is None:
            raise ConfigError(
                f"expected {n} finite numbers, found {value!r}", path=source, field=key
            )
        out.append(number)
    return np.array(out)


def check_coordinates(values: npt.ArrayLike, source: Path | None, key: str, what: str) -> None:
    """Refuse coordinates beyond :data:`MAX_COORDINATE_M` [m] (a typo or a unit mix-up).

    Args:
        values: Coordinates [m], any shape.
        source: File they came from (named in the error).
        key: Key at fault, e.g. ``readers[2].position``.
        what: What they place, e.g. ``reader R3``.

    Raises:
        ConfigError: Naming the file, the key and the value.
    """
    v = np.asarray(values, dtype=float)
    if not np.all(np.abs(v) <= MAX_COORDINATE_M):
        raise ConfigError(
            f"{what}: coordinates {v.tolist()} m are beyond {MAX_COORDINATE_M:g} m from the "
            "origin; no capture hall is that large (metres expected, check for a typo or "
            "millimetres)",
            path=source,
            field=key,
        )


def _covariance(value: object, key: str, source: Path | None) -> np.ndarray:
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise ConfigError("expected a 3x3 matrix [m^2]", path=source, field=key)
    cov = np.stack([_vector(row, 3, key, source) for row in value])
    if not np.allclose(cov, cov.T, atol=1e-12):
        raise ConfigError("covariance must be symmetric", path=source, field=key)
    if np.linalg.eigvalsh(cov).min() < -1e-12:
        raise ConfigError("covariance must be positive semi-definite", path=source, field=key)
    return cov


def finite_number(value: object) -> float | None:
    """A finite number, also from a string (PyYAML reads ``1e-4`` without a dot as text)."""
    if isinstance(value, bool):
        return None
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            return None
    if not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value)


def _positive(value: object, key: str, source: Path | None) -> float:
    number = finite_number(value)
    if number is None or number <= 0:
        raise ConfigError(
            f"expected a positive number of metres, found {value!r}", path=source, field=key
        )
    return number


def _parse_area(value: object, source: Path | None) -> np.ndarray:
    if not isinstance(value, list | tuple) or len(value) < 3:
        raise ConfigError(
            "expected a polygon of at least 3 [x, y] corners", path=source, field="area"
        )
    pts = np.stack([_vector(v, 2, f"area[{i}]", source) for i, v in enumerate(value)])
    for i, corner in enumerate(pts):
        check_coordinates(corner, source, f"area[{i}]", f"area corner {i}")
    x, y = pts[:, 0], pts[:, 1]
    signed = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    if abs(signed) < 1e-9:
        raise ConfigError("the area polygon has zero area", path=source, field="area")
    return pts
