"""Compiled signed distances of lattice nodes to one convex part: the distance grids of every
object (:func:`kinegrasp_env.world.sdf.build_grid`) are built from it.

The rule of :meth:`kinegrasp_env.world.polytope.ConvexPart.closest` (which also returns
the closest points), node by node: the largest plane value s = max_i (n_i . x + d_i) is the
signed distance when x is inside (s <= 0) or when its projection on that plane lies in the
part; otherwise the distance is the exact distance to the nearest edge. A node whose plane
value already reaches the value it holds (``current``) keeps it: s is a lower bound of the
distance, so the minimum over the parts is unchanged. The built-in objects' (float32) grids
equal those of ``ConvexPart.closest`` node by node bit for bit, built far sooner (compiled,
with no closest points to return).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit


@jit.kernel
def part_distances(points, planes, edges, tol, current):
    """Signed distances (n,) of points (n, 3) to the part with face planes (F, 4) and edges
    (E, 2, 3), or ``current`` (n,) where that is provably not larger (see module docstring).

    ``tol``: the on-face tolerance, metres (``INSIDE_TOL`` x the part's size)."""
    n = points.shape[0]
    out = np.empty(n)
    for i in range(n):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        top = -np.inf
        face = 0
        for f in range(planes.shape[0]):
            v = planes[f, 0] * x + planes[f, 1] * y + planes[f, 2] * z + planes[f, 3]
            if v > top:
                top = v
                face = f
        if top >= current[i]:
            out[i] = current[i]
            continue
        if top <= 0.0:
            out[i] = top
            continue
        px = x - top * planes[face, 0]
        py = y - top * planes[face, 1]
        pz = z - top * planes[face, 2]
        check = -np.inf
        for f in range(planes.shape[0]):
            v = planes[f, 0] * px + planes[f, 1] * py + planes[f, 2] * pz + planes[f, 3]
            if v > check:
                check = v
        if check <= tol:
            out[i] = top
            continue
        out[i] = np.sqrt(edge_distance2(edges, x, y, z))
    return out


@jit.kernel
def edge_distance2(edges, x, y, z):
    """Smallest squared distance from (x, y, z) to the segments (E, 2, 3)."""
    best = np.inf
    for e in range(edges.shape[0]):
        ax, ay, az = edges[e, 0, 0], edges[e, 0, 1], edges[e, 0, 2]
        dx, dy, dz = edges[e, 1, 0] - ax, edges[e, 1, 1] - ay, edges[e, 1, 2] - az
        rx, ry, rz = x - ax, y - ay, z - az
        length2 = max(dx * dx + dy * dy + dz * dz, 1e-300)
        t = min(max((rx * dx + ry * dy + rz * dz) / length2, 0.0), 1.0)
        qx, qy, qz = rx - t * dx, ry - t * dy, rz - t * dz
        d2 = qx * qx + qy * qy + qz * qz
        if d2 < best:
            best = d2
    return best
