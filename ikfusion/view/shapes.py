"""Solid bodies in the 3-D view: a robot's URDF meshes on its links, a human's capsules.

Entities below an actor's ``world/<actor>`` (world frame Z up, metres):

- ``links/<link>``: the frame of a robot link, one transform per frame;
  ``links/<link>/<visual>``: its mesh with its fixed placement in the link frame, logged once
  (static), so a recording holds each mesh a single time whatever its length;
- ``capsules``: one capsule around each bone (from a segment origin to its child's origin, or
  to the tip of a leaf segment) per frame, its radius a fixed share of the bone's length.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

import numpy as np

from .rerun_lib import entity_name, require_rerun
from .scene import LinkMeshes, MeshPart

#: Capsule radius / bone length per bone of the 23-segment model, keyed ``start>end`` with the
#: side dropped (``UpperLeg>LowerLeg`` is the thigh; a leaf's bone ends at its tip site, or at
#: ``tip``). Chosen so that a 1.75 m subject gets a trunk of radius 0.12 m, pelvis 0.09 m,
#: thigh 0.07 m, shank 0.05 m, upper arm 0.045 m, forearm 0.035 m and a head of 0.09 m; short
#: spine bones hence get ratios above 1.
CAPSULE_RADIUS_RATIO: dict[str, float] = {
    "Pelvis>L5": 1.2, "L5>L3": 1.2, "L3>T12": 1.2, "T12>T8": 1.2, "T8>Neck": 0.7,
    "Neck>Head": 0.4, "Head>HeadTop": 0.57, "Head>tip": 0.57,
    "T8>Shoulder": 0.4, "Shoulder>UpperArm": 0.26, "UpperArm>ForeArm": 0.14,
    "ForeArm>Hand": 0.14, "Hand>tip": 0.38,
    "Pelvis>UpperLeg": 1.0, "UpperLeg>LowerLeg": 0.16, "LowerLeg>Foot": 0.12,
    "Foot>Toe": 0.28, "Toe>Toe": 0.39, "Toe>tip": 0.39,
}

#: Ratio for bones of other skeletons (a BVH's own joints).
OTHER_BONE_RATIO = 0.15

#: Smallest and largest capsule radius drawn [m].
RADIUS_RANGE = (0.008, 0.15)


def bone_key(start: str, end: str) -> str:
    """Key of a bone in :data:`CAPSULE_RADIUS_RATIO`: ``start>end`` without Left/Right."""
    def side_free(name: str) -> str:
        return re.sub(r"^(Left|Right)", "", name)
    return f"{side_free(start)}>{side_free(end)}"


def capsule_radii(bones: Sequence[tuple[str, str]], lengths: np.ndarray) -> np.ndarray:
    """Radius [m] of the capsule around each bone.

    Args:
        bones: (start segment, end segment or tip site) of each bone.
        lengths: (B,) length of each bone [m] (NaN when unknown).

    Returns:
        (B,) radii: the bone's share of its length, within :data:`RADIUS_RANGE`.
    """
    ratio = np.array([CAPSULE_RADIUS_RATIO.get(bone_key(a, b), OTHER_BONE_RATIO)
                      for a, b in bones])
    radii = np.nan_to_num(ratio * np.asarray(lengths, dtype=float), nan=RADIUS_RANGE[0])
    return np.clip(radii, *RADIUS_RANGE)


def capsule_poses(strips: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pose and length of capsules along bones; a capsule's axis is its local +Z.

    Args:
        strips: (..., 2, 3) bone start and end points [m].

    Returns:
        Start points (..., 3) [m], quaternions (..., 4) in (x, y, z, w) order turning +Z onto
        the bone, lengths (...) [m].
    """
    start = strips[..., 0, :]
    axis = strips[..., 1, :] - start
    length = np.linalg.norm(axis, axis=-1)
    d = axis / np.where(length > 1e-9, length, 1.0)[..., None]
    d[length <= 1e-9] = (0.0, 0.0, 1.0)
    # half-way quaternion between +Z and d: (z x d, 1 + z . d), normalised
    quat_xyzw = np.stack([-d[..., 1], d[..., 0], np.zeros_like(d[..., 0]), 1.0 + d[..., 2]], -1)
    opposite = quat_xyzw[..., 3] < 1e-9  # d = -Z: half a turn about X
    quat_xyzw[opposite] = (1.0, 0.0, 0.0, 0.0)
    quat_xyzw /= np.linalg.norm(quat_xyzw, axis=-1, keepdims=True)
    return start, quat_xyzw, length


def log_capsules(rec: Any, path: str, index: list[Any], strips: np.ndarray,
                 bones: Sequence[tuple[str, str]], color: tuple[int, ...],
                 styles: bool = True) -> None:
    """Capsules around the bones at every frame (sent as columns).

    Args:
        rec: The ``rerun.RecordingStream``.
        path: Entity path.
        index: The time column of the frames.
        strips: (N, B, 2, 3) bones per frame [m].
        bones: (start, end) names of the B bones.
        color: RGB(A) of the capsules.
        styles: Also log the capsules' radii (from these frames' median bone lengths),
            colour and labels (static); a later batch of the same body keeps them.
    """
    rr = require_rerun()
    n, b = strips.shape[:2]
    start, quat_xyzw, length = capsule_poses(strips)
    if styles:
        radii = capsule_radii(bones, np.nanmedian(np.where(np.isfinite(length), length, np.nan),
                                                  axis=0) if n else np.zeros(b))
        rec.log(path, rr.Capsules3D.from_fields(radii=radii, colors=color,
                                                labels=[f"{a}>{e}" for a, e in bones],
                                                show_labels=False), static=True)
    rec.send_columns(path, indexes=index, columns=rr.Capsules3D.columns(
        translations=start.reshape(-1, 3), quaternions=quat_xyzw.reshape(-1, 4),
        lengths=length.reshape(-1)).partition(lengths=np.full(n, b)))


def log_link_meshes(rec: Any, base: str, index: list[Any], meshes: LinkMeshes,
                    color: tuple[int, ...]) -> None:
    """A robot's meshes once (static) under its links, and each link's pose per frame.

    Args:
        rec: The ``rerun.RecordingStream``.
        base: The actor's entity path.
        index: The time column of the frames.
        meshes: Links, their poses and their meshes.
        color: RGB(A) for meshes whose URDF gives no material colour.
    """
    rr = require_rerun()
    links = [f"{base}/links/{entity_name(name)}" for name in meshes.link_names]
    for path, p, quat_wxyz in zip(links, np.swapaxes(meshes.p_world_link, 0, 1),
                                  np.swapaxes(meshes.quat_wxyz_world_link, 0, 1)):
        rec.send_columns(path, indexes=index, columns=rr.Transform3D.columns(
            translation=p, quaternion=quat_wxyz[:, [1, 2, 3, 0]]))
    for part in meshes.parts:
        path = f"{links[part.link]}/{entity_name(part.name)}"
        T = part.T_link_mesh
        rec.log(path, rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3] @ np.diag(part.scale)),
                static=True)
        rec.log(path, mesh_archetype(part, color), static=True)


def mesh_archetype(part: MeshPart, color: tuple[int, ...]) -> Any:
    """``Asset3D`` of a mesh file Rerun reads, else ``Mesh3D`` of its triangles."""
    rr = require_rerun()
    rgba = tuple(int(round(255 * c)) for c in part.rgba) if part.rgba else tuple(color[:3])
    if part.vertices is None or part.triangles is None:
        return rr.Asset3D(path=part.file, albedo_factor=rgba)
    return rr.Mesh3D(vertex_positions=part.vertices, triangle_indices=part.triangles,
                     vertex_normals=vertex_normals(part.vertices, part.triangles),
                     albedo_factor=rgba)


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unit normals (V, 3) of a triangle mesh's vertices: the area-weighted face normals."""
    v = np.asarray(vertices, dtype=float)
    t = np.asarray(triangles, dtype=np.int64)
    face = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    normals = np.zeros_like(v)
    for corner in range(3):
        np.add.at(normals, t[:, corner], face)
    norm = np.linalg.norm(normals, axis=1, keepdims=True)
    return (normals / np.where(norm > 0, norm, 1.0)).astype(np.float32)
