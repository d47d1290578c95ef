"""The 22 ball joints of the human model and their anatomical angles (``configs/joints.yaml``).

A joint's rotation ``R_parent_child`` is an intrinsic Euler sequence of three anatomical angles
(flexion, abduction, rotation in a per-joint order and sign), see the YAML file's header.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..errors import ConfigError
from ..paths import shipped_config
from ..rotations import euler_to_matrix, matrix_to_euler
from ..yaml_files import read_yaml

#: The 23 segments in model order (SPEC section 2), parents before children.
SEGMENTS: tuple[str, ...] = (
    "Pelvis", "L5", "L3", "T12", "T8", "Neck", "Head",
    "RightShoulder", "RightUpperArm", "RightForeArm", "RightHand",
    "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand",
    "RightUpperLeg", "RightLowerLeg", "RightFoot", "RightToe",
    "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "LeftToe",
)

#: The 22 joints, each named after the segment it moves (same order as SEGMENTS[1:]).
JOINTS: tuple[str, ...] = (
    "jL5S1", "jL4L3", "jL1T12", "jT9T8", "jT1C7", "jC1Head",
    "jRightT4Shoulder", "jRightShoulder", "jRightElbow", "jRightWrist",
    "jLeftT4Shoulder", "jLeftShoulder", "jLeftElbow", "jLeftWrist",
    "jRightHip", "jRightKnee", "jRightAnkle", "jRightBallFoot",
    "jLeftHip", "jLeftKnee", "jLeftAnkle", "jLeftBallFoot",
)

ANGLE_NAMES: tuple[str, ...] = ("flex", "abd", "rot")


@dataclass(frozen=True)
class AngleSpec:
    """One anatomical angle of a joint.

    Attributes:
        name: ``"flex"``, ``"abd"`` or ``"rot"``.
        axis: Segment axis ``"x"``, ``"y"`` or ``"z"`` the angle rotates about.
        sign: +1 or -1: the rotation is ``R(axis, sign * angle)``.
        lower_deg: Lower limit of the range of motion [deg].
        upper_deg: Upper limit of the range of motion [deg].
    """

    name: str
    axis: str
    sign: int
    lower_deg: float
    upper_deg: float


@dataclass(frozen=True)
class JointSpec:
    """A ball joint between two segments with its Euler sequence of anatomical angles.

    Attributes:
        name: Joint name, e.g. ``"jRightKnee"``.
        parent: Parent segment.
        child: Child segment (the one the joint moves).
        angles: The three angles in the order of the Euler sequence.
    """

    name: str
    parent: str
    child: str
    angles: tuple[AngleSpec, AngleSpec, AngleSpec]

    @property
    def sequence(self) -> str:
        """Euler axes in order, e.g. ``"YXZ"``."""
        return "".join(a.axis.upper() for a in self.angles)

    @property
    def signs(self) -> np.ndarray:
        """Signs of the three angles, shape (3,)."""
        return np.array([a.sign for a in self.angles], dtype=float)

    @property
    def axis_coupling(self) -> float:
        """``c`` (+-1) such that the first and third angles' axes have the cosine ``c sin(a2)``.

        Both axes seen in the child frame, ``a2`` the middle anatomical angle; ``c`` is the
        product of the three signs and the sequence's parity (+1 for x-y-z, y-z-x, z-x-y). A
        change ``da = (d1, d2, d3)`` of the angles turns the joint by about
        ``sqrt(d1^2 + d2^2 + d3^2 + 2 c sin(a2) d1 d3)`` [rad]: near ``|a2| = 90`` deg
        (gimbal lock) the first and third angles can change a lot together while the joint
        barely turns.
        """
        i, j = ("xyz".index(a.axis) for a in self.angles[:2])
        parity = 1.0 if (j - i) % 3 == 1 else -1.0
        return parity * float(np.prod(self.signs))

    def column(self, angle: str) -> str:
        """Column name of one angle, e.g. ``jRightKnee_flex``."""
        return f"{self.name}_{angle}"

    def rotation(self, angles_rad: npt.ArrayLike) -> np.ndarray:
        """``R_parent_child`` from the angles [rad] in sequence order, shape ``S + (3,)``."""
        return euler_to_matrix(self.sequence, np.asarray(angles_rad, dtype=float) * self.signs)

    def angles_from_rotation(self, R_parent_child: npt.ArrayLike) -> np.ndarray:
        """Angles [rad] in sequence order from ``R_parent_child``; inverse of :meth:`rotation`."""
        return matrix_to_euler(self.sequence, R_parent_child) * self.signs


def load_joint_specs(path: str | Path | None = None) -> dict[str, JointSpec]:
    """Read and validate the joint definitions.

    Args:
        path: A ``joints.yaml``; the shipped ``configs/joints.yaml`` when omitted.

    Returns:
        Joint name -> :class:`JointSpec`, in the order of :data:`JOINTS`.

    Raises:
        ConfigError: A missing joint, an unknown segment, a bad axis, sign or range.
    """
    file = Path(path) if path is not None else shipped_config("joints.yaml")
    try:  # a file read before and unchanged since: its (immutable) specs again
        stat = file.stat()
        key: tuple[str, int, int] | None = (str(file.absolute()), stat.st_mtime_ns,
                                            stat.st_size)
    except OSError:
        key = None  # read_yaml names the problem
    if key is not None and key in _READ:
        return dict(_READ[key])
    specs = _read_joint_specs(file)
    if key is not None:
        _READ.clear()  # keep one: the shipped file, read for every model built
        _READ[key] = specs
    return dict(specs)


#: The specs of the last joints file read, by path, modification time and size.
_READ: dict[tuple[str, int, int], dict[str, JointSpec]] = {}


def _read_joint_specs(file: Path) -> dict[str, JointSpec]:
    """:func:`load_joint_specs` of ``file``, read and validated."""
    doc = read_yaml(file, "joints file")
    if not isinstance(doc, dict) or not isinstance(doc.get("joints"), dict):
        raise ConfigError("expected a mapping with key 'joints'", path=file, field="joints")
    entries = doc["joints"]
    missing = [j for j in JOINTS if j not in entries]
    if missing:
        raise ConfigError(f"joints missing: {', '.join(missing)}", path=file, field="joints")
    return {name: _parse_joint(file, name, entries[name]) for name in JOINTS}


def _parse_joint(file: Path, name: str, entry: object) -> JointSpec:
    if not isinstance(entry, dict):
        raise ConfigError("expected a mapping", path=file, field=name)
    for key in ("parent", "child"):
        if entry.get(key) not in SEGMENTS:
            raise ConfigError(
                f"{key} must be one of {', '.join(SEGMENTS)}; found {entry.get(key)!r}",
                path=file, field=f"{name}.{key}",
            )
    seq = entry.get("sequence")
    if not isinstance(seq, list) or len(seq) != 3:
        raise ConfigError("sequence must list three angles", path=file, field=f"{name}.sequence")
    angles = tuple(_parse_angle(file, name, i, item) for i, item in enumerate(seq))
    if sorted(a.name for a in angles) != sorted(ANGLE_NAMES):
        raise ConfigError("sequence must hold flex, abd and rot once each", path=file,
                          field=f"{name}.sequence")
    if len({a.axis for a in angles}) != 3:
        raise ConfigError("the three axes must differ", path=file, field=f"{name}.sequence")
    middle = angles[1]
    if not (-90.0 <= middle.lower_deg and middle.upper_deg <= 90.0):
        raise ConfigError(
            f"the middle angle {middle.name!r} must stay within [-90, 90] deg (gimbal lock)",
            path=file, field=f"{name}.sequence[1].range",
        )
    return JointSpec(name, entry["parent"], entry["child"], angles)  # type: ignore[arg-type]


def _parse_angle(file: Path, joint: str, index: int, item: object) -> AngleSpec:
    field = f"{joint}.sequence[{index}]"
    if not isinstance(item, dict):
        raise ConfigError("expected {angle, axis, sign, range}", path=file, field=field)
    axis = str(item.get("axis", "")).lower()
    if axis not in ("x", "y", "z"):
        raise ConfigError(f"axis must be x, y or z; found {item.get('axis')!r}", path=file,
                          field=f"{field}.axis")
    if item.get("sign") not in (1, -1):
        raise ConfigError("sign must be 1 or -1", path=file, field=f"{field}.sign")
    rng = item.get("range")
    if not (isinstance(rng, list) and len(rng) == 2 and all(isinstance(v, int | float) for v in rng)
            and -180.0 < rng[0] < rng[1] < 180.0):
        raise ConfigError("range must be [lower, upper] deg with -180 < lower < upper < 180",
                          path=file, field=f"{field}.range")
    return AngleSpec(str(item.get("angle")), axis, int(item["sign"]), float(rng[0]), float(rng[1]))
