"""OpenSim motion file ``motion.mot``: the motion as coordinates of the Rajagopal 2015 model.

The mapping from our model to OpenSim coordinates is read from ``configs/opensim.yaml``, whose
header explains every row. Frames: our world and N-pose segment frames are X forward, Y left,
Z up; OpenSim's ground and default-pose body frames are X forward, Y up, Z right, so vectors
change frame with ``v_opensim = C_OPENSIM_OURS @ v_ours`` and rotations with
``C @ R @ C.T``. Angles are written in degrees, translations in metres.

The file is the usual OpenSim motion format: a name line, ``version=1``, ``nRows=``,
``nColumns=`` (``time`` included), ``inDegrees=yes``, ``endheader``, then a tab-separated
header row starting with ``time`` and one row per frame.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..ik.pose import Motion
from ..model.angle_continuity import continuous_series
from ..model.motion_kinematics import frame_placements
from ..paths import shipped_config
from ..rotations import matrix_to_euler
from ..yaml_files import read_yaml
from .result_kinematics import ResultKinematics
from .text_table import write_rows

#: ``R_opensim_ours``: our axes (X forward, Y left, Z up) to OpenSim's (X forward, Y up, Z right).
C_OPENSIM_OURS = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
#: Body-fixed rotation order of OpenSim's ground_pelvis, back, hip and acromial joints, in
#: OpenSim axes: ``R = Rz(a0) @ Rx(a1) @ Ry(a2)``.
OPENSIM_SEQUENCE = "ZXY"
#: Name of the ground in ``euler`` rules.
WORLD = "world"
CONVENTIONS = ("rajagopal2015", "gait2392")


@dataclass(frozen=True)
class CoordinateRule:
    """How one OpenSim coordinate is computed from our motion.

    Attributes:
        name: OpenSim coordinate, e.g. ``knee_angle_r``.
        kind: ``"angle"``, ``"euler"`` or ``"position"``.
        source: Our angle column (``angle``), ``(parent, child)`` segments (``euler``) or a
            segment (``position``).
        index: Euler angle index 0..2 (``euler``) or OpenSim axis index 0..2 (``position``).
        sign: Multiplies the value.
        offset: Added after the sign [deg] (angles only).
    """

    name: str
    kind: str
    source: str | tuple[str, str]
    index: int = 0
    sign: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class OpenSimMapping:
    """The rows of ``configs/opensim.yaml``.

    Attributes:
        rules: One rule per coordinate, in column order.
        gait2392_negate: Coordinates whose sign flips for the gait2392 model.
    """

    rules: tuple[CoordinateRule, ...]
    gait2392_negate: tuple[str, ...]

    @property
    def names(self) -> list[str]:
        """Coordinate names in column order."""
        return [r.name for r in self.rules]


def load_opensim_mapping(path: str | Path | None = None) -> OpenSimMapping:
    """Read the coordinate mapping.

    Args:
        path: A mapping YAML; the shipped ``configs/opensim.yaml`` when omitted.

    Raises:
        ConfigError: Not YAML, no ``coordinates`` mapping, or a row that is not one valid rule.
    """
    if path is None:
        return _shipped_mapping()
    return _read_mapping(Path(path))


@functools.cache
def _shipped_mapping() -> OpenSimMapping:
    """``configs/opensim.yaml``, read once per process (the mapping is immutable)."""
    return _read_mapping(shipped_config("opensim.yaml"))


def _read_mapping(file: Path) -> OpenSimMapping:
    """:func:`load_opensim_mapping` of one file."""
    doc = read_yaml(file, "OpenSim mapping")
    if not isinstance(doc, dict) or not isinstance(doc.get("coordinates"), dict):
        raise ConfigError("expected a mapping with key 'coordinates'", path=file,
                          field="coordinates")
    rules = tuple(_parse_rule(file, name, entry) for name, entry in doc["coordinates"].items())
    negate = (doc.get("gait2392") or {}).get("negate", [])
    unknown = sorted(set(negate) - {r.name for r in rules})
    if unknown:
        raise ConfigError(f"gait2392.negate names unknown coordinates {unknown}", path=file,
                          field="gait2392")
    return OpenSimMapping(rules, tuple(negate))


def _parse_rule(file: Path, name: str, entry: object) -> CoordinateRule:
    """One ``coordinates`` row; see the YAML header for the three kinds."""
    if not isinstance(entry, dict):
        raise ConfigError("expected a mapping like {angle: jRightKnee_flex, sign: 1}",
                          path=file, field=name)
    kinds = [k for k in ("angle", "euler", "position") if k in entry]
    if len(kinds) != 1:
        raise ConfigError(f"expected exactly one of angle, euler, position; found {kinds}",
                          path=file, field=name)
    kind = kinds[0]
    sign = float(entry.get("sign", 1))
    offset = float(entry.get("offset", 0.0))
    if sign not in (1.0, -1.0):
        raise ConfigError(f"sign must be 1 or -1, found {sign}", path=file, field=name)
    if kind == "angle":
        return CoordinateRule(name, kind, str(entry["angle"]), sign=sign, offset=offset)
    if kind == "euler":
        pair = entry["euler"]
        index = entry.get("index")
        if not (isinstance(pair, list) and len(pair) == 2) or index not in (0, 1, 2):
            raise ConfigError("expected euler: [parent, child] and index 0, 1 or 2", path=file,
                              field=name)
        return CoordinateRule(name, kind, (str(pair[0]), str(pair[1])), index, sign, offset)
    axis = entry.get("axis")
    if axis not in ("x", "y", "z"):
        raise ConfigError(f"position needs axis x, y or z, found {axis!r}", path=file,
                          field=name)
    return CoordinateRule(name, kind, str(entry["position"]), "xyz".index(axis), sign)


def to_opensim_rotation(R_ours: np.ndarray) -> np.ndarray:
    """A rotation (stack ``S + (3, 3)``) re-expressed in OpenSim axes: ``C @ R @ C.T``."""
    return C_OPENSIM_OURS @ R_ours @ C_OPENSIM_OURS.T


def segment_poses(motion: Motion, names: set[str]) -> tuple[dict[str, np.ndarray],
                                                            dict[str, np.ndarray]]:
    """``R_world_segment`` (N, 3, 3) and origins ``p_world_segment`` (N, 3) [m] of segments.

    Both in our world frame (X forward, Y left, Z up) (all frames at once, see
    :func:`ikfusion.model.motion_kinematics.frame_placements`).
    """
    model = motion.model
    order = sorted(names)
    p, R = frame_placements(model.model, motion.q, [model.segment_frame_id(n) for n in order])
    return ({n: R[:, i] for i, n in enumerate(order)}, {n: p[:, i] for i, n in enumerate(order)})


def opensim_euler_deg(R_world_parent: np.ndarray | None, R_world_child: np.ndarray) -> np.ndarray:
    """Angles (N, 3) [deg] of ``R_parent_child`` in OpenSim axes and order, continuous in time.

    Args:
        R_world_parent: (N, 3, 3), or None for the ground.
        R_world_child: (N, 3, 3).

    Returns:
        ``(a0, a1, a2)`` per frame with ``C @ R_parent_child @ C.T = Rz(a0) @ Rx(a1) @ Ry(a2)``.
    """
    R = R_world_child if R_world_parent is None else \
        np.swapaxes(R_world_parent, -1, -2) @ R_world_child
    angles = matrix_to_euler(OPENSIM_SEQUENCE, to_opensim_rotation(R))
    return np.degrees(continuous_series(angles))


def opensim_coordinates(motion: Motion, mapping: OpenSimMapping | None = None,
                        convention: str = "rajagopal2015",
                        kinematics: ResultKinematics | None = None
                        ) -> tuple[list[str], np.ndarray]:
    """The OpenSim coordinates of a motion.

    Args:
        motion: The solved motion.
        mapping: The coordinate rules; the shipped ``configs/opensim.yaml`` when omitted.
        convention: ``"rajagopal2015"`` or ``"gait2392"`` (flips the knee and mtp signs).
        kinematics: The motion's angles and poses when already computed (else computed here).

    Returns:
        Coordinate names and values (N, names): angles [deg], translations [m] in OpenSim
        ground axes (X forward, Y up, Z right).
    """
    if convention not in CONVENTIONS:
        raise ValueError(f"convention must be one of {CONVENTIONS}, got {convention!r}")
    mapping = mapping or load_opensim_mapping()
    segments = {s for r in mapping.rules if isinstance(r.source, tuple) for s in r.source
                if s != WORLD}
    segments |= {str(r.source) for r in mapping.rules if r.kind == "position"}
    if kinematics is not None and segments <= kinematics.segment_index.keys():
        rotations, positions = kinematics.segment_poses(segments)
    else:
        rotations, positions = segment_poses(motion, segments)
    angles = motion.joint_angles() if kinematics is None else kinematics.angles
    column = {c: i for i, c in enumerate(motion.model.angle_columns)}
    euler: dict[tuple[str, str], np.ndarray] = {}
    values = np.empty((len(motion), len(mapping.rules)))
    for i, rule in enumerate(mapping.rules):
        if rule.kind == "angle":
            if rule.source not in column:
                raise ConfigError(f"unknown joint-angle column {rule.source!r}", field=rule.name)
            raw = angles[:, column[str(rule.source)]]
        elif rule.kind == "euler" and isinstance(rule.source, tuple):
            parent, child = rule.source
            if (parent, child) not in euler:
                euler[(parent, child)] = opensim_euler_deg(
                    None if parent == WORLD else rotations[parent], rotations[child])
            raw = euler[(parent, child)][:, rule.index]
        else:
            raw = (positions[str(rule.source)] @ C_OPENSIM_OURS.T)[:, rule.index]
        values[:, i] = rule.sign * raw + rule.offset
        if convention == "gait2392" and rule.name in mapping.gait2392_negate:
            values[:, i] *= -1.0
    return mapping.names, values


def write_mot(path: str | Path, time: np.ndarray, names: list[str], values: np.ndarray,
              name: str = "ikfusion motion", in_degrees: bool = True) -> Path:
    """Write an OpenSim ``.mot`` table (header, then tab-separated ``time`` and columns).

    Args:
        path: The file.
        time: (N,) [s].
        names: Column names after ``time``.
        values: (N, len(names)).
        name: First header line.
        in_degrees: Value of ``inDegrees``.
    """
    path = Path(path)
    table = np.column_stack([np.asarray(time, dtype=float), values])
    header = [name, "version=1", f"nRows={table.shape[0]}", f"nColumns={table.shape[1]}",
              f"inDegrees={'yes' if in_degrees else 'no'}", "endheader",
              "\t".join(["time", *names])]
    with path.open("wb") as out:
        out.write(("\n".join(header) + "\n").encode())
        write_rows(out, "\t".join(["%.6f"] * table.shape[1]) + "\n", table)
    return path


def write_motion_mot(path: str | Path, motion: Motion, mapping: OpenSimMapping | None = None,
                     convention: str = "rajagopal2015",
                     kinematics: ResultKinematics | None = None) -> Path:
    """Write ``motion.mot``: the motion as OpenSim coordinates, degrees and metres, Y up.

    Args:
        path: The file.
        motion: The solved motion.
        mapping: The coordinate rules; the shipped ``configs/opensim.yaml`` when omitted.
        convention: ``"rajagopal2015"`` (default) or ``"gait2392"``.
        kinematics: The motion's angles and poses when already computed (else computed here).

    Returns:
        The path.
    """
    names, values = opensim_coordinates(motion, mapping, convention, kinematics)
    return write_mot(path, motion.time, names, values, name=f"ikfusion motion ({convention})")
