"""BVH motion files: a strict reader, forward kinematics and an atomic writer.

A BVH file has two parts. ``HIERARCHY`` declares a tree of joints: each ``ROOT`` / ``JOINT``
has an ``OFFSET`` (the joint origin in its parent's frame, in file units) and a ``CHANNELS``
list; a leaf may close with an ``End Site`` (a fixed point, no channels). ``MOTION`` gives
``Frames:``, ``Frame Time:`` [s] and one line of numbers per frame, one number per channel,
in the order the ``CHANNELS`` lines appear in the file.

Conventions used here (they match what Blender, MotionBuilder and bvhio do):

* Rotation channels are degrees and compose in the written order, as intrinsic rotations:
  ``CHANNELS 3 Zrotation Xrotation Yrotation`` gives the local rotation
  ``R_parent_joint = Rz(z) @ Rx(x) @ Ry(y)``. Any order and any subset of the three axes is
  accepted, on any joint.
* Position channels give the joint's translation in its parent's frame and *replace* the
  matching ``OFFSET`` component (root channels are absolute positions; MotionBuilder writes
  6 channels on every joint with values equal to the offsets). Components without a
  channel keep the ``OFFSET`` value.
* Forward kinematics: ``R_file_j = R_file_parent @ R_parent_j`` and
  ``p_file_j = p_file_parent + R_file_parent @ t_j`` where ``t_j`` is the joint translation.
  With every channel at zero (the *rest pose*) every joint frame is parallel to the file frame.
* World frames: BVH files are usually Y-up. Our world is Z-up (SPEC section 1). A Y-up file is
  brought into our world by the fixed rotation :func:`rotation_zup_yup`, the cyclic axis
  permutation ``x_world = z_file, y_world = x_file, z_world = y_file``: the file's up axis
  (+Y) becomes +Z, and a character facing the file's +Z (the most common BVH convention,
  with its left hand towards the file's +X) faces our +X with its left hand towards our +Y,
  as in the MVN convention. A Z-up file is taken as it is.
* Units are whatever the file uses; ``scale`` [m per file unit] converts them
  (CMU: about 0.056444, SFU: inches, 0.0254; MVN exports: centimetres, 0.01).
  :func:`guess_bvh_scale` picks a unit from the skeleton size.
"""

from __future__ import annotations

import gzip
import math
import os
import re
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal, NamedTuple

import numpy as np
import numpy.typing as npt

from ..atomic import atomic_write_bytes
from ..errors import InputError, NameNotFound
from ..model.angle_continuity import continuous_series
from ..number_text import format_rows_bytes
from ..rotations import axis_rotation, matrix_to_euler
from .bad_samples import FAR_BEYOND_ANY_HALL_M, MAX_ANGLE_DEG, Kind, bad_samples, bridge_channel

__all__ = [
    "BVH_UNITS",
    "BvhMotion",
    "BvhSkeleton",
    "BvhWorldPoses",
    "guess_bvh_scale",
    "read_bvh",
    "rotation_world_file",
    "rotation_zup_yup",
    "write_bvh",
]

Up = Literal["y", "z"]

#: Common BVH units [m per file unit], tried in this order by :func:`guess_bvh_scale`.
BVH_UNITS: Mapping[str, float] = {
    "m": 1.0,
    "cm": 0.01,
    "mm": 0.001,
    "inch": 0.0254,
    "cmu": 0.056444,
}

_CHANNEL_NAMES = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
_KEYWORDS = frozenset({"root", "joint", "end", "offset", "channels", "{", "}", "motion"})
_FRAMES_RE = re.compile(r"^\s*frames\s*:?\s*(\S*)\s*$", re.IGNORECASE)
_GZIP_MAGIC = b"\x1f\x8b"
_FRAME_TIME_RE = re.compile(r"^\s*frame\s+time\s*:?\s*(\S*)\s*$", re.IGNORECASE)


def rotation_zup_yup() -> np.ndarray:
    """``R_zup_yup``: coordinates in a Y-up BVH world to our Z-up world.

    The cyclic permutation ``(x, y, z)_zup = (z, x, y)_yup``, a proper rotation (det +1):
    file +Y (up) -> world +Z, file +Z -> world +X (forward), file +X -> world +Y (left).
    """
    return np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def rotation_world_file(up: Up) -> np.ndarray:
    """``R_world_file`` for a file whose up axis is ``up`` (``"y"`` or ``"z"``)."""
    if up == "y":
        return rotation_zup_yup()
    if up == "z":
        return np.eye(3)
    raise ValueError(f"up must be 'y' or 'z', got {up!r}")


class BvhWorldPoses(NamedTuple):
    """Joint poses in our Z-up world, from :meth:`BvhMotion.world_poses`.

    Attributes:
        p_world_joint: Joint origins, shape (F, J, 3) [m].
        R_world_joint: Joint frames (BVH joint axes), shape (F, J, 3, 3).
        p_world_end_site: End Site points, shape (F, E, 3) [m].
    """

    p_world_joint: np.ndarray
    R_world_joint: np.ndarray
    p_world_end_site: np.ndarray


@dataclass(frozen=True, eq=False)
class BvhSkeleton:
    """A joint tree for :func:`write_bvh`, in metres and in the axes of the world it is given in.

    Attributes:
        joint_names: Names, one per joint; joint 0 is the root.
        parents: Parent index per joint, shape (J,), ``-1`` for the root and ``parents[j] < j``.
        offsets: Joint origin in the parent frame with all rotations at zero, shape (J, 3) [m];
            ``offsets[0]`` is the root's rest position.
        end_site_parents: Joint index of each End Site, shape (E,).
        end_site_offsets: End Site point in its joint frame, shape (E, 3) [m].
    """

    joint_names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    end_site_parents: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    end_site_offsets: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.joint_names)
        parents = np.asarray(self.parents, dtype=int).reshape(-1)
        offsets = np.asarray(self.offsets, dtype=float)
        es_parents = np.asarray(self.end_site_parents, dtype=int).reshape(-1)
        es_offsets = np.asarray(self.end_site_offsets, dtype=float).reshape(-1, 3)
        n = len(names)
        if n == 0:
            raise ValueError("a skeleton needs at least one joint")
        if parents.shape != (n,) or offsets.shape != (n, 3):
            raise ValueError(
                f"{n} joint names need parents of shape ({n},) and offsets of shape ({n}, 3); "
                f"got {parents.shape} and {offsets.shape}"
            )
        if parents[0] != -1 or np.any(parents[1:] < 0) or np.any(parents[1:] >= np.arange(1, n)):
            raise ValueError(
                "parents must be -1 for joint 0 (the root) and parents[j] < j for the others; "
                f"got {parents.tolist()}"
            )
        if es_parents.shape[0] != es_offsets.shape[0]:
            raise ValueError("end_site_parents and end_site_offsets need the same length")
        if np.any(es_parents < 0) or np.any(es_parents >= n):
            raise ValueError(f"end_site_parents must index joints 0..{n - 1}")
        for name in names:
            if not name or any(c.isspace() for c in name) or name in "{}":
                raise ValueError(f"joint name {name!r} must be non-empty without spaces or braces")
        if not (np.all(np.isfinite(offsets)) and np.all(np.isfinite(es_offsets))):
            raise ValueError("skeleton offsets must be finite")
        object.__setattr__(self, "joint_names", names)
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "end_site_parents", es_parents)
        object.__setattr__(self, "end_site_offsets", es_offsets)

    @property
    def num_joints(self) -> int:
        """Number of joints J."""
        return len(self.joint_names)


@dataclass(frozen=True, eq=False)
class BvhMotion:
    """The content of a BVH file, values exactly as written (file units, degrees).

    Attributes:
        joint_names: Joint names in file order (depth first); joint 0 is the root.
        parents: Parent index per joint, shape (J,), ``-1`` for the root, ``parents[j] < j``.
        offsets: ``OFFSET`` of each joint in its parent frame, shape (J, 3) [file units].
        joint_channels: Channel names of each joint in written order, canonical spelling
            (``"Xposition"`` ... ``"Zrotation"``).
        end_site_parents: Joint index of each End Site, shape (E,).
        end_site_offsets: ``OFFSET`` of each End Site in its joint frame, shape (E, 3).
        frame_time: Seconds per frame [s].
        channels: Channel values, shape (F, C), grouped by joint in joint order (the file's
            column order for any depth-first file; see :attr:`channel_names`); positions in
            file units, rotations in degrees.
        path: The file read, if any.
        warnings: What the reader bridged (channels with NaN, infinite or absurd values).
    """

    joint_names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    joint_channels: tuple[tuple[str, ...], ...]
    end_site_parents: np.ndarray
    end_site_offsets: np.ndarray
    frame_time: float
    channels: np.ndarray
    path: Path | None = None
    warnings: tuple[str, ...] = ()

    # ----------------------------------------------------------------- sizes and time
    @property
    def num_frames(self) -> int:
        """Number of frames F."""
        return int(self.channels.shape[0])

    @property
    def num_joints(self) -> int:
        """Number of joints J (End Sites not included)."""
        return len(self.joint_names)

    @property
    def frame_rate(self) -> float:
        """Frames per second [Hz], ``1 / frame_time``."""
        return 1.0 / self.frame_time

    @property
    def duration(self) -> float:
        """Time of the last frame [s], ``(F - 1) * frame_time`` (0 for one frame or none)."""
        return max(self.num_frames - 1, 0) * self.frame_time

    @property
    def times(self) -> np.ndarray:
        """Frame times [s], shape (F,), starting at 0."""
        return np.arange(self.num_frames) * self.frame_time

    @property
    def channel_starts(self) -> np.ndarray:
        """Column of each joint's first channel in :attr:`channels`, shape (J,)."""
        counts = [len(c) for c in self.joint_channels]
        return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int)

    @property
    def channel_names(self) -> tuple[str, ...]:
        """Column names of :attr:`channels`, ``"<joint>.<channel>"``."""
        return tuple(
            f"{name}.{ch}" for name, chans in zip(self.joint_names, self.joint_channels)
            for ch in chans
        )

    def rotation_order(self, joint: int | str) -> str:
        """Axes of a joint's rotation channels in written order, e.g. ``"ZXY"`` (may be short)."""
        j = self.joint_index(joint)
        return "".join(ch[0] for ch in self.joint_channels[j] if ch.endswith("rotation"))

    def joint_index(self, joint: int | str) -> int:
        """Index of a joint given by name (first match) or index.

        Raises:
            NameNotFound: The name is not a joint of this file.
        """
        if isinstance(joint, int | np.integer):
            if not 0 <= int(joint) < self.num_joints:
                raise IndexError(f"joint index {joint} out of range 0..{self.num_joints - 1}")
            return int(joint)
        try:
            return self.joint_names.index(joint)
        except ValueError:
            raise NameNotFound("BVH joint", str(joint), self.joint_names) from None

    def children(self, joint: int | str) -> list[int]:
        """Indices of the joints whose parent is ``joint``."""
        j = self.joint_index(joint)
        return [int(k) for k in np.flatnonzero(self.parents == j)]

    # ----------------------------------------------------------------- kinematics
    def local_rotations(
        self, frames: npt.ArrayLike | slice | None = None, *, up: Up | None = None
    ) -> np.ndarray:
        """Joint rotations ``R_parent_joint`` from the Euler channels in their written order.

        Args:
            frames: Frames to use (index array or slice); all when None.
            up: None for the file's own axes. ``"y"`` or ``"z"`` (the file's up axis) gives the
                same rotations expressed in axes parallel to our Z-up world (conjugated by
                :func:`rotation_world_file`), the form :func:`write_bvh` takes.

        Returns:
            Shape (F, J, 3, 3).
        """
        values = self._frames(frames)
        starts = self.channel_starts
        R = np.broadcast_to(np.eye(3), (values.shape[0], self.num_joints, 3, 3)).copy()
        for j, chans in enumerate(self.joint_channels):
            for c, ch in enumerate(chans):
                if ch.endswith("rotation"):
                    angle = np.deg2rad(values[:, starts[j] + c])
                    R[:, j] = R[:, j] @ axis_rotation(ch[0], angle)
        if up is not None:
            A = rotation_world_file(up)
            R = A @ R @ A.T
        return R

    def local_translations(self, frames: npt.ArrayLike | slice | None = None) -> np.ndarray:
        """Joint translations in the parent frame: OFFSET with position channels replacing it.

        Returns:
            Shape (F, J, 3) [file units], in the file's axes.
        """
        values = self._frames(frames)
        starts = self.channel_starts
        t = np.broadcast_to(self.offsets, (values.shape[0], self.num_joints, 3)).copy()
        for j, chans in enumerate(self.joint_channels):
            for c, ch in enumerate(chans):
                if ch.endswith("position"):
                    t[:, j, "XYZ".index(ch[0])] = values[:, starts[j] + c]
        return t

    def world_poses(
        self,
        scale: float = 1.0,
        up: Up = "y",
        frames: npt.ArrayLike | slice | None = None,
    ) -> BvhWorldPoses:
        """Forward kinematics: joint and End Site poses in our Z-up world.

        Args:
            scale: Metres per file unit [m].
            up: The file's up axis; a Y-up file is turned by :func:`rotation_zup_yup`.
            frames: Frames to use (index array or slice); all when None.

        Returns:
            Positions [m] and orientations ``R_world_joint`` (world from BVH joint axes).
        """
        A = rotation_world_file(up)
        R_local = self.local_rotations(frames)
        t_local = self.local_translations(frames) * scale
        n_frames = R_local.shape[0]
        R_world = np.empty_like(R_local)
        p_world = np.empty((n_frames, self.num_joints, 3))
        for j in range(self.num_joints):
            parent = int(self.parents[j])
            if parent < 0:
                R_world[:, j] = A @ R_local[:, j]
                p_world[:, j] = t_local[:, j] @ A.T
            else:
                R_world[:, j] = R_world[:, parent] @ R_local[:, j]
                p_world[:, j] = p_world[:, parent] + np.einsum(
                    "fab,fb->fa", R_world[:, parent], t_local[:, j]
                )
        end = self.end_site_offsets * scale
        p_end = p_world[:, self.end_site_parents] + np.einsum(
            "feab,eb->fea", R_world[:, self.end_site_parents], end
        )
        return BvhWorldPoses(p_world, R_world, p_end)

    def rest_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint and End Site positions with every rotation at zero, from the offsets only.

        Returns:
            ``(p_file_joint (J, 3), p_file_end_site (E, 3))`` [file units] in the file's axes.
        """
        p = np.zeros((self.num_joints, 3))
        for j in range(self.num_joints):
            parent = int(self.parents[j])
            p[j] = self.offsets[j] + (p[parent] if parent >= 0 else 0.0)
        return p, p[self.end_site_parents] + self.end_site_offsets

    def skeleton(self, scale: float = 1.0, up: Up = "y") -> BvhSkeleton:
        """This file's joint tree in metres and in our world axes, for :func:`write_bvh`."""
        A = rotation_world_file(up)
        return BvhSkeleton(
            self.joint_names,
            self.parents.copy(),
            self.offsets @ A.T * scale,
            self.end_site_parents.copy(),
            self.end_site_offsets @ A.T * scale,
        )

    def root_positions(
        self, scale: float = 1.0, up: Up = "y", frames: npt.ArrayLike | slice | None = None
    ) -> np.ndarray:
        """Root joint translation per frame in our world, shape (F, 3) [m]."""
        return self.local_translations(frames)[:, 0] @ rotation_world_file(up).T * scale

    def _frames(self, frames: npt.ArrayLike | slice | None) -> np.ndarray:
        if frames is None:
            return self.channels
        if isinstance(frames, slice):
            return self.channels[frames]
        return self.channels[np.asarray(frames, dtype=int).reshape(-1)]


# --------------------------------------------------------------------------- units
def guess_bvh_scale(
    motion: BvhMotion,
    height: float | None = None,
    *,
    human_range: tuple[float, float] = (1.2, 2.2),
) -> float:
    """Metres per file unit, guessed from the size of the rest skeleton.

    The size is the largest extent along a file axis of the rest pose (joints and End
    Sites, every channel at zero). For a standing skeleton this is the head-to-foot extent; for
    a T-pose it may be the arm span, which for humans is close to the height. The common units
    of :data:`BVH_UNITS` are tried in order and the first that makes this size a plausible
    human height (``human_range`` [m], i.e. a person 1.5-2.0 m tall whose joints span a bit
    less) is returned. When none fits, the scale that makes the size 1.7 m is returned.

    Args:
        motion: The file read by :func:`read_bvh`.
        height: The subject's known size [m]; when given the scale is simply
            ``height / size``.
        human_range: Plausible skeleton size [m] for a unit to be accepted.

    Returns:
        Metres per file unit [m].
    """
    p_joint, p_end = motion.rest_positions()
    points = np.vstack([p_joint, p_end])
    size = float(np.max(np.ptp(points, axis=0)))
    if not size > 0.0 or not math.isfinite(size):
        raise InputError(
            "cannot guess the unit: the rest skeleton has no extent (all offsets zero)",
            motion.path, field="OFFSET",
        )
    if height is not None:
        return float(height) / size
    low, high = human_range
    for unit in BVH_UNITS.values():
        if low <= size * unit <= high:
            return unit
    return 1.7 / size


# --------------------------------------------------------------------------- reader
@dataclass
class _JointDecl:
    name: str
    parent: int
    line: int
    offset: np.ndarray | None = None
    channels: tuple[str, ...] = ()
    channel_order: int = -1  # position of this joint's CHANNELS statement in the file


@dataclass
class _Tokens:
    """Hierarchy tokens with their 1-based line numbers."""

    items: list[tuple[str, int]]
    last_line: int
    pos: int = 0

    def peek(self) -> tuple[str, int] | None:
        return self.items[self.pos] if self.pos < len(self.items) else None

    def next(self, path: Path, expected: str) -> tuple[str, int]:
        if self.pos >= len(self.items):
            raise InputError(
                f"the hierarchy ends early: expected {expected} before MOTION",
                path, line=self.last_line, field=expected,
            )
        item = self.items[self.pos]
        self.pos += 1
        return item


def read_bvh(path: str | os.PathLike[str], *, bridge: bool = True) -> BvhMotion:
    """Read a BVH file.

    Args:
        path: The ``.bvh`` file, or a gzip-compressed one (``.bvh.gz``; line numbers in
            errors are those of the decompressed text).
        bridge: Bridge bad values (NaN, infinite, a position far beyond any hall, an angle
            beyond any spin) as :mod:`ikfusion.io.bad_samples` says, with a warning naming the
            lines and the channel in :attr:`BvhMotion.warnings`. False keeps them as written.

    Returns:
        The hierarchy and the channel values as written (bridged where they were bad).

    Raises:
        InputError: Unreadable file or a file that breaks the format, naming the line and the
            field at fault: missing ``MOTION``, an unknown channel name, a frame line with the
            wrong number of values, a value that is not a number, a ``Frames:`` count that does
            not match the frame lines; with ``bridge``, a channel whose bad values cannot be
            bridged honestly (none good, a long run, too many).
    """
    p = Path(path)
    lines = _bvh_text(p).splitlines()
    motion_line = _find_motion(lines, p)
    tokens = _tokenize(lines[: motion_line - 1])
    joints, end_parents, end_offsets = _parse_hierarchy(tokens, p)
    frame_time, values, frame_lines = _parse_motion(lines, motion_line, joints, p)
    # Columns follow the order of the CHANNELS statements (depth first in every file seen);
    # store them by joint index.
    by_statement = sorted(range(len(joints)), key=lambda j: joints[j].channel_order)
    first_column: dict[int, int] = {}
    column = 0
    for j in by_statement:
        first_column[j] = column
        column += len(joints[j].channels)
    columns = [
        first_column[j] + c for j in range(len(joints)) for c in range(len(joints[j].channels))
    ]
    motion = BvhMotion(
        joint_names=tuple(j.name for j in joints),
        parents=np.array([j.parent for j in joints], dtype=int),
        offsets=np.array([j.offset for j in joints], dtype=float).reshape(-1, 3),
        joint_channels=tuple(j.channels for j in joints),
        end_site_parents=np.array(end_parents, dtype=int),
        end_site_offsets=np.array(end_offsets, dtype=float).reshape(-1, 3),
        frame_time=frame_time,
        channels=values if columns == sorted(columns) else values[:, columns],
        path=p,
    )
    return _bridged(motion, frame_lines) if bridge else motion


def _bvh_text(path: Path) -> str:
    """The text of a BVH file, plain or gzip-compressed (recognised by its magic bytes)."""
    try:
        raw = path.read_bytes()
        if raw[:2] == _GZIP_MAGIC:
            raw = gzip.decompress(raw)
    except OSError as err:  # unreadable, or a damaged gzip stream (BadGzipFile is an OSError)
        raise InputError(f"cannot read the BVH file: {err.strerror or err}", path) from err
    except (EOFError, zlib.error) as err:
        raise InputError(f"cannot read the BVH file: damaged gzip data ({err})", path) from err
    return raw.decode("utf-8-sig", errors="replace")


def _bridged(motion: BvhMotion, frame_lines: np.ndarray) -> BvhMotion:
    """``motion`` with its bad channel values bridged (or InputError), see ``read_bvh``."""
    try:  # a unit above a metre only comes from a degenerate (tiny) skeleton: not trusted
        unit = min(guess_bvh_scale(motion), max(BVH_UNITS.values()))
    except InputError:  # no skeleton extent: allow the smallest common unit
        unit = min(BVH_UNITS.values())
    limit = FAR_BEYOND_ANY_HALL_M / unit  # [file units]
    channels = motion.channels
    kinds: list[Kind] = ["position" if name.endswith("position") else "angle_deg"
                         for name in motion.channel_names]
    warnings: list[str] = []
    for c in _suspect_channels(channels, kinds, limit):
        name, kind = motion.channel_names[c], kinds[c]
        bad = bad_samples(channels[:, c], kind, limit)
        if not bad.any():
            continue
        if channels is motion.channels:
            channels = channels.copy()
        channels[:, c], warning = bridge_channel(
            channels[:, c], bad, rate=motion.frame_rate, path=motion.path, channel=name,
            kind=kind, frame_lines=frame_lines)
        if warning is not None:
            warnings.append(warning)
    if not warnings:
        return motion
    return replace(motion, channels=channels, warnings=tuple(warnings))


def _suspect_channels(channels: np.ndarray, kinds: list[Kind], limit: float) -> list[int]:
    """The columns with a value :func:`bad_samples` could find bad, all checked in one pass.

    Most files have none; only these columns are then looked at one by one.

    Args:
        channels: (F, C) values as written.
        kinds: Each column's kind (``position`` or ``angle_deg``).
        limit: The farthest plausible position [file units].
    """
    largest = np.array([limit if kind == "position" else MAX_ANGLE_DEG for kind in kinds])
    with np.errstate(invalid="ignore"):
        within = np.isfinite(channels).all(axis=0) & (np.abs(channels) <= largest).all(axis=0)
    return [int(c) for c in np.flatnonzero(~within)]


def _find_motion(lines: list[str], path: Path) -> int:
    """1-based line number of the ``MOTION`` keyword."""
    first = next((i for i, line in enumerate(lines) if line.strip()), None)
    if first is None:
        raise InputError("the file is empty; expected a BVH file", path, line=1, field="HIERARCHY")
    if lines[first].split()[0].upper() != "HIERARCHY":
        raise InputError(
            f"expected 'HIERARCHY' on the first line, found {lines[first].strip()[:40]!r}",
            path, line=first + 1, field="HIERARCHY",
        )
    for i, line in enumerate(lines):
        words = line.split()
        if words and words[0].upper() == "MOTION":
            return i + 1
    raise InputError(
        "no MOTION section: the file ends after the hierarchy (truncated or not a BVH file)",
        path, line=len(lines), field="MOTION",
    )


def _tokenize(lines: list[str]) -> _Tokens:
    items: list[tuple[str, int]] = []
    for number, line in enumerate(lines, start=1):
        for tok in line.replace("{", " { ").replace("}", " } ").split():
            items.append((tok, number))
    return _Tokens(items, last_line=len(lines))


def _parse_hierarchy(
    tokens: _Tokens, path: Path
) -> tuple[list[_JointDecl], list[int], list[np.ndarray]]:
    tok, line = tokens.next(path, "HIERARCHY")
    if tok.upper() != "HIERARCHY":  # pragma: no cover - _find_motion checked it
        raise InputError(f"expected HIERARCHY, found {tok!r}", path, line=line, field="HIERARCHY")
    tok, line = tokens.next(path, "ROOT")
    if tok.upper() != "ROOT":
        raise InputError(f"expected ROOT, found {tok!r}", path, line=line, field="ROOT")
    joints: list[_JointDecl] = []
    end_parents: list[int] = []
    end_offsets: list[np.ndarray] = []
    counter = [0]
    _parse_joint(tokens, path, -1, line, joints, end_parents, end_offsets, counter)
    extra = tokens.peek()
    if extra is not None:
        what = "a second ROOT (several skeletons in one file are not supported)" if (
            extra[0].upper() == "ROOT") else f"{extra[0]!r}"
        raise InputError(
            f"unexpected {what} after the root joint's closing brace",
            path, line=extra[1], field=extra[0],
        )
    return joints, end_parents, end_offsets


def _parse_joint(
    tokens: _Tokens,
    path: Path,
    parent: int,
    line: int,
    joints: list[_JointDecl],
    end_parents: list[int],
    end_offsets: list[np.ndarray],
    counter: list[int],
) -> None:
    # The name is the rest of the keyword's line (it may hold spaces or read like a keyword).
    name_parts: list[str] = []
    while True:
        nxt = tokens.peek()
        if nxt is None or nxt[1] != line or nxt[0] == "{":
            break
        name_parts.append(tokens.next(path, "joint name")[0])
    brace, brace_line = tokens.next(path, "{")
    if brace != "{":
        raise InputError(
            f"expected '{{' after the joint name, found {brace!r}", path, line=brace_line,
            field="JOINT",
        )
    if not name_parts:
        raise InputError("a joint without a name", path, line=line, field="JOINT")
    index = len(joints)
    decl = _JointDecl(" ".join(name_parts), parent, line)
    joints.append(decl)
    seen_channels = False
    while True:
        tok, tok_line = tokens.next(path, "}")
        key = tok.lower()
        if key == "}":
            break
        if key == "offset":
            if decl.offset is not None:
                raise InputError(f"joint {decl.name!r} has two OFFSET lines", path,
                                 line=tok_line, field="OFFSET")
            decl.offset = _read_offset(tokens, path, tok_line, decl.name)
        elif key == "channels":
            if seen_channels:
                raise InputError(f"joint {decl.name!r} has two CHANNELS lines", path,
                                 line=tok_line, field="CHANNELS")
            seen_channels = True
            decl.channels = _read_channels(tokens, path, tok_line, decl.name)
            decl.channel_order = counter[0]
            counter[0] += 1
        elif key == "joint":
            _parse_joint(tokens, path, index, tok_line, joints, end_parents, end_offsets, counter)
        elif key == "end":
            site, site_line = tokens.next(path, "Site")
            if site.lower() != "site":
                raise InputError(f"expected 'End Site', found 'End {site}'", path,
                                 line=site_line, field="End Site")
            brace, brace_line = tokens.next(path, "{")
            if brace != "{":
                raise InputError(f"expected '{{' after End Site, found {brace!r}", path,
                                 line=brace_line, field="End Site")
            off, off_line = tokens.next(path, "OFFSET")
            if off.lower() != "offset":
                raise InputError(f"expected OFFSET in End Site, found {off!r}", path,
                                 line=off_line, field="OFFSET")
            end_offsets.append(_read_offset(tokens, path, off_line, f"{decl.name} End Site"))
            end_parents.append(index)
            close, close_line = tokens.next(path, "}")
            if close != "}":
                raise InputError(f"expected '}}' closing End Site, found {close!r}", path,
                                 line=close_line, field="End Site")
        elif key == "root":
            raise InputError("ROOT inside a joint; use JOINT for children", path,
                             line=tok_line, field="ROOT")
        else:
            raise InputError(
                f"unexpected {tok!r} in joint {decl.name!r}; expected OFFSET, CHANNELS, JOINT, "
                "End Site or '}'", path, line=tok_line, field=tok,
            )
    if decl.offset is None:
        raise InputError(f"joint {decl.name!r} has no OFFSET", path, line=line, field="OFFSET")


def _read_offset(tokens: _Tokens, path: Path, line: int, owner: str) -> np.ndarray:
    values = []
    for axis in "xyz":
        tok, tok_line = tokens.next(path, f"OFFSET {axis}")
        try:
            values.append(float(tok))
        except ValueError:
            raise InputError(
                f"OFFSET of {owner!r} needs 3 numbers; {axis} is {tok!r}", path,
                line=tok_line, field="OFFSET",
            ) from None
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"OFFSET of {owner!r} is not finite: {values}", path, line=line,
                         field="OFFSET")
    return np.array(values)


def _read_channels(tokens: _Tokens, path: Path, line: int, owner: str) -> tuple[str, ...]:
    tok, tok_line = tokens.next(path, "channel count")
    try:
        count = int(tok)
    except ValueError:
        raise InputError(f"CHANNELS of {owner!r} needs a count, found {tok!r}", path,
                         line=tok_line, field="CHANNELS") from None
    if count < 0:
        raise InputError(f"CHANNELS of {owner!r} has a negative count {count}", path,
                         line=tok_line, field="CHANNELS")
    canonical = {n.lower(): n for n in _CHANNEL_NAMES}
    names: list[str] = []
    for _ in range(count):
        nxt = tokens.peek()
        if nxt is None or nxt[0].lower() in _KEYWORDS:
            raise InputError(
                f"CHANNELS of {owner!r} declares {count} channels but names {len(names)}",
                path, line=line, field="CHANNELS",
            )
        tok, tok_line = tokens.next(path, "channel name")
        name = canonical.get(tok.lower())
        if name is None:
            raise InputError(
                f"unknown channel name {tok!r} for joint {owner!r}; expected one of "
                f"{', '.join(_CHANNEL_NAMES)}", path, line=tok_line, field="CHANNELS",
            )
        if name in names:
            raise InputError(f"joint {owner!r} lists channel {name} twice", path,
                             line=tok_line, field="CHANNELS")
        names.append(name)
    return tuple(names)


def _parse_motion(
    lines: list[str], motion_line: int, joints: list[_JointDecl], path: Path
) -> tuple[float, np.ndarray, np.ndarray]:
    """Frame time, the (F, C) values in file column order and each frame's 1-based line."""
    rest = [(i + 1, lines[i]) for i in range(motion_line, len(lines)) if lines[i].strip()]
    if len(rest) < 2:
        raise InputError("MOTION needs 'Frames:' and 'Frame Time:' lines", path,
                         line=motion_line, field="Frames")
    frames_line, text = rest[0]
    match = _FRAMES_RE.match(text)
    if match is None:
        raise InputError(f"expected 'Frames: N', found {text.strip()[:40]!r}", path,
                         line=frames_line, field="Frames")
    try:
        n_frames = int(match.group(1))
    except ValueError:
        raise InputError(f"the frame count {match.group(1)!r} is not an integer", path,
                         line=frames_line, field="Frames") from None
    if n_frames < 0:
        raise InputError(f"negative frame count {n_frames}", path, line=frames_line,
                         field="Frames")
    time_line, text = rest[1]
    match = _FRAME_TIME_RE.match(text)
    if match is None:
        raise InputError(f"expected 'Frame Time: seconds', found {text.strip()[:40]!r}", path,
                         line=time_line, field="Frame Time")
    try:
        frame_time = float(match.group(1))
    except ValueError:
        frame_time = math.nan
    if not (math.isfinite(frame_time) and frame_time > 0.0):
        raise InputError(f"Frame Time must be a positive number of seconds, found "
                         f"{match.group(1)!r}", path, line=time_line, field="Frame Time")

    # Column names in file order (the order of the CHANNELS statements).
    ordered = sorted((j for j in joints if j.channels), key=lambda j: j.channel_order)
    names = [f"{j.name}.{ch}" for j in ordered for ch in j.channels]
    n_channels = len(names)
    data = rest[2:]
    if len(data) > n_frames:
        raise InputError(
            f"more frame lines than the {n_frames} that 'Frames:' declares (line "
            f"{frames_line}); the first extra one is here", path, line=data[n_frames][0],
            field="Frames",
        )
    frame_lines = np.array([number for number, _ in data], dtype=int)
    if n_channels and data and len(data) == n_frames:
        values = _all_numbers(data, n_channels)
        if values is not None:
            return frame_time, values, frame_lines
    # a line to blame: count and read every line
    rows: list[list[str]] = []
    for k, (number, text) in enumerate(data):
        words = text.split()
        if len(words) != n_channels:
            if len(words) < n_channels:
                fld = names[len(words)]
                what = f"missing values from {fld}"
            else:
                fld = "(extra values)"
                what = f"{len(words) - n_channels} values too many"
            raise InputError(
                f"frame {k + 1} has {len(words)} values, expected {n_channels} (one per "
                f"channel): {what}", path, line=number, field=fld,
            )
        rows.append(words)
    if len(rows) < n_frames:
        raise InputError(
            f"'Frames: {n_frames}' but the file holds {len(rows)} frame lines (truncated?)",
            path, line=frames_line, field="Frames",
        )
    if n_channels == 0:
        return frame_time, np.zeros((n_frames, 0)), frame_lines
    try:
        values = np.array(rows, dtype=float)
    except ValueError:
        for k, (number, _) in enumerate(data):
            for c, word in enumerate(rows[k]):
                try:
                    float(word)
                except ValueError:
                    raise InputError(
                        f"frame {k + 1}: value {word!r} is not a number", path,
                        line=number, field=names[c],
                    ) from None
        raise  # pragma: no cover - numpy and float() disagree on a token
    return frame_time, values.reshape(n_frames, n_channels), frame_lines


def _all_numbers(data: list[tuple[int, str]], n_channels: int) -> np.ndarray | None:
    """The frame lines' values (F, C) read at once, or None when a line is malformed.

    NumPy's text reader parses every number as ``float()`` does; any line with another count
    of values or a word that is not a number makes it fail, and the caller then reads line by
    line to name the line and the field.
    """
    try:
        values = np.loadtxt([text for _, text in data], dtype=float, comments=None, ndmin=2)
    except ValueError:
        return None
    return values if values.shape == (len(data), n_channels) else None


# --------------------------------------------------------------------------- writer
def write_bvh(
    path: str | os.PathLike[str],
    skeleton: BvhSkeleton,
    root_positions: npt.ArrayLike,
    local_rotations: npt.ArrayLike,
    frame_time: float,
    *,
    rotation_order: str | Sequence[str] | Mapping[str, str] = "ZXY",
    up: Up = "z",
    scale: float = 1.0,
    decimals: int | None = 6,
) -> Path:
    """Write a BVH file atomically (a temporary file beside ``path``, then ``os.replace``).

    The root gets 6 channels (``Xposition Yposition Zposition`` then its rotations), every
    other joint 3 rotation channels. Each joint's rotation is written as intrinsic Euler angles
    in ``rotation_order``: ``"ZXY"`` writes ``Zrotation Xrotation Yrotation`` with
    ``R = Rz @ Rx @ Ry``, the classic Biovision order, whose middle (X) axis is the one that
    reaches gimbal lock at +-90 deg. Angles are unwrapped over time (no 360 deg jumps), so a
    value may leave (-180, 180]. At gimbal lock the first angle is set to 0 and the last one
    carries the rest, so the written rotation is still exact.

    Args:
        path: The file to write.
        skeleton: Joint tree in metres, in the axes of our Z-up world (the axes the rotations
            and root positions are given in).
        root_positions: Root joint position per frame in our world, shape (F, 3) [m]. It is
            written as the root's position channels (absolute, replacing the root OFFSET).
        local_rotations: ``R_parent_joint`` per frame and joint, shape (F, J, 3, 3), in axes
            parallel to our world; the root's entry is ``R_world_root``.
        frame_time: Seconds per frame [s].
        rotation_order: One axis order for every joint, a sequence with one per joint, or a
            mapping from joint name to order (joints not named get ``"ZXY"``).
        up: The written file's up axis. ``"z"`` writes our world as it is; ``"y"`` turns
            everything (offsets, positions, rotations) by ``R_zup_yup.T`` into the usual Y-up
            BVH world, so that :func:`read_bvh` then ``world_poses(up="y")`` gives back our
            world.
        scale: Metres per written unit [m] (1 writes metres, 0.01 centimetres).
        decimals: Digits after the decimal point; ``None`` writes the shortest text that reads
            back to the same float (exact round trip, longer file).

    Returns:
        The path written.

    Raises:
        ValueError: Shapes that do not match the skeleton, non-finite values, a bad order.
    """
    target = Path(path)
    n_joints = skeleton.num_joints
    positions = np.asarray(root_positions, dtype=float)
    rotations = np.asarray(local_rotations, dtype=float)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise ValueError(f"root_positions must have shape (F, 3), got {positions.shape}")
    n_frames = positions.shape[0]
    if rotations.shape != (n_frames, n_joints, 3, 3):
        raise ValueError(
            f"local_rotations must have shape ({n_frames}, {n_joints}, 3, 3), got "
            f"{rotations.shape}"
        )
    if not (math.isfinite(frame_time) and frame_time > 0.0):
        raise ValueError(f"frame_time must be a positive number of seconds, got {frame_time}")
    if not (math.isfinite(scale) and scale > 0.0):
        raise ValueError(f"scale must be a positive number of metres per unit, got {scale}")
    if decimals is not None and decimals < 0:
        raise ValueError(f"decimals must be >= 0 or None, got {decimals}")
    bad = ~(np.all(np.isfinite(positions), axis=1)
            & np.all(np.isfinite(rotations), axis=(1, 2, 3)))
    if np.any(bad):
        first = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"{int(bad.sum())} frames hold NaN or infinite values (first: frame {first}); "
            "BVH cannot store them: fill or drop those frames first"
        )
    orders = _rotation_orders(rotation_order, skeleton.joint_names)
    A = rotation_world_file(up).T  # R_file_world
    offsets = skeleton.offsets @ A.T / scale
    end_offsets = skeleton.end_site_offsets @ A.T / scale
    file_positions = positions @ A.T / scale
    file_rotations = _conjugated(A, rotations)

    order = _depth_first(skeleton.parents)
    angles = np.stack([_euler_angles(orders[j], file_rotations[:, j]) for j in order], axis=1)
    # continuous over the frames (no wraps, no Euler branch jumps), every joint at once
    degrees = np.rad2deg(continuous_series(angles)).reshape(n_frames, 3 * len(order))
    values = np.concatenate([file_positions, degrees], axis=1)

    out: list[str] = ["HIERARCHY"]
    # Offsets are written once: 4 more digits (trailing zeros dropped) keep long chains exact.
    fmt_offset = _formatter(None if decimals is None else decimals + 4)
    _write_joint(out, skeleton, 0, 0, orders, offsets, end_offsets, fmt_offset)
    out.append("MOTION")
    out.append(f"Frames: {n_frames}")
    out.append(f"Frame Time: {frame_time!r}")
    atomic_write_bytes(target, ("\n".join(out) + "\n").encode() + _frame_text(values, decimals))
    return target


def _conjugated(A: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``A @ R @ A.T`` for a stack of matrices R (..., 3, 3), by indexing when A permutes axes.

    A permutation (the identity included) only reorders the entries: the products add exact
    zeros, which leave every value as it is but turn ``-0.0`` into ``0.0`` (``+ 0.0`` does
    the same), so the result is the product's, bit for bit, without a 3x3 product per matrix.
    """
    if np.isin(A, (0.0, 1.0)).all() and (A.sum(axis=0) == 1.0).all() \
            and (A.sum(axis=1) == 1.0).all():
        p = np.argmax(A, axis=1)  # (A @ R @ A.T)[i, j] = R[p[i], p[j]]
        if (p == np.arange(3)).all():  # the identity (a Z-up file): no reordering
            return R + 0.0
        return _permuted_entries(R, p)
    return A @ R @ A.T


def _permuted_entries(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``R[..., p, :][..., :, p] + 0.0`` bit for bit, a C-ordered new array, in half the time.

    Each of the 9 output entries is one strided copy (plus the exact ``+ 0.0``) of an input
    entry over the whole stack, instead of two fancy-indexing passes.
    """
    flat = np.ascontiguousarray(R).reshape(-1, 9)
    out = np.empty_like(flat)
    for k, source in enumerate((3 * p[:, None] + p[None, :]).ravel().tolist()):
        np.add(flat[:, source], 0.0, out=out[:, k])
    return out.reshape(R.shape)


#: Relative distance from half a unit of the last digit within which ``%`` decides the rounding
#: (far wider than the rounding of the threshold itself, about 1e-16).
_HALF_MARGIN = 1e-12


def _frame_text(values: np.ndarray, decimals: int | None) -> bytes:
    """One line per frame, each with its newline: fixed decimals (no ``-0.000``) or ``repr``.

    As UTF-8 bytes (ASCII), written as they are (no text layer).
    """
    if decimals is None:
        return "".join(" ".join(map(repr, row)) + "\n" for row in values.tolist()).encode()
    if not len(values):
        return b""
    number = f"%.{decimals}f"
    flat = np.array(values, dtype=float).reshape(-1)
    # Values that would print as -0.000 (negative and rounding to zero, or -0.0 itself) are
    # written as 0.000. Those clearly below half a unit of the last digit round to zero, those
    # clearly above do not; only the few within rounding of the half are formatted to decide.
    half = 0.5 * 10.0 ** -decimals
    negative = np.flatnonzero(np.signbit(flat) & (flat > -2.0 * half))
    size = -flat[negative]
    flat[negative[size < half * (1.0 - _HALF_MARGIN)]] = 0.0
    negative_zero = "-" + number % 0.0
    for i in negative[(size >= half * (1.0 - _HALF_MARGIN))
                      & (size <= half * (1.0 + _HALF_MARGIN))].tolist():
        if number % flat[i] == negative_zero:
            flat[i] = 0.0
    return format_rows_bytes(" ".join([number] * values.shape[1]) + "\n",
                             flat.reshape(values.shape))


def _depth_first(parents: np.ndarray) -> list[int]:
    """Joint indices in the order the hierarchy is written (depth first, children by index)."""
    order: list[int] = []
    stack = [0]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(int(c) for c in np.flatnonzero(parents == j)[::-1])
    return order


def _rotation_orders(
    rotation_order: str | Sequence[str] | Mapping[str, str], names: tuple[str, ...]
) -> list[str]:
    if isinstance(rotation_order, str):
        orders = [rotation_order] * len(names)
    elif isinstance(rotation_order, Mapping):
        unknown = set(rotation_order) - set(names)
        if unknown:
            raise ValueError(f"rotation_order names joints not in the skeleton: {sorted(unknown)}")
        orders = [rotation_order.get(n, "ZXY") for n in names]
    else:
        orders = list(rotation_order)
        if len(orders) != len(names):
            raise ValueError(f"rotation_order needs {len(names)} entries, got {len(orders)}")
    result = []
    for order in orders:
        up_order = str(order).upper()
        if len(up_order) != 3 or set(up_order) != {"X", "Y", "Z"}:
            raise ValueError(f"rotation order must be 3 distinct axes of XYZ, got {order!r}")
        result.append(up_order)
    return result


def _euler_angles(order: str, R: np.ndarray) -> np.ndarray:
    """Intrinsic angles [rad] in ``order`` with ``R = R_a @ R_b @ R_c``, exact at gimbal lock.

    Args:
        order: Three distinct axes, e.g. ``"ZXY"``.
        R: Rotations, shape (F, 3, 3).

    Returns:
        Angles (F, 3) [rad], each frame's principal triple.
    """
    angles = matrix_to_euler(order, R)
    i, j, k = ("XYZ".index(c) for c in order)
    parity = 1.0 if (j - i) % 3 == 1 else -1.0
    # The middle angle from atan2 is accurate everywhere (arcsin is not near +-90 deg).
    cos_middle = np.hypot(R[:, j, k], R[:, k, k])
    angles[:, 1] = np.arctan2(parity * R[:, i, k], cos_middle)
    locked = cos_middle < 1e-8
    if np.any(locked):
        # The outer angles are coupled: set the first to 0, then R_c(last) = R_b(middle)^T R.
        rest = np.swapaxes(axis_rotation(order[1], angles[locked, 1]), -1, -2) @ R[locked]
        p, q = (k + 1) % 3, (k + 2) % 3
        angles[locked, 0] = 0.0
        angles[locked, 2] = np.arctan2(rest[:, q, p], rest[:, p, p])
    return angles


def _formatter(decimals: int | None) -> Callable[[float], str]:
    """Offset formatting: ``decimals`` digits without trailing zeros, or exact ``repr`` text."""
    if decimals is None:
        return repr

    def fixed(value: float) -> str:
        text = f"{value:.{decimals}f}"
        if "." in text:
            text = text.rstrip("0").rstrip(".")
        return "0" if text in ("-0", "") else text

    return fixed


def _write_joint(
    out: list[str],
    skeleton: BvhSkeleton,
    j: int,
    depth: int,
    orders: list[str],
    offsets: np.ndarray,
    end_offsets: np.ndarray,
    fmt: Callable[[float], str],
) -> None:
    pad = "\t" * depth
    keyword = "ROOT" if j == 0 else "JOINT"
    out.append(f"{pad}{keyword} {skeleton.joint_names[j]}")
    out.append(f"{pad}{{")
    out.append(f"{pad}\tOFFSET {' '.join(fmt(float(v)) for v in offsets[j])}")
    rot = " ".join(f"{axis}rotation" for axis in orders[j])
    if j == 0:
        out.append(f"{pad}\tCHANNELS 6 Xposition Yposition Zposition {rot}")
    else:
        out.append(f"{pad}\tCHANNELS 3 {rot}")
    for child in np.flatnonzero(skeleton.parents == j):
        _write_joint(out, skeleton, int(child), depth + 1, orders, offsets, end_offsets, fmt)
    for e in np.flatnonzero(skeleton.end_site_parents == j):
        out.append(f"{pad}\tEnd Site")
        out.append(f"{pad}\t{{")
        out.append(f"{pad}\t\tOFFSET {' '.join(fmt(float(v)) for v in end_offsets[e])}")
        out.append(f"{pad}\t}}")
    out.append(f"{pad}}}")


