"""Convex decomposition of an imported mesh (CoACD), and what follows from the parts.

* :func:`decompose`: CoACD (Wei et al., "Approximate Convex Decomposition for 3D Meshes with
  Collision-Aware Concavity and Tree Search", SIGGRAPH 2022) with a fixed seed, so the same
  mesh and settings give the same parts; each part is reduced to its hull's vertices, and a
  hull with more than :data:`MAX_HULL_VERTICES` is simplified (:func:`simplify_hull`: both
  engines' cost per draw grows with the parts' faces, and CoACD's hulls of a smooth mesh can
  have thousands).
* :func:`mass_properties`: centre of mass and r_max of the parts' union. Uniform density;
  the centroid is the volume-weighted mean of the parts' centroids (CoACD cuts the mesh into
  pieces with disjoint interiors before taking hulls, so overlaps are small), which is
  defined whether or not the source mesh is watertight. r_max is the largest distance from
  the centre of mass to a part vertex: the farthest point of a union of convex parts is a
  vertex of one of them, so this is GraspIt's maxRadius of the union (docs/conventions.md).

How far the parts are from the source mesh is measured by :mod:`kinegrasp_env.world.deviation`.
"""

from __future__ import annotations

import logging

import numpy as np
import trimesh
from scipy.spatial import ConvexHull, QhullError

log = logging.getLogger(__name__)

#: CoACD's concavity threshold (its own default): smaller = more parts, closer to the mesh.
DEFAULT_THRESHOLD = 0.05
#: Most parts kept (CoACD merges beyond it); each part costs both engines time per draw.
DEFAULT_MAX_PARTS = 32
#: CoACD's random seed: fixed so that an import is reproducible.
COACD_SEED = 0
#: Parts thinner than this fraction of the object's size are dropped (slivers), relative.
SLIVER = 1e-6
#: Most vertices kept per part (the built-in objects' parts have at most 96).
MAX_HULL_VERTICES = 96
#: A simplified hull stops growing once every dropped vertex is this close to it (metres).
HULL_TOLERANCE = 2e-4


def decompose(mesh: trimesh.Trimesh, threshold: float = DEFAULT_THRESHOLD,
              max_parts: int = DEFAULT_MAX_PARTS, seed: int = COACD_SEED) -> list[np.ndarray]:
    """Convex parts of ``mesh`` (object frame, metres), each a (V_i, 3) array of its hull's
    vertices (at most :data:`MAX_HULL_VERTICES`). ``max_parts`` <= 0: no limit.
    Deterministic for a given mesh and settings."""
    import coacd

    if hasattr(coacd, "set_log_level"):
        coacd.set_log_level("error")
    source = coacd.Mesh(np.asarray(mesh.vertices, dtype=np.float64),
                        np.asarray(mesh.faces, dtype=np.int32))
    pieces = coacd.run_coacd(source, threshold=float(threshold),
                             max_convex_hull=int(max_parts) if max_parts > 0 else -1,
                             seed=int(seed))
    size = float(np.max(mesh.extents))
    parts = []
    for vertices, _ in pieces:
        hull = hull_vertices(np.asarray(vertices, dtype=float), size * SLIVER)
        if hull is not None:
            parts.append(simplify_hull(hull)[0])
    log.info("CoACD: %d parts (%d dropped as slivers)", len(parts), len(pieces) - len(parts))
    return parts


def hull_vertices(points: np.ndarray, thickness: float) -> np.ndarray | None:
    """The vertices (V, 3) of the convex hull of ``points``, or None when the hull is
    thinner than ``thickness`` (metres) in some direction (flat or degenerate)."""
    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError):
        return None
    eq = hull.equations
    # the hull's width across each face normal: a flat hull is thin across its big faces
    widths = -(hull.points[hull.vertices] @ eq[:, :3].T + eq[:, 3]).min(axis=0)
    if float(widths.min()) < thickness:
        return None
    return np.ascontiguousarray(hull.points[hull.vertices], dtype=float)


def simplify_hull(vertices: np.ndarray, cap: int = MAX_HULL_VERTICES,
                  tolerance: float = HULL_TOLERANCE) -> tuple[np.ndarray, float]:
    """At most ``cap`` of a convex hull's vertices (V, 3) whose hull is close to it.

    Greedy: from four extreme vertices, add the vertex farthest outside the hull of those
    kept until none is farther than ``tolerance`` or ``cap`` are kept. The result lies inside
    the original hull, and the returned error (metres) is exactly how far the original
    reaches beyond it (the farthest point of a polytope from a convex set is a vertex).
    """
    if len(vertices) <= cap:
        return vertices, 0.0
    keep = list(extreme_vertices(vertices))
    while True:
        hull = ConvexHull(vertices[keep])
        eq = hull.equations
        outside = np.max(vertices @ eq[:, :3].T + eq[:, 3], axis=1)
        far = int(np.argmax(outside))
        if len(keep) >= cap or outside[far] <= tolerance:
            return (np.ascontiguousarray(vertices[keep][hull.vertices]),
                    float(max(outside[far], 0.0)))
        keep.append(far)


def extreme_vertices(points: np.ndarray) -> tuple[int, int, int, int]:
    """Indices of four points spanning a large tetrahedron: the farthest from the centroid,
    the farthest from that, the farthest from their line, the farthest from their plane."""
    a = int(np.argmax(np.linalg.norm(points - points.mean(axis=0), axis=1)))
    b = int(np.argmax(np.linalg.norm(points - points[a], axis=1)))
    axis = (points[b] - points[a]) / np.linalg.norm(points[b] - points[a])
    rel = points - points[a]
    c = int(np.argmax(np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)))
    normal = np.cross(points[b] - points[a], points[c] - points[a])
    d = int(np.argmax(np.abs(rel @ normal)))
    return a, b, c, d


def hull_volume_centroid(vertices: np.ndarray) -> tuple[float, np.ndarray]:
    """Volume (m^3) and centroid (3,) of the convex hull of ``vertices`` (V, 3): a fan of
    tetrahedra from an interior point over the hull's triangles."""
    hull = ConvexHull(vertices)
    apex = vertices.mean(axis=0)
    tri = hull.points[hull.simplices]  # (T, 3, 3)
    volumes = np.abs(np.einsum("tk,tk->t", tri[:, 0] - apex,
                               np.cross(tri[:, 1] - apex, tri[:, 2] - apex))) / 6.0
    centroids = (tri.sum(axis=1) + apex) / 4.0
    volume = float(volumes.sum())
    return volume, (volumes[:, None] * centroids).sum(axis=0) / volume


def mass_properties(parts: list[np.ndarray]) -> tuple[np.ndarray, float, float]:
    """(centre of mass (3,), r_max (metres), volume (m^3)) of the union of convex parts
    (uniform density; see the module docstring)."""
    stats = [hull_volume_centroid(p) for p in parts]
    volumes = np.array([v for v, _ in stats])
    centroids = np.array([c for _, c in stats])
    com = (volumes[:, None] * centroids).sum(axis=0) / volumes.sum()
    r_max = max(float(np.linalg.norm(p - com, axis=1).max()) for p in parts)
    return com, r_max, float(volumes.sum())
