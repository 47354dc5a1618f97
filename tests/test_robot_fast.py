"""The fast engine of a description robot (the Panda on the cube) against the reference
engine (pybullet closest points) on the same draws: outcomes, contacts, exact distances,
sigma-0 force closure of the planned grasps and the P(FC) of a ranking."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from kinegrasp_env.closing.finger_paths import link_poses
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, START_COLLISION
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp, make_engine
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.toolkit.grasp_planner import plan_grasps

SIGMA = 0.0133
DRAWS = 60
#: Draws with the same outcome on both engines: 400 of 400 measured (4 grasps x 100 draws);
#: a draw whose closest pair is a tie (a pad over the cube's edge) may flip, so 97% is held.
SAME_OUTCOME = 0.97
#: Contact points: 90% within 3.7e-6 m measured (pybullet's GJK against the exact pair);
#: 1e-5 m held. The rest are ties of the closest pair (the edge under a pad or the pad's
#: patch centre), measured at most 7.5e-3 m apart: bounded by the pad (2 cm) here.
POINT_TOL, POINT_SHARE, POINT_MAX = 1e-5, 0.9, 0.02
#: Contact normals: 90% within 2.1e-4 measured (edge contacts: pybullet's normal from its
#: own pair); 2e-3 held.
NORMAL_TOL = 2e-3
#: Exact link-object distance against pybullet's (margins added back): at most 2.6e-6 m
#: measured (the fast pair the nearer, by the same amount at both openings: pybullet's GJK on
#: the jaw's hull over an edge) on 148 link distances of the first EXACT_DRAWS draws of each
#: grasp; 5e-6 m held (the contact tolerance is 2e-4 m).
GAP_TOL = 5e-6
EXACT_DRAWS = 12


@pytest.fixture(scope="module")
def grasps():
    return plan_grasps("panda", "cube", count=4, seed=0)


@pytest.fixture(scope="module")
def engines():
    fast, reference = make_engine("fast", "panda", "cube"), make_engine("pybullet", "panda",
                                                                         "cube")
    yield fast, reference
    fast.close()
    reference.close()


@pytest.fixture(scope="module")
def draws(grasps, engines):
    """(q (n, 8), fast draws, reference draws) per grasp, the same noise."""
    fast, reference = engines
    rng = np.random.default_rng(3)
    out = []
    for g in grasps:
        q = np.repeat(np.asarray(g.q0)[None], DRAWS, axis=0)
        q[:, :7] += JointNoise(SIGMA).sample(DRAWS, 7, rng)
        out.append((q, fast.run(q), reference.run(q)))
    return out


def test_same_outcomes_on_the_same_draws(draws):
    same = sum(int((a.outcome == b.outcome).sum()) for _, a, b in draws)
    total = sum(a.outcome.size for _, a, _ in draws)
    assert same >= SAME_OUTCOME * total, f"{same} of {total}"
    outcomes = np.concatenate([a.outcome for _, a, _ in draws])
    assert (outcomes == FORCE_CLOSURE).any() and (outcomes == START_COLLISION).any()


def test_contacts_match_the_reference(draws):
    point_err, normal_err = [], []
    for _, a, b in draws:
        for i in np.flatnonzero((a.n_contacts == b.n_contacts) & (a.n_contacts > 0)):
            k = a.n_contacts[i]
            oa = np.lexsort((a.link[i, :k], a.finger[i, :k]))
            ob = np.lexsort((b.link[i, :k], b.finger[i, :k]))
            assert np.array_equal(a.finger[i, oa], b.finger[i, ob])
            point_err += list(np.linalg.norm(a.points[i, oa] - b.points[i, ob], axis=1))
            normal_err += list(np.linalg.norm(a.normals[i, oa] - b.normals[i, ob], axis=1))
    point_err, normal_err = np.array(point_err), np.array(normal_err)
    assert point_err.size > 100
    assert np.mean(point_err <= POINT_TOL) >= POINT_SHARE, np.quantile(point_err, 0.9)
    assert point_err.max() <= POINT_MAX
    assert np.mean(normal_err <= NORMAL_TOL) >= POINT_SHARE, np.quantile(normal_err, 0.9)


def test_exact_distance_against_pybullet(draws, engines):
    """At the reference's closed state of noisy draws (pads on faces and over edges), and
    with the jaws opened from there by 2 mm, the fast closing's link distance (its exact
    convex pair) equals pybullet's (margins added back)."""
    fast, reference = engines
    world, hand = reference.world, fast.hand
    checked = 0
    for q_all, _, _ in draws:
        for q in q_all[:EXACT_DRAWS]:
            result = world.auto_close(q)
            if result.start_collision:
                continue
            for opening in (0.0, 0.002):
                values = {k: np.array([v + opening]) for k, v in result.joints.items()}
                world.set_joint_values({k: float(v[0]) for k, v in values.items()})
                palm = hand.obj.pose_inverse @ hand.kinematics.pose(q, hand.description.palm_link)
                for path in hand.paths:
                    for link in path.links:
                        pose = link_poses(palm, values, path.chains[link])
                        d = hand.exact(pose, link)[0]
                        expected, _ = world.gap((link,))
                        assert abs(d[0] - expected) <= GAP_TOL, (link, d[0], expected)
                        checked += 1
    assert checked >= 40


def test_sigma_zero_is_force_closure_on_both_engines(grasps, engines):
    for engine in engines:
        for g in grasps:
            r = evaluate_grasp(g, sigma=0.0, n=2, seed=0, engine=engine)
            assert r.p_fc == 1.0, (engine.name, g.id, r.counts)


def test_rank_intervals_overlap(grasps, engines):
    for g in grasps:
        a, b = (evaluate_grasp(g, sigma=SIGMA, n=300, seed=0, engine=e) for e in engines)
        assert a.ci[0] <= b.ci[1] and b.ci[0] <= a.ci[1], (g.id, a.ci, b.ci)


def test_engine_by_name_and_bad_name(grasps):
    r = evaluate_grasp(grasps[0], sigma=0.0, n=1, engine="fast")
    assert r.p_fc == 1.0
    with pytest.raises(ValueError, match="engine must be one of"):
        evaluate_grasp(grasps[0], sigma=0.0, n=1, engine="mujoco")


def test_cli_rank_and_evaluate_take_the_fast_engine(grasps, tmp_path, capsys):
    """``rank --engine fast`` and ``evaluate --engine fast`` of the Panda's grasps print the
    P(FC) that evaluate_grasp gives; ``--engine physics`` is refused in one line."""
    from kinegrasp_env.cli import main
    from kinegrasp_env.world.grasps import save_grasps

    path = tmp_path / "g.json"
    save_grasps(grasps[:2], path, planner_seed=0)
    out = tmp_path / "ranked.csv"
    assert main(["rank", str(path), "--sigma", str(SIGMA), "--samples", "40", "--engine",
                 "fast", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    for g in grasps[:2]:
        expected = evaluate_grasp(g, sigma=SIGMA, n=40, seed=0, engine="fast")
        assert f"{expected.p_fc:.3f}" in printed
    with open(out, newline="") as handle:
        assert {row["engine"] for row in csv.DictReader(handle)} == {"fast"}
    assert main(["evaluate", "--grasps", str(path), "--sigma", str(SIGMA), "--samples",
                 "10", "--engine", "fast", "--json"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["samples"] == 10
    assert main(["rank", str(path), "--samples", "10", "--engine", "physics"]) == 0


def test_a_mesh_object_same_outcomes_on_the_same_draws():
    """The drill (a mesh object, whose pybullet points lie up to its collision margin off the
    surface): the Panda's shipped drill grasps give the same outcome in both engines on at
    least SAME_OUTCOME of the same draws."""
    from kinegrasp_env.world.grasps import shipped_grasps

    fast, reference = make_engine("fast", "panda", "drill"), make_engine("pybullet", "panda",
                                                                        "drill")
    rng = np.random.default_rng(4)
    same = total = 0
    for g in shipped_grasps("drill", "panda")[:2]:
        q = np.repeat(np.asarray(g.q0)[None], DRAWS, axis=0)
        q[:, :7] += JointNoise(SIGMA).sample(DRAWS, 7, rng)
        a, b = fast.run(q), reference.run(q)
        same += int((a.outcome == b.outcome).sum())
        total += DRAWS
    fast.close()
    reference.close()
    assert same >= SAME_OUTCOME * total, f"{same} of {total}"


def _random_convex(rng, k: int) -> np.ndarray:
    """A counter-clockwise convex polygon (m, 2): scipy's hull of k random points."""
    from scipy.spatial import ConvexHull

    points = rng.normal(size=(k, 2))
    return points[ConvexHull(points).vertices]


def test_hull_2d_against_scipy():
    """The compiled 2-D hull (monotone chain) has scipy's (qhull's) vertices, counter-
    clockwise; collinear points give the segment of the extremes, one point itself."""
    from scipy.spatial import ConvexHull

    from kinegrasp_env.closing.polygon_2d import hull_2d

    rng = np.random.default_rng(1)
    for k in (3, 5, 12, 40):
        for _ in range(20):
            points = np.round(rng.normal(size=(k, 2)), 12)
            out = np.empty((2 * k, 2))
            m = hull_2d(points.copy(), k, out)
            expected = points[ConvexHull(points).vertices]
            assert m == len(expected)
            assert {tuple(p) for p in out[:m]} == {tuple(p) for p in expected}
            x, y = out[:m, 0], out[:m, 1]
            assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0  # CCW
    line = np.round(np.outer(rng.uniform(size=7), [1.0, 2.0]), 12)
    out = np.empty((14, 2))
    assert hull_2d(line.copy(), 7, out) == 2
    assert {tuple(p) for p in out[:2]} == {tuple(line[line[:, 0].argmin()]),
                                           tuple(line[line[:, 0].argmax()])}
    assert hull_2d(np.array([[0.5, 0.5], [0.5, 0.5]]), 2, out) == 1


def test_patch_clip_and_centroid_against_halfspaces():
    """Clipping a convex polygon by another, and the area centroid of the result, against
    scipy's half-space intersection of the two polygons' edges (qhull) and the centroid of a
    fan of its triangles; a disjoint pair clips to nothing."""
    from scipy.spatial import ConvexHull, HalfspaceIntersection

    from kinegrasp_env.closing.polygon_2d import centroid_2d, clip_convex

    rng = np.random.default_rng(2)
    checked = 0
    for _ in range(60):
        a, b = _random_convex(rng, 8), _random_convex(rng, 8) + rng.normal(scale=0.5, size=2)
        clipped = clip_convex(a, b)
        halfspaces = np.vstack([ConvexHull(p).equations for p in (a, b)])
        inside = np.mean(np.vstack([a, b]), axis=0)
        if len(clipped) < 3 or np.max(halfspaces[:, :2] @ inside + halfspaces[:, 2]) >= 0:
            continue  # the polygons' mean is no interior point of the overlap
        vertices = HalfspaceIntersection(halfspaces, inside).intersections
        ring = vertices[ConvexHull(vertices).vertices]
        tri = np.stack([np.repeat(ring[:1], len(ring) - 2, axis=0), ring[1:-1], ring[2:]], 1)
        u, w = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        area = 0.5 * np.abs(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0])
        expected = (area[:, None] * tri.mean(axis=1)).sum(axis=0) / area.sum()
        np.testing.assert_allclose(centroid_2d(clipped), expected, atol=1e-9)
        checked += 1
    assert checked >= 10
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert len(clip_convex(square + 3.0, square)) == 0


def test_compiled_distances_against_numpy_and_the_exact_pair(grasps, engines):
    """The link vertices against the object's parts (compiled) equal the numpy closest points
    of ``GraspObject.closest_points``, and with a limit ``below`` they are those wherever
    that is below it (at or above it elsewhere); GJK's bound lies below the exact link
    distance."""
    from kinegrasp_env.closing.hull_edges import vertices_against_parts

    hand = engines[0].hand
    rng = np.random.default_rng(5)
    q = np.repeat(np.asarray(grasps[0].q0)[None], 40, axis=0)
    q[:, :7] += JointNoise(3 * SIGMA).sample(40, 7, rng)
    poses = hand.kinematics.forward(q, list(hand.geometry))
    for link, geom in hand.geometry.items():
        pose = hand.obj.pose_inverse @ poses[link]
        rot = np.ascontiguousarray(pose[:, :3, :3])
        trans = np.ascontiguousarray(pose[:, :3, 3])
        verts = geom.vertices @ np.swapaxes(rot, 1, 2) + trans[:, None]
        _, d, _ = hand.obj.closest_points(verts.reshape(-1, 3))
        d = d.reshape(40, -1).min(axis=1)
        for below in (np.inf, float(np.median(d))):
            dist, fp, op = np.empty(40), np.empty((40, 3)), np.empty((40, 3))
            vertices_against_parts(*hand.distances.parts, rot, trans, geom.vertices, below,
                                   dist, fp, op)
            under = d < below
            np.testing.assert_allclose(dist[under], d[under], atol=1e-12)
            assert np.all(dist[~under] >= below), link
        exact = hand.exact(pose, link)[0]
        assert np.all(hand.distance_bound(pose, link)[0] <= exact + 1e-14), link


@pytest.mark.parametrize("robot", ["kuka_sdh", "panda"])
def test_a_fingers_compiled_poses_are_its_chain_products(robot):
    """The fast closing's poses of a finger's links (one compiled forward pass over the
    finger's joints from the palm, ``tree_poses``) equal the product of each link's chain
    joint by joint (``link_poses``, numpy; itself checked against pybullet's distances
    above) to 1e-12 m and rotation entries, at random joint values within the limits and
    random palm poses."""
    from kinegrasp_env.closing.finger_paths import tree_poses
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.kinematics import axis_angle_matrix

    engine = make_engine("fast", robot, "cube")
    rng = np.random.default_rng(4)
    palm = np.tile(np.eye(4), (50, 1, 1))
    axes = rng.normal(size=(50, 3))
    palm[:, :3, :3] = np.stack([axis_angle_matrix(a / np.linalg.norm(a), np.array([t]))[0]
                                for a, t in zip(axes, rng.uniform(-3, 3, 50), strict=True)])
    palm[:, :3, 3] = rng.uniform(-0.3, 0.3, (50, 3))
    model = load_robot(robot).model
    checked = 0
    for path in engine.hand.paths:
        values = {}
        for name in path.tree.model.actuated:
            joint = model.joint(name)
            lo, hi = max(joint.lower, -3.0), min(joint.upper, 3.0)
            values[name] = rng.uniform(lo, hi, 50)
        found = tree_poses(path.tree, palm, values, path.links)
        for link in path.links:
            np.testing.assert_allclose(found[link], link_poses(palm, values,
                                                               path.chains[link]),
                                       rtol=0, atol=1e-12)
            checked += 1
    assert checked >= 2
