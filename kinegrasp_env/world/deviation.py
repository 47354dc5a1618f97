"""How far a convex decomposition is from its source mesh, both ways (metres).

* ``missing``: points sampled on the source surface, their distance to the parts' union
  (0 inside it): where the parts lose material (a thin feature dropped, a hole not filled).
* ``added``: points sampled on the parts' outer surface (samples inside another part, or on
  a face two parts share, are not on the union's surface and are left out), their distance
  to the source surface where they lie outside the source solid (0 inside it, by the
  generalized winding number, defined for meshes with holes too): where the parts add
  material (a concavity bridged by a hull).

Each maximum is a one-sided Hausdorff distance estimated from the samples (a lower bound
that tightens with more samples); the distances themselves are exact (point to convex
polytope, :class:`~kinegrasp_env.world.polytope.ConvexPart`; point to triangle,
``trimesh.triangles.closest_point``). Samples are drawn from a seeded generator: the same
mesh and parts give the same numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import ConvexHull, cKDTree

from kinegrasp_env.world.polytope import ConvexPart, face_planes

#: Surface samples per direction.
SAMPLES = 2000
#: Point-triangle pairs evaluated per block (bounds memory).
PAIR_BLOCK = 200_000
#: A part's surface point within this distance (relative to the object's size) of another
#: part lies on a face they share, inside the union.
SHARED = 1e-6


@dataclass(frozen=True)
class Deviation:
    """Distances between a decomposition and its source surface (metres).

    Attributes:
        missing_max, missing_mean: source surface samples to the parts' union (0 inside).
        added_max, added_mean: samples of the parts' outer surface to the source surface.
        samples: samples per direction.
    """

    missing_max: float
    missing_mean: float
    added_max: float
    added_mean: float
    samples: int

    def to_dict(self) -> dict:
        return {"missing_max": self.missing_max, "missing_mean": self.missing_mean,
                "added_max": self.added_max, "added_mean": self.added_mean,
                "samples": self.samples}


def sample_triangles(triangles: np.ndarray, count: int, rng: np.random.Generator,
                     owner: np.ndarray | None = None):
    """``count`` points (count, 3) uniform by area on triangles (T, 3, 3); with ``owner``
    (T,), also the owner (count,) of each point's triangle."""
    area = 0.5 * np.linalg.norm(np.cross(triangles[:, 1] - triangles[:, 0],
                                         triangles[:, 2] - triangles[:, 0]), axis=1)
    pick = rng.choice(len(triangles), size=count, p=area / area.sum())
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    tri = triangles[pick]
    points = tri[:, 0] + u[:, None] * (tri[:, 1] - tri[:, 0]) + v[:, None] * (tri[:, 2] - tri[:, 0])
    return points if owner is None else (points, owner[pick])


def outside_others(parts: list[ConvexPart], points: np.ndarray, owner: np.ndarray,
                   tol: float) -> np.ndarray:
    """(n,) True where a point sampled on part ``owner`` lies farther than ``tol`` outside
    every other part: on the union's outer surface, not inside another part nor on a face
    two parts share (CoACD's cuts)."""
    keep = np.ones(len(points), dtype=bool)
    for index, part in enumerate(parts):
        rows = np.flatnonzero(owner != index)
        keep[rows[part.closest(points[rows])[1] <= tol]] = False
    return keep


def union_distance(parts: list[ConvexPart], points: np.ndarray) -> np.ndarray:
    """(n,) signed distance of points (n, 3) to a union of convex parts: the smallest over
    the parts (> 0 outside all, < 0 inside one; inside, a lower bound of the depth)."""
    best = np.full(len(points), np.inf)
    for part in parts:
        np.minimum(best, part.closest(points)[1], out=best)
    return best


def surface_distance(triangles: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(n,) exact unsigned distance of points (n, 3) to a triangle soup (T, 3, 3).

    A point's distance to its nearest triangle corner d0 bounds the answer, so only the
    triangles whose bounding sphere comes within d0 are checked exactly."""
    centres = triangles.mean(axis=1)
    radii = np.linalg.norm(triangles - centres[:, None], axis=2).max(axis=1)
    corners = triangles.reshape(-1, 3)
    d0 = cKDTree(corners).query(points)[0]
    tree = cKDTree(centres)
    reach = d0 + radii.max()
    out = d0.copy()
    rows: list[int] = []
    cols: list[int] = []
    for i, near in enumerate(tree.query_ball_point(points, reach)):
        near = np.asarray(near, dtype=np.intp)
        keep = near[np.linalg.norm(centres[near] - points[i], axis=1) - radii[near] <= d0[i]]
        rows.extend([i] * keep.size)
        cols.extend(keep.tolist())
        if len(rows) >= PAIR_BLOCK or i == len(points) - 1:
            _exact(triangles, points, np.array(rows, np.intp), np.array(cols, np.intp), out)
            rows, cols = [], []
    return out


def _exact(triangles: np.ndarray, points: np.ndarray, rows: np.ndarray, cols: np.ndarray,
           out: np.ndarray) -> None:
    """Lower ``out[rows]`` to the exact point-triangle distances of the pairs."""
    if rows.size == 0:
        return
    closest = trimesh.triangles.closest_point(triangles[cols], points[rows])
    np.minimum.at(out, rows, np.linalg.norm(closest - points[rows], axis=1))


def winding_number(triangles: np.ndarray, points: np.ndarray, block: int = 4_000_000
                   ) -> np.ndarray:
    """(n,) generalized winding number of a triangle soup (T, 3, 3) at points (n, 3): 1 inside
    a closed outward-oriented surface, 0 outside, and a smooth inside measure for a surface
    with holes (Jacobson et al. 2013; van Oosterom-Strackee solid angles)."""
    out = np.zeros(len(points))
    step = max(1, block // max(1, len(triangles)))
    for lo in range(0, len(points), step):
        rel = triangles[None] - points[lo:lo + step, None, None, :]  # (b, T, 3, 3)
        a, b, c = rel[..., 0, :], rel[..., 1, :], rel[..., 2, :]
        la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
        det = np.einsum("btk,btk->bt", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("btk,btk->bt", a, b) * lc
               + np.einsum("btk,btk->bt", b, c) * la + np.einsum("btk,btk->bt", c, a) * lb)
        out[lo:lo + step] = np.arctan2(det, den).sum(axis=1) / (2.0 * np.pi)
    return out


def hull_triangles(vertices: np.ndarray) -> np.ndarray:
    """(T, 3, 3) triangles of the convex hull of ``vertices`` (V, 3)."""
    hull = ConvexHull(vertices)
    return hull.points[hull.simplices]


def deviation(source: trimesh.Trimesh, parts: list[np.ndarray], samples: int = SAMPLES,
              seed: int = 0) -> Deviation:
    """Both one-sided distances between ``source`` and the union of ``parts`` (each (V_i, 3)
    hull vertices), from ``samples`` surface samples each way (see the module docstring)."""
    rng = np.random.default_rng(seed)
    convex = [ConvexPart(p, face_planes(p)) for p in parts]
    on_source = sample_triangles(np.asarray(source.triangles), samples, rng)
    missing = np.maximum(union_distance(convex, on_source), 0.0)
    tris = [hull_triangles(p) for p in parts]
    owner = np.repeat(np.arange(len(parts)), [len(t) for t in tris])
    picked, which = sample_triangles(np.concatenate(tris), samples, rng, owner)
    scale = float(np.max(source.extents))
    picked = picked[outside_others(convex, picked, which, SHARED * scale)]
    triangles = np.asarray(source.triangles)
    added = np.zeros(len(picked))
    beyond = np.abs(winding_number(triangles, picked)) < 0.5
    added[beyond] = surface_distance(triangles, picked[beyond])
    return Deviation(float(missing.max()), float(missing.mean()),
                     float(added.max()) if added.size else 0.0,
                     float(added.mean()) if added.size else 0.0, samples)

