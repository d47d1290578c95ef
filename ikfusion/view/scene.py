"""The neutral in-memory scene that ``ikfusion view`` draws, independent of any drawing library.

Everything is in the world frame (right-handed, Z up) in metres and seconds; joint angles are
in degrees as in ``joint_angles.csv``. Quaternions are scalar first (w, x, y, z) and give
``R_world_segment``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class MeshPart:
    """One visual mesh of a robot link, as its URDF places it.

    Attributes:
        name: Name of the visual (the URDF's link name and a number, e.g. ``pelvis_0``).
        link: Index of the link it moves with in :attr:`LinkMeshes.link_names`.
        file: The mesh file (resolved from ``package://`` or relative paths).
        T_link_mesh: (4, 4) pose of the mesh frame in the link frame [m].
        scale: (3,) scale of the mesh file's coordinates (the URDF's ``scale``).
        rgba: Colour of the URDF material (0-1 each), or None when it gives none.
        vertices: (V, 3) vertices in the mesh frame, scaled [m], for files the viewer cannot
            read itself (COLLADA); None when ``file`` is drawn as it is.
        triangles: (T, 3) vertex indices of ``vertices``, or None.
    """

    name: str
    link: int
    file: Path
    T_link_mesh: np.ndarray
    scale: np.ndarray
    rgba: tuple[float, float, float, float] | None = None
    vertices: np.ndarray | None = None
    triangles: np.ndarray | None = None


@dataclass(frozen=True)
class LinkMeshes:
    """The meshes of a robot and the pose of each of its links at every frame.

    Attributes:
        link_names: The L links that carry a mesh (URDF link names).
        p_world_link: (N, L, 3) link frame origins [m].
        quat_wxyz_world_link: (N, L, 4) link orientations ``R_world_link``.
        parts: The meshes, each fixed to one link.
    """

    link_names: tuple[str, ...]
    p_world_link: np.ndarray
    quat_wxyz_world_link: np.ndarray
    parts: tuple[MeshPart, ...]


@dataclass(frozen=True)
class Actor:
    """One moving body: a tree of segments, with optional sites, contacts and curves.

    Attributes:
        name: Label shown in the viewer (``subject``, ``truth``, a folder name, ...).
        time: (N,) frame times [s].
        segment_names: The S segments (or BVH joints), parents before children.
        segment_parents: (S,) index of each segment's parent in ``segment_names``, -1 at the root.
        p_world_segment: (N, S, 3) segment origins (proximal joints) [m].
        quat_wxyz_world_segment: (N, S, 4) segment orientations ``R_world_segment``, or None
            when the source has no segment frames.
        segment_tips: Site to draw the bone of a leaf segment to, e.g. ``{"Head": "HeadTop"}``.
        site_names: The M sites (tags, contact points, sensor sites).
        p_world_site: (N, M, 3) site positions [m].
        contact_names: The k contact points (each also a site when its position is known).
        contacts: (N, k) bool contact phases.
        angle_names: Joint-angle columns, e.g. ``jRightKnee_flex``.
        joint_angles_deg: (N, A) joint angles [deg].
        solve_time_ms: (N,) solve time per frame [ms], or None.
        ghost: Drawn faint (a reference such as the truth), not as the main body.
        meshes: A robot's link meshes and link poses; None draws the body as capsules
            around its bones (ghosts as bones only).
        notes: Facts about how the actor is drawn (e.g. why a robot has no meshes).
    """

    name: str
    time: np.ndarray
    segment_names: tuple[str, ...]
    segment_parents: np.ndarray
    p_world_segment: np.ndarray
    quat_wxyz_world_segment: np.ndarray | None = None
    segment_tips: dict[str, str] = field(default_factory=dict)
    site_names: tuple[str, ...] = ()
    p_world_site: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3)))
    contact_names: tuple[str, ...] = ()
    contacts: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=bool))
    angle_names: tuple[str, ...] = ()
    joint_angles_deg: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    solve_time_ms: np.ndarray | None = None
    ghost: bool = False
    meshes: LinkMeshes | None = None
    notes: tuple[str, ...] = ()

    @property
    def frames(self) -> int:
        """Number of frames N."""
        return len(self.time)

    @property
    def duration(self) -> float:
        """Time from the first to the last frame [s]."""
        return float(self.time[-1] - self.time[0]) if self.frames else 0.0

    def site_index(self, name: str) -> int | None:
        """Column of a site in ``p_world_site``, or None when the actor has no such site."""
        return self.site_names.index(name) if name in self.site_names else None

    def children(self, segment: int) -> list[int]:
        """Indices of the segments whose parent is ``segment``."""
        return [int(i) for i in np.flatnonzero(self.segment_parents == segment)]


@dataclass(frozen=True)
class Readers:
    """UWB readers (anchors) of the capture.

    Attributes:
        ids: Reader ids.
        p_world_reader: (R, 3) antenna positions [m].
    """

    ids: tuple[str, ...]
    p_world_reader: np.ndarray


@dataclass(frozen=True)
class Scene:
    """Everything one ``ikfusion view`` shows on one timeline.

    Attributes:
        actors: The bodies, drawn together (ghosts faint).
        readers: UWB readers, or None.
        tag_sites: Sites whose paths are drawn (UWB tags), when an actor has them.
        source: What was loaded (for titles and messages).
        notes: Short facts shown beside the view (summary values, warnings).
    """

    actors: tuple[Actor, ...]
    readers: Readers | None = None
    tag_sites: tuple[str, ...] = ("HeadTop", "LeftFootTop", "RightFootTop")
    source: str = ""
    notes: tuple[str, ...] = ()

    @property
    def main(self) -> Actor:
        """The first actor that is not a ghost (the first one when all are)."""
        return next((a for a in self.actors if not a.ghost), self.actors[0])

    @property
    def frames(self) -> int:
        """Frames of the main actor."""
        return self.main.frames

    @property
    def duration(self) -> float:
        """Duration of the main actor [s]."""
        return self.main.duration
