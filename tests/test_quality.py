"""Ferrari-Canny quality: conventions, hand-checked values, fast == qhull, invariances."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from quality_cases import box_contacts, pad_pinch, sphere_contacts
from scipy.spatial import ConvexHull

from kinegrasp_env.quality import (
    ferrari_canny,
    ferrari_canny_batch,
    friction_cone_edges,
    grasp_wrench_space_volume,
    is_force_closure,
    is_force_closure_batch,
    tangent_basis,
    wrench_matrix,
)

CUBE_NORMALS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]])


# ----------------------------------------------------------------------------- conventions
def test_tangent_basis_convention():
    t1, t2 = tangent_basis(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.6, 0.0, 0.8]]))
    # n = z: smallest |n_i| is a tie between x and y -> x (lowest index); t1 = z x x = y
    np.testing.assert_allclose(t1[0], [0, 1, 0])
    np.testing.assert_allclose(t2[0], [-1, 0, 0])
    # n = x: tie y/z -> y; t1 = x x y = z; t2 = x x z = -y
    np.testing.assert_allclose(t1[1], [0, 0, 1])
    np.testing.assert_allclose(t2[1], [0, -1, 0])
    # n = (0.6, 0, 0.8): smallest is y; t1 = n x y normalized = (-0.8, 0, 0.6)
    np.testing.assert_allclose(t1[2], [-0.8, 0, 0.6])


def test_cone_edges_and_wrenches_follow_design():
    n = np.array([[0.0, 0.0, 1.0]])
    edges = friction_cone_edges(n, friction=0.5, num_edges=4)[0]
    np.testing.assert_allclose(edges, [[0, 0.5, 1], [-0.5, 0, 1], [0, -0.5, 1], [0.5, 0, 1]],
                               atol=1e-15)
    p = np.array([[0.1, 0.0, 0.0]])
    w = wrench_matrix(p, n, friction=0.5, num_edges=4, torque_scale=2.0, center=(0, 0, 0.05))
    lever = 2.0 * (p[0] - [0, 0, 0.05])
    np.testing.assert_allclose(w[:, :3], edges)
    np.testing.assert_allclose(w[:, 3:], np.cross(lever, edges))


# ----------------------------------------------------------------------------- hand-checked
@pytest.mark.parametrize(("num_edges", "factor"), [(4, 1 / np.sqrt(3)), (8, np.sqrt(2 / 3)),
                                                   (16, np.sqrt(2 / 3))])
@pytest.mark.parametrize("mu", [0.3, 0.5, 1.0])
def test_cube_face_centres(num_edges, factor, mu):
    """Six contacts at the face centres of a cube of half-size a, torque scale 1/a.

    Every normal passes through the centre, so p x n = 0 and each edge wrench is
    (n + mu v, -mu n x v) with v a unit tangent: all torques are mu times unit vectors
    perpendicular to n, at the cone's edge angles. In the torque direction
    d = (0, 0, 0, 1, 1, 1)/sqrt(3) the largest support is mu/sqrt(3) for m = 4 (torques
    along the axes) and mu sqrt(2)/sqrt(3) for m = 8 and 16 (torques at 45 degrees between
    two axes); forces do not enter. So Q <= that support, and the hull attains it.
    """
    a = 0.05
    q = ferrari_canny(-a * CUBE_NORMALS, CUBE_NORMALS, friction=mu, num_edges=num_edges,
                      torque_scale=1 / a)
    assert q == pytest.approx(mu * factor, rel=1e-9)


def test_not_in_force_closure_by_inspection():
    a = 0.05
    up = np.tile([0.0, 0.0, 1.0], (3, 1))
    pts = np.array([[0.02, 0, -a], [-0.02, 0.01, -a], [0, -0.02, -a]])
    # every finger pushes +z: no wrench with force along -z can be resisted
    assert ferrari_canny(pts, up) == 0.0
    # two antipodal contacts: no torque about their common line (rank-deficient)
    assert ferrari_canny([[a, 0, 0], [-a, 0, 0]], [[-1, 0, 0], [1, 0, 0]]) == 0.0
    # three contacts on one line: no torque about it
    line = np.array([[a, 0, 0], [-a, 0, 0], [0.0, 0, 0]])
    normals = np.array([[0, 0, 1.0], [0, 0, 1.0], [0, 0, -1.0]])
    assert ferrari_canny(line, normals) == 0.0
    # frictionless: 3 contacts cannot close 6 wrench dimensions
    ang = np.deg2rad([0, 120, 240])
    n3 = -np.stack([np.cos(ang), np.sin(ang), 0 * ang], axis=1)
    assert ferrari_canny(-a * n3, n3, friction=0.0) == 0.0
    assert ferrari_canny(-a * n3, n3, friction=0.5, torque_scale=1 / a) > 0.0
    # a single contact
    assert ferrari_canny([[0, 0, a]], [[0, 0, -1.0]]) == 0.0


# ----------------------------------------------------------------------------- fast vs qhull
@pytest.mark.parametrize("num_edges", [4, 6, 8, 12, 16])
@pytest.mark.parametrize("shape", ["sphere", "box"])
def test_fast_equals_reference_three_contacts(num_edges, shape):
    rng = np.random.default_rng(num_edges + (100 if shape == "box" else 0))
    batch = 400 if num_edges <= 8 else 150
    if shape == "sphere":
        pts, nrm = sphere_contacts(rng, batch, 3, jitter=0.3)
        scale = 1 / 0.05
    else:
        pts, nrm = box_contacts(rng, batch, 3)
        scale = 1 / np.linalg.norm([0.04, 0.03, 0.08])
    kwargs = {"num_edges": num_edges, "torque_scale": scale, "friction": 0.5}
    fast = ferrari_canny_batch(pts, nrm, method="fast", **kwargs)
    ref = ferrari_canny_batch(pts, nrm, method="qhull", **kwargs)
    np.testing.assert_array_equal(fast > 0, ref > 0)
    both = ref > 0
    assert 0.1 < both.mean() < 0.9  # the test sees both outcomes
    np.testing.assert_allclose(fast[both], ref[both], rtol=1e-9, atol=0)


def test_fast_path_certifies_random_grasps():
    from kinegrasp_env.quality.three_contacts import epsilon_three_contacts

    rng = np.random.default_rng(3)
    pts, nrm = sphere_contacts(rng, 500, 3, jitter=0.3)
    w = wrench_matrix(pts, nrm, torque_scale=20.0)
    _, certified = epsilon_three_contacts(w, 8)
    assert certified.mean() > 0.99


def test_support_function_bounds_q():
    """Independent of any hull: Q = min over unit directions u of max_i u . w_i."""
    rng = np.random.default_rng(11)
    pts, nrm = sphere_contacts(rng, 20, 3, jitter=0.2)
    w = wrench_matrix(pts, nrm, torque_scale=20.0)
    q = ferrari_canny_batch(pts, nrm, torque_scale=20.0, method="fast")
    dirs = rng.normal(size=(20_000, 6))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    for b in np.flatnonzero(q > 0):
        support = (w[b] @ dirs.T).max(axis=0)
        assert support.min() >= q[b] * (1 - 1e-12)
        # the nearest facet's normal attains Q: take it from qhull
        hull = ConvexHull(w[b])
        best = hull.equations[np.argmax(hull.equations[:, -1])]
        assert (w[b] @ best[:6]).max() == pytest.approx(q[b], rel=1e-9)


@pytest.mark.parametrize("k", [4, 5])
def test_more_contacts_agree_with_the_reference(k):
    """4-5 contacts go through the certified expansion: qhull's Q to 1e-9, same FC set."""
    from kinegrasp_env.quality.expansion import epsilon_epa_batch
    from kinegrasp_env.quality.wrenches import edge_wrenches

    rng = np.random.default_rng(k)
    pts, nrm = sphere_contacts(rng, 40, k, jitter=0.3)
    auto = ferrari_canny_batch(pts, nrm, torque_scale=20.0)
    ref = ferrari_canny_batch(pts, nrm, torque_scale=20.0, method="qhull")
    np.testing.assert_array_equal(auto > 0, ref > 0)
    np.testing.assert_allclose(auto, ref, rtol=1e-9, atol=1e-15)
    assert 0.2 < (ref > 0).mean() < 0.9
    w = edge_wrenches(pts, nrm, 0.5, 8, np.full(40, 20.0), np.zeros((40, 3)))
    _, certified = epsilon_epa_batch(np.ascontiguousarray(w))
    assert certified.mean() > 0.9  # the qhull fallback is the exception
    with pytest.raises(ValueError, match="fast path needs 3 contacts"):
        ferrari_canny_batch(pts, nrm, method="fast")


# ----------------------------------------------------------------------------- invariances
@pytest.fixture(scope="module")
def grasps():
    rng = np.random.default_rng(5)
    pts, nrm = sphere_contacts(rng, 60, 3, jitter=0.3)
    q = ferrari_canny_batch(pts, nrm, torque_scale=20.0)
    keep = q > 0
    return pts[keep], nrm[keep], q[keep]


def test_permuting_contacts(grasps):
    pts, nrm, q = grasps
    order = [2, 0, 1]
    np.testing.assert_allclose(ferrari_canny_batch(pts[:, order], nrm[:, order],
                                                   torque_scale=20.0), q, rtol=1e-9)


def test_scaling_object_and_torque_scale_together(grasps):
    pts, nrm, q = grasps
    np.testing.assert_allclose(ferrari_canny_batch(3.7 * pts, nrm, torque_scale=20.0 / 3.7),
                               q, rtol=1e-9)


def test_rotating_the_grasp(grasps):
    """Rotations that map coordinate axes to axes are exact symmetries (the tangent basis
    turns by a multiple of 90 degrees, a symmetry of the 8-gon). A general rotation turns
    each cone polygon about its normal by some angle; an m-gon of radius mu contains every
    turned copy of radius mu cos(pi/m), and Q grows with mu, so Q is bracketed."""
    from scipy.spatial.transform import Rotation

    pts, nrm, q = grasps
    centre = np.array([0.01, -0.02, 0.03])
    for quarter in (Rotation.from_rotvec([0, 0, np.pi / 2]), Rotation.from_rotvec([np.pi, 0, 0]),
                    Rotation.from_euler("zx", [np.pi / 2, np.pi / 2])):
        rot = quarter.as_matrix()
        rq = ferrari_canny_batch((pts - centre) @ rot.T + centre, nrm @ rot.T,
                                 torque_scale=20.0, center=centre)
        base = ferrari_canny_batch(pts, nrm, torque_scale=20.0, center=centre)
        np.testing.assert_allclose(rq, base, rtol=1e-9)
    rot = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()
    shrink = np.cos(np.pi / 8)
    turned = ferrari_canny_batch(pts @ rot.T, nrm @ rot.T, torque_scale=20.0)
    assert np.all(turned >= ferrari_canny_batch(pts, nrm, torque_scale=20.0,
                                                friction=0.5 * shrink) * (1 - 1e-9))
    assert np.all(q >= ferrari_canny_batch(pts @ rot.T, nrm @ rot.T, torque_scale=20.0,
                                           friction=0.5 * shrink) * (1 - 1e-9))
    assert not np.allclose(turned, q, rtol=1e-6)  # the bracket is what holds, not equality


def test_adding_a_contact_never_lowers_q(grasps):
    pts, nrm, q = grasps
    rng = np.random.default_rng(8)
    extra_p, extra_n = sphere_contacts(rng, pts.shape[0], 1, jitter=0.3)
    q4 = ferrari_canny_batch(np.concatenate([pts, extra_p], axis=1),
                             np.concatenate([nrm, extra_n], axis=1), torque_scale=20.0)
    assert np.all(q4 >= q * (1 - 1e-12))


# ----------------------------------------------------------------------------- variants
def test_linf_and_volume():
    a = 0.05
    kwargs = {"friction": 0.5, "num_edges": 4, "torque_scale": 1 / a}
    q1 = ferrari_canny(-a * CUBE_NORMALS[:3], CUBE_NORMALS[:3], **kwargs)
    ang = np.deg2rad([0, 120, 240])
    n3 = -np.stack([np.cos(ang), np.sin(ang), 0 * ang], axis=1)
    q1 = ferrari_canny(-a * n3, n3, **kwargs)
    qinf = ferrari_canny(-a * n3, n3, norm="linf", **kwargs)
    # the Minkowski sum contains the L1 hull: its epsilon is at least as large
    assert qinf >= q1 > 0
    vol1 = grasp_wrench_space_volume(-a * n3, n3, **kwargs)
    volinf = grasp_wrench_space_volume(-a * n3, n3, norm="linf", **kwargs)
    assert volinf > vol1 > 0
    # an independent volume: qhull on the same wrench matrix
    w = wrench_matrix(-a * n3, n3, **kwargs)
    assert vol1 == pytest.approx(ConvexHull(w).volume, rel=1e-12)
    assert grasp_wrench_space_volume([[a, 0, 0], [-a, 0, 0]], [[-1, 0, 0], [1, 0, 0]]) == 0.0


def test_force_closure_helpers():
    a = 0.05
    ang = np.deg2rad([0, 120, 240])
    n3 = -np.stack([np.cos(ang), np.sin(ang), 0 * ang], axis=1)
    assert is_force_closure(-a * n3, n3, torque_scale=1 / a)
    assert not is_force_closure(-a * n3, n3, friction=0.0)
    up = np.tile([0.0, 0.0, 1.0], (3, 1))  # every finger pushes +z
    batch = is_force_closure_batch(np.stack([-a * n3, -a * n3]), np.stack([n3, up]),
                                   torque_scale=1 / a)
    np.testing.assert_array_equal(batch, [True, False])


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(("points", "normals", "kwargs", "needle"), [
    ([[0, 0, np.nan], [1, 0, 0]], [[0, 0, 1], [1, 0, 0]], {}, "points contains NaN"),
    ([[0, 0, 0], [1, 0, 0]], [[0, 0, np.inf], [1, 0, 0]], {}, "normals contains NaN or inf"),
    ([[0, 0, 0], [1, 0, 0]], [[0, 0, 1]], {}, "differ in shape"),
    ([[0, 0, 0, 1]], [[0, 0, 1, 0]], {}, r"must have shape \(k, 3\)"),
    ([[0, 0, 0], [1, 0, 0]], [[0, 0, 0], [1, 0, 0]], {}, r"contact \(0,\) has zero length"),
    (np.zeros((0, 3)), np.zeros((0, 3)), {}, "at least one contact"),
    ([[0, 0, 0]], [[0, 0, 1]], {"friction": -0.1}, "friction must be finite and >= 0"),
    ([[0, 0, 0]], [[0, 0, 1]], {"num_edges": 2}, "num_edges must be an integer >= 3"),
    ([[0, 0, 0]], [[0, 0, 1]], {"torque_scale": 0.0}, "torque_scale must be > 0"),
    ([[0, 0, 0]], [[0, 0, 1]], {"center": (0, 0)}, r"center must have shape \(3,\)"),
    ([[0, 0, 0]], [[0, 0, 1]], {"method": "magic"}, "unknown method 'magic'"),
])
def test_bad_input(points, normals, kwargs, needle):
    with pytest.raises(ValueError, match=needle):
        ferrari_canny(points, normals, **kwargs)


def test_degenerate_but_valid_sets_give_zero():
    a = 0.05
    same = np.tile([[a, 0, 0]], (3, 1))
    assert ferrari_canny(same, np.tile([[-1.0, 0, 0]], (3, 1))) == 0.0  # coincident
    par = np.array([[a, 0, 0], [a, 0.01, 0], [a, 0, 0.01]])
    assert ferrari_canny(par, np.tile([[-1.0, 0, 0]], (3, 1))) == 0.0  # parallel normals
    assert ferrari_canny(same, np.tile([[-1.0, 0, 0]], (3, 1)), method="qhull") == 0.0


def test_per_row_torque_scale_and_center():
    rng = np.random.default_rng(2)
    pts, nrm = sphere_contacts(rng, 10, 3, jitter=0.3)
    scales = rng.uniform(10, 30, size=10)
    centres = rng.normal(scale=0.005, size=(10, 3))
    batch = ferrari_canny_batch(pts, nrm, torque_scale=scales, center=centres)
    single = [ferrari_canny(pts[i], nrm[i], torque_scale=scales[i], center=centres[i])
              for i in range(10)]
    np.testing.assert_allclose(batch, single, rtol=1e-12)


# ----------------------------------------------------------------------------- expansion path
def test_expansion_path_on_a_known_polytope():
    """The cross-polytope conv(+-e_i) in R^6: every facet at distance 1/sqrt(6); interior
    points change nothing; shifted off the origin, Q is 0."""
    from kinegrasp_env.quality.expansion import epsilon_epa

    cross = np.vstack([np.eye(6), -np.eye(6)])
    inner = np.random.default_rng(0).uniform(-0.1, 0.1, (20, 6))
    q, certified = epsilon_epa(np.vstack([cross, inner]))
    assert certified
    assert q == pytest.approx(1 / np.sqrt(6), rel=1e-12)
    q, certified = epsilon_epa(cross + np.array([1.5, 0, 0, 0, 0, 0]))
    assert certified and q == 0.0


def test_expansion_certifies_flat_pad_pinches():
    """A flat pad puts all its corners' cone wrenches on one hyperplane; a thin facet there,
    its hyperplane derived from its parents' (the pencil), can miss another of them by more
    than the tolerance, and the polytope looked not convex. Pinches 378, 394 and 763 are
    such sets: with those facets refit from their own vertices they are certified, and every
    certified Q is qhull's (its hull's nearest facet)."""
    from kinegrasp_env.quality.expansion import epsilon_epa_batch
    from kinegrasp_env.quality.wrenches import edge_wrenches

    seeds = [378, 394, 763, *range(40)]
    points, normals = (np.array(a) for a in zip(*map(pad_pinch, seeds), strict=True))
    w = edge_wrenches(points, normals, 0.5, 8, np.full(len(seeds), 1 / 0.0433),
                      np.zeros((len(seeds), 3)))
    q, certified = epsilon_epa_batch(np.ascontiguousarray(w))
    assert certified[:3].all()
    assert certified.mean() == 1.0
    for wrenches, value in zip(w, q, strict=True):
        expected = max(-ConvexHull(wrenches).equations[:, -1].max(), 0.0)
        assert value == pytest.approx(expected, rel=1e-9, abs=1e-12)


def test_expansion_path_matches_qhull_on_random_clouds():
    from scipy.spatial import ConvexHull

    from kinegrasp_env.quality.expansion import (
        epsilon_epa,
        epsilon_epa_batch,
        expand_from,
        new_polytope,
        new_ridges,
        screen,
    )

    rng = np.random.default_rng(11)
    clouds = rng.normal(size=(150, 40, 6)) + rng.normal(scale=0.6, size=(150, 1, 6))
    q, certified = epsilon_epa_batch(clouds)
    assert certified.mean() > 0.95
    for cloud, value in zip(clouds[certified], q[certified], strict=True):
        offsets = ConvexHull(cloud).equations[:, -1]
        expected = max(-offsets.max(), 0.0)
        assert value == pytest.approx(expected, rel=1e-9, abs=1e-12)
    # the interpreted twin of the numba kernel gives the same numbers
    for cloud in clouds[:5]:
        assert epsilon_epa.py_func(cloud) == epsilon_epa(cloud)
    # the batch reuses one set of tables for every grasp: the same answers as fresh ones
    assert [epsilon_epa(cloud) for cloud in clouds] == list(zip(q, certified, strict=True))
    # and so do single calls that share tables (ferrari_canny's, one set per thread)
    tables = (new_polytope(), new_ridges())
    shared = []
    for cloud in clouds:
        start, value, done = screen(cloud)
        shared.append((value, done) if start[0] < 0 else expand_from(cloud, start, *tables))
    assert shared == list(zip(q, certified, strict=True))


def _hyperplane_svd(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Unit normal a (6,) and offset b of the hyperplane a . x = b through 6 points (6, 6):
    the null vector of [points, -1] by SVD (numpy's LAPACK, independent of the expansion)."""
    null = np.linalg.svd(np.hstack([points, -np.ones((6, 1))]))[2][-1]
    size = np.linalg.norm(null[:6])
    return null[:6] / size, null[6] / size


def _expanded(cloud: np.ndarray) -> tuple | None:
    """The polytope tables after the expansion of one wrench set (certified); None where the
    origin is outside the hull (no polytope)."""
    from kinegrasp_env.quality.expansion import expand_from, new_polytope, new_ridges, screen

    poly = new_polytope()
    start, _, _ = screen(cloud)
    if start[0] < 0:
        return None
    _, certified = expand_from(cloud, start, poly, new_ridges())
    assert certified
    return poly


@pytest.mark.parametrize("k, m", [(4, 8), (5, 12)])
def test_expansion_facets_lie_on_the_hyperplanes_of_their_vertices(k, m):
    """Every live facet of the expanded polytope (most from their neighbours' hyperplanes,
    ``facets.pencil_facet``) against the hyperplane through its 6 vertices by SVD (whose own
    vertex residuals are below 1e-15 of the wrench scale): normals within 1e-12 (measured
    3.7e-13 on 80 sets), offsets within 3e-13 of the wrench scale (measured 1.5e-13), every
    vertex within PENCIL_TOL = 1e-13 of its facet (measured 4e-14); the normal points away
    from the interior point. Neighbours: facet f's neighbour across the ridge opposite its
    vertex j is live, holds exactly f's vertices but that one, and has f as a neighbour; and
    the polytope is closed (the expansion no longer checks it, its construction keeps it):
    every ridge of the live facets, counted here, lies in exactly two of them."""
    pts, nrm = sphere_contacts(np.random.default_rng(7), 12, k, jitter=0.3)
    w = np.ascontiguousarray(wrench_matrix(pts, nrm, num_edges=m, torque_scale=20.0))
    polytopes = [(cloud, poly) for cloud in w if (poly := _expanded(cloud)) is not None]
    assert len(polytopes) >= 5
    for cloud, poly in polytopes:
        verts, normal, offset, alive, interior, neighbour = *poly[:5], poly[8]
        scale = np.abs(cloud).max()
        live = np.flatnonzero(alive)
        assert live.size > 20
        ridges = Counter(tuple(sorted(np.delete(verts[f], j))) for f in live for j in range(6))
        assert set(ridges.values()) == {2}
        for f in live:
            a, b = _hyperplane_svd(cloud[verts[f]])
            if a @ interior > b:
                a, b = -a, -b
            np.testing.assert_allclose(normal[f], a, atol=1e-12)
            assert abs(offset[f] - b) <= 3e-13 * scale
            assert np.abs(cloud[verts[f]] @ normal[f] - offset[f]).max() <= 1e-13 * scale
            for j in range(6):
                h = neighbour[f, j]
                assert alive[h]
                assert set(verts[h]) & set(verts[f]) == set(np.delete(verts[f], j))
                assert f in neighbour[h]


def test_pencil_facet_against_the_hyperplane_through_ridge_and_apex():
    """One new facet from a visible facet f and its neighbour h across a ridge: the pencil
    combination is accepted (not left to Gram-Schmidt) and equals the SVD hyperplane through
    the ridge's 5 vertices and the apex to 1e-12."""
    from kinegrasp_env.quality.facets import pencil_facet

    rng = np.random.default_rng(3)
    checked = 0
    for cloud in rng.normal(size=(40, 30, 6)) + rng.normal(scale=0.3, size=(40, 1, 6)):
        poly = _expanded(np.ascontiguousarray(cloud))
        if poly is None:
            continue
        verts, normal, offset, alive, interior, height, neighbour = (
            poly[0], poly[1], poly[2], poly[3], poly[4], poly[9], poly[8])
        scale = np.abs(cloud).max()
        f = int(np.flatnonzero(alive)[0])
        h = int(neighbour[f, 0])
        # an apex beyond f but below h: f's centroid pushed out along its normal
        apex = cloud[verts[f]].mean(axis=0) + 0.05 * scale * normal[f]
        if normal[h] @ apex - offset[h] > 0:
            continue
        w = np.vstack([cloud, apex])
        g = int(np.flatnonzero(~alive)[0])
        verts[g, :5] = verts[f, 1:]
        verts[g, 5] = len(cloud)
        height[f] = normal[f] @ apex - offset[f]
        assert pencil_facet(w, poly, g, f, h, scale)
        a, b = _hyperplane_svd(w[verts[g]])
        if a @ interior > b:
            a, b = -a, -b
        np.testing.assert_allclose(normal[g], a, atol=1e-12)
        assert offset[g] == pytest.approx(b, abs=1e-12 * scale)
        checked += 1
    assert checked >= 10


@pytest.mark.parametrize("dantzig", [50, 0])
def test_phase_one_finds_a_simplex_around_the_origin(monkeypatch, dantzig):
    """Phase 1 (Dantzig's pivot rule, then Bland's; ``dantzig = 0``: Bland's alone, run
    interpreted so that the module constant can be changed): every simplex it returns
    contains the origin (barycentric weights from a 7 x 7 solve >= -1e-12), and it says
    "outside" exactly where an LP (SciPy's HiGHS) finds no convex combination equal to 0."""
    from scipy.optimize import linprog

    from kinegrasp_env.quality import phase_one

    monkeypatch.setattr(phase_one, "DANTZIG_PIVOTS", dantzig)
    pts, nrm = sphere_contacts(np.random.default_rng(5), 40, 5, jitter=0.3)
    w = np.ascontiguousarray(wrench_matrix(pts, nrm, num_edges=12, torque_scale=20.0))
    inside = 0
    for cloud in w:
        start = phase_one.initial_simplex.py_func(cloud, 1e-12)
        lp = linprog(np.zeros(len(cloud)), A_eq=np.vstack([cloud.T, np.ones(len(cloud))]),
                     b_eq=np.r_[np.zeros(6), 1.0], bounds=(0, None), method="highs")
        assert (start[0] == -1) == (lp.status == 2)
        if start[0] >= 0:
            lam = np.linalg.solve(np.vstack([cloud[start].T, np.ones(7)]), np.r_[np.zeros(6), 1])
            assert lam.min() >= -1e-12
            inside += 1
    assert 10 <= inside <= 35


def test_expansion_tables_reused_after_a_set_abandoned_midway():
    """64 points on the trigonometric moment curve (a cyclic polytope: more facets than the
    4,096-row table) make the expansion give up in the middle of a step, with neighbour
    slots already rewritten; a batch that alternates it with other sets (grasps, up to vertex
    id 63) on the same tables gives each set the answer of fresh tables (nothing of an
    abandoned set is read), and every certified answer equals qhull's to 1e-9."""
    from kinegrasp_env.quality.expansion import epsilon_epa, epsilon_epa_batch

    t = 2 * np.pi * np.arange(64) / 64
    full = np.stack([np.cos(t), np.sin(t), np.cos(2 * t), np.sin(2 * t), np.cos(3 * t),
                     np.sin(3 * t)], axis=1)
    assert epsilon_epa(full) == (0.0, False)
    rng = np.random.default_rng(4)
    pts, nrm = sphere_contacts(rng, 40, 4, jitter=0.3)
    grasps = wrench_matrix(pts, nrm, num_edges=16, torque_scale=20.0)  # 64 wrenches each
    sets = np.ascontiguousarray(np.stack([x for g in grasps[:8] for x in (full, g)]))
    q, certified = epsilon_epa_batch(sets)
    assert [epsilon_epa(x) for x in sets] == list(zip(q, certified, strict=True))
    assert certified[1::2].sum() >= 3
    for w, value in zip(sets[certified], q[certified], strict=True):
        expected = max(-ConvexHull(w).equations[:, -1].max(), 0.0)
        assert value == pytest.approx(expected, rel=1e-9, abs=1e-12)


def test_expansion_path_declines_sets_beyond_its_bound():
    from kinegrasp_env.quality.expansion import MAX_POINTS, epsilon_epa

    cloud = np.random.default_rng(2).normal(size=(MAX_POINTS + 1, 6))
    assert epsilon_epa(cloud) == (0.0, False)


def test_batch_thresholding_applies_the_single_grasp_rule():
    """The engines' vectorized thresholding against the single-grasp rule, row by row, on the
    cases the rule tells apart: NaN, Q on either side of FC_TOL of the wrench scale, a barely
    positive Q of a rank-deficient set (zeroed) and of a full-rank one (kept), ordinary Q."""
    from kinegrasp_env.quality.epsilon import FC_TOL, thresholded, thresholded_batch

    rng = np.random.default_rng(5)
    full = rng.normal(size=(24, 6))
    flat = full.copy()
    flat[:, 5] = 0.0  # affine hull of dimension 5
    w = np.stack([full, full, full, full, flat, full, full])
    scale = np.abs(full).max()
    q = np.array([np.nan, 0.5 * FC_TOL * scale, 2.0 * FC_TOL * scale, 0.0,
                  1e-9 * np.abs(flat).max(), 1e-9 * scale, 0.3])
    expected = [thresholded(qi, wi) for qi, wi in zip(q, w, strict=True)]
    assert expected == [0.0, 0.0, q[2], 0.0, 0.0, q[5], 0.3]
    # bit for bit: both keep q or set 0 (a selection, no arithmetic on q)
    np.testing.assert_array_equal(thresholded_batch(q, w), expected)


def test_plain_input_fast_checks_match_the_full_checks():
    """The compiled pass for plain input (float64 arrays) against the full numpy checks (taken
    for the same values given as lists): the same unit normals over lengths 1e-6..1e6,
    single and batched (to 2 ulps: two code paths); huge normals (whose squares overflow)
    and every bad input still go through the full checks (same results, same errors); the
    float-and-tuple fast path of the torque scale and centre gives the arrays per_row
    gives."""
    from kinegrasp_env.quality.wrenches import (
        _plain_contacts,
        check_contacts,
        per_row,
        scale_center,
    )

    rng = np.random.default_rng(11)
    for batched, shape in ((False, (5, 3)), (True, (40, 4, 3))):
        points = rng.normal(size=shape)
        normals = rng.normal(size=shape) * 10.0 ** rng.uniform(-6, 6, size=(*shape[:-1], 1))
        fast = check_contacts(points, normals, batched)
        full = check_contacts(points.tolist(), normals.tolist(), batched)
        assert _plain_contacts(points, normals, batched) is not None
        np.testing.assert_array_equal(fast[0], full[0])  # the points, passed through
        # unit normals by two code paths (compiled kernel, numpy): 2 ulps of 1
        np.testing.assert_allclose(fast[1], full[1], rtol=0, atol=2 * np.finfo(float).eps)
    huge = np.array([[1e200, 0.0, 0.0], [0.0, 3e300, 4e300]])
    assert _plain_contacts(np.zeros((2, 3)), huge, False) is None
    np.testing.assert_allclose(check_contacts(np.zeros((2, 3)), huge, False)[1],
                               [[1.0, 0.0, 0.0], [0.0, 0.6, 0.8]], rtol=1e-15)
    for bad_points, bad_normals, message in (
            (np.array([[np.nan, 0, 0]]), np.ones((1, 3)), "points contains NaN"),
            (np.zeros((1, 3)), np.zeros((1, 3)), "has zero length"),
            (np.zeros((2, 3)), np.ones((3, 3)), "differ in shape")):
        with pytest.raises(ValueError, match=message):
            check_contacts(bad_points, bad_normals, False)
    scale, center = scale_center(20.0, (0.1, -0.2, 0.3), 4)
    np.testing.assert_array_equal(scale, per_row(np.float64(20.0), 4, (), "torque_scale"))
    np.testing.assert_array_equal(center, per_row(np.array([0.1, -0.2, 0.3]), 4, (3,), "c"))
    assert scale_center(20.0, (0.1, -0.2, 0.3), 1)[1].shape == (1, 3)
    with pytest.raises(ValueError, match="torque_scale must be > 0"):
        scale_center(-1.0, (0.0, 0.0, 0.0), 1)


# ----------------------------------------------------------------------------- one call
def _step_by_step(points, normals, friction, num_edges, torque_scale, center) -> float:
    """The single-grasp path as it ran before the one compiled call: numpy checks, the
    wrench kernel, phase 1 and the expansion called from Python, qhull where uncertified."""
    from kinegrasp_env.quality.epsilon import single_l1
    from kinegrasp_env.quality.wrenches import check_contacts, edge_wrenches, scale_center

    points, normals = check_contacts(points, normals, batched=False)
    scale, ctr = scale_center(torque_scale, center, 1)
    w = edge_wrenches(points[None], normals[None], friction, num_edges, scale, ctr)[0]
    return single_l1(w, points.shape[0])


def test_one_compiled_call_equals_the_step_by_step_path():
    """``ferrari_canny`` on plain input (one compiled call, quality/single.py) gives, bit for
    bit, the Q of the same steps run one by one from Python (a re-plumbing: the same kernels,
    the same arithmetic), over 1-6 contacts, 3-12 edges (k m up to 64 and past it, where
    qhull serves), friction 0-1.2, normals of any length, centres as tuples, lists and
    arrays, torque scales as int, float and numpy float; and both equal qhull to 1e-9
    relative (the independent check). Sphere and box contacts: on boxes many grasps are
    equilibria on the hull (the certified-zero ends of phase 1)."""
    rng = np.random.default_rng(2026)
    calls = 0
    for k in range(1, 7):
        for num_edges in (3, 4, 8, 12):
            for shape in ("sphere", "box"):
                if shape == "sphere":
                    pts, nrm = sphere_contacts(rng, 6, k, jitter=0.3)
                else:
                    pts, nrm = box_contacts(rng, 6, k)
                nrm = nrm * rng.uniform(0.1, 10.0, size=(6, k, 1))
                for b in range(6):
                    friction = float(rng.choice([0.0, 0.3, 0.5, 1.2]))
                    torque_scale = [20, 20.0, np.float64(12.5)][b % 3]
                    center = [(0.0, 0.0, 0.0), [0.01, -0.02, 0.0],
                              rng.normal(scale=0.01, size=3)][b % 3]
                    args = (pts[b], nrm[b], friction, num_edges, torque_scale, center)
                    q = ferrari_canny(pts[b], nrm[b], friction=friction, num_edges=num_edges,
                                      torque_scale=torque_scale, center=center)
                    assert q == _step_by_step(*args), (k, num_edges, shape, b)
                    reference = ferrari_canny(pts[b], nrm[b], friction=friction,
                                              num_edges=num_edges, torque_scale=torque_scale,
                                              center=center, method="qhull")
                    assert q == pytest.approx(reference, rel=1e-9, abs=0.0)
                    calls += 1
    assert calls == 6 * 4 * 2 * 6


def test_one_compiled_call_hands_back_what_needs_python(monkeypatch):
    """The statuses the compiled call returns are served as the step-by-step path serves
    them (the call wrapped so that it reports a status it would rarely report): not
    certified -> qhull on the wrenches it left, exactly the reference's Q; a barely positive
    Q -> 0 where the set is rank-deficient (friction 0: three distinct wrenches), else that
    Q; a rejected input -> the full checks' one-line error."""
    import kinegrasp_env.quality.single as single

    real = single.single_epsilon
    forced = {}

    def wrapped(*args):
        status, q = real(*args)
        return forced.get("status", status), forced.get("q", q)

    monkeypatch.setattr(single, "single_epsilon", wrapped)
    pts, nrm = sphere_contacts(np.random.default_rng(3), 8, 4, jitter=0.3)
    forced["status"] = single.NOT_CERTIFIED
    for p, n in zip(pts, nrm, strict=True):
        assert ferrari_canny(p, n, torque_scale=20.0) == ferrari_canny(
            p, n, torque_scale=20.0, method="qhull")
    forced.update(status=single.CHECK_RANK, q=1e-10)
    assert ferrari_canny(pts[0], nrm[0], torque_scale=20.0, friction=0.0) == 0.0
    assert ferrari_canny(pts[0], nrm[0], torque_scale=20.0) == 1e-10
    forced.clear()
    with pytest.raises(ValueError, match="points contains NaN"):
        ferrari_canny(np.full((3, 3), np.nan), nrm[0, :3])
    with pytest.raises(ValueError, match="has zero length"):
        ferrari_canny(pts[0], np.zeros((4, 3)))
    with pytest.raises(ValueError, match=r"the torques reach"):
        ferrari_canny(1e300 * pts[0], nrm[0], torque_scale=1e10)
