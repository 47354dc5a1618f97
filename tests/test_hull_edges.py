"""The object's edges against a link's hull (``hull_edges.edges_against_hull``): the least
signed distance over the edges, against an independent computation, SciPy's bounded Brent
minimisation along each edge of the numpy point-to-hull distance
(``ConvexPart.closest``, a convex function of the edge's parameter), on random hulls and
edges that pass beside the hull (the exact segment-to-part pair) and through it (the
golden-section search of a signed distance at most 0)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation

from kinegrasp_env.closing.hull_edges import edges_against_hull
from kinegrasp_env.closing.link_distances import GOLD, SEARCH
from kinegrasp_env.closing.packed_geometry import pack_parts, parts_tuple
from kinegrasp_env.world.polytope import INSIDE_TOL, ConvexPart, face_planes

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
    edges_against_hull(part.planes, part.edges, INSIDE_TOL * part.scale, sphere,
                       parts_tuple(pack_parts([part])), np.empty((2, len(part.planes))),
                       rot, trans, ends, np.inf, SEARCH, GOLD, best, link_point,
                       object_point, np.empty_like(ends))
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
