"""Exact distance between segments (finger-capsule axes) and an object: compiled kernel.

The closest pair of a segment and a convex part is at an end of the segment (its closest
point being anywhere on the part, :mod:`kinegrasp_env.world.polytope`) or between the segment
and an edge of the part; the smallest over the parts is the answer, exact for segments that do
not cross the object (a finger axis at contact is a capsule radius away). One compiled loop
over the segments, with prunings that skip only what provably cannot change the result:

- parts are visited by increasing plane bound max_i min(s_i(a), s_i(b)) (ties by part
  index) until it exceeds the best distance found (the search usually stops after the
  nearest part); a part whose bounding sphere is farther than the best is skipped;
- an edge is skipped when a lower bound of its distance exceeds the best found so far: the
  distance from its bounding sphere, or from the plane of either face it bounds (a point's
  distance to the edge is at least its distance to that plane: |s_f(x)|; a segment's, the
  smaller of its ends' when the plane does not separate them); each part's edges are
  packed in blocks of nearby edges (:func:`spatial_blocks`), and a block whose bounding
  sphere is farther than the best is skipped whole (exact queries on the spray flask's
  144-edge prisms 25% faster, the mug's 15-25%);
- the closing loop starts each query's best distance at that of an object point an earlier
  query found (:func:`segment_search_near`: the same result, the plain search taking over
  where it does not hold), instead of inf.

Every bound is compared with a margin (:data:`PRUNE_MARGIN`) far above its rounding error, so
every candidate that could win is kept, in the plain search's order and compared as there:
the results are identical bit for bit (tested: the same search, interpreted, with
``PRUNE_MARGIN = inf`` turning the prunings off). The kernels allocate nothing and are
compiled without reference counting (see :mod:`kinegrasp_env.closing.close_kernel`).
Both engines use it in the near field, where a gap decides contact.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from itertools import pairwise

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.world.objects import GraspObject, load_object
from kinegrasp_env.world.polytope import INSIDE_TOL

#: Bounds prune only when they exceed the best distance by this much (metres): far above
#: their rounding error (~1e-16 m) and the faces' plane residuals (< FACE_RESIDUAL).
PRUNE_MARGIN = 1e-9
#: An edge bounds a face when both its ends lie within this of the face's plane (metres).
FACE_RESIDUAL = 1e-12
#: Largest number of edges in a block: each part's edges are ordered so that blocks of
#: nearby edges are consecutive, and a block whose bounding sphere cannot beat the best
#: distance is skipped whole (the spray flask's 48-gon prisms have 144 edges a part).
BLOCK_EDGES = 4


@dataclass(frozen=True, eq=False)
class PackedGeometry:
    """An object's parts as flat arrays for the kernel.

    Attributes:
        planes: (P, 4) all parts' planes (unit normals); plane_start: (n_parts + 1,) offsets.
        edges: (E, 2, 3) all parts' edges; edge_start: (n_parts + 1,) offsets.
        scale: (n_parts,) part sizes (tolerance of the on-face test).
        edge_mid: (E, 3) edge midpoints; edge_half: (E,) half lengths (bounding spheres).
        edge_faces: (E, 2) int64 rows of ``planes`` of the two faces each edge bounds (-1
            where no plane of its part holds both its ends within ``FACE_RESIDUAL``).
        part_center: (n_parts, 3), part_radius: (n_parts,): a sphere holding each part
            (centre: the mean of its edges' end points; radius: the farthest of them).
        block_start: (n_parts + 1,) int64 offsets of each part's edge blocks;
            block_edge: (n_blocks + 1,) int64 offsets of each block's edges (a part's edges
            are ordered by :func:`spatial_blocks`); block_center (n_blocks, 3),
            block_radius (n_blocks,): a sphere holding each block's edges.
    """

    planes: np.ndarray
    plane_start: np.ndarray
    edges: np.ndarray
    edge_start: np.ndarray
    scale: np.ndarray
    edge_mid: np.ndarray
    edge_half: np.ndarray
    edge_faces: np.ndarray
    part_center: np.ndarray
    part_radius: np.ndarray
    block_start: np.ndarray
    block_edge: np.ndarray
    block_center: np.ndarray
    block_radius: np.ndarray


def edge_faces(planes: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(E, 2) int64: for each edge (E, 2, 3) the two planes (P, 4) nearest to both its ends,
    -1 where that is above ``FACE_RESIDUAL`` (metres)."""
    residual = np.abs(edges @ planes[:, :3].T + planes[:, 3]).max(axis=1)  # (E, P)
    nearest = np.argsort(residual, axis=1, kind="stable")[:, :2]
    close = np.take_along_axis(residual, nearest, axis=1) < FACE_RESIDUAL
    return np.where(close, nearest, -1).astype(np.int64)


def spatial_blocks(mid: np.ndarray, size: int = BLOCK_EDGES) -> list[np.ndarray]:
    """Indices of points mid (E, 3) in blocks of at most ``size`` nearby points: halved at
    the median of the widest coordinate until small enough (a k-d tree's leaves, in order)."""
    todo, leaves = [np.arange(len(mid))], []
    while todo:
        idx = todo.pop()
        if len(idx) <= size:
            leaves.append(idx)
            continue
        axis = int(np.argmax(np.ptp(mid[idx], axis=0)))
        idx = idx[np.argsort(mid[idx, axis], kind="stable")]
        todo += [idx[len(idx) // 2:], idx[:len(idx) // 2]]  # the lower half next
    return leaves


def pack(obj: GraspObject) -> PackedGeometry:
    parts = obj.convex_parts
    planes, plane_start = obj.packed_planes  # the parts' planes, stacked
    part_edges, faces, blocks = [], [], []
    for part, first in zip(parts, plane_start[:-1], strict=True):
        leaves = spatial_blocks(part.edges.mean(axis=1)) if len(part.edges) else []
        ordered = part.edges[np.concatenate(leaves)] if leaves else part.edges
        part_edges.append(ordered)
        found = edge_faces(part.planes, ordered)
        faces.append(np.where(found >= 0, found + first, -1))
        blocks.append([len(leaf) for leaf in leaves])
    edges = np.concatenate(part_edges)
    edge_start = np.cumsum([0] + [len(e) for e in part_edges])
    corners = [p.edges.reshape(-1, 3) for p in parts]
    center = np.array([c.mean(axis=0) for c in corners])
    radius = np.array([np.linalg.norm(c - m, axis=1).max()
                       for c, m in zip(corners, center, strict=True)])
    block_edge = np.cumsum([0] + [n for part in blocks for n in part])
    block_start = np.cumsum([0] + [len(part) for part in blocks])
    ends = [edges[a:b].reshape(-1, 3) for a, b in pairwise(block_edge)]
    block_center = np.array([0.5 * (e.min(axis=0) + e.max(axis=0)) for e in ends])
    # a sphere holding both ends of every edge of the block holds the edges (convex); the
    # relative margin covers the rounding of the distances it is compared with
    block_radius = np.array([np.linalg.norm(e - c, axis=1).max() for e, c in
                             zip(ends, block_center, strict=True)]) * (1 + 1e-9) + 1e-12
    return PackedGeometry(planes, plane_start,
                          np.ascontiguousarray(edges), edge_start.astype(np.int64),
                          np.array([p.scale for p in parts]),
                          np.ascontiguousarray(edges.mean(axis=1)),
                          0.5 * np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1),
                          np.concatenate(faces).astype(np.int64), center, radius,
                          block_start.astype(np.int64), block_edge.astype(np.int64),
                          np.ascontiguousarray(block_center.reshape(-1, 3)),
                          block_radius.reshape(-1))


def packed(name: str) -> PackedGeometry:
    """The packed parts of catalog object ``name`` as it is now: an object re-imported
    under the same name is a new :class:`GraspObject` (``load_object`` keys it by its
    catalog version), so it is packed afresh."""
    return packed_object(load_object(name))


@lru_cache(maxsize=8)
def packed_object(obj: GraspObject) -> PackedGeometry:
    """:func:`pack` of ``obj``, cached per object (by identity, not by name: two objects of
    one name, before and after a re-import, never share an entry)."""
    return pack(obj)


@jit.kernel(inline="always")
def point_edges(geo, part, x, y, z, values, side, limit):
    """Closest point of (x, y, z) (end ``side`` of the segment, plane values (2, P)) on the
    edges of one part: (distance, point (3 floats)). A block of edges is skipped when its
    bounding sphere is farther than the best so far (or ``limit``), an edge when its own is,
    or the plane of one of its faces is farther than that or than ``limit`` (a distance
    found elsewhere: the result is exact wherever it is below ``limit``, and at least
    ``limit`` elsewhere)."""
    edges, mid, half, faces = geo[2], geo[5], geo[6], geo[7]
    block_start, block_edge, block_center, block_radius = geo[11], geo[12], geo[13], geo[14]
    best = np.inf
    cap = limit  # min(limit, sqrt(best))
    bx = by = bz = 0.0
    for block in range(block_start[part], block_start[part + 1]):
        mx, my, mz = (x - block_center[block, 0], y - block_center[block, 1],
                      z - block_center[block, 2])
        far = cap + block_radius[block] + 2.0 * PRUNE_MARGIN
        if mx * mx + my * my + mz * mz >= far * far:
            continue
        for e in range(block_edge[block], block_edge[block + 1]):
            f0, f1 = faces[e, 0], faces[e, 1]
            plane = max(abs(values[side, f0]) if f0 >= 0 else 0.0,
                        abs(values[side, f1]) if f1 >= 0 else 0.0)
            if plane - 2.0 * PRUNE_MARGIN >= cap:
                continue
            sx, sy, sz = edges[e, 0, 0], edges[e, 0, 1], edges[e, 0, 2]
            dx, dy, dz = edges[e, 1, 0] - sx, edges[e, 1, 1] - sy, edges[e, 1, 2] - sz
            # bounding sphere of the edge: skip when it cannot beat the best (or the limit)
            mx, my, mz = x - mid[e, 0], y - mid[e, 1], z - mid[e, 2]
            r2 = mx * mx + my * my + mz * mz
            far = cap + half[e] + 2.0 * PRUNE_MARGIN
            if r2 >= far * far:
                continue
            reach = np.sqrt(r2) - half[e]
            if reach > 0.0 and reach * reach >= best:
                continue
            len2 = max(dx * dx + dy * dy + dz * dz, 1e-300)
            t = ((x - sx) * dx + (y - sy) * dy + (z - sz) * dz) / len2
            t = min(max(t, 0.0), 1.0)
            qx, qy, qz = sx + t * dx, sy + t * dy, sz + t * dz
            d2 = (x - qx) ** 2 + (y - qy) ** 2 + (z - qz) ** 2
            if d2 < best:
                best = d2
                cap = min(limit, np.sqrt(d2))
                bx, by, bz = qx, qy, qz
    return np.sqrt(best), bx, by, bz

@jit.kernel(inline="always")
def point_part(geo, part, x, y, z, values, side, limit):
    """Signed distance and closest point of (x, y, z), end ``side`` of the segment whose
    plane values (2, P) are given, to one part; exact wherever below ``limit`` (see
    :func:`point_edges`)."""
    planes, plane_start, scale = geo[0], geo[1], geo[4]
    p0, p1 = plane_start[part], plane_start[part + 1]
    top = -np.inf
    face = p0
    for i in range(p0, p1):
        v = values[side, i]
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
    if worst <= geo[10] * scale[part]:
        return top, cx, cy, cz
    return point_edges(geo, part, x, y, z, values, side, limit)

@jit.kernel(_nrt=False)
def part_bounds(planes, plane_start, ax, ay, az, ex, ey, ez, bounds, values):
    """Lower bound of each part's distance to segment [a, e] into bounds (n_parts,): the
    largest over the part's planes of min(s(a), s(e)) (a plane's value s is linear along
    the segment, and a point's distance to a convex part is at least its largest s). The
    plane values at a and e go to values (2, P)."""
    for part in range(plane_start.shape[0] - 1):
        bounds[part] = part_bound(planes, plane_start, part, ax, ay, az, ex, ey, ez, values)

@jit.kernel(inline="always")
def part_bound(planes, plane_start, part, ax, ay, az, ex, ey, ez, values):
    """:func:`part_bounds` of one part."""
    bound = -np.inf
    for k in range(plane_start[part], plane_start[part + 1]):
        va = planes[k, 0] * ax + planes[k, 1] * ay + planes[k, 2] * az + planes[k, 3]
        vb = planes[k, 0] * ex + planes[k, 1] * ey + planes[k, 2] * ez + planes[k, 3]
        values[0, k] = va
        values[1, k] = vb
        v = min(va, vb)
        if v > bound:
            bound = v
    return bound

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

@jit.kernel(inline="always")
def plane_gap(va, vb):
    """Lower bound of a segment's distance to a plane from its ends' values va, vb: the
    smaller |s| when the plane does not separate them, else 0."""
    if va > 0.0 and vb > 0.0:
        return min(va, vb)
    if va < 0.0 and vb < 0.0:
        return min(-va, -vb)
    return 0.0

@jit.kernel(inline="always")
def point_to_segment2(px, py, pz, ax, ay, az, ux, uy, uz, inv_uu):
    """Squared distance (m^2) from point p to segment a + s u, s in [0, 1] (inv_uu =
    1 / u . u)."""
    wx, wy, wz = px - ax, py - ay, pz - az
    s = min(max((wx * ux + wy * uy + wz * uz) * inv_uu, 0.0), 1.0)
    dx, dy, dz = wx - s * ux, wy - s * uy, wz - s * uz
    return dx * dx + dy * dy + dz * dz

@jit.kernel(inline="always")
def point_to_segment(px, py, pz, ax, ay, az, ux, uy, uz, inv_uu):
    """Distance (metres) from point p to segment a + s u, s in [0, 1] (inv_uu = 1 / u . u)."""
    return np.sqrt(point_to_segment2(px, py, pz, ax, ay, az, ux, uy, uz, inv_uu))

@jit.kernel(inline="always")
def sphere_reaches(cx, cy, cz, r, ax, ay, az, ux, uy, uz, inv_uu, limit):
    """Whether the sphere (centre c, radius r) comes within ``limit`` of the segment
    a + s u (inv_uu = 1 / u . u)."""
    reach = limit + r
    if reach <= 0.0:
        return False
    return point_to_segment2(cx, cy, cz, ax, ay, az, ux, uy, uz, inv_uu) < reach * reach

@jit.kernel(inline="always")  # inlined: a call per part made the search ~2% slower
def segment_part(geo, part, ax, ay, az, ex, ey, ez, values, limit):
    """Closest pair of segment [a, e] (plane values of its ends: (2, P)) and one part:
    (distance, point on the part (3 floats), point on the segment (3 floats)). The nearer
    of the ends' closest points, then every edge that can come closer than the best so
    far. ``limit``: the best distance of the other parts; what cannot beat it is skipped
    too (the result is then the same wherever it is below ``limit``, and at least ``limit``
    elsewhere)."""
    edges, mid, half, faces = geo[2], geo[5], geo[6], geo[7]
    block_start, block_edge, block_center, block_radius = geo[11], geo[12], geo[13], geo[14]
    ux, uy, uz = ex - ax, ey - ay, ez - az
    uu = ux * ux + uy * uy + uz * uz
    inv_uu = 1.0 / max(uu, 1e-300)
    mx, my, mz = ax + 0.5 * ux, ay + 0.5 * uy, az + 0.5 * uz
    seg_half = 0.5 * np.sqrt(uu)
    da, cxa, cya, cza = point_part(geo, part, ax, ay, az, values, 0, limit)
    db, cxb, cyb, czb = point_part(geo, part, ex, ey, ez, values, 1, min(da, limit))
    if db < da:
        d, ox, oy, oz, sx, sy, sz = db, cxb, cyb, czb, ex, ey, ez
    else:
        d, ox, oy, oz, sx, sy, sz = da, cxa, cya, cza, ax, ay, az
    for block in range(block_start[part], block_start[part + 1]):
        # skip the block when its bounding sphere is farther than the best so far (and the
        # other parts' best), by the margin
        if not sphere_reaches(block_center[block, 0], block_center[block, 1],
                              block_center[block, 2], block_radius[block], ax, ay, az, ux,
                              uy, uz, inv_uu, min(d, limit) + PRUNE_MARGIN):
            continue
        for e in range(block_edge[block], block_edge[block + 1]):
            # skip the edge when the plane of one of its faces, or its bounding sphere, is
            # farther than the best so far (and the other parts' best), by the margin
            reach = min(d, limit) + PRUNE_MARGIN
            f0, f1 = faces[e, 0], faces[e, 1]
            if max(plane_gap(values[0, f0], values[1, f0]) if f0 >= 0 else 0.0,
                   plane_gap(values[0, f1], values[1, f1]) if f1 >= 0 else 0.0) >= reach:
                continue
            if not sphere_reaches(mid[e, 0], mid[e, 1], mid[e, 2], half[e], ax, ay, az, ux,
                                  uy, uz, inv_uu, reach):
                continue
            gap = (np.sqrt((mid[e, 0] - mx) ** 2 + (mid[e, 1] - my) ** 2
                           + (mid[e, 2] - mz) ** 2) - seg_half - half[e])
            if gap >= d:
                continue
            cx0, cy0, cz0 = edges[e, 0, 0], edges[e, 0, 1], edges[e, 0, 2]
            vx, vy, vz = edges[e, 1, 0] - cx0, edges[e, 1, 1] - cy0, edges[e, 1, 2] - cz0
            dd, qx, qy, qz, px, py, pz = segment_edge(ax, ay, az, ux, uy, uz, uu, cx0, cy0,
                                                      cz0, vx, vy, vz)
            if dd < d:
                d, ox, oy, oz, sx, sy, sz = dd, qx, qy, qz, px, py, pz
    return d, ox, oy, oz, sx, sy, sz

@jit.kernel(inline="always")
def float_lt(a, b):
    """a < b with NaN last."""
    return a < b or (np.isnan(b) and not np.isnan(a))

@jit.kernel(inline="always")
def insert_part(bounds, order, k, part):
    """Insert ``part`` into order[:k] (sorted by bounds, ties by part index, NaN last),
    after every entry of equal bound: parts inserted by increasing index end in the order
    of ``np.argsort(bounds, kind="stable")``."""
    value = bounds[part]
    j = k
    while j > 0 and float_lt(value, bounds[order[j - 1]]):
        order[j] = order[j - 1]
        j -= 1
    order[j] = part

@jit.kernel(_nrt=False)
def part_order(bounds, order):
    """order = ``np.argsort(bounds, kind="stable")`` (NaN last), without allocating: the
    order the search visits parts in (it decides between parts at equal distance)."""
    for part in range(bounds.shape[0]):
        insert_part(bounds, order, part, part)

@jit.kernel(inline="always")
def sphere_bound(center, radius, part, ax, ay, az, ux, uy, uz, inv_uu):
    """Lower bound of the distance from segment a + s u to a part inside the sphere
    (center[part], radius[part]) when positive (the segment is then outside the part);
    -inf when the segment meets the sphere."""
    bound = (point_to_segment(center[part, 0], center[part, 1], center[part, 2], ax, ay, az,
                              ux, uy, uz, inv_uu) - radius[part] - PRUNE_MARGIN)
    return bound if bound > 0.0 else -np.inf

@jit.kernel(_nrt=False)
def segment_bound(geo, ax, ay, az, ex, ey, ez, work):
    """A lower bound of the distance between segment [a, e] and the object (the smallest
    :func:`part_bounds`), and the first step of :func:`segment_one`: :func:`segment_search`
    may follow with the same work buffers."""
    bounds = work[0]
    part_bounds(geo[0], geo[1], ax, ay, az, ex, ey, ez, bounds, work[2])
    low = np.inf
    for part in range(bounds.shape[0]):
        low = min(low, bounds[part])
    return low

@jit.kernel(_nrt=False)
def visit_parts(geo, ax, ay, az, ex, ey, ez, work, start, k):
    """The search proper: parts order[:k] (work's order: by increasing bound, their bounds
    and plane values in work) visited until a bound reaches the best distance, which starts
    at ``start`` (metres): the result is the same wherever the object's distance is below
    ``start`` (the argument of :func:`segment_part`'s ``limit``, applied from the first
    part on), and ``start`` (nothing found) elsewhere."""
    center, radius = geo[8], geo[9]
    bounds, order, values = work[0], work[1], work[2]
    ux, uy, uz = ex - ax, ey - ay, ez - az
    inv_uu = 1.0 / max(ux * ux + uy * uy + uz * uz, 1e-300)
    best = start
    box = boy = boz = bsx = bsy = bsz = 0.0
    bpart = 0
    for rank in range(k):
        part = order[rank]
        if bounds[part] >= best:
            break
        if sphere_bound(center, radius, part, ax, ay, az, ux, uy, uz, inv_uu) >= best:
            continue
        d, ox, oy, oz, sx, sy, sz = segment_part(geo, part, ax, ay, az, ex, ey, ez, values,
                                                 best)
        if d < best:
            best = d
            box, boy, boz, bsx, bsy, bsz = ox, oy, oz, sx, sy, sz
            bpart = part
    return best, box, boy, boz, bsx, bsy, bsz, bpart

@jit.kernel(_nrt=False)
def segment_search(geo, ax, ay, az, ex, ey, ez, work):
    """:func:`segment_one` after its part bounds are in work (:func:`segment_bound`)."""
    part_order(work[0], work[1])
    return visit_parts(geo, ax, ay, az, ex, ey, ez, work, np.inf, work[0].shape[0])

@jit.kernel(_nrt=False)
def near_candidates(geo, ax, ay, az, ex, ey, ez, work, start, known):
    """The parts that can come closer than ``start`` to segment [a, e]: those whose
    bounding sphere and plane bound are below it, into work's order[:k] by increasing
    bound (ties by index), their bounds and plane values into work; returns k. The other
    parts' plane values are not computed. ``known``: every part's bound and plane values
    are in work already (:func:`segment_bound`)."""
    planes, plane_start, center, radius = geo[0], geo[1], geo[8], geo[9]
    bounds, order, values = work[0], work[1], work[2]
    ux, uy, uz = ex - ax, ey - ay, ez - az
    inv_uu = 1.0 / max(ux * ux + uy * uy + uz * uz, 1e-300)
    k = 0
    for part in range(plane_start.shape[0] - 1):
        if sphere_bound(center, radius, part, ax, ay, az, ux, uy, uz, inv_uu) >= start:
            continue
        if not known:
            bounds[part] = part_bound(planes, plane_start, part, ax, ay, az, ex, ey, ez,
                                      values)
        bound = bounds[part]
        if bound < start:
            insert_part(bounds, order, k, part)
            k += 1
    return k

@jit.kernel(_nrt=False)
def segment_search_near(geo, ax, ay, az, ex, ey, ez, work, px, py, pz, known):
    """:func:`segment_one`, faster when (px, py, pz) is a point of the object near the
    closest one (the one a query a moment earlier found): the same result, bit for bit.

    The search runs from start = |p - segment| + PRUNE_MARGIN, over the parts that can come
    closer than that (:func:`near_candidates`: the mug's queries compute the plane values
    of ~5 of its 52 parts). Where the result d is below start (the usual case: every point
    of the object is at least d from the segment; the margin keeps the point that is itself
    the closest one above rounding), it is d exactly: the candidates are visited in the
    plain search's order and compared as there (a part left out could neither be visited
    nor beat ``start``), the parts that beat ``start`` give the same values, the first of
    the smallest wins as there. Elsewhere (nothing below start: a segment through a part,
    whose distance function can exceed |p - segment|, or no point given: NaN) the plain
    search runs. The result never depends on p; only the time does. ``known``: the part
    bounds are in work already (:func:`segment_bound`)."""
    ux, uy, uz = ex - ax, ey - ay, ez - az
    inv_uu = 1.0 / max(ux * ux + uy * uy + uz * uz, 1e-300)
    start = point_to_segment(px, py, pz, ax, ay, az, ux, uy, uz, inv_uu) + PRUNE_MARGIN
    if start < np.inf:
        k = near_candidates(geo, ax, ay, az, ex, ey, ez, work, start, known)
        found = visit_parts(geo, ax, ay, az, ex, ey, ez, work, start, k)
        if found[0] < start:
            return found
    if known:
        return segment_search(geo, ax, ay, az, ex, ey, ez, work)
    return segment_one(geo, ax, ay, az, ex, ey, ez, work)

@jit.kernel(_nrt=False)
def segment_one(geo, ax, ay, az, ex, ey, ez, work):
    """Closest pair of segment [a, e] and the object (``geo``: :func:`geometry_tuple`):
    (distance, point on the object (3 floats), point on the segment (3 floats), part);
    work: :func:`segment_buffers`.

    Parts are visited by increasing :func:`part_bounds`, until the bound reaches the best
    distance found; a part whose bounding sphere is farther than that is skipped."""
    segment_bound(geo, ax, ay, az, ex, ey, ez, work)
    return segment_search(geo, ax, ay, az, ex, ey, ez, work)

@jit.kernel
def segment_buffers(planes, plane_start):
    """The work buffers of :func:`segment_one` for an object's planes (P, 4) in n_parts
    parts: (bounds (n_parts,), order (n_parts,) int64, plane values (2, P))."""
    n_parts = plane_start.shape[0] - 1
    return (np.empty(n_parts), np.empty(n_parts, dtype=np.int64),
            np.empty((2, planes.shape[0])))

@jit.kernel
def segments_closest(geo, a, b, out_d, out_obj, out_seg, out_part):
    """Closest pairs of segments [a, b] (n, 3) and the object (see :func:`segment_one`) into
    out_d (n,), out_obj, out_seg (n, 3), out_part (n,)."""
    work = segment_buffers(geo[0], geo[1])
    for i in range(a.shape[0]):
        (out_d[i], out_obj[i, 0], out_obj[i, 1], out_obj[i, 2], out_seg[i, 0],
         out_seg[i, 1], out_seg[i, 2], out_part[i]) = segment_one(
            geo, a[i, 0], a[i, 1], a[i, 2], b[i, 0], b[i, 1], b[i, 2], work)

def geometry_tuple(obj: GraspObject) -> tuple:
    """The object's packed parts as the kernels' ``geo`` tuple: planes, plane_start, edges,
    edge_start, scale, edge_mid, edge_half, edge_faces, part_center, part_radius, the
    relative on-face tolerance, block_start, block_edge, block_center, block_radius
    (:class:`PackedGeometry`)."""
    geo = packed_object(obj)
    return (geo.planes, geo.plane_start, geo.edges, geo.edge_start, geo.scale, geo.edge_mid,
            geo.edge_half, geo.edge_faces, geo.part_center, geo.part_radius, INSIDE_TOL,
            geo.block_start, geo.block_edge, geo.block_center, geo.block_radius)


def closest_to_segments(obj: GraspObject, a: np.ndarray, b: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Exact closest pairs between segments [a, b] (n, 3) (object frame, metres) that do
    not cross the object, and the object.

    Returns (on the object (n, 3), on the segment (n, 3), distance (n,), part (n,)).
    """
    a = np.ascontiguousarray(np.atleast_2d(a), dtype=float)
    b = np.ascontiguousarray(np.atleast_2d(b), dtype=float)
    n = len(a)
    out_d = np.empty(n)
    out_obj, out_seg = np.empty((n, 3)), np.empty((n, 3))
    out_part = np.zeros(n, dtype=np.int64)
    segments_closest(geometry_tuple(obj), a, b, out_d, out_obj, out_seg, out_part)
    return out_obj, out_seg, out_d, out_part
