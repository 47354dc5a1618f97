"""Which face of the object a finger's contact lies on, for its contact patch.

A contact's face is the one face plane of the object's nearest convex part within a
tolerance of the contact point (:func:`faces_of`); none at an edge or a corner. A closest-point
query returns an arbitrary point of the region where a flat pad touches a face, and that
point may lie on the face's border: there the face a pad lies flat on is the one whose
plane its collision geometry does not cross by more than the depth a pad is pressed in
(:func:`flat_face`, with :data:`~kinegrasp_env.closing.contact_patch.PATCH_DEPTH`), as both
closings decide it. The patch on that face: :mod:`~kinegrasp_env.closing.contact_patch`.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.contact_patch import PATCH_DEPTH


def _planes_near(obj, points: np.ndarray, tol: float):
    """Per nearest part of the object-frame points (n, 3) (``GraspObject.nearest_part``):
    yields (part, rows (r,) of the points it is nearest to, its face planes (F, 4) with unit
    outward normals, (r, F) bool: the planes within ``tol`` metres of each of those points)."""
    part = obj.nearest_part(points)
    for p in np.unique(part):
        rows = np.flatnonzero(part == p)
        pl = obj.planes[p] / np.linalg.norm(obj.planes[p][:, :3], axis=1, keepdims=True)
        yield p, rows, pl, np.abs(points[rows] @ pl[:, :3].T + pl[:, 3]) < tol


def faces_of(obj, points: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The face each object-frame point (n, 3) lies on: ((n,) its part, -1 where none;
    (n, 4) its plane, outward unit normal and offset). A point's part is the object's
    nearest part (``GraspObject.nearest_part``); its face the one face plane of that part
    within ``tol`` metres; none at an edge or a corner (two or more planes that near) or off
    the surface."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    found, planes = np.full(len(points), -1, dtype=np.int64), np.zeros((len(points), 4))
    for p, rows, pl, near in _planes_near(obj, points, tol):
        one = near.sum(axis=1) == 1
        planes[rows[one]] = pl[np.argmax(near[one], axis=1)]
        found[rows[one]] = p
    return found, planes


def flat_face(obj, points: np.ndarray, vertices: np.ndarray, tol: float,
              depth: float = PATCH_DEPTH) -> tuple[np.ndarray, np.ndarray]:
    """The face a flat link presses on at each object-frame point (n, 3) that
    :func:`faces_of` finds at an edge or a corner: ((n,) its part, -1 where none; (n, 4) its
    plane, outward unit normal and offset). Of the face planes of the point's nearest part
    within ``tol`` metres of it, the one plane that the link's vertices (n, V, 3; object
    frame: its collision geometry's, as both closings read it) do not cross by more than
    ``depth`` metres (the depth a pad is pressed in, as its footprint counts it:
    :data:`~kinegrasp_env.closing.contact_patch.PATCH_DEPTH`) and that a face of the link
    lies on (three vertices not on one line within ``depth`` of the plane), or an edge of
    the link lies across (two vertices within ``depth`` of the plane, more than sqrt(2)
    ``depth`` apart: :func:`spans`, one of them more than ``depth`` inside the face from
    every other plane there): a pad on a face lies
    on that face's outer side, or dips past its edge by less than that where it is tilted,
    and crosses the plane of the face beside it by its whole overhang; a tilted pad whose
    edge lies on a face and runs off it over the face's edge touches the face along a
    segment, whose end the closest point may be (the contact then goes to its patch's
    centre, about the middle of that segment, as it goes where the closest point lies inside
    the face); a pad on the edge itself, tilted between the two faces, crosses both by more,
    or touches with a corner of its own only, or with an edge along the object's edge."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    found, planes = np.full(len(points), -1, dtype=np.int64), np.zeros((len(points), 4))
    for p, rows, pl, near in _planes_near(obj, points, tol):
        heights = vertices[rows] @ pl[:, :3].T + pl[:, 3]  # (rows, V, planes)
        beside = near & (heights.min(axis=1) >= -depth)
        r, k = np.nonzero(beside)
        if r.size:  # a face of the link on the plane, or an edge of it lying across the face
            on = np.abs(heights[r, :, k]) <= depth  # (n, V) the link's vertices on the plane
            others = near[r] & (np.arange(pl.shape[0]) != k[:, None])  # (n, planes)
            # inside the face: deeper than the pressed depth below every other plane at the
            # point (off the edge, into the face)
            inside = np.all(~others[:, None, :] | (heights[r] < -depth), axis=2)  # (n, V)
            beside[r, k] = (spans_a_face(vertices[rows[r]], on, depth)
                            | (spans_a_segment(vertices[rows[r]], on, depth)
                               & (on & inside).any(axis=1)))
        one = beside.sum(axis=1) == 1
        planes[rows[one]] = pl[np.argmax(beside[one], axis=1)]
        found[rows[one]] = p
    return found, planes


def spans(points: np.ndarray, on: np.ndarray, tol: float, dimension: int) -> np.ndarray:
    """(m,) bool: the points (m, V, 3) flagged ``on`` (m, V) span a figure of ``dimension``
    (1: a segment, 2: a polygon): singular value ``dimension`` of the centred points (the
    square root of that eigenvalue of their scatter, k x their covariance for k points),
    largest first, above ``tol``: two points more than sqrt(2) ``tol`` apart; three points
    not within about ``tol`` metres of one line."""
    count = on.sum(axis=1)
    weights = on / np.maximum(count, 1)[:, None]
    mean = np.einsum("mv,mvi->mi", weights, points)
    centred = (points - mean[:, None, :]) * on[:, :, None]
    scatter = np.einsum("mvi,mvj->mij", centred, centred)
    value = np.linalg.eigvalsh(scatter)[:, 3 - dimension]
    return (count >= dimension + 1) & (value > tol * tol)


def spans_a_segment(points: np.ndarray, on: np.ndarray, tol: float) -> np.ndarray:
    """:func:`spans` a segment."""
    return spans(points, on, tol, 1)


def spans_a_face(points: np.ndarray, on: np.ndarray, tol: float) -> np.ndarray:
    """:func:`spans` a polygon."""
    return spans(points, on, tol, 2)
