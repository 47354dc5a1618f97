"""Exact distance between segments (finger-capsule axes) and an object: compiled kernel.

The same computation as :meth:`kinegrasp_env.world.objects.GraspObject.closest_to_segments` (the
numpy twin, see :mod:`kinegrasp_env.world.polytope` for the method), as one compiled loop over the
segments with two cheap prunings that do not change the result: a part is skipped when the
plane bound max_i min(s_i(a), s_i(b)) already exceeds the best distance found, and an edge
when the distance between the bounding spheres of the edge and the segment does (parts are
visited by increasing bound, so the search usually stops after the nearest one).
Both engines use it in the near field, where a gap decides contact.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.world.objects import GraspObject, load_object
from kinegrasp_env.world.polytope import INSIDE_TOL


@dataclass(frozen=True, eq=False)
class PackedGeometry:
    """An object's parts as flat arrays for the kernel.

    Attributes:
        planes: (P, 4) all parts' planes; plane_start: (n_parts + 1,) offsets.
        edges: (E, 2, 3) all parts' edges; edge_start: (n_parts + 1,) offsets.
        scale: (n_parts,) part sizes (tolerance of the on-face test).
        edge_mid: (E, 3) edge midpoints; edge_half: (E,) half lengths (bounding spheres).
    """

    planes: np.ndarray
    plane_start: np.ndarray
    edges: np.ndarray
    edge_start: np.ndarray
    scale: np.ndarray
    edge_mid: np.ndarray
    edge_half: np.ndarray


def pack(obj: GraspObject) -> PackedGeometry:
    parts = obj.convex_parts
    planes = np.concatenate([p.planes for p in parts])
    edges = np.concatenate([p.edges for p in parts])
    plane_start = np.cumsum([0] + [len(p.planes) for p in parts])
    edge_start = np.cumsum([0] + [len(p.edges) for p in parts])
    return PackedGeometry(np.ascontiguousarray(planes), plane_start.astype(np.int64),
                          np.ascontiguousarray(edges), edge_start.astype(np.int64),
                          np.array([p.scale for p in parts]),
                          np.ascontiguousarray(edges.mean(axis=1)),
                          0.5 * np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1))


@lru_cache(maxsize=8)
def packed(name: str) -> PackedGeometry:
    return pack(load_object(name))


@jit.kernel
def point_part(planes, p0, p1, edges, mid, half, e0, e1, x, y, z, tol):
    """Signed distance and closest point of (x, y, z) to one part."""
    top = -np.inf
    face = p0
    for i in range(p0, p1):
        v = planes[i, 0] * x + planes[i, 1] * y + planes[i, 2] * z + planes[i, 3]
        if v > top:
            top = v
            face = i
    cx = x - top * planes[face, 0]
    cy = y - top * planes[face, 1]
    cz = z - top * planes[face, 2]
    if top <= 0.0:
        return top, cx, cy, cz
    worst = -np.inf
    for i in range(p0, p1):
        v = planes[i, 0] * cx + planes[i, 1] * cy + planes[i, 2] * cz + planes[i, 3]
        if v > worst:
            worst = v
    if worst <= tol:
        return top, cx, cy, cz
    best = np.inf
    bx = by = bz = 0.0
    for e in range(e0, e1):
        sx, sy, sz = edges[e, 0, 0], edges[e, 0, 1], edges[e, 0, 2]
        dx, dy, dz = edges[e, 1, 0] - sx, edges[e, 1, 1] - sy, edges[e, 1, 2] - sz
        # bounding sphere of the edge: skip when it cannot beat the best
        mx, my, mz = x - mid[e, 0], y - mid[e, 1], z - mid[e, 2]
        reach = np.sqrt(mx * mx + my * my + mz * mz) - half[e]
        if reach > 0.0 and reach * reach >= best:
            continue
        len2 = max(dx * dx + dy * dy + dz * dz, 1e-300)
        t = ((x - sx) * dx + (y - sy) * dy + (z - sz) * dz) / len2
        t = min(max(t, 0.0), 1.0)
        qx, qy, qz = sx + t * dx, sy + t * dy, sz + t * dz
        d2 = (x - qx) ** 2 + (y - qy) ** 2 + (z - qz) ** 2
        if d2 < best:
            best = d2
            bx, by, bz = qx, qy, qz
    return np.sqrt(best), bx, by, bz

@jit.kernel
def part_bounds(planes, plane_start, ax, ay, az, ex, ey, ez, bounds):
    """Lower bound of each part's distance to segment [a, e] into bounds (n_parts,): the
    largest over the part's planes of min(s(a), s(e)) (a plane's value s is linear along
    the segment, and a point's distance to a convex part is at least its largest s)."""
    for part in range(plane_start.shape[0] - 1):
        bound = -np.inf
        for k in range(plane_start[part], plane_start[part + 1]):
            va = planes[k, 0] * ax + planes[k, 1] * ay + planes[k, 2] * az + planes[k, 3]
            vb = planes[k, 0] * ex + planes[k, 1] * ey + planes[k, 2] * ez + planes[k, 3]
            v = min(va, vb)
            if v > bound:
                bound = v
        bounds[part] = bound

@jit.kernel(inline="always")  # inlined: a call per edge made the search ~3% slower
def segment_edge(ax, ay, az, ux, uy, uz, uu, cx0, cy0, cz0, vx, vy, vz):
    """Closest pair of segment a + s u and edge c0 + t v (s, t in [0, 1]; uu = u . u):
    (distance, point on the edge (3 floats), point on the segment (3 floats))."""
    ee = vx * vx + vy * vy + vz * vz
    rx, ry, rz = ax - cx0, ay - cy0, az - cz0
    bb = ux * vx + uy * vy + uz * vz
    cc = rx * ux + ry * uy + rz * uz
    ff = rx * vx + ry * vy + rz * vz
    denom = uu * ee - bb * bb
    s = 0.0
    if denom > 1e-14 * uu * ee:
        s = min(max((bb * ff - cc * ee) / denom, 0.0), 1.0)
    t = (bb * s + ff) / ee
    if t < 0.0:
        s = min(max(-cc / uu, 0.0), 1.0)
    elif t > 1.0:
        s = min(max((bb - cc) / uu, 0.0), 1.0)
    t = min(max(t, 0.0), 1.0)
    px, py, pz = ax + s * ux, ay + s * uy, az + s * uz
    qx, qy, qz = cx0 + t * vx, cy0 + t * vy, cz0 + t * vz
    dd = np.sqrt((px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2)
    return dd, qx, qy, qz, px, py, pz

@jit.kernel(inline="always")  # inlined: a call per part made the search ~2% slower
def segment_part(planes, p0, p1, edges, mid, half, e0, e1, ax, ay, az, ex, ey, ez, ptol):
    """Closest pair of segment [a, e] and one part (planes p0:p1, edges e0:e1, on-face
    tolerance ptol): (distance, point on the part (3 floats), point on the segment (3
    floats)). The nearer of the ends' closest points, then every edge whose bounding
    sphere can come closer than the best so far."""
    ux, uy, uz = ex - ax, ey - ay, ez - az
    uu = ux * ux + uy * uy + uz * uz
    mx, my, mz = ax + 0.5 * ux, ay + 0.5 * uy, az + 0.5 * uz
    seg_half = 0.5 * np.sqrt(uu)
    da, cxa, cya, cza = point_part(planes, p0, p1, edges, mid, half, e0, e1, ax, ay, az,
                                   ptol)
    db, cxb, cyb, czb = point_part(planes, p0, p1, edges, mid, half, e0, e1, ex, ey, ez,
                                   ptol)
    if db < da:
        d, ox, oy, oz, sx, sy, sz = db, cxb, cyb, czb, ex, ey, ez
    else:
        d, ox, oy, oz, sx, sy, sz = da, cxa, cya, cza, ax, ay, az
    for e in range(e0, e1):
        cx0, cy0, cz0 = edges[e, 0, 0], edges[e, 0, 1], edges[e, 0, 2]
        vx, vy, vz = edges[e, 1, 0] - cx0, edges[e, 1, 1] - cy0, edges[e, 1, 2] - cz0
        gap = (np.sqrt((mid[e, 0] - mx) ** 2 + (mid[e, 1] - my) ** 2
                       + (mid[e, 2] - mz) ** 2) - seg_half - half[e])
        if gap >= d:
            continue
        dd, qx, qy, qz, px, py, pz = segment_edge(ax, ay, az, ux, uy, uz, uu, cx0, cy0, cz0,
                                                  vx, vy, vz)
        if dd < d:
            d, ox, oy, oz, sx, sy, sz = dd, qx, qy, qz, px, py, pz
    return d, ox, oy, oz, sx, sy, sz

@jit.kernel
def segment_one(planes, plane_start, edges, edge_start, scale, mid, half, ax, ay, az, ex,
                ey, ez, bounds, tol):
    """Closest pair of segment [a, e] and the object: (distance, point on the object
    (3 floats), point on the segment (3 floats), part); bounds: (n_parts,) buffer.

    Parts are visited by increasing :func:`part_bounds`, until the bound reaches the best
    distance found."""
    part_bounds(planes, plane_start, ax, ay, az, ex, ey, ez, bounds)
    order = np.argsort(bounds)
    best = np.inf
    box = boy = boz = bsx = bsy = bsz = 0.0
    bpart = 0
    for rank in range(plane_start.shape[0] - 1):
        part = order[rank]
        if bounds[part] >= best:
            break
        d, ox, oy, oz, sx, sy, sz = segment_part(
            planes, plane_start[part], plane_start[part + 1], edges, mid, half,
            edge_start[part], edge_start[part + 1], ax, ay, az, ex, ey, ez,
            tol * scale[part])
        if d < best:
            best = d
            box, boy, boz, bsx, bsy, bsz = ox, oy, oz, sx, sy, sz
            bpart = part
    return best, box, boy, boz, bsx, bsy, bsz, bpart

@jit.kernel
def segments_closest(planes, plane_start, edges, edge_start, scale, mid, half, a, b, out_d,
                     out_obj, out_seg, out_part, tol):
    """Closest pairs of segments [a, b] (n, 3) and the object (see :func:`segment_one`) into
    out_d (n,), out_obj, out_seg (n, 3), out_part (n,)."""
    bounds = np.empty(plane_start.shape[0] - 1)
    for i in range(a.shape[0]):
        (out_d[i], out_obj[i, 0], out_obj[i, 1], out_obj[i, 2], out_seg[i, 0],
         out_seg[i, 1], out_seg[i, 2], out_part[i]) = segment_one(
            planes, plane_start, edges, edge_start, scale, mid, half, a[i, 0], a[i, 1],
            a[i, 2], b[i, 0], b[i, 1], b[i, 2], bounds, tol)

def closest_to_segments(obj: GraspObject, a: np.ndarray, b: np.ndarray, kernel: str = "numba"
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Exact closest pairs between segments [a, b] (n, 3) (object frame) and the object.

    Returns (on the object (n, 3), on the segment (n, 3), distance (n,), part (n,)), as
    :meth:`GraspObject.closest_to_segments` (``kernel="numpy"`` calls it).
    """
    a = np.ascontiguousarray(np.atleast_2d(a), dtype=float)
    b = np.ascontiguousarray(np.atleast_2d(b), dtype=float)
    if kernel == "numpy":
        return obj.closest_to_segments(a, b)
    if kernel != "numba":
        raise ValueError(f"unknown kernel {kernel!r}; choose numba or numpy")
    geo = packed(obj.name)
    n = len(a)
    out_d = np.empty(n)
    out_obj, out_seg = np.empty((n, 3)), np.empty((n, 3))
    out_part = np.zeros(n, dtype=np.int64)
    segments_closest(geo.planes, geo.plane_start, geo.edges, geo.edge_start, geo.scale,
                     geo.edge_mid, geo.edge_half, a, b, out_d, out_obj, out_seg, out_part,
                     INSIDE_TOL)
    return out_obj, out_seg, out_d, out_part
