"""A robot's visual meshes from its URDF, fixed to its links, for ``ikfusion view``.

Pinocchio's ``buildGeomFromUrdf`` reads the URDF's ``<visual>`` elements and resolves their
mesh files: ``package://<package>/<path>`` against the package directories given (the ``share``
folder of ``example-robot-data`` when installed, then the folders holding the URDF), other
paths relative to the URDF. Each mesh is placed in the frame of the link that carries it;
the viewer logs a mesh once and moves only its link frame per frame.

Files the viewer reads itself (STL, OBJ, glTF) are kept as files; the others (COLLADA ``.dae``,
as iCub and Romeo ship) are handed over as triangles read by Pinocchio's mesh loader, and the
URDF's boxes, cylinders and spheres (Talos's wrist sensors and IMU) as tessellated triangles.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import InputError
from .scene import MeshPart

#: Mesh files that Rerun's ``Asset3D`` reads as they are.
VIEWER_MESH_FORMATS = frozenset({".stl", ".obj", ".glb", ".gltf"})

#: The colour Pinocchio gives a visual whose URDF names no material.
_NO_MATERIAL = (0.0, 0.0, 0.0, 1.0)


def package_dirs(urdf: Path) -> list[str]:
    """Folders in which ``package://`` mesh paths of ``urdf`` are looked up, in order."""
    from ..retarget.robot_config import example_robot_data_dir, robots_installed

    dirs = [str(example_robot_data_dir().parent.parent)] if robots_installed() else []
    return dirs + [str(p) for p in Path(urdf).resolve().parents]


def visual_meshes(model: pin.Model, urdf: Path) -> tuple[list[int], list[MeshPart], int]:
    """The URDF's visual meshes on the links of ``model`` (built from the same URDF).

    Args:
        model: The robot's Pinocchio model (possibly reduced: locked links stay frames).
        urdf: Its URDF file.

    Returns:
        The Pinocchio frame ids of the links that carry meshes, the meshes (``MeshPart.link``
        indexes the first list; boxes, cylinders and spheres come as triangles), and how many
        visuals were left out because they are shapes of another kind.

    Raises:
        InputError: The URDF's visuals cannot be read, e.g. a mesh file is missing.
    """
    try:
        geometry = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.VISUAL,
                                         package_dirs=package_dirs(urdf))
    except (RuntimeError, ValueError, OSError) as err:
        raise InputError(f"cannot read the robot's visual meshes: {err}", path=urdf) from None
    frames: list[int] = []
    parts: list[MeshPart] = []
    primitives = 0
    for visual in geometry.geometryObjects:
        file = Path(visual.meshPath)
        shape = None if file.is_file() else primitive_triangles(visual.geometry)
        if not file.is_file() and shape is None:
            primitives += 1
            continue
        if visual.parentFrame not in frames:
            frames.append(visual.parentFrame)
        T_link_mesh = model.frames[visual.parentFrame].placement.inverse() * visual.placement
        rgba = tuple(float(c) for c in visual.meshColor)
        common = {"name": visual.name, "link": frames.index(visual.parentFrame), "file": file,
                  "T_link_mesh": T_link_mesh.homogeneous.copy(),
                  "rgba": None if np.allclose(rgba, _NO_MATERIAL) else rgba}
        if shape is None and file.suffix.lower() in VIEWER_MESH_FORMATS:
            parts.append(MeshPart(scale=np.asarray(visual.meshScale, dtype=float).copy(),
                                  **common))
        else:  # Pinocchio's loader already scaled the vertices
            vertices, triangles = shape or mesh_triangles(visual.geometry)
            parts.append(MeshPart(scale=np.ones(3), vertices=vertices, triangles=triangles,
                                  **common))
    return frames, parts, primitives


def mesh_triangles(mesh: object) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) [m] and triangles (T, 3) of a mesh loaded by Pinocchio (a BVH model)."""
    vertices = np.asarray(mesh.vertices(), dtype=np.float32)  # type: ignore[attr-defined]
    count = int(mesh.num_tris)  # type: ignore[attr-defined]
    triangles = np.empty((count, 3), dtype=np.uint32)
    for i in range(count):
        corner = mesh.tri_indices(i)  # type: ignore[attr-defined]
        triangles[i] = (corner[0], corner[1], corner[2])
    return vertices, triangles


def primitive_triangles(shape: object, sides: int = 24) -> tuple[np.ndarray, np.ndarray] | None:
    """Triangles of a URDF primitive as Pinocchio holds it, centred on its frame.

    A box (``halfSide`` [m]), a cylinder along Z (``radius``, ``halfLength`` [m]) or a sphere
    (``radius`` [m]), the round ones with ``sides`` facets around; None for other shapes.
    """
    kind = type(shape).__name__
    if kind == "Box":
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
                 (1, 5, 7, 3)]  # -x, +x, -y, +y, -z, +z; counter-clockwise seen from outside
        quads = np.array(faces)
        triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
        vertices = corners * np.asarray(shape.halfSide)  # type: ignore[attr-defined]
        return vertices.astype(np.float32), triangles.astype(np.uint32)
    angle = 2 * np.pi * np.arange(sides) / sides
    ring = np.column_stack([np.cos(angle), np.sin(angle)])
    if kind == "Cylinder":
        r, h = float(shape.radius), float(shape.halfLength)  # type: ignore[attr-defined]
        rim = np.concatenate([np.column_stack([r * ring, np.full(sides, z)]) for z in (-h, h)])
        vertices = np.concatenate([rim, [[0, 0, -h], [0, 0, h]]])
        i = np.arange(sides)
        j = (i + 1) % sides
        triangles = np.concatenate([
            np.column_stack([i, j, sides + j]), np.column_stack([i, sides + j, sides + i]),
            np.column_stack([np.full(sides, 2 * sides), j, i]),
            np.column_stack([np.full(sides, 2 * sides + 1), sides + i, sides + j])])
        return vertices.astype(np.float32), triangles.astype(np.uint32)
    if kind == "Sphere":
        r = float(shape.radius)  # type: ignore[attr-defined]
        rows = sides // 2
        polar = np.pi * np.arange(1, rows) / rows
        bands = [np.column_stack([r * np.sin(t) * ring, np.full(sides, r * np.cos(t))])
                 for t in polar]
        vertices = np.concatenate([[[0, 0, r]], *bands, [[0, 0, -r]]])
        i = np.arange(sides)
        j = (i + 1) % sides
        tris = [np.column_stack([np.zeros(sides, int), 1 + i, 1 + j])]
        for b in range(rows - 2):
            top, low = 1 + b * sides, 1 + (b + 1) * sides
            tris += [np.column_stack([top + i, low + i, low + j]),
                     np.column_stack([top + i, low + j, top + j])]
        last = len(vertices) - 1
        tris.append(np.column_stack([np.full(sides, last), last - sides + j, last - sides + i]))
        return vertices.astype(np.float32), np.concatenate(tris).astype(np.uint32)
    return None


def link_poses(data: pin.Data, frames: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """Positions (L, 3) [m] and rotations (L, 3, 3) ``R_world_link`` of the given frames.

    ``data`` must hold the frame placements (after ``pin.framesForwardKinematics``).
    """
    placements = [data.oMf[f] for f in frames]
    return (np.array([T.translation for T in placements]).reshape(-1, 3),
            np.array([T.rotation for T in placements]).reshape(-1, 3, 3))
