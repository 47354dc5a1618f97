"""The fast engine of a description robot (the Panda on the cube) against the reference
engine (pybullet closest points) on the same draws: outcomes, contacts, exact distances,
sigma-0 force closure of the planned grasps and the P(FC) of a ranking."""

from __future__ import annotations

import json

import numpy as np
import pytest

from kinegrasp_env.closing.link_geometry import hull_samples
from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE, START_COLLISION
from kinegrasp_env.montecarlo.robot_evaluate import evaluate_robot_grasp, make_engine
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.toolkit.robot_planner import plan_robot_grasps

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
    return plan_robot_grasps("panda", "cube", count=4, seed=0)


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
                    for link in path["links"]:
                        pose = hand._link_poses(palm, values, link, path["chains"][link])
                        d, _, _ = hand._exact(pose, link)
                        expected, _ = world.gap((link,))
                        assert abs(d[0] - expected) <= GAP_TOL, (link, d[0], expected)
                        checked += 1
    assert checked >= 40


def test_sigma_zero_is_force_closure_on_both_engines(grasps, engines):
    for engine in engines:
        for g in grasps:
            r = evaluate_robot_grasp(g, sigma=0.0, n=2, seed=0, engine=engine)
            assert r.p_fc == 1.0, (engine.name, g.id, r.counts)


def test_rank_intervals_overlap(grasps, engines):
    for g in grasps:
        a, b = (evaluate_robot_grasp(g, sigma=SIGMA, n=300, seed=0, engine=e) for e in engines)
        assert a.ci[0] <= b.ci[1] and b.ci[0] <= a.ci[1], (g.id, a.ci, b.ci)


def test_engine_by_name_and_bad_name(grasps):
    r = evaluate_robot_grasp(grasps[0], sigma=0.0, n=1, engine="fast")
    assert r.p_fc == 1.0
    with pytest.raises(ValueError, match="engine must be one of"):
        evaluate_robot_grasp(grasps[0], sigma=0.0, n=1, engine="physics")


def test_hull_samples_lie_on_and_cover_the_hull():
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(0)
    vertices = rng.normal(size=(20, 3)) * [0.01, 0.02, 0.03]
    spacing = 2e-3
    points = hull_samples(vertices, spacing)
    hull = ConvexHull(vertices)
    values = points @ hull.equations[:, :3].T + hull.equations[:, 3]
    assert values.max() <= 1e-12 and np.all(np.abs(values).min(axis=1) <= 1e-12)
    tri = vertices[hull.simplices]  # random points on random triangles: within spacing
    w = rng.dirichlet(np.ones(3), size=500)
    pick = tri[rng.integers(len(tri), size=500)]
    probe = np.einsum("nk,nkj->nj", w, pick)
    nearest = np.min(np.linalg.norm(probe[:, None] - points[None], axis=2), axis=1)
    assert nearest.max() <= spacing


def test_cli_rank_and_evaluate_take_the_fast_engine(grasps, tmp_path, capsys):
    """``rank --engine fast`` and ``evaluate --engine fast`` of the Panda's grasps print the
    P(FC) that evaluate_robot_grasp gives; ``--engine physics`` is refused in one line."""
    from kinegrasp_env.cli import main
    from kinegrasp_env.world.grasps import save_grasps

    path = tmp_path / "g.json"
    save_grasps(grasps[:2], path, planner_seed=0)
    out = tmp_path / "ranked.csv"
    assert main(["rank", str(path), "--sigma", str(SIGMA), "--samples", "40", "--engine",
                 "fast", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    for g in grasps[:2]:
        expected = evaluate_robot_grasp(g, sigma=SIGMA, n=40, seed=0, engine="fast")
        assert f"{expected.p_fc:.3f}" in printed
    assert main(["evaluate", "--grasps", str(path), "--sigma", str(SIGMA), "--samples",
                 "10", "--engine", "fast", "--json"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["samples"] == 10
    assert main(["rank", str(path), "--samples", "10", "--engine", "physics"]) == 2
    assert "pybullet or fast engine only" in capsys.readouterr().err


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
