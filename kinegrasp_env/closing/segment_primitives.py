"""Small compiled pieces of the exact segment search
(:mod:`kinegrasp_env.closing.segment_distance`): the closest pair of two segments,
point-segment distances, sphere and plane bounds, and the allocation-free stable ordering of
parts by their bounds (most inlined where they are called).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit


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
    """Closest pair of segment a + s u and edge c0 + t v (s, t in [0, 1]; uu = u . u, 0
    for a segment that is a point): (distance, point on the edge (3 floats), point on the
    segment (3 floats))."""
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
    if t < 0.0:  # uu may be 0: a segment that is a point (a sphere's core)
        s = min(max(-cc / max(uu, 1e-300), 0.0), 1.0)
    elif t > 1.0:
        s = min(max((bb - cc) / max(uu, 1e-300), 0.0), 1.0)
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
