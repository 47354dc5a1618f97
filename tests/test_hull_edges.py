"""The object's edges against a link's hull (``hull_edges.edges_against_hull``): the least
signed distance over the edges, against an independent computation, SciPy's bounded Brent
minimisation along each edge of the numpy point-to-hull distance
(``ConvexPart.closest``, a convex function of the edge's parameter), on random hulls and
edges that pass beside the hull (the exact segment-to-part pair) and through it (the
golden-section search of a signed distance at most 0); a roof whose shallow ridge is an edge
of the part (``ConvexPart.edges`` keeps every edge between two planes of ``face_planes``),
against an exact formula; and segments of no length (a sphere's core) against the numpy
point distances."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation

from kinegrasp_env.closing.hull_edges import edges_against_hull
from kinegrasp_env.closing.link_distances import GOLD, SEARCH
from kinegrasp_env.closing.packed_geometry import pack_parts, parts_tuple
from kinegrasp_env.world.polytope import ConvexPart, face_planes

#: Measured: at most 2e-17 m from the reference on 81 draws of edges beside the hull (the
#: reference's parameter tolerance, 1e-12, times an edge's length, bounds it); 1e-12 m allowed.
BESIDE_TOL = 1e-12
#: Through the hull (69 draws): at most 3.7e-10 m (the golden search's parameter to
#: 0.618**40 = 4e-9 of an edge's length); 1e-9 m allowed.
THROUGH_TOL = 1e-9


def _signed(part: ConvexPart, points: np.ndarray) -> np.ndarray:
    return part.closest(points)[1]


def _reference(part: ConvexPart, a: np.ndarray, b: np.ndarray) -> float:
    """The least signed distance of segment [a, b] to ``part`` (Brent along it)."""
    along = lambda s: float(_signed(part, (a + s * (b - a))[None])[0])  # noqa: E731
    found = minimize_scalar(along, bounds=(0.0, 1.0), method="bounded",
                            options={"xatol": 1e-12})
    return min(found.fun, along(0.0), along(1.0))


def _cases(seed: int, n_draws: int):
    rng = np.random.default_rng(seed)
    vertices = rng.normal(size=(20, 3)) * 0.02
    part = ConvexPart(vertices, face_planes(vertices))
    ends = rng.uniform(-0.05, 0.05, (4, 2, 3))
    rot = Rotation.random(n_draws, random_state=seed).as_matrix()
    trans = rng.uniform(-0.06, 0.06, (n_draws, 3))
    return part, np.ascontiguousarray(ends), np.ascontiguousarray(rot), trans


def _kernel(part, ends, rot, trans):
    n = rot.shape[0]
    best, link_point, object_point = np.full(n, np.inf), np.empty((n, 3)), np.empty((n, 3))
    centre = part.vertices.mean(axis=0)
    sphere = np.append(centre, np.linalg.norm(part.vertices - centre, axis=1).max())
    edges_against_hull(parts_tuple(pack_parts([part])), sphere,
                       np.empty((2, len(part.planes))), rot, trans, ends, np.inf, SEARCH, GOLD,
                       best, link_point, object_point, np.empty_like(ends), False)
    return best, link_point, object_point


@pytest.mark.parametrize("seed", range(6))
def test_least_edge_distance_against_brent(seed):
    part, ends, rot, trans = _cases(seed, 25)
    best, link_point, object_point = _kernel(part, ends, rot, trans)
    through = beside = 0
    for i in range(rot.shape[0]):
        # the object's edges in the link's frame: x_link = R^T (x - t)
        local = (ends - trans[i]) @ rot[i]
        want = min(_reference(part, a, b) for a, b in local)
        if want > 0.0:
            beside += 1
            assert abs(best[i] - want) <= BESIDE_TOL, (i, best[i], want)
            # the pair found is that far apart, its object point on an object edge
            assert abs(np.linalg.norm(link_point[i] - object_point[i]) - best[i]) <= 1e-12
        else:
            through += 1
            assert abs(best[i] - want) <= THROUGH_TOL, (i, best[i], want)
        on_edge = [np.linalg.norm(np.cross(object_point[i] - a, b - a)) / np.linalg.norm(b - a)
                   for a, b in ends]
        assert min(on_edge) <= 1e-12
    assert beside >= 5 and through >= 1, (beside, through)


def _roof(half_angle: float) -> tuple[ConvexPart, float]:
    """A 10 cm block whose top is a roof of two faces meeting at a ridge along x (z = top),
    each tilted by ``half_angle`` (radians) off the horizontal; and the ridge's height."""
    x, y, eaves = 0.05, 0.05, 0.04
    top = eaves + y * np.tan(half_angle)
    vertices = np.array([[sx * x, sy * y, 0.0] for sx in (-1, 1) for sy in (-1, 1)]
                        + [[sx * x, sy * y, eaves] for sx in (-1, 1) for sy in (-1, 1)]
                        + [[sx * x, 0.0, top] for sx in (-1, 1)])
    return ConvexPart(vertices, face_planes(vertices)), top


@pytest.mark.parametrize("half_angle", [5e-7, 1e-5, 1e-2])
def test_a_shallow_ridge_is_an_edge(half_angle):
    """A ridge between two faces that are not one face of ``face_planes`` (their planes
    differ) is an edge, however shallow: a point above it, and an edge crossing above it,
    are h from the roof (the ridge is the nearest point: an exact formula); a ridge left out
    puts them nearer one face's plane and further by about the segment's length times the
    angle."""
    part, top = _roof(half_angle)
    assert len(part.planes) == 7  # both roof faces kept
    h = 1e-3
    closest, distance = part.closest(np.array([[0.01, 0.0, top + h]]))
    assert abs(distance[0] - h) <= 1e-15 and abs(closest[0, 2] - top) <= 1e-15
    ends = np.array([[[0.01, -0.04, top + h], [0.01, 0.04, top + h]]])
    best, link_point, _ = _kernel(part, ends, np.eye(3)[None], np.zeros((1, 3)))
    assert abs(best[0] - h) <= 1e-15, best[0] - h
    assert abs(link_point[0, 1]) <= 1e-15 and abs(link_point[0, 2] - top) <= 1e-15


def test_a_segment_that_is_a_point():
    """A zero-length segment (a URDF sphere's core, an edge of no length) is a point: its
    distance to a part or to the object is the numpy point distance
    (``ConvexPart.closest``, ``GraspObject.closest_points``), beside a corner, a face and an
    edge, where the closest pair of segments divides by the segment's length."""
    from kinegrasp_env.closing.segment_distance import closest_to_segments
    from kinegrasp_env.world.objects import load_object

    cube = np.array([[x, y, z] for x in (-.02, .02) for y in (-.02, .02) for z in (-.02, .02)])
    part = ConvexPart(cube, face_planes(cube))
    points = np.array([[0.05, 0.0, 0.0], [0.03, 0.03, 0.03], [0.0, 0.03, 0.021]])
    for p in points:
        best = _kernel(part, np.array([[p, p]]), np.eye(3)[None], np.zeros((1, 3)))[0]
        assert abs(best[0] - part.closest(p[None])[1][0]) <= 1e-15
    obj = load_object("cube")
    corner = np.vstack([q.vertices for q in obj.convex_parts]).max(axis=0)
    points = corner + np.array([[0.01, 0.01, 0.01], [0.01, 0.0, 0.0], [0.0, -0.01, 0.004]])
    distance = closest_to_segments(obj, points, points)[2]
    np.testing.assert_allclose(distance, obj.closest_points(points)[1], rtol=0, atol=1e-15)


def test_two_smallest_is_the_stable_sorts_first_two():
    """The packing's choice of each edge's two nearest planes (O(P) a row) is the first two
    of a stable sort, ties, infinities and NaN included (values drawn from a few integers:
    many ties)."""
    from kinegrasp_env.closing.packed_geometry import _two_smallest

    rng = np.random.default_rng(2)
    for width in (1, 2, 3, 7, 40):
        values = rng.integers(0, 4, (300, width)).astype(float)
        values[rng.random(values.shape) < 0.6] = np.nan  # NaN sorts last
        values[rng.random(values.shape) < 0.1] = np.inf
        want = np.argsort(values, axis=1, kind="stable")[:, :2]
        np.testing.assert_array_equal(_two_smallest(values), want)
