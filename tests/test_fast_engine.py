"""The fast engine: exact geometry kernels, the distance grid, the compiled closing loop (its
agreement with the reference engine and with pybullet: tests/test_agreement.py)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.interpolate import RegularGridInterpolator

from kinegrasp_env.closing.capsule_gap import capsule_gaps, posed_min_distance
from kinegrasp_env.closing.close_rules import secant_root
from kinegrasp_env.closing.segment_distance import closest_to_segments
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.world.grasps import shipped_grasps
from kinegrasp_env.world.objects import OBJECT_NAMES, load_object
from kinegrasp_env.world.sdf import MARGIN, build_grid, grid_of, object_grid


def _random_segments(obj, n, seed, length=0.0865, pad=0.02):
    rng = np.random.default_rng(seed)
    lo, hi = obj.mesh.bounds
    a = rng.uniform(lo - pad, hi + pad, size=(n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return a, a + length * d


def _clear(obj, a, b, samples=30, margin=2e-3):
    """Segments that stay more than ``margin`` away from the object (sampled exactly): a
    selection of inputs only, the checks below compare with :func:`reference_distance`."""
    t = np.linspace(0.0, 1.0, samples)[None, :, None]
    pts = (a[:, None] + t * (b - a)[:, None]).reshape(-1, 3)
    return obj.closest_points(pts)[1].reshape(len(a), samples).min(axis=1) > margin


def grid_at(grid, points: np.ndarray) -> np.ndarray:
    """(n,) the grid's distance at points (n, 3), by the library's compiled lookup (the one
    the engine uses): each point as a pose's translation, one sample at its origin."""
    poses = np.tile(np.eye(4), (len(points), 1, 1))
    poses[:, :3, 3] = points
    return posed_min_distance(grid, poses, np.zeros((1, 3)))


def interpolated(grid, points: np.ndarray) -> np.ndarray:
    """(...,) the grid's distance at points (..., 3) sharing no code with the library's
    lookup: scipy's trilinear interpolation of the lattice at the point clamped to the
    lattice box, plus the point's distance to the box (the rule of
    :mod:`kinegrasp_env.world.sdf`)."""
    axes = [grid.origin[k] + grid.spacing * np.arange(grid.shape[k]) for k in range(3)]
    lo, hi = np.array([x[0] for x in axes]), np.array([x[-1] for x in axes])
    flat = points.reshape(-1, 3)
    clamped = np.clip(flat, lo, hi)
    inside = RegularGridInterpolator(axes, grid.values, method="linear")(clamped)
    return (inside + np.linalg.norm(flat - clamped, axis=1)).reshape(points.shape[:-1])


def reference_distance(obj, points: np.ndarray, chunk: int = 2_000_000) -> np.ndarray:
    """(n,) signed distance (metres) of points (n, 3) to the union of ``obj``'s convex parts,
    sharing no code with the library's geometry: each part's hull is rebuilt by trimesh
    (qhull) from its vertices; a point inside a hull has the largest of trimesh's face-plane
    values (its depth, negative; the smallest over the hulls that hold it), a point outside
    every hull the distance to the nearest triangle of all hulls, by trimesh's exact
    point-triangle closest point over every triangle (brute force:
    ``trimesh.proximity.closest_point``'s tree search was measured to miss the nearest
    triangle by 6e-7 m on the mug)."""
    hulls = [trimesh.convex.convex_hull(part.vertices) for part in obj.convex_parts]
    depth = np.full(len(points), np.inf)
    for hull in hulls:
        values = np.einsum("pfk,fk->pf", points[:, None, :] - hull.triangles[None, :, 0, :],
                           hull.face_normals).max(axis=1)
        depth = np.minimum(depth, np.where(values < 0.0, values, np.inf))
    triangles = np.concatenate([hull.triangles for hull in hulls])
    out = depth.copy()
    outside = np.flatnonzero(np.isinf(depth))
    step = max(1, chunk // len(triangles))
    for start in range(0, len(outside), step):
        rows = outside[start:start + step]
        p = np.repeat(points[rows], len(triangles), axis=0)
        near = trimesh.triangles.closest_point(np.tile(triangles, (len(rows), 1, 1)), p)
        out[rows] = np.linalg.norm(near - p, axis=1).reshape(len(rows), -1).min(axis=1)
    return out


def test_reference_distance_matches_the_box_formula():
    """The trimesh reference itself, on the cube (centre (0, 0, 0.03), half-width 0.03 m)
    against the box's signed-distance formula, inside and outside."""
    cube = load_object("cube")
    pts = np.random.default_rng(12).uniform(-0.06, 0.09, size=(3000, 3))
    rel = np.abs(pts - np.array([0.0, 0.0, 0.03])) - 0.03
    box = np.linalg.norm(np.maximum(rel, 0.0), axis=1) + np.minimum(rel.max(axis=1), 0.0)
    assert (box < 0).sum() > 100
    np.testing.assert_allclose(reference_distance(cube, pts), box, rtol=0, atol=1e-15)


def test_point_distance_to_the_cube_matches_the_box_formula():
    cube = load_object("cube")
    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.06, 0.09, size=(3000, 3))
    closest, dist, _ = cube.closest_points(pts)
    centre, half = np.array([0.0, 0.0, 0.03]), 0.03
    rel = np.abs(pts - centre) - half
    outside = np.linalg.norm(np.maximum(rel, 0.0), axis=1)
    inside = np.minimum(rel.max(axis=1), 0.0)
    np.testing.assert_allclose(dist, outside + inside, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(pts - closest, axis=1), np.abs(dist), atol=1e-12)


@pytest.mark.parametrize("name", ["spray_flask", "mug"])
def test_segment_distance_matches_dense_sampling(name):
    """closest_to_segments (compiled) on segments clear of the object, against references
    that share none of its code: the object point lies on the surface and the distance is
    that of the pair, both by the trimesh reference (:func:`reference_distance`); and the
    distance is the minimum over the segment: below the reference distance of each of 801
    samples, and above the smallest of them by at most the sampling error (h/2)^2 / (2 d)
    (h: sample spacing, d: the distance; at an interior minimum the pair's direction is
    normal to the segment, so a sample x away lies within sqrt(d^2 + x^2) of the object
    point), on 25 segments; on every clear segment the same two bounds with 101 samples
    of the numpy point distances (:meth:`GraspObject.closest_points`, another code path)."""
    obj = load_object(name)
    a, b = _random_segments(obj, 400, seed=1)
    on_obj, on_seg, dist, _ = closest_to_segments(obj, a, b)
    clear = _clear(obj, a, b)  # the method is for segments that do not cross the object
    np.testing.assert_allclose(np.linalg.norm(on_obj - on_seg, axis=1)[clear], dist[clear],
                               atol=1e-12)
    for samples, rows, distance in (
            (801, np.flatnonzero(clear)[:25], lambda p: reference_distance(obj, p)),
            (101, np.flatnonzero(clear), lambda p: obj.closest_points(p)[1])):
        assert len(rows) >= 25
        t = np.linspace(0.0, 1.0, samples)[None, :, None]
        pts = a[rows, None] + t * (b - a)[rows, None]
        dense = distance(pts.reshape(-1, 3)).reshape(len(rows), samples).min(axis=1)
        half_step = 0.5 * np.linalg.norm(b - a, axis=1)[rows] / (samples - 1)
        assert (dist[rows] <= dense + 1e-12).all()
        assert (dense - dist[rows] <= half_step**2 / (2.0 * dist[rows]) + 1e-12).all()
    rows = np.flatnonzero(clear)[:25]
    np.testing.assert_allclose(reference_distance(obj, on_obj[rows]), 0.0, atol=1e-12)


@pytest.mark.parametrize("name", OBJECT_NAMES)
def test_distance_grid_is_close_to_exact_distance_near_the_surface(name):
    """The distance grid (written from the library's exact point distances) against the
    trimesh reference (:func:`reference_distance`, no shared code) at 6000 random points
    within 3 mm of the surface: the trilinear error of the 1.5 mm grid next to edges and
    corners, measured (seed 2) at the 99th percentile 1.6e-4 / 3.0e-4 / 3.1e-4 / 5.0e-4 m
    (cube, spray flask, drill, mug) and at most 3.0e-4 / 5.9e-4 / 6.5e-4 / 7.2e-4 m; bounds
    1.5x and 2x the largest."""
    obj = load_object(name)
    grid = object_grid(name)
    rng = np.random.default_rng(2)
    lo, hi = obj.mesh.bounds
    pts = rng.uniform(lo - 0.01, hi + 0.01, size=(6000, 3))
    exact = reference_distance(obj, pts)
    near = np.abs(exact) < 3e-3
    assert near.sum() > 300
    err = np.abs(grid_at(grid, pts) - exact)[near]
    assert np.percentile(err, 99) < 7.5e-4
    assert err.max() < 1.5e-3


def test_grid_cache_round_trip(tmp_path, monkeypatch):
    monkeypatch.setenv("KINEGRASP_CACHE", str(tmp_path))
    built = grid_of.__wrapped__(load_object("cube"))
    assert len(list((tmp_path / "sdf").glob("cube-*.npz"))) == 1
    loaded = grid_of.__wrapped__(load_object("cube"))
    np.testing.assert_array_equal(loaded.values, built.values)
    np.testing.assert_array_equal(loaded.origin, built.origin)


def test_grid_is_exact_next_to_cube_faces():
    cube = load_object("cube")
    grid = build_grid(cube)
    rng = np.random.default_rng(3)
    # points above the top face's interior: the distance is linear there (float32 nodes)
    pts = np.column_stack([rng.uniform(-0.02, 0.02, 500), rng.uniform(-0.02, 0.02, 500),
                           rng.uniform(0.061, 0.075, 500)])
    np.testing.assert_allclose(grid_at(grid, pts), pts[:, 2] - 0.06, atol=1e-8)


def test_grid_nodes_are_the_exact_distances_capped_at_the_margin():
    """Every node of the cube's grid (the compiled node distances) is, bit for bit, the
    float32 value of min(margin, the exact signed distance) computed by the numpy point
    distances (:meth:`GraspObject.closest_points`: the same rule, another code path); the
    interior nodes against the box formula too."""
    cube = load_object("cube")
    grid = build_grid(cube)
    axes = [grid.origin[k] + grid.spacing * np.arange(grid.shape[k]) for k in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    exact = np.minimum(cube.closest_points(nodes)[1], MARGIN)
    np.testing.assert_array_equal(grid.values.reshape(-1),
                                  exact.astype(np.float32).astype(np.float64))
    rel = np.abs(nodes - np.array([0.0, 0.0, 0.03])) - 0.03
    box = np.linalg.norm(np.maximum(rel, 0.0), axis=1) + np.minimum(rel.max(axis=1), 0.0)
    inside = box < 0
    assert inside.sum() > 1000
    np.testing.assert_allclose(grid.values.reshape(-1)[inside], box[inside], rtol=0, atol=2e-9)


@pytest.mark.parametrize("name", ["spray_flask", "drill"])
def test_capsule_gaps_follow_the_grid_and_match_exact_distance(name):
    """capsule_gaps (compiled) against scipy's interpolation of the same grid
    (:func:`interpolated`, no shared code) and the exact distance. Each gap is a value of
    the rule at the returned s: grid(a + s (b - a)) - radius, less half the sample spacing
    where it is a lower bound (above NEAR); a lower bound is below the minimum of the
    interpolated grid over 2001 samples; a refined gap is above that minimum by at most
    the golden search's error (measured at most 3.0e-6 / 2.8e-6 m (spray flask, drill);
    bound 6e-6); near contact the gap is the exact one to the grid's error. The gap at s:
    measured to 1.0e-16 m, bound 1e-15."""
    from kinegrasp_env.closing.capsule_gap import NEAR, SAMPLES

    obj = load_object(name)
    grid = object_grid(name)
    a, b = _random_segments(obj, 3000, seed=4)
    keep = _clear(obj, a, b, margin=1e-3)
    a, b = a[keep], b[keep]
    radius = np.full(len(a), 0.011)
    gap, s = capsule_gaps(grid, a, b, radius)
    half = 0.5 * np.linalg.norm(b - a, axis=1) / (SAMPLES - 1)
    frac = np.linspace(0.0, 1.0, SAMPLES)[None, :, None]
    sampled = interpolated(grid, a[:, None] + frac * (b - a)[:, None]).min(axis=1)
    refined = sampled - half - radius <= NEAR  # the bound the rule refines below NEAR
    assert 50 < refined.sum() < len(gap) - 50
    at_s = interpolated(grid, a + s[:, None] * (b - a))
    np.testing.assert_allclose(gap, at_s - radius - np.where(refined, 0.0, half), rtol=0,
                               atol=1e-15)
    t = np.linspace(0.0, 1.0, 2001)[None, :, None]
    dense = interpolated(grid, a[:, None] + t * (b - a)[:, None]).min(axis=1) - radius
    assert (gap[~refined] <= dense[~refined] + 1e-12).all()
    assert (gap[refined] - dense[refined]).max() < 6e-6
    exact = closest_to_segments(obj, a, b)[2] - radius
    near = np.abs(exact) < 2e-3
    assert near.sum() > 20
    assert np.abs(gap - exact)[near].max() < 5e-4
    # far away the gap is a lower bound up to the grid error
    assert np.all(gap[~near] <= exact[~near] + 5e-4)


def test_posed_min_distance_follows_the_grid():
    """posed_min_distance (compiled) against scipy's interpolation of the same grid
    (:func:`interpolated`, no shared code) at the posed points, rotations and translations
    at random, many points outside the lattice box: measured to 2.4e-17 m, bound 1e-15."""
    from scipy.spatial.transform import Rotation

    grid = object_grid("mug")
    rng = np.random.default_rng(5)
    poses = np.tile(np.eye(4), (50, 1, 1))
    poses[:, :3, :3] = Rotation.random(50, random_state=6).as_matrix()
    poses[:, :3, 3] = rng.uniform(-0.05, 0.1, size=(50, 3))
    local = rng.normal(scale=0.02, size=(40, 3))
    points = np.einsum("nij,pj->npi", poses[:, :3, :3], local) + poses[:, None, :3, 3]
    lo = grid.origin
    hi = grid.origin + grid.spacing * (np.array(grid.shape) - 1)
    assert ((points < lo) | (points > hi)).any(axis=-1).sum() > 50
    np.testing.assert_allclose(posed_min_distance(grid, poses, local),
                               interpolated(grid, points).min(axis=1), rtol=0, atol=1e-15)


def test_secant_root_finds_the_zero_of_a_smooth_gap():
    root = secant_root(lambda t: 0.3 * (t - 0.4) + 0.05 * (t - 0.4) ** 2, 0.4003,
                       0.3 * 0.0003 + 0.05 * 0.0003**2, 0.0, 1.0)
    assert root == pytest.approx(0.4, abs=1e-8)


@pytest.mark.parametrize("name", OBJECT_NAMES)
def test_fast_engine_at_sigma_zero_reproduces_the_nominal_grasps(name):
    grasps = shipped_grasps(name)
    draws = make_engine("fast", DEFAULT_ROBOT, name).run(np.stack([g.q0 for g in grasps]))
    assert np.all(draws.outcome == FORCE_CLOSURE)
    # both engines polish each contact to a gap of 1e-9 m, so they agree far inside the
    # 0.2 mm contact tolerance (not to round-off: the roots are found from different
    # brackets). Measured over the 48 shipped grasps: Q 2.95e-7 relative (drill), points
    # 2.5e-9 m (spray flask); tolerances about 3.4x and 4x that
    for i, g in enumerate(grasps):
        assert draws.n_contacts[i] == len(g.points)
        assert draws.quality[i] == pytest.approx(g.q_nominal, rel=1e-6, abs=0)
        np.testing.assert_allclose(draws.points[i, :len(g.points)], g.points, rtol=0,
                                   atol=1e-8)


def test_evaluate_with_the_fast_engine_is_reproducible_across_processes():
    """In this process (one engine call) and in chunks on two worker processes: the same
    statistics and the same draws, bit for bit."""
    from dataclasses import fields

    from kinegrasp_env.montecarlo.execution import LocalExecutor

    grasp = shipped_grasps("cube")[1]
    one = evaluate_grasp(grasp, sigma=0.02, n=300, seed=11, engine="fast")
    with LocalExecutor(2) as executor:
        two = evaluate_grasp(grasp, sigma=0.02, n=300, seed=11, engine="fast",
                             executor=executor)
    assert one.n == 300 and one.counts["force_closure"] > 2
    for field in fields(one):
        a, b = getattr(one, field.name), getattr(two, field.name)
        if field.name == "draws":
            for name in ("outcome", "quality", "n_contacts", "points", "normals", "finger",
                         "link", "hand"):
                np.testing.assert_array_equal(getattr(a, name), getattr(b, name),
                                              err_msg=name)
        else:
            np.testing.assert_equal(a, b, err_msg=field.name)
    with pytest.raises(ValueError, match="engine must be one of"):
        evaluate_grasp(grasp, sigma=0.02, n=10, engine="warp")


def test_chunks_run_together_give_the_draws_of_chunks_run_alone():
    """A run's rows closed in one call of the fast engine (the evaluation's) are the rows
    closed piece by piece (rows 60 c .. 60 c + 59 of the same run, each its own call)."""
    from kinegrasp_env.montecarlo.evaluate import evaluation_rows

    grasp = shipped_grasps("cube")[1]
    together = evaluate_grasp(grasp, sigma=0.02, n=4 * 60, seed=3, engine="fast").draws
    engine = make_engine("fast", DEFAULT_ROBOT, "cube")
    alone = []
    for c in range(4):
        q, errors = evaluation_rows(grasp, engine, sigma=0.02, n=60, seed=3, offset=60 * c)
        alone.append(engine.run(q, **errors))
    for field in ("outcome", "quality", "n_contacts", "points", "normals", "finger", "link"):
        np.testing.assert_array_equal(getattr(together, field),
                                      np.concatenate([getattr(a, field) for a in alone]))


def test_finger_axes_equal_the_capsule_axes_of_forward_kinematics():
    """finger_axes (Rodrigues rotations of the proximal joint frame, compiled), fed the
    default robot's capsule fingers as the compiled closing reads them from its description
    (:func:`~kinegrasp_env.closing.capsule_fingers.capsule_finger`), against the capsule
    ends placed by the robot's forward kinematics at the full configuration (the URDF chain,
    tested against pybullet in tests/test_kinematics.py), for random arm configurations,
    spreads and flexions over and past the joint ranges: to 4e-16 m (coordinates ~0.5 m,
    two code paths)."""
    from kinegrasp_env.closing.capsule_fingers import capsule_finger
    from kinegrasp_env.closing.finger_axes import finger_axes
    from kinegrasp_env.closing.generic_fast import FastRobotHand
    from kinegrasp_env.robot.catalog import load_robot

    hand = FastRobotHand(load_robot("kuka_sdh"), load_object("cube"), grid=object_grid("cube"))
    model = hand.description.model
    rng = np.random.default_rng(4)
    q = np.tile(shipped_grasps("cube")[0].q0, (50, 1))
    q[:, :7] += rng.normal(scale=0.3, size=(50, 7))
    q[:, 7:] = rng.uniform(-0.2, 1.6, size=(50, 7))
    values = model.expand(q)
    checked = 0
    for f, path in enumerate(hand.paths):
        finger = capsule_finger(f, path, hand.geometry)
        links = hand.kinematics.forward(q, [finger.parent, *path.links])
        flex = [finger.sign[j] * values[path.joints[j]] for j in range(2)]
        ends = finger_axes(links[finger.parent] @ finger.origin, finger.axis_p, flex[0],
                           finger.distal_origin, finger.axis_d, flex[1], finger.ends_p,
                           finger.ends_d)
        placed = [links[link][:, None, :3, :3] @ e[None, :, :, None]
                  for link, e in zip(path.links, (finger.ends_p, finger.ends_d), strict=True)]
        expected = np.concatenate(
            [p[..., 0] + links[link][:, None, :3, 3]
             for p, link in zip(placed, path.links, strict=True)], axis=1)
        np.testing.assert_allclose(ends, expected, rtol=0, atol=4e-16)
        checked += 1
    assert checked == 3


PRUNING_FREE_SEARCH = """
import os, sys
os.environ["NUMBA_DISABLE_JIT"] = "1"
import numpy as np
from kinegrasp_env.closing import segment_distance
from kinegrasp_env.world.objects import load_object
segment_distance.PRUNE_MARGIN = np.inf  # every margin-guarded pruning off
inputs = np.load(sys.argv[2])
found = segment_distance.closest_to_segments(load_object(sys.argv[1]), inputs["a"], inputs["b"])
np.savez(sys.argv[3], *found)
"""


@pytest.mark.parametrize("name", OBJECT_NAMES)
def test_segment_distance_prunings_change_no_bit(name, tmp_path):
    # the compiled search against the same search interpreted with every pruning that a
    # bound decides (part spheres, face planes, limits from other parts and ends) turned
    # off (PRUNE_MARGIN = inf): identical bit for bit, on segments at the distance of a
    # capsule axis in contact (where the bounds are tight) and at random
    import subprocess
    import sys

    obj = load_object(name)
    a, b = _random_segments(obj, 6000, seed=7)
    dist = closest_to_segments(obj, a, b)[2]
    keep = np.concatenate([np.flatnonzero(np.abs(dist - 0.01) < 0.004)[:600], np.arange(200)])
    assert keep.size > 500
    np.savez(tmp_path / "in.npz", a=a[keep], b=b[keep])
    subprocess.run([sys.executable, "-c", PRUNING_FREE_SEARCH, name, str(tmp_path / "in.npz"),
                    str(tmp_path / "out.npz")], check=True, timeout=600)
    plain = np.load(tmp_path / "out.npz")
    pruned = closest_to_segments(obj, a[keep], b[keep])
    for i, field in enumerate(("on_obj", "on_seg", "distance", "part")):
        np.testing.assert_array_equal(pruned[i], plain[f"arr_{i}"], err_msg=field)


def test_part_order_is_a_stable_argsort():
    # the exact search visits parts by increasing bound, ties by part index (the order
    # decides between parts at equal distance); part_order computes it without allocating:
    # numpy's stable argsort, NaN last, on values with many ties
    from kinegrasp_env.closing.segment_distance import part_order

    rng = np.random.default_rng(8)
    for n in list(range(1, 60)) * 20:
        values = rng.integers(0, max(2, n // 3), n) * 0.25  # many ties
        if rng.random() < 0.3:
            values = rng.normal(size=n)
        if rng.random() < 0.2:
            values[rng.integers(n)] = np.nan
        order = np.empty(n, np.int64)
        part_order(values, order)
        np.testing.assert_array_equal(order, np.argsort(values, kind="stable"))


@pytest.mark.parametrize("name", ["cube", "spray_flask", "mug"])
def test_search_below_a_limit_is_the_plain_search_there(name):
    """closest_to_segments with a limit (the closings' near-field queries, which need a
    distance only where it is below the contact band) against the plain search on
    segments clear of the object: the same pair bit for bit where the plain distance is
    below the limit, and the limit with NaN points (the distance is at least the limit)
    elsewhere; limits at a capsule radius from contact, and one below every distance."""
    obj = load_object(name)
    a, b = _random_segments(obj, 3000, seed=11)
    clear = _clear(obj, a, b)
    a, b = a[clear], b[clear]
    on_obj, on_seg, dist, part = closest_to_segments(obj, a, b)
    for limit in (0.01, 0.02, float(dist.min()) - 1e-6):
        found = closest_to_segments(obj, a, b, limit)
        below = dist < limit
        assert 0 < below.sum() < len(a) or limit < dist.min()
        for got, plain in zip(found, (on_obj, on_seg, dist, part), strict=True):
            np.testing.assert_array_equal(got[below], plain[below])
        np.testing.assert_array_equal(found[2][~below], limit)
        assert np.isnan(found[0][~below]).all() and np.isnan(found[1][~below]).all()
        np.testing.assert_array_equal(found[3][~below], -1)


@pytest.mark.parametrize("name", ["cube", "spray_flask", "mug"])
def test_search_started_near_a_known_point_changes_no_bit(name):
    """The exact search started from an object point found by an earlier query (the closing
    loop's: segment_search_near) against the plain search, bit for bit, on segments at
    random (many through the object), with four kinds of point: the closest point of the
    segment moved 0.1 mm (what the closing loop passes), a part's vertex at random, the
    segment's midpoint where it lies inside the object (closer to the segment than the
    distance function there, which for a segment through a part is an edge distance: the
    plain search must take over), and none (NaN)."""
    from kinegrasp_env.closing.segment_distance import (
        geometry_tuple,
        segment_bound,
        segment_buffers,
        segment_search,
        segment_search_near,
    )

    obj = load_object(name)
    geo = geometry_tuple(obj)
    work = segment_buffers(geo[0], geo[1])
    a, b = _random_segments(obj, 1500, seed=9)
    on_obj = closest_to_segments(obj, a, b)[0]
    rng = np.random.default_rng(10)
    shift = rng.normal(scale=1e-4, size=a.shape)
    vertices = geo[2].reshape(-1, 3)
    mid = 0.5 * (a + b) + shift
    inside = (obj.part_distance(mid) < 0).any(axis=1)
    through = 0
    for i in range(len(a)):
        ends = (*(a[i] + shift[i]), *(b[i] + shift[i]))
        segment_bound(geo, *ends, work)
        plain = segment_search(geo, *ends, work)
        points = [on_obj[i], vertices[rng.integers(len(vertices))], np.full(3, np.nan)]
        if inside[i]:
            points.append(mid[i])
            through += plain[0] > 1e-9  # the start (0 + the margin) is below the result
        for point in points:
            for known in (False, True):  # part bounds computed here, or already in work
                segment_bound(geo, *ends, work)
                assert segment_search_near(geo, *ends, work, *point, known) == plain, (i, point)
    assert through > 20  # the take-over was exercised


@pytest.mark.parametrize("name", OBJECT_NAMES)
def test_edge_blocks_cover_each_part_and_hold_their_edges(name):
    """The packed geometry's edge blocks: each part's edges are the part's own (the same
    set, reordered), split into consecutive blocks of at most BLOCK_EDGES, and every edge's
    ends lie inside its block's sphere (what skipping a block whole relies on)."""
    from kinegrasp_env.closing.packed_geometry import BLOCK_EDGES, pack

    obj = load_object(name)
    geo = pack(obj)
    for index, part in enumerate(obj.convex_parts):
        mine = geo.edges[geo.edge_start[index]:geo.edge_start[index + 1]]
        key = np.sort(np.round(part.edges.reshape(len(part.edges), 6), 12), axis=0)
        np.testing.assert_array_equal(np.sort(np.round(mine.reshape(len(mine), 6), 12),
                                              axis=0), key)
        blocks = range(geo.block_start[index], geo.block_start[index + 1])
        assert geo.block_edge[blocks[0]] == geo.edge_start[index]
        assert geo.block_edge[blocks[-1] + 1] == geo.edge_start[index + 1]
        for block in blocks:
            first, last = geo.block_edge[block], geo.block_edge[block + 1]
            assert 0 < last - first <= BLOCK_EDGES
            ends = geo.edges[first:last].reshape(-1, 3)
            assert (np.linalg.norm(ends - geo.block_center[block], axis=1)
                    <= geo.block_radius[block]).all()


@pytest.mark.parametrize("robot", ["kuka_sdh", "panda"])
def test_the_start_collision_test_alone_agrees_with_the_reference_closing(robot):
    """``starts_in_collision`` of the fast engine (its start-collision test, no closing)
    against the outcome of pybullet's reference closing of the same configurations: noisy
    draws of the shipped cube grasps, half of them with the hand's joints turned 0.6 rad
    past their pre-shape toward closing (many then start in the cube), the same verdict on
    every one."""
    from kinegrasp_env.montecarlo.draws import START_COLLISION
    from kinegrasp_env.sampling.noise import JointNoise

    fast = make_engine("fast", robot, "cube")
    description = fast.description
    arm = description.arm_dof
    rows = []
    for k, grasp in enumerate(shipped_grasps("cube", robot)[:3]):
        q = np.repeat(np.asarray(grasp.q0, dtype=float)[None], 40, axis=0)
        q[:, :arm] += JointNoise(0.02).sample(40, arm, np.random.default_rng(k))
        for j, name in enumerate(description.hand_joints):
            q[20:, arm + j] += 0.6 * description.close.get(name, 0)
        rows.append(q)
    q = np.concatenate(rows)
    with make_engine("pybullet", robot, "cube") as reference:
        expected = reference.run(q).outcome == START_COLLISION
    got = fast.starts_in_collision(q)
    assert 10 <= expected.sum() <= len(q) - 10, expected.sum()
    np.testing.assert_array_equal(got, expected)
