"""Where a flat finger pad presses on a face: the centre of the contact patch.

Two flat faces in contact (a parallel jaw's pad on a box's face) touch over a whole region,
and a closest-point query returns one arbitrary point of it (a corner of the overlap, which
jumps from one corner to another as the pad tilts by a hair). The contact of such a finger
is placed at the centre of its patch instead:

* the finger link's collision geometry (pybullet's: the convex hull of each collision mesh,
  scaled, or a box's corners) in the object frame (:func:`link_hull_vertices`);
* its *footprint*: the convex hull, projected onto the face's plane, of its vertices within
  :data:`PATCH_DEPTH` of the lowest one above the plane (the part of a pad that a compliant
  finger presses in; a polygon, a segment when an edge touches, a point at a corner);
* the *patch*: the footprint clipped to the face (a convex polygon of the object's convex
  part), and the contact point its centroid (area centroid; a segment's midpoint), on the
  face. An empty clip (the pad's footprint beside the face) leaves the point as it was.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.spatial import ConvexHull, QhullError

#: The depth of the pad counted as pressing (metres): vertices within it of the lowest.
PATCH_DEPTH = 1e-3
#: Object vertices within this of a face plane lie on the face (metres).
FACE_TOL = 1e-7


@lru_cache(maxsize=32)
def _mesh_hull(filename: str) -> np.ndarray:
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
            local = _mesh_hull(filename.decode()) * np.asarray(dims, dtype=float)
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


def _plane_basis(normal: np.ndarray) -> np.ndarray:
    """(2, 3) orthonormal tangents of a plane with unit ``normal``."""
    helper = np.eye(3)[np.argmin(np.abs(normal))]
    t1 = np.cross(normal, helper)
    t1 /= np.linalg.norm(t1)
    return np.stack([t1, np.cross(normal, t1)])


def _hull_2d(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex polygon (m, 2) of points (n, 2): m = 1 (a point), 2 (a
    segment) or more."""
    unique = np.unique(np.round(points, 12), axis=0)
    if len(unique) >= 3:
        try:
            return unique[ConvexHull(unique).vertices]
        except QhullError:  # collinear
            pass
    if len(unique) == 1:
        return unique
    direction = unique[-1] - unique[0]
    s = unique @ direction
    return unique[[int(np.argmin(s)), int(np.argmax(s))]]


def _side(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> np.ndarray:
    """> 0 where points p (..., 2) lie left of the directed line a -> b."""
    edge = b - a
    return edge[0] * (p[..., 1] - a[1]) - edge[1] * (p[..., 0] - a[0])


def clip_convex(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """The part (k, 2) of a convex polygon (k >= 3), segment (2) or point (1) ``subject``
    inside the counter-clockwise convex polygon ``clip`` (empty (0, 2) when none):
    Sutherland-Hodgman for a polygon, the parameter interval of a segment, a point kept or
    not."""
    edges = [(clip[i], clip[(i + 1) % len(clip)]) for i in range(len(clip))]
    if len(subject) == 1:
        inside = all(_side(a, b, subject[0]) >= 0 for a, b in edges)
        return subject if inside else np.empty((0, 2))
    if len(subject) == 2:
        p, q = subject
        t0, t1 = 0.0, 1.0
        for a, b in edges:
            sp, sq = float(_side(a, b, p)), float(_side(a, b, q))
            if sp < 0 and sq < 0:
                return np.empty((0, 2))
            if (sp < 0) != (sq < 0):
                t = sp / (sp - sq)
                t0, t1 = (max(t0, t), t1) if sp < 0 else (t0, min(t1, t))
        if t0 > t1:
            return np.empty((0, 2))
        return np.array([p + (q - p) * t0, p + (q - p) * t1])
    out = subject
    for a, b in edges:
        kept = []
        for j in range(len(out)):
            p, q = out[j], out[(j + 1) % len(out)]
            sp, sq = float(_side(a, b, p)), float(_side(a, b, q))
            if sp >= 0:
                kept.append(p)
            if (sp >= 0) != (sq >= 0):
                kept.append(p + (q - p) * (sp / (sp - sq)))
        out = np.array(kept).reshape(-1, 2)
        if len(out) == 0:
            break
    return out


def centroid_2d(polygon: np.ndarray) -> np.ndarray:
    """(2,) area centroid of a polygon (k >= 3, ordered), a segment's midpoint (k = 2), the
    point (k = 1); the vertices' mean where the area vanishes."""
    if len(polygon) < 3:
        return polygon.mean(axis=0)
    x, y = polygon[:, 0], polygon[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    area = 0.5 * cross.sum()
    if abs(area) < 1e-16:
        return polygon.mean(axis=0)
    return np.array([((x + np.roll(x, -1)) * cross).sum(),
                     ((y + np.roll(y, -1)) * cross).sum()]) / (6.0 * area)


def patch_centre(finger_vertices: np.ndarray, face_vertices: np.ndarray, inward: np.ndarray,
                 on_plane: np.ndarray) -> np.ndarray | None:
    """(3,) the centre of a finger's patch on a face, or None when the footprint misses it.

    Args:
        finger_vertices: (V, 3) the finger link's geometry (object frame).
        face_vertices: (F, 3) the face's vertices (object frame; F >= 3).
        inward: (3,) the face's unit inward normal.
        on_plane: (3,) a point of the face's plane.
    """
    basis = _plane_basis(inward)
    height = (on_plane - finger_vertices) @ inward  # > 0 above the face (outside)
    near = finger_vertices[height <= height.min() + PATCH_DEPTH]
    footprint = _hull_2d((near - on_plane) @ basis.T)
    face = _hull_2d((face_vertices - on_plane) @ basis.T)
    if len(face) < 3:
        return None
    patch = clip_convex(footprint, face)
    if len(patch) == 0:
        return None
    return on_plane + centroid_2d(_hull_2d(patch) if len(patch) >= 3 else patch) @ basis


def face_patch_point(parts: tuple[np.ndarray, ...], finger_vertices: np.ndarray,
                     face: tuple[int, np.ndarray], point: np.ndarray) -> np.ndarray:
    """The contact point of a finger pressing on a face: the centre of its patch
    (:func:`patch_centre`), or ``point`` (3,) where the face has fewer than three vertices or
    the footprint misses it.

    Args:
        parts: the object's convex parts, each (n_i, 3) vertices (object frame).
        finger_vertices: (V, 3) the finger link's geometry (object frame).
        face: (part index, its face plane (4,): outward unit normal, offset).
        point: (3,) the closest point found on that face (object frame).
    """
    part, plane = face
    corners = parts[part]
    on_face = corners[np.abs(corners @ plane[:3] + plane[3]) < FACE_TOL]
    if len(on_face) < 3:
        return point
    on_plane = point - (point @ plane[:3] + plane[3]) * plane[:3]
    centre = patch_centre(finger_vertices, on_face, -plane[:3], on_plane)
    return point if centre is None else centre

