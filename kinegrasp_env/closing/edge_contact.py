"""Where a flat finger pad presses on an edge of the object: the middle of the pressed part.

A flat pad laid against an edge of the object (a parallel jaw on a cylinder's mesh that
turns an edge, not a face, towards it) touches it along a segment, and a closest-point query
returns one arbitrary point of it (an end of the pad, an end of the edge, or any point
between, as round-off decides): two jaws on opposite edges then get contacts at different
heights, out of force closure, where the same jaws on a mesh turned by half a facet are in
it. The contact is placed at the middle of the pressed segment instead, as
:mod:`~kinegrasp_env.closing.contact_patch` places a pad on a face at its patch's centre:

* the edge: the one edge of the object's convex parts whose interior holds the contact point
  (:func:`~kinegrasp_env.closing.pair_normals.segment_holding`), or at a corner, the edge
  from it that runs most nearly along the contact's tangent plane (:func:`flattest_edge_at`:
  a pad along a cylinder's side, touching it at the rim), cut to the part of it within
  :data:`~kinegrasp_env.closing.contact_patch.PATCH_DEPTH` (the depth a pad is pressed in)
  of the contact's tangent plane (the plane through the point normal to the contact's
  normal);
* the pad's *footprint* on that plane: the convex hull, projected onto it, of the link's
  vertices within that depth of the lowest one (as a patch's footprint is counted);
* the pressed segment: the cut edge clipped to the footprint
  (:func:`~kinegrasp_env.closing.polygon_2d.clip_polygon`), and the contact point its
  midpoint, on the edge. A footprint that is a segment or a point (the pad touches with an
  edge or a corner of its own: one point of contact) or misses the edge leaves the point as
  it was.

Both generic closings call :func:`edge_midpoints` (one compiled loop, allocation-free) on
the contacts of flat links at an edge of the object, with the normals they found there.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.closing.contact_patch import PATCH_DEPTH, pad_footprint, plane_basis
from kinegrasp_env.closing.pair_normals import LINE_TOL, segment_holding
from kinegrasp_env.closing.polygon_2d import clip_polygon, hull_2d

__all__ = ["edge_midpoints", "place_on_edges"]


@jit.kernel(_nrt=False)
def flattest_edge_at(edges, x, y, z, nx, ny, nz, tol):
    """Index of the edge of ``edges`` (E, 2, 3) with an end within ``tol`` metres of the
    corner (x, y, z) that leaves it most nearly along the plane normal to the unit
    (nx, ny, nz) (the least |cos| between the edge and the normal), or -1 where none."""
    best, found = np.inf, -1
    for e in range(edges.shape[0]):
        for end in range(2):
            if np.sqrt((edges[e, end, 0] - x) ** 2 + (edges[e, end, 1] - y) ** 2
                       + (edges[e, end, 2] - z) ** 2) >= tol:
                continue
            dx = edges[e, 1, 0] - edges[e, 0, 0]
            dy = edges[e, 1, 1] - edges[e, 0, 1]
            dz = edges[e, 1, 2] - edges[e, 0, 2]
            length = np.sqrt(dx * dx + dy * dy + dz * dz)
            slope = abs(dx * nx + dy * ny + dz * nz) / max(length, 1e-300)
            if slope < best:
                best, found = slope, e
    return found


@jit.kernel(_nrt=False)
def edge_midpoints(vertices, poses, edges, normals, points, depth, line_tol, work, direction,
                   out, found):
    """The middle of the pressed part of the object's edge at each of M contacts (the
    module's steps).

    Args:
        vertices: (V, 3) the link's hull vertices in its own frame (metres).
        poses: (M, 4, 4) the link's pose in the object frame, per contact.
        edges: (E, 2, 3) the object's convex parts' edges (object frame).
        normals: (M, 3) the contacts' unit normals, into the object.
        points: (M, 3) the contact points found (on the object's surface).
        depth: the pressed depth (metres); line_tol: a point within this of an edge's
            interior lies on it (metres).
        work: (4, S, 2) scratch, S >= 2 V + 8; direction: (3,) scratch.
        out: (M, 3) the contact points: the pressed segment's midpoint, else the point.
        found: (M,) bool, True where a midpoint was placed.
    """
    for i in range(points.shape[0]):
        ox, oy, oz = points[i, 0], points[i, 1], points[i, 2]
        out[i, 0], out[i, 1], out[i, 2] = ox, oy, oz
        found[i] = False
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        e = segment_holding(edges, ox, oy, oz, line_tol, direction)
        if e < 0:
            e = flattest_edge_at(edges, ox, oy, oz, nx, ny, nz, line_tol)
        if e < 0:
            continue
        ux, uy, uz, vx, vy, vz = plane_basis(nx, ny, nz)
        # the edge's part within the pressed depth of the tangent plane: t in [t0, t1]
        ax, ay, az = edges[e, 0, 0] - ox, edges[e, 0, 1] - oy, edges[e, 0, 2] - oz
        dx, dy, dz = edges[e, 1, 0] - edges[e, 0, 0], edges[e, 1, 1] - edges[e, 0, 1], \
            edges[e, 1, 2] - edges[e, 0, 2]
        ha = ax * nx + ay * ny + az * nz  # heights into the object
        hd = dx * nx + dy * ny + dz * nz
        t0, t1 = 0.0, 1.0
        if hd > 1e-15:
            t1 = min(t1, (depth - ha) / hd)
        elif hd < -1e-15:
            t0 = max(t0, (depth - ha) / hd)
        if t0 >= t1:
            continue
        # the pad's footprint on the tangent plane
        k = pad_footprint(vertices, poses, i, ox, oy, oz, nx, ny, nz, ux, uy, uz, vx, vy, vz,
                          depth, work[0])
        mp = hull_2d(work[0], k, work[1])
        if mp < 3:
            continue
        px, py = ax + t0 * dx, ay + t0 * dy  # the cut edge, projected
        pz = az + t0 * dz
        qx, qy, qz = ax + t1 * dx, ay + t1 * dy, az + t1 * dz
        work[2, 0, 0], work[2, 0, 1] = px * ux + py * uy + pz * uz, px * vx + py * vy + pz * vz
        work[2, 1, 0], work[2, 1, 1] = qx * ux + qy * uy + qz * uz, qx * vx + qy * vy + qz * vz
        span = (work[2, 1, 0] - work[2, 0, 0]) ** 2 + (work[2, 1, 1] - work[2, 0, 1]) ** 2
        if span < 1e-24:  # the edge points into the pad: touched at a point
            continue
        mc = clip_polygon(work[2], 2, work[1], mp, work[3], work[0])
        if mc < 2:
            continue
        s0 = ((work[3, 0, 0] - work[2, 0, 0]) * (work[2, 1, 0] - work[2, 0, 0])
              + (work[3, 0, 1] - work[2, 0, 1]) * (work[2, 1, 1] - work[2, 0, 1])) / span
        s1 = ((work[3, 1, 0] - work[2, 0, 0]) * (work[2, 1, 0] - work[2, 0, 0])
              + (work[3, 1, 1] - work[2, 0, 1]) * (work[2, 1, 1] - work[2, 0, 1])) / span
        t = t0 + 0.5 * (s0 + s1) * (t1 - t0)
        out[i, 0] = edges[e, 0, 0] + t * dx
        out[i, 1] = edges[e, 0, 1] + t * dy
        out[i, 2] = edges[e, 0, 2] + t * dz
        found[i] = True


def place_on_edges(vertices: np.ndarray, poses: np.ndarray, edges: np.ndarray,
                   normals: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((M, 3) contact points, (M,) bool placed): :func:`edge_midpoints` of a link's
    vertices (V, 3, its frame) at poses (M, 4, 4) (object frame) against the object's edges
    (E, 2, 3), for contacts at points (M, 3) with unit normals (M, 3) into the object."""
    m = len(points)
    out, found = np.empty((m, 3)), np.empty(m, dtype=np.bool_)
    vertices = np.ascontiguousarray(vertices, dtype=float)
    edge_midpoints(vertices, np.ascontiguousarray(poses, dtype=float),
                   np.ascontiguousarray(edges, dtype=float),
                   np.ascontiguousarray(normals, dtype=float),
                   np.ascontiguousarray(points, dtype=float), PATCH_DEPTH, LINE_TOL,
                   np.empty((4, 2 * len(vertices) + 8, 2)), np.empty(3), out, found)
    return out, found
