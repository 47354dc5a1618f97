"""The normal of a contact that is not on one face of the object, compiled: the direction
of the closest pair of a link and the object where the object's side of it is an edge or a
corner (pybullet's normal there).

The rule, per pair (link point p on the link's hulls, object point o, signed distance d):

1. p inside one face of the link's hulls (within ``face_tol`` + r of exactly one
   face plane): that face's outward normal;
2. else, o inside one object edge (direction u): where p lies inside one link edge too
   (within ``line_tol`` + 2 r; direction v, not parallel to u), u x v, turned
   towards (o - p) sign(d); else the part of (o - p) sign(d) perpendicular to u (p at a link
   corner);
3. else (o at an object corner) (o - p) sign(d).

A touching pair may overlap by up to the contact tolerance; p, the witness of that
penetration, lies on the face it leaves by and as deep below a neighbouring face as o is
(an object edge crossing a link edge: p up to |d| off that edge, on one of its faces), so
the link's features are taken within r = |o - p| where d < 0 (else r = 0): an object edge
across a pad's edge, overlapping it by 0.09 mm, took the normal of the face p lay on.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit

#: A point within this of a segment's interior (metres) lies on it (:func:`segment_holding`).
LINE_TOL = 1e-7
#: Below this |u x v| two unit edge directions count as parallel.
PARALLEL = 1e-6

__all__ = ["LINE_TOL", "PARALLEL", "pair_normals", "segment_holding"]


@jit.kernel(_nrt=False)
def segment_holding(segments, x, y, z, tol, direction):
    """Index of the one segment of ``segments`` (E, 2, 3) whose interior holds the point
    (x, y, z) (within ``tol`` metres, not within ``tol`` of its ends), its unit direction in
    ``direction`` (3,); -1 where none, several, or the point lies at an end of one."""
    found = -1
    for e in range(segments.shape[0]):
        ax, ay, az = segments[e, 0, 0], segments[e, 0, 1], segments[e, 0, 2]
        dx, dy, dz = segments[e, 1, 0] - ax, segments[e, 1, 1] - ay, segments[e, 1, 2] - az
        if (np.sqrt((x - ax) ** 2 + (y - ay) ** 2 + (z - az) ** 2) < tol
                or np.sqrt((x - ax - dx) ** 2 + (y - ay - dy) ** 2 + (z - az - dz) ** 2) < tol):
            return -1
        length2 = dx * dx + dy * dy + dz * dz
        s = ((x - ax) * dx + (y - ay) * dy + (z - az) * dz) / max(length2, 1e-300)
        s = min(max(s, 0.0), 1.0)
        gap = np.sqrt((ax + s * dx - x) ** 2 + (ay + s * dy - y) ** 2 + (az + s * dz - z) ** 2)
        length = np.sqrt(length2)
        if gap < tol and s * length > tol and (1.0 - s) * length > tol:
            if found >= 0:
                return -1
            found = e
            direction[0], direction[1], direction[2] = dx / length, dy / length, dz / length
    return found


@jit.kernel(_nrt=False)
def pair_normals(planes, link_edges, edge_starts, object_edges, rot, trans, link_point,
                 object_point, distance, face_tol, line_tol, scratch, out):
    """Per pair i: out[i] (3,), the module's rule (not unit length). The link: its hulls'
    face planes (F, 4) (outward unit normals, link frame), its hulls' edges link_edges
    (H, 2, 3) (hull p: rows edge_starts[p]:edge_starts[p + 1]), posed by rot (m, 3, 3) and
    trans (m, 3) (object frame); object_edges (E, 2, 3); link_point, object_point (m, 3),
    distance (m,): the pairs, object frame, metres. ``scratch`` (2, 3)."""
    for i in range(rot.shape[0]):
        r = rot[i]
        wx = link_point[i, 0] - trans[i, 0]
        wy = link_point[i, 1] - trans[i, 1]
        wz = link_point[i, 2] - trans[i, 2]
        lx = r[0, 0] * wx + r[1, 0] * wy + r[2, 0] * wz
        ly = r[0, 1] * wx + r[1, 1] * wy + r[2, 1] * wz
        lz = r[0, 2] * wx + r[1, 2] * wy + r[2, 2] * wz
        reach = 0.0  # a penetration's witness lies up to its depth |o - p| off its features
        if distance[i] < 0.0:
            reach = np.sqrt((object_point[i, 0] - link_point[i, 0]) ** 2
                            + (object_point[i, 1] - link_point[i, 1]) ** 2
                            + (object_point[i, 2] - link_point[i, 2]) ** 2)
        count, face = 0, -1
        for f in range(planes.shape[0]):
            if abs(planes[f, 0] * lx + planes[f, 1] * ly + planes[f, 2] * lz
                   + planes[f, 3]) < face_tol + reach:
                count += 1
                face = f
        if count == 1:
            for k in range(3):
                out[i, k] = (r[k, 0] * planes[face, 0] + r[k, 1] * planes[face, 1]
                             + r[k, 2] * planes[face, 2])
            continue
        sign = np.sign(distance[i])
        dx = (object_point[i, 0] - link_point[i, 0]) * sign
        dy = (object_point[i, 1] - link_point[i, 1]) * sign
        dz = (object_point[i, 2] - link_point[i, 2]) * sign
        u = scratch[0]
        if segment_holding(object_edges, object_point[i, 0], object_point[i, 1],
                           object_point[i, 2], line_tol, u) < 0:
            out[i, 0], out[i, 1], out[i, 2] = dx, dy, dz
            continue
        done = False
        for p in range(edge_starts.shape[0] - 1):
            w = scratch[1]
            if segment_holding(link_edges[edge_starts[p]:edge_starts[p + 1]], lx, ly, lz,
                               line_tol + 2.0 * reach, w) < 0:
                continue
            vx = r[0, 0] * w[0] + r[0, 1] * w[1] + r[0, 2] * w[2]
            vy = r[1, 0] * w[0] + r[1, 1] * w[1] + r[1, 2] * w[2]
            vz = r[2, 0] * w[0] + r[2, 1] * w[1] + r[2, 2] * w[2]
            cx = u[1] * vz - u[2] * vy
            cy = u[2] * vx - u[0] * vz
            cz = u[0] * vy - u[1] * vx
            if np.sqrt(cx * cx + cy * cy + cz * cz) > PARALLEL:
                turn = np.sign(cx * dx + cy * dy + cz * dz)
                out[i, 0], out[i, 1], out[i, 2] = cx * turn, cy * turn, cz * turn
                done = True
                break
        if not done:
            along = dx * u[0] + dy * u[1] + dz * u[2]
            out[i, 0] = dx - along * u[0]
            out[i, 1] = dy - along * u[1]
            out[i, 2] = dz - along * u[2]
