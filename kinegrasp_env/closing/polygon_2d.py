"""Convex polygons in the plane, compiled and allocation-free (the caller hands every
buffer in): the convex hull of points (:func:`hull_2d`), the clip of a convex polygon by
another (:func:`clip_polygon`), a polygon's area centroid (:func:`polygon_centroid`) and
measure (:func:`polygon_measure`), and its thinning to its widest corners
(:func:`thin_polygon`); :func:`clip_convex` and :func:`centroid_2d` call them from Python.
The steps of a flat pad's contact patch (:mod:`~kinegrasp_env.closing.contact_patch`).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit

__all__ = ["centroid_2d", "clip_convex", "clip_polygon", "hull_2d", "polygon_centroid",
           "polygon_measure", "thin_polygon"]


@jit.kernel(_nrt=False, inline="always")
def _side(ax, ay, bx, by, px, py):
    """> 0 where the point (px, py) lies left of the directed line a -> b."""
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax)


@jit.kernel(_nrt=False)
def hull_2d(points, n, out):
    """The convex hull of ``points[:n]`` (rows (x, y); rounded to 12 decimals, sorted and
    deduplicated in place) into ``out`` (at least 2 n rows), counter-clockwise from the
    lowest-leftmost vertex; returns its vertex count: 1 (a point), 2 (a segment: the two
    extreme points, every point on one line to round-off) or more (Andrew's monotone chain,
    turns below 1e-12 of the extent squared taken as straight)."""
    for i in range(n):
        points[i, 0] = round(points[i, 0], 12)
        points[i, 1] = round(points[i, 1], 12)
    for i in range(1, n):  # insertion sort by (x, y): n is a pad's few vertices
        x, y = points[i, 0], points[i, 1]
        j = i - 1
        while j >= 0 and (points[j, 0] > x or (points[j, 0] == x and points[j, 1] > y)):
            points[j + 1, 0], points[j + 1, 1] = points[j, 0], points[j, 1]
            j -= 1
        points[j + 1, 0], points[j + 1, 1] = x, y
    m = 0
    for i in range(n):
        if m == 0 or points[i, 0] != points[m - 1, 0] or points[i, 1] != points[m - 1, 1]:
            points[m, 0], points[m, 1] = points[i, 0], points[i, 1]
            m += 1
    if m == 1:
        out[0, 0], out[0, 1] = points[0, 0], points[0, 1]
        return 1
    # a turn smaller than this (relative to the points' extent squared) is no turn: points
    # on one line up to round-off give a segment
    low, high = points[0, 1], points[0, 1]
    for i in range(m):
        low, high = min(low, points[i, 1]), max(high, points[i, 1])
    flat = 1e-12 * ((points[m - 1, 0] - points[0, 0]) ** 2 + (high - low) ** 2)
    k = 0
    for i in range(m):  # lower chain
        while k >= 2 and _side(out[k - 2, 0], out[k - 2, 1], out[k - 1, 0], out[k - 1, 1],
                               points[i, 0], points[i, 1]) <= flat:
            k -= 1
        out[k, 0], out[k, 1] = points[i, 0], points[i, 1]
        k += 1
    lower = k + 1
    for i in range(m - 2, -1, -1):  # upper chain
        while k >= lower and _side(out[k - 2, 0], out[k - 2, 1], out[k - 1, 0],
                                   out[k - 1, 1], points[i, 0], points[i, 1]) <= flat:
            k -= 1
        out[k, 0], out[k, 1] = points[i, 0], points[i, 1]
        k += 1
    k -= 1  # the chain ends where it started
    if k < 3:
        out[0, 0], out[0, 1] = points[0, 0], points[0, 1]
        out[1, 0], out[1, 1] = points[m - 1, 0], points[m - 1, 1]
        return 2
    return k


@jit.kernel(_nrt=False)
def clip_polygon(subject, ns, clip, nc, out, work):
    """The part of a convex polygon (ns >= 3 rows), segment (2) or point (1) ``subject``
    inside the counter-clockwise convex polygon ``clip[:nc]``, into ``out``; returns its
    vertex count (0: none). Sutherland-Hodgman for a polygon, the parameter interval of a
    segment, a point kept or not. ``out`` and ``work``: at least ns + nc rows each."""
    if ns == 1:
        for e in range(nc):
            f = (e + 1) % nc
            if _side(clip[e, 0], clip[e, 1], clip[f, 0], clip[f, 1], subject[0, 0],
                     subject[0, 1]) < 0.0:
                return 0
        out[0, 0], out[0, 1] = subject[0, 0], subject[0, 1]
        return 1
    if ns == 2:
        px, py, qx, qy = subject[0, 0], subject[0, 1], subject[1, 0], subject[1, 1]
        t0, t1 = 0.0, 1.0
        for e in range(nc):
            f = (e + 1) % nc
            sp = _side(clip[e, 0], clip[e, 1], clip[f, 0], clip[f, 1], px, py)
            sq = _side(clip[e, 0], clip[e, 1], clip[f, 0], clip[f, 1], qx, qy)
            if sp < 0.0 and sq < 0.0:
                return 0
            if (sp < 0.0) != (sq < 0.0):
                t = sp / (sp - sq)
                if sp < 0.0:
                    t0 = max(t0, t)
                else:
                    t1 = min(t1, t)
        if t0 > t1:
            return 0
        out[0, 0], out[0, 1] = px + (qx - px) * t0, py + (qy - py) * t0
        out[1, 0], out[1, 1] = px + (qx - px) * t1, py + (qy - py) * t1
        return 2
    count = ns
    for j in range(ns):
        out[j, 0], out[j, 1] = subject[j, 0], subject[j, 1]
    for e in range(nc):
        f = (e + 1) % nc
        ax, ay, bx, by = clip[e, 0], clip[e, 1], clip[f, 0], clip[f, 1]
        kept = 0
        for j in range(count):
            k = (j + 1) % count
            sp = _side(ax, ay, bx, by, out[j, 0], out[j, 1])
            sq = _side(ax, ay, bx, by, out[k, 0], out[k, 1])
            if sp >= 0.0:
                work[kept, 0], work[kept, 1] = out[j, 0], out[j, 1]
                kept += 1
            if (sp >= 0.0) != (sq >= 0.0):
                t = sp / (sp - sq)
                work[kept, 0] = out[j, 0] + (out[k, 0] - out[j, 0]) * t
                work[kept, 1] = out[j, 1] + (out[k, 1] - out[j, 1]) * t
                kept += 1
        for j in range(kept):
            out[j, 0], out[j, 1] = work[j, 0], work[j, 1]
        count = kept
        if count == 0:
            break
    return count


#: A polygon whose area is below this (square metres) has none: it is a segment or a point.
VANISHING_AREA = 1e-16


@jit.kernel(_nrt=False, inline="always")
def _signed_area(polygon, k):
    """The signed area of ``polygon[:k]`` (ordered; counter-clockwise positive): the
    shoelace sum."""
    area = 0.0
    for j in range(k):
        n = (j + 1) % k
        area += 0.5 * (polygon[j, 0] * polygon[n, 1] - polygon[n, 0] * polygon[j, 1])
    return area


@jit.kernel(_nrt=False)
def polygon_centroid(polygon, k):
    """(x, y): the area centroid of ``polygon[:k]`` (k >= 3, ordered), a segment's midpoint
    (k = 2), the point (k = 1); the vertices' mean where the area vanishes
    (:data:`VANISHING_AREA`)."""
    mx, my = 0.0, 0.0
    for j in range(k):
        mx += polygon[j, 0] / k
        my += polygon[j, 1] / k
    if k < 3:
        return mx, my
    area = _signed_area(polygon, k)
    if abs(area) < VANISHING_AREA:
        return mx, my
    cx, cy = 0.0, 0.0
    for j in range(k):
        n = (j + 1) % k
        cross = polygon[j, 0] * polygon[n, 1] - polygon[n, 0] * polygon[j, 1]
        cx += (polygon[j, 0] + polygon[n, 0]) * cross
        cy += (polygon[j, 1] + polygon[n, 1]) * cross
    return cx / (6.0 * area), cy / (6.0 * area)


@jit.kernel(_nrt=False)
def polygon_measure(polygon, k):
    """(dimension, measure) of ``polygon[:k]`` (ordered) as :func:`polygon_centroid` reads
    it: (2, its area) for k >= 3 of area at least :data:`VANISHING_AREA`; (1, the longest
    distance between two of its vertices) for a segment (k = 2) or a polygon of vanishing
    area; (0, 0.0) for a point."""
    if k >= 3:
        area = abs(_signed_area(polygon, k))
        if area >= VANISHING_AREA:
            return 2, area
    longest = 0.0
    for j in range(k):
        for n in range(j + 1, k):
            longest = max(longest, np.hypot(polygon[n, 0] - polygon[j, 0],
                                            polygon[n, 1] - polygon[j, 1]))
    return (1, longest) if k >= 2 else (0, 0.0)


@jit.kernel(_nrt=False)
def thin_polygon(polygon, k, most):
    """Thin the convex polygon ``polygon[:k]`` (ordered) in place to at most ``most``
    vertices, each time dropping the vertex whose triangle with its two neighbours has the
    least area (the one whose loss shrinks the polygon least); returns the count kept. The
    result is a subset of the polygon."""
    while k > most and k > 2:
        drop, least = 0, np.inf
        for j in range(k):
            a, c = (j + k - 1) % k, (j + 1) % k
            area = abs(_side(polygon[a, 0], polygon[a, 1], polygon[j, 0], polygon[j, 1],
                             polygon[c, 0], polygon[c, 1]))
            if area < least:
                drop, least = j, area
        for j in range(drop, k - 1):
            polygon[j, 0], polygon[j, 1] = polygon[j + 1, 0], polygon[j + 1, 1]
        k -= 1
    return k


# ----------------------------------------------------------------------------- from Python
def _buffer(rows: int) -> np.ndarray:
    return np.empty((rows, 2))


def clip_convex(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """The part (k, 2) of a convex polygon (k >= 3), segment (2) or point (1) ``subject``
    inside the counter-clockwise convex polygon ``clip`` (empty (0, 2) when none):
    :func:`clip_polygon`."""
    subject, clip = np.asarray(subject, dtype=float), np.asarray(clip, dtype=float)
    rows = len(subject) + len(clip) + 1
    out = _buffer(rows)
    count = clip_polygon(subject, len(subject), clip, len(clip), out, _buffer(rows))
    return out[:count].copy()


def centroid_2d(polygon: np.ndarray) -> np.ndarray:
    """(2,) :func:`polygon_centroid` of a polygon (k, 2)."""
    polygon = np.asarray(polygon, dtype=float)
    return np.array(polygon_centroid(polygon, len(polygon)))
