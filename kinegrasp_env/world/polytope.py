"""Exact closest points on a convex polytope (one convex part of an object).

A part is given by its vertices; its face planes and true edges (between faces that are not
coplanar) come from its convex hull. For a query point x with plane values
s_i = n_i . x + d_i (outward unit normals):

- inside (max s_i <= 0): the nearest boundary point is the projection on the plane of the
  largest s_i, at signed distance max s_i <= 0;
- outside: every s_i is a lower bound of the distance, so if the projection on the plane of
  the largest s_i lies in the part it is the closest point; otherwise the closest point is
  on an edge (or a vertex), found by the exact point-to-segment distance to every edge.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

#: Relative tolerance for "the face projection lies in the part" (metres, times the size).
INSIDE_TOL = 1e-12
#: Bytes of the largest temporary (points x edges x 3 float64) per block.
BLOCK_BYTES = 64 * 2**20


def plane_keys(equations: np.ndarray) -> np.ndarray:
    """(T, 4) a key per hull triangle's plane [unit normal, offset] (T, 4): equal for the
    triangles of one face (coplanar to 1e-9), which qhull may give several of."""
    return np.round(equations, 9)


def face_planes(vertices: np.ndarray) -> np.ndarray:
    """(F, 4) unique outward face planes [unit normal, offset] of the hull of (V, 3) points."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(vertices)
    eq = hull.equations
    # merge coplanar triangles: unique planes
    _, first = np.unique(plane_keys(eq), axis=0, return_index=True)
    return eq[np.sort(first)]


@dataclass(frozen=True, eq=False)
class ConvexPart:
    """One convex polytope.

    Attributes:
        vertices: (V, 3) metres.
        planes: (F, 4) unique outward face planes [unit normal, offset], n . x + d <= 0 inside.
        known_edges: (E, 2, 3) :attr:`edges` as computed before (kept with a catalog
            object's cached geometry), or None to compute them.
    """

    vertices: np.ndarray
    planes: np.ndarray
    known_edges: np.ndarray | None = field(default=None, repr=False)

    @cached_property
    def edges(self) -> np.ndarray:
        """(E, 2, 3) end points of the true edges (between faces that are not one face of
        :func:`face_planes`: their triangles' :func:`plane_keys` differ), from the
        vertices' convex hull (qhull)."""
        if self.known_edges is not None:
            return self.known_edges
        from scipy.spatial import ConvexHull

        hull = ConvexHull(self.vertices)
        keys = plane_keys(hull.equations)
        seen: set[tuple[int, int]] = set()
        edges = []
        for t, simplex in enumerate(hull.simplices):
            for k in range(3):
                other = hull.neighbors[t, k]
                a, b = sorted(int(v) for k2, v in enumerate(simplex) if k2 != k)
                if (a, b) in seen:
                    continue
                seen.add((a, b))
                if not np.array_equal(keys[t], keys[other]):
                    edges.append((hull.points[a], hull.points[b]))
        return np.asarray(edges, dtype=float)

    @cached_property
    def scale(self) -> float:
        return float(np.ptp(self.vertices, axis=0).max())

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Closest boundary points and signed distances of points (n, 3).

        Returns:
            (closest (n, 3), signed distance (n,): > 0 outside, < 0 inside), exact.
        """
        points = np.atleast_2d(np.asarray(points, dtype=float))
        normals, offsets = self.planes[:, :3], self.planes[:, 3]
        values = points @ normals.T + offsets
        face = np.argmax(values, axis=1)
        top = values[np.arange(len(points)), face]
        closest = points - top[:, None] * normals[face]
        distance = top.copy()
        outside = top > 0
        if outside.any():
            check = closest[outside] @ normals.T + offsets
            off_face = np.flatnonzero(outside)[check.max(axis=1) > INSIDE_TOL * self.scale]
            if off_face.size:
                near, dist = segment_closest(points[off_face], self.edges)
                closest[off_face], distance[off_face] = near, dist
        return closest, distance


def segment_closest(points: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest point over a set of segments, and its distance, for each point.

    Args:
        points: (n, 3).
        segments: (E, 2, 3) end points.

    Returns:
        (closest (n, 3), distance (n,)).
    """
    start = segments[:, 0]
    direction = segments[:, 1] - start
    length2 = np.maximum(np.einsum("ek,ek->e", direction, direction), 1e-300)
    out_p = np.empty_like(points)
    out_d = np.empty(len(points))
    block = max(1, BLOCK_BYTES // (24 * len(segments)))
    for lo in range(0, len(points), block):
        p = points[lo:lo + block]
        rel = p[:, None, :] - start[None]  # (b, E, 3)
        t = np.clip(np.einsum("bek,ek->be", rel, direction) / length2, 0.0, 1.0)
        diff = rel - t[..., None] * direction
        d2 = np.einsum("bek,bek->be", diff, diff)
        best = np.argmin(d2, axis=1)
        rows = np.arange(len(p))
        out_p[lo:lo + block] = start[best] + t[rows, best, None] * direction[best]
        out_d[lo:lo + block] = np.sqrt(d2[rows, best])
    return out_p, out_d
