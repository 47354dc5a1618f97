"""Where a flat finger pad presses on a face: the centre of the contact patch.

Two flat faces in contact (a parallel jaw's pad on a box's face) touch over a whole region,
and a closest-point query returns one arbitrary point of it (a corner of the overlap, which
jumps from one corner to another as the pad tilts by a hair). The contact of such a finger
is placed at the centre of its patch instead:

* the finger link's collision geometry (pybullet's: the convex hull of each collision mesh,
  scaled, or a box's corners) in the object frame (:func:`link_hull_vertices`);
* its *footprint*: the convex hull, projected onto the face's plane, of its vertices within
  :data:`PATCH_DEPTH` of the lowest one, counted from no lower than the plane (the part of a
  pad that a compliant finger presses in; a polygon, a segment when an edge touches, a point
  at a corner; a vertex below the plane lies off the face, past its edge, where a pad
  overhangs it, and presses nothing);
* the *patch*: the footprint clipped to the face (a convex polygon of the object's convex
  part) and to every other part's face in the same plane (a flat side of an object split
  into convex parts is several parts' faces side by side: a pad across them presses them
  all, whichever part the query named), and the contact point its centroid (area centroid;
  a segment's midpoint), on the face. An empty clip (the pad's footprint beside the faces)
  leaves the point as it was.

One compiled loop places any number of contacts (:func:`patch_points`: both generic closings
call it, the reference one contact at a time, the fast one every contact of a batch at once);
its steps are the compiled polygon functions of :mod:`~kinegrasp_env.closing.polygon_2d`
(:func:`~kinegrasp_env.closing.polygon_2d.hull_2d`, :func:`~kinegrasp_env.closing.polygon_2d.
clip_polygon`, :func:`~kinegrasp_env.closing.polygon_2d.polygon_centroid`), without
allocation: the caller hands every buffer in. Which face a contact lies on is decided by
:mod:`~kinegrasp_env.closing.pad_faces`.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.closing.polygon_2d import (
    clip_polygon,
    hull_2d,
    polygon_centroid,
    polygon_measure,
    thin_polygon,
)

#: The depth of the pad counted as pressing (metres): vertices within it of the lowest one
#: (counted from no lower than the face's plane).
PATCH_DEPTH = 1e-3
#: Object vertices within this of a face plane lie on the face (metres).
FACE_TOL = 1e-7
#: Another convex part's vertices within this of a contact face's plane lie in that plane
#: (metres): the parts a convex decomposition splits one flat side into are not exactly
#: coplanar (3.4 um apart on an open box's wall, measured).
COPLANAR_TOL = 1e-5
#: Corners of a patch kept for the patch contact model (a box pad's patch on a larger face
#: is a quadrilateral; a patch of more corners is thinned to this many:
#: :func:`~kinegrasp_env.closing.polygon_2d.thin_polygon`).
PATCH_CORNERS = 4


@lru_cache(maxsize=32)
def mesh_hull(filename: str) -> np.ndarray:
    """(V, 3) the convex hull vertices of a mesh file (its own units, unscaled)."""
    import trimesh

    mesh = trimesh.load(filename, force="mesh", process=False)
    return np.asarray(mesh.convex_hull.vertices, dtype=float)


def link_hull_vertices(bullet, body: int, link: int) -> np.ndarray | None:
    """(V, 3) world-frame vertices of a link's collision geometry (meshes: their convex
    hulls, as pybullet collides them; boxes: their corners), or None for other shapes."""
    if link < 0:
        position, orientation = bullet.getBasePositionAndOrientation(body)
    else:
        state = bullet.getLinkState(body, link, computeForwardKinematics=True)
        position, orientation = state[0], state[1]  # the link's inertial frame
    out = []
    for shape in bullet.getCollisionShapeData(body, link):
        kind, dims, filename, local_pos, local_orn = shape[2], shape[3], shape[4], shape[5], \
            shape[6]
        if kind == 5:  # GEOM_MESH
            local = mesh_hull(filename.decode()) * np.asarray(dims, dtype=float)
        elif kind == 3:  # GEOM_BOX: full extents
            half = 0.5 * np.asarray(dims, dtype=float)
            local = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                              for sz in (-1, 1)]) * half
        else:
            return None
        pos, orn = bullet.multiplyTransforms(position, orientation, local_pos, local_orn)
        rot = np.reshape(bullet.getMatrixFromQuaternion(orn), (3, 3))
        out.append(local @ rot.T + np.asarray(pos))
    return np.vstack(out) if out else None


@jit.kernel(_nrt=False, inline="always")
def plane_basis(ix, iy, iz):
    """(ux, uy, uz, vx, vy, vz): an orthonormal basis of the plane normal to the unit vector
    (ix, iy, iz), u normal to it and to the coordinate axis along which it is smallest (the
    lowest index of a tie), v = i x u."""
    hx, hy, hz = 1.0, 0.0, 0.0
    if abs(iy) < abs(ix) and abs(iy) <= abs(iz):
        hx, hy = 0.0, 1.0
    elif abs(iz) < abs(ix) and abs(iz) < abs(iy):
        hx, hz = 0.0, 1.0
    ux, uy, uz = iy * hz - iz * hy, iz * hx - ix * hz, ix * hy - iy * hx
    norm = np.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / norm, uy / norm, uz / norm
    return ux, uy, uz, iy * uz - iz * uy, iz * ux - ix * uz, ix * uy - iy * ux


@jit.kernel(_nrt=False)
def pad_footprint(vertices, poses, i, ox, oy, oz, ix, iy, iz, ux, uy, uz, vx, vy, vz, depth,
                  out):
    """A pad's footprint on a plane, its points' count k: of a link's vertices (V, 3, its
    frame) posed at ``poses[i]`` (4, 4), those within ``depth`` of the lowest one (its
    height above the plane through (ox, oy, oz) with the unit normal (ix, iy, iz) into the
    object; counted from no lower than the plane: a vertex below it lies off the face, past
    its edge, pressing nothing), projected onto the plane's basis (u, v) into ``out[:k]``
    (rows (x, y))."""
    low = np.inf
    k = 0
    for pas in range(2):  # the lowest vertex, then those near it
        if pas == 1:
            low = max(low, 0.0)
        k = 0
        for v in range(vertices.shape[0]):
            wx = (poses[i, 0, 0] * vertices[v, 0] + poses[i, 0, 1] * vertices[v, 1]
                  + poses[i, 0, 2] * vertices[v, 2] + poses[i, 0, 3]) - ox
            wy = (poses[i, 1, 0] * vertices[v, 0] + poses[i, 1, 1] * vertices[v, 1]
                  + poses[i, 1, 2] * vertices[v, 2] + poses[i, 1, 3]) - oy
            wz = (poses[i, 2, 0] * vertices[v, 0] + poses[i, 2, 1] * vertices[v, 1]
                  + poses[i, 2, 2] * vertices[v, 2] + poses[i, 2, 3]) - oz
            height = -(wx * ix + wy * iy + wz * iz)
            if pas == 0:
                low = min(low, height)
            elif height <= low + depth:
                out[k, 0] = wx * ux + wy * uy + wz * uz
                out[k, 1] = wx * vx + wy * vy + wz * vz
                k += 1
    return k


@jit.kernel(_nrt=False)
def face_in_plane(corners, starts, p, chosen, nx, ny, nz, off, ox, oy, oz, ux, uy, uz, vx, vy,
                  vz, face_tol, out):
    """The count of part p's corners on the plane (outward unit normal (nx, ny, nz), offset
    ``off``; within ``face_tol``, or :data:`COPLANAR_TOL` for a part other than the
    ``chosen`` one, the contact's own), projected onto the plane's basis (u, v) about the
    point (ox, oy, oz) into ``out`` (rows (x, y)); 0 where a corner of another part lies
    further than that outside the plane (the plane is not a face of that part)."""
    if not chosen:
        face_tol = COPLANAR_TOL
    nf = 0
    for c in range(starts[p], starts[p + 1]):
        cx, cy, cz = corners[c, 0], corners[c, 1], corners[c, 2]
        height = cx * nx + cy * ny + cz * nz + off
        if height > face_tol and not chosen:
            return 0
        if abs(height) < face_tol:
            cx, cy, cz = cx - ox, cy - oy, cz - oz
            out[nf, 0] = cx * ux + cy * uy + cz * uz
            out[nf, 1] = cx * vx + cy * vy + cz * vz
            nf += 1
    return nf


@jit.kernel(_nrt=False)
def patch_points(vertices, poses, corners, starts, spheres, parts, planes, points, depth,
                 face_tol, work, out, found, poly, counts):
    """The patch centre of a link on a face, and the patch's corners, for M contacts (the
    module's steps).

    The footprint is clipped to the contact's face and to every other convex part's face in
    the same plane (a flat side of an object split into convex parts is the faces of several
    parts, side by side): the patch is those pieces, its centre their centroid weighted by
    area (by length where every piece is a segment; their mean where every piece is a
    point), its corners the convex hull of the pieces' corners. A region that k overlapping
    parts cover weighs k times in the centre (a decomposition's parts seldom overlap).

    Args:
        vertices: (V, 3) the link's hull vertices in its own frame (metres).
        poses: (M, 4, 4) the link's pose in the object frame, per contact.
        corners: (C, 3) every convex part's vertices, stacked (object frame).
        starts: (P + 1,) int64: part p's corners are rows starts[p] .. starts[p + 1] - 1.
        spheres: (P, 4) a sphere about each part's corners (centre, radius): a part whose
            sphere misses the plane has no face in it.
        parts: (M,) the part of each contact's face; planes: (M, 4) the face's plane
            (outward unit normal, offset); points: (M, 3) the closest point found on it.
        depth: :data:`PATCH_DEPTH`; face_tol: :data:`FACE_TOL` (metres).
        work: (7, S, 2) scratch, S >= 2 (P V + C) + 8.
        out: (M, 3) the contact points: the patch centre, else the point as given.
        found: (M,) bool, True where a patch centre was placed.
        poly: (M, K, 3) the patch's corners (object frame), in order around it; a patch of
            more than K corners is thinned to K of them
            (:func:`~kinegrasp_env.closing.polygon_2d.thin_polygon`: a subset of the patch).
        counts: (M,) int64 corners given (0 where no patch was placed).
    """
    for i in range(points.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = points[i, 0], points[i, 1], points[i, 2]
        found[i] = False
        counts[i] = 0
        nx, ny, nz, off = planes[i, 0], planes[i, 1], planes[i, 2], planes[i, 3]
        s = points[i, 0] * nx + points[i, 1] * ny + points[i, 2] * nz + off
        ox, oy, oz = points[i, 0] - s * nx, points[i, 1] - s * ny, points[i, 2] - s * nz
        ux, uy, uz, vx, vy, vz = plane_basis(-nx, -ny, -nz)
        k = pad_footprint(vertices, poses, i, ox, oy, oz, -nx, -ny, -nz, ux, uy, uz, vx, vy,
                          vz, depth, work[2])
        mp = hull_2d(work[2], k, work[5])  # the footprint, kept for every part
        pieces, gathered, dimension, weight, px, py = 0, 0, -1, 0.0, 0.0, 0.0
        cx, cy = 0.0, 0.0
        for p in range(starts.shape[0] - 1):
            if p != parts[i] and abs(spheres[p, 0] * nx + spheres[p, 1] * ny
                                     + spheres[p, 2] * nz + off) > spheres[p, 3] + COPLANAR_TOL:
                continue
            nf = face_in_plane(corners, starts, p, p == parts[i], nx, ny, nz, off, ox, oy, oz,
                               ux, uy, uz, vx, vy, vz, face_tol, work[0])
            if nf < 3:
                continue
            mf = hull_2d(work[0], nf, work[1])
            if mf < 3:
                continue
            mc = clip_polygon(work[5], mp, work[1], mf, work[4], work[2])
            if mc == 0:
                continue
            piece = 4
            if mc >= 3:
                mc = hull_2d(work[4], mc, work[3])
                piece = 3
            cx, cy = polygon_centroid(work[piece], mc)
            dim, measure = polygon_measure(work[piece], mc)
            if dim > dimension:  # a piece of a higher dimension outweighs the rest
                dimension, weight, px, py = dim, 0.0, 0.0, 0.0
            if dim == dimension:
                w = measure if measure > 0.0 else 1.0
                weight += w
                px, py = px + w * cx, py + w * cy
            for j in range(mc):
                work[6, gathered + j, 0] = work[piece, j, 0]
                work[6, gathered + j, 1] = work[piece, j, 1]
            gathered += mc
            pieces += 1
        if pieces == 0:
            continue
        if pieces == 1:  # the piece itself, its centroid and corners in its own order
            px, py = cx, cy
            for j in range(gathered):
                work[2, j, 0], work[2, j, 1] = work[6, j, 0], work[6, j, 1]
            mc = gathered
        else:
            px, py = px / weight, py / weight
            mc = hull_2d(work[6], gathered, work[2])
        out[i, 0] = ox + px * ux + py * vx
        out[i, 1] = oy + px * uy + py * vy
        out[i, 2] = oz + px * uz + py * vz
        found[i] = True
        keep = thin_polygon(work[2], mc, poly.shape[1])
        for j in range(keep):
            ax, ay = work[2, j, 0], work[2, j, 1]
            poly[i, j, 0] = ox + ax * ux + ay * vx
            poly[i, j, 1] = oy + ax * uy + ay * vy
            poly[i, j, 2] = oz + ax * uz + ay * vz
        counts[i] = keep


class PatchGeometry:
    """An object's convex parts packed for :func:`patch_points` (corners stacked, offsets).

    Args:
        parts: each convex part's (n_i, 3) vertices (object frame).
    """

    def __init__(self, parts: tuple[np.ndarray, ...]) -> None:
        self.corners = np.ascontiguousarray(np.vstack(parts), dtype=float)
        self.starts = np.concatenate([[0], np.cumsum([len(p) for p in parts])]).astype(np.int64)
        centres = np.array([0.5 * (p.min(axis=0) + p.max(axis=0)) for p in parts])
        radii = [np.linalg.norm(p - c, axis=1).max() for p, c in zip(parts, centres, strict=True)]
        self.spheres = np.ascontiguousarray(np.column_stack([centres, radii]), dtype=float)

    def place(self, vertices: np.ndarray, poses: np.ndarray, parts: np.ndarray,
              planes: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """((M, 3) contact points, (M,) bool found): :func:`patch_points` of a link's
        vertices (V, 3, its frame) at poses (M, 4, 4) on faces (part (M,), plane (M, 4)),
        the closest points (M, 3) found on them."""
        out, found, _, _ = self.patches(vertices, poses, parts, planes, points)
        return out, found

    def patches(self, vertices: np.ndarray, poses: np.ndarray, parts: np.ndarray,
                planes: np.ndarray, points: np.ndarray, corners: int = PATCH_CORNERS
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`place`'s centres and flags, and each patch's corners: ((M, corners, 3)
        object frame, NaN beyond each count; (M,) int64 counts, 0 where no patch)."""
        m = len(points)
        out, found = np.empty((m, 3)), np.empty(m, dtype=np.bool_)
        poly, counts = np.full((m, corners, 3), np.nan), np.zeros(m, dtype=np.int64)
        parts_count = len(self.starts) - 1
        work = np.empty((7, 2 * (parts_count * len(vertices) + len(self.corners)) + 8, 2))
        patch_points(np.ascontiguousarray(vertices, dtype=float),
                     np.ascontiguousarray(poses, dtype=float), self.corners, self.starts,
                     self.spheres, np.ascontiguousarray(parts, dtype=np.int64),
                     np.ascontiguousarray(planes, dtype=float),
                     np.ascontiguousarray(points, dtype=float), PATCH_DEPTH, FACE_TOL, work,
                     out, found, poly, counts)
        return out, found, poly, counts


def patch_centre(finger_vertices: np.ndarray, face_vertices: np.ndarray, inward: np.ndarray,
                 on_plane: np.ndarray) -> np.ndarray | None:
    """(3,) the centre of a finger's patch on a face, or None when the footprint misses it
    (or the face has fewer than three vertices).

    Args:
        finger_vertices: (V, 3) the finger link's geometry (object frame).
        face_vertices: (F, 3) the face's vertices (object frame; on its plane).
        inward: (3,) the face's unit inward normal.
        on_plane: (3,) a point of the face's plane.
    """
    inward, on_plane = np.asarray(inward, dtype=float), np.asarray(on_plane, dtype=float)
    plane = np.append(-inward, inward @ on_plane)
    out, found = PatchGeometry((np.asarray(face_vertices, dtype=float),)).place(
        finger_vertices, np.eye(4)[None], np.zeros(1, np.int64), plane[None], on_plane[None])
    return out[0] if found[0] else None


def face_patch_point(patch: PatchGeometry, finger_vertices: np.ndarray,
                     face: tuple[int, np.ndarray], point: np.ndarray) -> np.ndarray:
    """The contact point of a finger pressing on a face: the centre of its patch
    (:func:`patch_points`: on that face and every face in its plane), or ``point`` (3,)
    where the footprint misses them.

    Args:
        patch: the object's convex parts, packed.
        finger_vertices: (V, 3) the finger link's geometry (object frame).
        face: (part index, its face plane (4,): outward unit normal, offset).
        point: (3,) the closest point found on that face (object frame).
    """
    part, plane = face
    out, _ = patch.place(
        finger_vertices, np.eye(4)[None], np.array([part], np.int64), np.asarray(plane)[None],
        np.asarray(point, dtype=float)[None])
    return out[0]
