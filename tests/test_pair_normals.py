"""The normal of a link-object pair off the object's faces (compiled), case by case against
directions derived by hand: a face of the link, two crossing edges, a link corner over an
object edge, an object corner; in a random frame, and turned with the distance's sign."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinegrasp_env.closing.pair_normals import LINE_TOL, pair_normals
from kinegrasp_env.world.polytope import ConvexPart, face_planes

H = 0.01  # the link: the box [-H, H]^3 in its frame
FACE_TOL = 5e-5


def _normal(link_local, object_point, object_edge, distance=1.0, seed=0):
    """pair_normals of one pair: the link point given in the link frame, the rest in the
    object frame (the link posed by a random rotation and translation)."""
    box = np.array([[x, y, z] for x in (-H, H) for y in (-H, H) for z in (-H, H)])
    part = ConvexPart(box, face_planes(box))
    rot = Rotation.random(random_state=seed).as_matrix()
    trans = np.array([0.1, -0.2, 0.3])
    link_point = rot @ link_local + trans
    out = np.empty((1, 3))
    pair_normals(part.planes, np.ascontiguousarray(part.edges), np.array([0, len(part.edges)]),
                 np.asarray(object_edge, dtype=float)[None], rot[None], trans[None],
                 link_point[None], np.asarray(object_point, dtype=float)[None],
                 np.array([distance]), FACE_TOL, LINE_TOL, np.empty((2, 3)), out)
    return out[0], rot, link_point


def _unit(v):
    return v / np.linalg.norm(v)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_link_face(seed):
    # the link point inside the link's +z face: that face's outward normal, object frame
    got, rot, _ = _normal(np.array([0.002, -0.003, H]), np.zeros(3),
                          [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]], seed=seed)
    np.testing.assert_allclose(_unit(got), rot @ [0.0, 0.0, 1.0], atol=1e-12)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_crossing_edges(sign):
    # the link point inside the link's edge along x at (y, z) = (H, H), the object point on
    # an object edge along u through it: u x (R e_x), turned towards (o - p) sign(d)
    rot = Rotation.random(random_state=4).as_matrix()
    v = rot @ [1.0, 0.0, 0.0]
    u = _unit(np.cross(v, rot @ [0.0, 1.0, 1.0]) + 0.3 * v)  # not parallel to v
    m = _unit(np.cross(u, v))
    p_local = np.array([0.003, H, H])
    p = rot @ p_local + np.array([0.1, -0.2, 0.3])
    o = p + 1e-3 * m
    got, _, _ = _normal(p_local, o, [o - 0.05 * u, o + 0.07 * u], distance=sign, seed=4)
    np.testing.assert_allclose(_unit(got), sign * m, atol=1e-12)


def test_link_corner_over_an_object_edge():
    # the link point at a corner: (o - p) without its component along the object's edge
    p_local = np.array([H, H, H])
    rot = Rotation.random(random_state=5).as_matrix()
    p = rot @ p_local + np.array([0.1, -0.2, 0.3])
    u = _unit(np.array([1.0, 2.0, -0.5]))
    o = p + np.array([0.001, -0.002, 0.0015])
    got, _, _ = _normal(p_local, o, [o - 0.04 * u, o + 0.03 * u], seed=5)
    d = o - p
    np.testing.assert_allclose(got, d - (d @ u) * u, atol=1e-15)


def test_object_corner():
    # the object point at an end of the object's edge (a corner): o - p
    p_local = np.array([H, H, 0.0])  # on a link edge
    rot = Rotation.random(random_state=6).as_matrix()
    p = rot @ p_local + np.array([0.1, -0.2, 0.3])
    o = p + np.array([0.0004, 0.0011, -0.0007])
    got, _, _ = _normal(p_local, o, [o, o + np.array([0.05, 0.0, 0.0])], distance=-2e-5, seed=6)
    np.testing.assert_allclose(got, -(o - p), atol=1e-15)


def test_an_object_edge_across_a_link_edge_overlapping_it():
    """An object edge crossing the link's edge along x at (y, z) = (H, H), 0.1 mm into the
    link along the edge's outward bisector (its direction u chosen so that u x v is that
    bisector): the pair's link point lies on the +y face, 0.07 mm below the +z face plane,
    the object point on the object edge, d = -0.07 mm. The normal is the crossing edges'
    u x v, pointing out of the link (towards (o - p) sign(d)): the bisector. The +y face's
    normal was taken (the link point more than FACE_TOL off the +z face, though a
    penetration's witness lies up to its depth off the features)."""
    rot = Rotation.random(random_state=7).as_matrix()
    trans = np.array([0.1, -0.2, 0.3])  # as _normal poses the link
    bisector = rot @ np.array([0.0, 1.0, 1.0]) / np.sqrt(2)
    u = _unit(rot @ np.array([0.3, 1.0, -1.0]))  # u x (R e_x) along -bisector
    depth = 1e-4
    o_local = np.array([0.003, H, H]) - depth * np.array([0.0, 1.0, 1.0]) / np.sqrt(2)
    p_local = np.array([o_local[0], H, o_local[2]])  # the nearest face, +y (a tie with +z)
    o = rot @ o_local + trans
    assert FACE_TOL < H - p_local[2] < FACE_TOL + np.linalg.norm(o_local - p_local)
    got, _, _ = _normal(p_local, o, [o - 0.05 * u, o + 0.04 * u],
                        distance=-np.linalg.norm(o_local - p_local), seed=7)
    np.testing.assert_allclose(_unit(got), bisector, atol=1e-9)
