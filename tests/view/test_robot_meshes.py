"""A robot's URDF visuals for the viewer: primitive shapes turned into closed, outward meshes."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.view.robot_meshes import primitive_triangles

coal = pytest.importorskip("coal", reason="Pinocchio's geometry library coal is not installed")


def _volume(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """Signed volume [m^3] enclosed by a triangle mesh (positive when its faces point out)."""
    a, b, c = (vertices[triangles[:, k]].astype(float) for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _closed(triangles: np.ndarray) -> bool:
    """Every edge is shared by exactly two faces, once in each direction."""
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    directed = {tuple(e) for e in edges.tolist()}
    return len(directed) == len(edges) and all((b, a) in directed for a, b in directed)


@pytest.mark.parametrize(("shape", "volume", "rtol"), [
    (coal.Box(0.1, 0.2, 0.3), 0.1 * 0.2 * 0.3, 1e-6),
    (coal.Cylinder(0.04, 0.1), 0.5 * 24 * 0.04**2 * np.sin(2 * np.pi / 24) * 0.1, 1e-5),
    (coal.Sphere(0.05), 4 / 3 * np.pi * 0.05**3, 0.03),
])
def test_urdf_primitives_become_closed_meshes_facing_out(shape: object, volume: float,
                                                         rtol: float) -> None:
    found = primitive_triangles(shape)
    assert found is not None
    vertices, triangles = found
    assert _closed(triangles)
    assert _volume(vertices, triangles) == pytest.approx(volume, rel=rtol)
