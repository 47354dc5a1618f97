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
  sphere is farther than the best is skipped whole (it pays most on parts of many edges,
  such as the spray flask's 144-edge prisms);
- the closing loop starts each query's best distance at that of an object point an earlier
  query found (:func:`segment_search_near`: the same result, the plain search taking over
  where it does not hold), instead of inf.

Every bound is compared with a margin (:data:`PRUNE_MARGIN`) far above its rounding error, so
every candidate that could win is kept, in the plain search's order and compared as there:
the results are identical bit for bit (tested: the same search, interpreted, with
``PRUNE_MARGIN = inf`` turning the prunings off). The kernels allocate nothing and are
compiled without reference counting (see :mod:`kinegrasp_env.closing.close_kernel`).
Both engines use it in the near field, where a gap decides contact.

The parts' packing: :mod:`kinegrasp_env.closing.packed_geometry`; the small kernels the search
inlines: :mod:`kinegrasp_env.closing.segment_primitives`.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.closing.packed_geometry import geometry_tuple
from kinegrasp_env.closing.segment_primitives import (
    insert_part,
    part_bound,
    part_bounds,
    part_order,
    plane_gap,
    point_to_segment,
    segment_edge,
    sphere_reaches,
)
from kinegrasp_env.world.objects import GraspObject

#: Bounds prune only when they exceed the best distance by this much (metres): far above
#: their rounding error (~1e-16 m) and the faces' plane residuals (< FACE_RESIDUAL,
#: :mod:`kinegrasp_env.closing.packed_geometry`).
PRUNE_MARGIN = 1e-9


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


@jit.kernel
def segments_within(geo, a, b, limit, out_d, out_obj, out_seg, out_part):
    """:func:`segments_closest` where the distance is below ``limit`` (metres), the same
    pair bit for bit; elsewhere ``limit`` (the distance is at least that), NaN points and
    part -1. Only the parts that can come closer than ``limit`` are searched
    (:func:`near_candidates`, :func:`visit_parts`)."""
    work = segment_buffers(geo[0], geo[1])
    for i in range(a.shape[0]):
        ax, ay, az, ex, ey, ez = a[i, 0], a[i, 1], a[i, 2], b[i, 0], b[i, 1], b[i, 2]
        k = near_candidates(geo, ax, ay, az, ex, ey, ez, work, limit, False)
        found = visit_parts(geo, ax, ay, az, ex, ey, ez, work, limit, k)
        if found[0] < limit:
            (out_d[i], out_obj[i, 0], out_obj[i, 1], out_obj[i, 2], out_seg[i, 0],
             out_seg[i, 1], out_seg[i, 2], out_part[i]) = found
        else:
            out_d[i] = limit
            out_obj[i, :] = np.nan
            out_seg[i, :] = np.nan
            out_part[i] = -1


def closest_to_segments(obj: GraspObject, a: np.ndarray, b: np.ndarray,
                        limit: float = np.inf
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Exact closest pairs between segments [a, b] (n, 3) (object frame, metres) that do
    not cross the object, and the object; with a finite ``limit`` (metres), only where the
    distance is below it (elsewhere: ``limit``, NaN points, part -1:
    :func:`segments_within`).

    Returns (on the object (n, 3), on the segment (n, 3), distance (n,), part (n,)).
    """
    a = np.ascontiguousarray(np.atleast_2d(a), dtype=float)
    b = np.ascontiguousarray(np.atleast_2d(b), dtype=float)
    n = len(a)
    out_d = np.empty(n)
    out_obj, out_seg = np.empty((n, 3)), np.empty((n, 3))
    out_part = np.zeros(n, dtype=np.int64)
    if np.isfinite(limit):
        segments_within(geometry_tuple(obj), a, b, float(limit), out_d, out_obj, out_seg,
                        out_part)
    else:
        segments_closest(geometry_tuple(obj), a, b, out_d, out_obj, out_seg, out_part)
    return out_obj, out_seg, out_d, out_part
