"""The object's edges against a robot link's convex hull, compiled: the half of the exact
closest pair of two convex polytopes that the object's vertices cannot give (every closest
pair of two polytopes apart has a vertex of one polytope, or points on an edge of each; the
link's vertices against the object are the other half, :meth:`~kinegrasp_env.world.objects.
GraspObject.closest_points`); the same kernel also runs the link's edges through the object's
parts, where the two overlap (``meeting_only``).

An edge that passes beside the hull is measured exactly as a finger's capsule axis is
against the object: the nearer of its ends' closest points or of its closest pairs with the
hull's edges (:func:`~kinegrasp_env.closing.segment_distance.segment_part`, the hull packed
as one part). An edge that meets the hull (clipped by the hull's face planes, a piece is
left) has a signed distance at most 0 there, a convex function of the point's parameter
along the edge, whose minimum is found by golden-section search
(:data:`~kinegrasp_env.closing.link_distances.SEARCH` steps, then the two ends compared).
An edge whose distance to the hull's bounding ball, or whose plane bound (the largest over
the hull's face planes of the smaller plane value of its two ends), both lower bounds of its
distance, cannot beat the best distance so far is skipped; a search stops as soon as the
distance's Lipschitz bound over the bracket (the edge's length times the bracket's width
below the smaller of its two values) cannot beat it either. The link's vertices against the
object's parts are compiled here too (:func:`vertices_against_parts`).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.closing.segment_distance import PRUNE_MARGIN, segment_part
from kinegrasp_env.closing.segment_primitives import part_bound, point_to_segment


@jit.kernel(_nrt=False, inline="always")
def point_hull(planes, edges, tol, x, y, z, limit):
    """(signed distance, closest x, y, z) of a point to a convex hull given by its face
    planes (F, 4) (outward unit normals) and edges (H, 2, 3): exact, as
    :meth:`~kinegrasp_env.world.polytope.ConvexPart.closest`; where the largest plane value
    (a lower bound of the distance) is at or above ``limit``, that value (and its plane
    projection) instead."""
    top = -np.inf
    face = 0
    for f in range(planes.shape[0]):
        v = planes[f, 0] * x + planes[f, 1] * y + planes[f, 2] * z + planes[f, 3]
        if v > top:
            top, face = v, f
    px = x - top * planes[face, 0]
    py = y - top * planes[face, 1]
    pz = z - top * planes[face, 2]
    if top <= 0.0 or top >= limit:
        return top, px, py, pz
    worst = -np.inf
    for f in range(planes.shape[0]):
        v = planes[f, 0] * px + planes[f, 1] * py + planes[f, 2] * pz + planes[f, 3]
        if v > worst:
            worst = v
    if worst <= tol:
        return top, px, py, pz
    best = np.inf
    bx, by, bz = px, py, pz
    for e in range(edges.shape[0]):
        ax, ay, az = edges[e, 0, 0], edges[e, 0, 1], edges[e, 0, 2]
        dx, dy, dz = edges[e, 1, 0] - ax, edges[e, 1, 1] - ay, edges[e, 1, 2] - az
        length2 = max(dx * dx + dy * dy + dz * dz, 1e-300)
        s = ((x - ax) * dx + (y - ay) * dy + (z - az) * dz) / length2
        s = min(max(s, 0.0), 1.0)
        cx, cy, cz = ax + s * dx, ay + s * dy, az + s * dz
        d2 = (x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2
        if d2 < best:
            best, bx, by, bz = d2, cx, cy, cz
    return np.sqrt(best), bx, by, bz


@jit.kernel(_nrt=False, inline="always")
def edge_at(planes, edges, tol, rot, trans, ends, e, i, s):
    """Distance and closest hull point (link frame) of the point at parameter s of object
    edge e, placed in the link frame of draw i."""
    wx = ends[e, 0, 0] + s * (ends[e, 1, 0] - ends[e, 0, 0]) - trans[i, 0]
    wy = ends[e, 0, 1] + s * (ends[e, 1, 1] - ends[e, 0, 1]) - trans[i, 1]
    wz = ends[e, 0, 2] + s * (ends[e, 1, 2] - ends[e, 0, 2]) - trans[i, 2]
    x = rot[i, 0, 0] * wx + rot[i, 1, 0] * wy + rot[i, 2, 0] * wz
    y = rot[i, 0, 1] * wx + rot[i, 1, 1] * wy + rot[i, 2, 1] * wz
    z = rot[i, 0, 2] * wx + rot[i, 1, 2] * wy + rot[i, 2, 2] * wz
    return point_hull(planes, edges, tol, x, y, z, np.inf)


@jit.kernel(_nrt=False, inline="always")
def _ball_gap(local, e, sphere):
    """A lower bound (metres) of the distance of segment local[e] (2, 3) to what a ball
    (``sphere`` (4,): centre, radius) holds: the segment's distance to its centre, less
    its radius."""
    ax, ay, az = local[e, 0, 0], local[e, 0, 1], local[e, 0, 2]
    ux, uy, uz = local[e, 1, 0] - ax, local[e, 1, 1] - ay, local[e, 1, 2] - az
    inv_uu = 1.0 / max(ux * ux + uy * uy + uz * uz, 1e-300)
    return point_to_segment(sphere[0], sphere[1], sphere[2], ax, ay, az, ux, uy, uz,
                            inv_uu) - sphere[3]


@jit.kernel(_nrt=False, inline="always")
def meets_hull(values, margin):
    """Whether a segment meets a convex hull grown by ``margin`` (metres), from its ends'
    values on the hull's face planes (``values`` (2, F)): the segment clipped by every
    plane (Cyrus-Beck) leaves a piece."""
    lo, hi = 0.0, 1.0
    for f in range(values.shape[1]):
        a, b = values[0, f] - margin, values[1, f] - margin
        if a > 0.0 and b > 0.0:
            return False
        if a > 0.0:
            lo = max(lo, a / (a - b))
        elif b > 0.0:
            hi = min(hi, a / (a - b))
        if lo > hi:
            return False
    return True


@jit.kernel(_nrt=False)
def edges_against_hull(geo, sphere, values, rot, trans, ends, below, steps, gold, best,
                       link_point, object_point, local, meeting_only):
    """For each draw i (rot (n, 3, 3), trans (n, 3): the link's object-frame pose), lower
    best[i] to the least distance of the object's edges ``ends`` (E, 2, 3) to the hull
    (``geo``: packed as one part, :func:`~kinegrasp_env.closing.packed_geometry.
    parts_tuple`: its face planes (F, 4), edges and on-face tolerance) where that is
    smaller, with its link point and object point (object frame, (n, 3)).

    Edges whose distance to the hull's bounding ball (``sphere`` (4,): centre, radius;
    link frame), and then whose plane bound, is not below min(best[i], below) are skipped.
    An edge that does not meet the hull is measured exactly by the closest pair of a
    segment and a convex part (:func:`~kinegrasp_env.closing.segment_distance.
    segment_part`); one that meets it (a signed distance at most 0, a convex function of
    the edge's parameter) by ``steps`` golden-section steps, the rest of whose search is
    skipped once its Lipschitz bound over the bracket is not below min(best[i], below).
    ``local`` (E, 2, 3) and ``values`` (2, F) are scratch: the edges' ends in the link
    frame of the draw, an edge's ends' plane values. ``meeting_only``: edges that do not meet
    the hull are skipped (the link's edges against the object's parts: only an edge through
    the other polytope can give what its vertices and the other's edges do not, a depth)."""
    planes, edges, tol = geo[0], geo[2], geo[10] * geo[4][0]
    for i in range(rot.shape[0]):
        for e in range(ends.shape[0]):  # the edges' ends in the link frame of draw i
            for k in range(2):
                wx = ends[e, k, 0] - trans[i, 0]
                wy = ends[e, k, 1] - trans[i, 1]
                wz = ends[e, k, 2] - trans[i, 2]
                local[e, k, 0] = rot[i, 0, 0] * wx + rot[i, 1, 0] * wy + rot[i, 2, 0] * wz
                local[e, k, 1] = rot[i, 0, 1] * wx + rot[i, 1, 1] * wy + rot[i, 2, 1] * wz
                local[e, k, 2] = rot[i, 0, 2] * wx + rot[i, 1, 2] * wy + rot[i, 2, 2] * wz
        for e in range(ends.shape[0]):
            if not _ball_gap(local, e, sphere) < min(best[i], below):
                continue
            ax, ay, az = local[e, 0, 0], local[e, 0, 1], local[e, 0, 2]
            ex, ey, ez = local[e, 1, 0], local[e, 1, 1], local[e, 1, 2]
            if not part_bound(planes, geo[1], 0, ax, ay, az, ex, ey, ez, values) < min(best[i],
                                                                                   below):
                continue
            if not meets_hull(values, PRUNE_MARGIN):
                if meeting_only:
                    continue
                d, hx, hy, hz, sx, sy, sz = segment_part(geo, 0, ax, ay, az, ex, ey, ez,
                                                         values, min(best[i], below))
                if d < best[i]:
                    best[i] = d
                    for k in range(3):
                        link_point[i, k] = (rot[i, k, 0] * hx + rot[i, k, 1] * hy
                                            + rot[i, k, 2] * hz + trans[i, k])
                        object_point[i, k] = (rot[i, k, 0] * sx + rot[i, k, 1] * sy
                                              + rot[i, k, 2] * sz + trans[i, k])
                continue
            lo, hi = 0.0, 1.0
            x1, x2 = hi - gold * (hi - lo), lo + gold * (hi - lo)
            f1 = edge_at(planes, edges, tol, rot, trans, ends, e, i, x1)[0]
            f2 = edge_at(planes, edges, tol, rot, trans, ends, e, i, x2)[0]
            length = np.sqrt((ends[e, 1, 0] - ends[e, 0, 0]) ** 2
                             + (ends[e, 1, 1] - ends[e, 0, 1]) ** 2
                             + (ends[e, 1, 2] - ends[e, 0, 2]) ** 2)
            hopeless = False
            for _ in range(steps):
                # the distance is length-Lipschitz in s: nothing in [lo, hi] (where the
                # minimum lies) can come below the limit
                if min(f1, f2) - length * (hi - lo) - tol >= min(best[i], below):
                    hopeless = True
                    break
                if f1 < f2:
                    hi, x2, f2 = x2, x1, f1
                    x1 = hi - gold * (hi - lo)
                    f1 = edge_at(planes, edges, tol, rot, trans, ends, e, i, x1)[0]
                else:
                    lo, x1, f1 = x1, x2, f2
                    x2 = lo + gold * (hi - lo)
                    f2 = edge_at(planes, edges, tol, rot, trans, ends, e, i, x2)[0]
            if hopeless:
                continue
            s = 0.5 * (lo + hi)
            d, cx, cy, cz = edge_at(planes, edges, tol, rot, trans, ends, e, i, s)
            for end in (0.0, 1.0):
                de, ex, ey, ez = edge_at(planes, edges, tol, rot, trans, ends, e, i, end)
                if de < d:
                    s, d, cx, cy, cz = end, de, ex, ey, ez
            if d < best[i]:
                best[i] = d
                for k in range(3):
                    object_point[i, k] = ends[e, 0, k] + s * (ends[e, 1, k] - ends[e, 0, k])
                    link_point[i, k] = (rot[i, k, 0] * cx + rot[i, k, 1] * cy
                                        + rot[i, k, 2] * cz + trans[i, k])


@jit.kernel(_nrt=False)
def vertices_against_parts(planes, plane_starts, edges, edge_starts, tols, rot, trans,
                           vertices, below, best, link_point, object_point):
    """For each draw i (rot (n, 3, 3), trans (n, 3): the link's object-frame pose), the
    least signed distance of the link's vertices (V, 3, its frame) to the object's convex
    parts (part p: face planes planes[plane_starts[p]:plane_starts[p + 1]], edges
    edges[edge_starts[p]:edge_starts[p + 1]], tolerance tols[p]; :func:`point_hull`), into
    best[i], with that vertex (link_point, object frame (n, 3)) and its closest object point
    (object_point); a vertex whose largest plane value is not below min(best[i], below) is
    not examined further (a best[i] left at or above ``below`` is only an upper bound)."""
    for i in range(rot.shape[0]):
        best[i] = np.inf
        for v in range(vertices.shape[0]):
            lx, ly, lz = vertices[v, 0], vertices[v, 1], vertices[v, 2]
            x = rot[i, 0, 0] * lx + rot[i, 0, 1] * ly + rot[i, 0, 2] * lz + trans[i, 0]
            y = rot[i, 1, 0] * lx + rot[i, 1, 1] * ly + rot[i, 1, 2] * lz + trans[i, 1]
            z = rot[i, 2, 0] * lx + rot[i, 2, 1] * ly + rot[i, 2, 2] * lz + trans[i, 2]
            for p in range(plane_starts.shape[0] - 1):
                d, cx, cy, cz = point_hull(planes[plane_starts[p]:plane_starts[p + 1]],
                                           edges[edge_starts[p]:edge_starts[p + 1]], tols[p],
                                           x, y, z, min(best[i], below))
                if d < best[i]:
                    best[i] = d
                    link_point[i, 0], link_point[i, 1], link_point[i, 2] = x, y, z
                    object_point[i, 0], object_point[i, 1], object_point[i, 2] = cx, cy, cz
