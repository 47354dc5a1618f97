"""Geometry for the report's 3-D views: points moved by a pose, friction cones as meshes.

Lengths in metres; poses are (4, 4) homogeneous transforms.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.quality.wrenches import friction_cone_edges


def transform(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Points (..., 3) mapped by a (4, 4) pose."""
    return np.asarray(points) @ pose[:3, :3].T + pose[:3, 3]


def cone_meshes(points: np.ndarray, normals: np.ndarray, friction: float, num_edges: int,
                height: float) -> tuple[np.ndarray, np.ndarray]:
    """Linearized friction cones as one triangle mesh, drawn outside the object.

    Each cone has its apex at a contact point p (k, 3) and its ``num_edges`` edges along
    -f_j (the mirror of the cone edges f_j of docs/conventions.md, so the cone stands on the
    surface instead of inside the object), scaled so its axis is ``height`` metres long.

    Returns:
        vertices (k (m + 1), 3) and faces (k m, 3).
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    edges = friction_cone_edges(np.asarray(normals, dtype=float).reshape(-1, 3), friction,
                                num_edges)
    m = num_edges
    ring = points[:, None, :] - height * edges  # normal component of f_j is 1
    vertices = np.concatenate([points[:, None, :], ring], axis=1).reshape(-1, 3)
    base = (m + 1) * np.arange(len(points))[:, None]
    j = np.arange(m)
    faces = np.stack([np.zeros(m, int), 1 + j, 1 + (j + 1) % m], axis=1)
    return vertices, (base[:, None, :] + faces[None]).reshape(-1, 3)
