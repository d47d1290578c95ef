"""Retargeting configs (``configs/retarget/<robot>.yaml``) and the robot URDFs they name.

A config says which robot link follows which human segment, how hard the scaled positions
pull, where the soles' corners are, which capsules stand for the links in self-collision checks
and which capsule pairs must never touch. Lengths in metres, angles in radians (``*_deg`` keys
in degrees). The shipped robots' URDFs come from the ``example-robot-data`` package (extra
``robots``), read by path: it has no Python loader module.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError, InputError
from ..paths import configs_dir
from ..yaml_files import YamlDocument, read_yaml_document
from .settings import RetargetSettings

#: Robots with a shipped config, by the name ``--robot`` takes.
SHIPPED_ROBOTS = ("g1", "talos", "icub", "romeo")

#: Where ``example-robot-data`` installs its robots, below a ``site-packages`` folder.
_EXAMPLE_ROBOT_DATA = Path("cmeel.prefix", "share", "example-robot-data", "robots")


@dataclass(frozen=True)
class Capsule:
    """A capsule fixed to a link: the points within ``radius`` of the segment ``a``-``b``.

    Attributes:
        link: Robot link (Pinocchio frame) it moves with.
        a, b: Segment end points in the link frame [m].
        radius: [m].
    """

    link: str
    a: np.ndarray
    b: np.ndarray
    radius: float


@dataclass(frozen=True)
class Foot:
    """A robot foot: its link and the sole's corners in the link frame (4, 3) [m]."""

    link: str
    corners: np.ndarray


@dataclass
class RetargetConfig:
    """One robot's retargeting config (see the module docstring).

    Attributes:
        urdf: The robot's URDF file.
        links: Human segment -> robot link whose orientation follows it.
        position_weights: Human segment -> weight of its scaled position task [1/m^2].
        feet: ``left``/``right`` -> :class:`Foot`.
        solver: Weights, step counts and tolerances of the solve: ``configs/retarget/
            defaults.yaml`` overlaid by the config's ``solver`` key.
        capsules: Name -> :class:`Capsule`.
        collision_pairs: Capsule pairs that must keep apart.
        locked_joints: Joint -> fixed value [rad] (removed from the model).
        rest_pose: Joint -> value [rad] of the pose matching the human N-pose (others 0).
        joint_ranges: Joint -> (lower, upper) [rad] narrower than the URDF's, where the URDF
            allows what a human-like motion should not use (G1's elbows bend 30 deg past
            straight).
        scale: Human-to-robot length scale; None: robot hip height / human hip height.
        orientation_offsets_deg: Segment -> (roll, pitch, yaw) [deg] replacing the offset
            computed from the two rest poses (``R_link = R_segment @ R_offset``).
        source: The config file.
    """

    urdf: Path
    links: dict[str, str]
    position_weights: dict[str, float]
    feet: dict[str, Foot]
    solver: RetargetSettings
    capsules: dict[str, Capsule] = field(default_factory=dict)
    collision_pairs: list[tuple[str, str]] = field(default_factory=list)
    locked_joints: dict[str, float] = field(default_factory=dict)
    rest_pose: dict[str, float] = field(default_factory=dict)
    joint_ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    scale: float | None = None
    orientation_offsets_deg: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    source: Path | None = None


def example_robot_data_dir() -> Path:
    """The ``robots`` folder of the installed ``example-robot-data`` package.

    Raises:
        ConfigError: When the package is not installed (``pip install 'ikfusion[robots]'``).
    """
    for entry in sys.path:
        candidate = Path(entry) / _EXAMPLE_ROBOT_DATA
        if candidate.is_dir():
            return candidate
    raise ConfigError("the shipped robots need the example-robot-data package: "
                      "pip install 'ikfusion[robots]'")


def robots_installed() -> bool:
    """Whether the shipped robots' URDFs (``example-robot-data``) are installed."""
    try:
        example_robot_data_dir()
    except ConfigError:
        return False
    return True


def config_path(robot: str) -> Path:
    """The shipped config of ``robot`` (one of :data:`SHIPPED_ROBOTS`)."""
    return configs_dir() / "retarget" / f"{robot}.yaml"


def load_retarget_config(robot: str | Path, config: str | Path | None = None) -> RetargetConfig:
    """The config for ``robot``: a shipped name, or a URDF path with ``config`` given.

    Args:
        robot: ``g1``, ``talos``, ``icub``, ``romeo`` or a ``.urdf`` path.
        config: A config file; overrides the shipped one (its ``urdf`` key may be left out
            when ``robot`` is a URDF path).

    Raises:
        ConfigError: Unknown robot, missing or malformed config (file and field named).
    """
    urdf: Path | None = None
    if str(robot).lower().endswith(".urdf"):
        urdf = Path(robot)
        if not urdf.is_file():
            raise InputError("URDF not found", path=urdf)
        if config is None:
            raise ConfigError("a robot given as a URDF needs --config (see "
                              "configs/retarget/g1.yaml for the keys)", field="config")
    elif str(robot) not in SHIPPED_ROBOTS:
        raise ConfigError(f"unknown robot {robot!r}; shipped: {', '.join(SHIPPED_ROBOTS)}, "
                          f"human, or a .urdf path with --config", field="robot")
    path = Path(config) if config is not None else config_path(str(robot))
    document = read_yaml_document(path, "retarget config")
    if not isinstance(document.data, dict):
        raise ConfigError("a retarget config is a mapping of keys", path=path)
    return _parse(document, urdf)


def _parse(document: YamlDocument, urdf: Path | None) -> RetargetConfig:
    data: dict[str, Any] = document.data
    path = document.path
    if urdf is None:
        text = _require(data, "urdf", str, path)
        urdf = Path(text) if Path(text).is_absolute() else _resolve_urdf(text, path)
    feet = {}
    for side in ("left", "right"):
        foot = _require(_require(data, "feet", dict, path), side, dict, path, f"feet.{side}")
        corners = _array(foot.get("corners"), (4, 3), path, f"feet.{side}.corners")
        feet[side] = Foot(_require(foot, "link", str, path, f"feet.{side}.link"), corners)
    capsules = {}
    for name, spec in (data.get("capsules") or {}).items():
        key = f"capsules.{name}"
        if not isinstance(spec, dict):
            raise ConfigError("expected link, a, b, radius", path=path, field=key)
        capsules[str(name)] = Capsule(_require(spec, "link", str, path, f"{key}.link"),
                                      _array(spec.get("a"), (3,), path, f"{key}.a"),
                                      _array(spec.get("b"), (3,), path, f"{key}.b"),
                                      _positive(spec.get("radius"), path, f"{key}.radius"))
    pairs = []
    for n, pair in enumerate(data.get("collision_pairs") or []):
        if not (isinstance(pair, list) and len(pair) == 2 and all(p in capsules for p in pair)):
            raise ConfigError(f"expected two capsule names out of {sorted(capsules)}, "
                              f"found {pair!r}", path=path, field=f"collision_pairs[{n}]")
        pairs.append((str(pair[0]), str(pair[1])))
    scale = data.get("scale")
    offsets = {str(k): tuple(float(x) for x in _array(v, (3,), path,
                                                      f"orientation_offsets_deg.{k}"))
               for k, v in (data.get("orientation_offsets_deg") or {}).items()}
    return RetargetConfig(
        urdf=urdf,
        links={str(k): str(v) for k, v in _require(data, "links", dict, path).items()},
        position_weights={str(k): float(v) for k, v in
                          (data.get("position_weights") or {}).items()},
        feet=feet, solver=RetargetSettings.load(document), capsules=capsules, collision_pairs=pairs,
        locked_joints={str(k): float(v) for k, v in (data.get("locked_joints") or {}).items()},
        rest_pose={str(k): float(v) for k, v in (data.get("rest_pose") or {}).items()},
        joint_ranges={str(k): _range(v, path, f"joint_ranges.{k}")
                      for k, v in (data.get("joint_ranges") or {}).items()},
        scale=None if scale is None else _positive(scale, path, "scale"),
        orientation_offsets_deg=offsets,  # type: ignore[arg-type]
        source=path)


def _resolve_urdf(text: str, config: Path) -> Path:
    """A relative ``urdf`` key: beside the config, else in ``example-robot-data``."""
    beside = config.parent / text
    if beside.is_file():
        return beside
    found = example_robot_data_dir() / text
    if not found.is_file():
        raise ConfigError(f"URDF {text!r} not found beside the config nor in "
                          f"example-robot-data", path=config, field="urdf")
    return found


def _require(data: dict[str, Any], key: str, kind: type, path: Path,
             name: str | None = None) -> Any:
    value = data.get(key)
    if not isinstance(value, kind):
        raise ConfigError(f"missing or not a {kind.__name__}", path=path, field=name or key)
    return value


def _array(value: Any, shape: tuple[int, ...], path: Path, name: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape != shape or not np.isfinite(a).all():
        raise ConfigError(f"expected {' x '.join(map(str, shape))} numbers, found {value!r}",
                          path=path, field=name)
    return a


def _range(value: Any, path: Path, name: str) -> tuple[float, float]:
    lower, upper = _array(value, (2,), path, name)
    if not lower < upper:
        raise ConfigError(f"expected [lower, upper] with lower < upper, found {value!r}",
                          path=path, field=name)
    return float(lower), float(upper)


def _positive(value: Any, path: Path, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if not v > 0:
        raise ConfigError(f"expected a positive number, found {value!r}", path=path, field=name)
    return v
